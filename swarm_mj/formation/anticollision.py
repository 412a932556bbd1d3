"""Anti-collision by altitude changes (paper Fig. 5, §5.3; SPEC §4).

Every rule has the same small interface, vectorised over drones (index 0 is the leader):

    rule.reset(positions (n, 3))
    pos_d, hold = rule.update(t, positions (n, 3), pos_d (n, 3), formation_alt)

``pos_d`` are the formation setpoints (slot of each follower; the leader's own reference
in row 0) and come back adjusted; ``hold`` (n,) flags drones told to keep their (x, y)
(their velocity reference should then be zero). Each rule appends its decisions to
``rule.events`` as dicts ``{t, drone, other, action}`` (action: up, down, release, climb,
cross, drop, hold).

Decentralised: a drone's decision uses only its own state, the leader's position (through
its slot and the formation altitude) and the positions of drones within its sensing range.
"""

from __future__ import annotations

import numpy as np

from ..errors import UserError


class NoRule:
    """No anti-collision (``anti_collision = "off"``): setpoints pass through unchanged."""

    name = "off"

    def __init__(self, n: int, **_: float) -> None:
        self.n = n
        self.events: list[dict] = []

    def reset(self, positions: np.ndarray) -> None:
        self.events = []

    def update(self, t: float, positions: np.ndarray, pos_d: np.ndarray, formation_alt: float):
        return pos_d, np.zeros(self.n, dtype=bool)


def _horizontal_distances(positions: np.ndarray) -> np.ndarray:
    """Pairwise horizontal distances (n, n), +inf on the diagonal."""
    d = positions[:, None, :2] - positions[None, :, :2]
    h = np.sqrt(np.einsum("ijk,ijk->ij", d, d))
    np.fill_diagonal(h, np.inf)
    return h


class PaperRule:
    """The paper's rule exactly as printed (Fig. 5), with the details SPEC §4 fixes.

    When two drones are closer than the safety distance D̄ = 0.8 m in the horizontal
    plane, the one with the higher index yields (a follower always yields to the leader):
    its altitude setpoint moves by ``hop`` = 0.4 m, up if it is not below the other drone,
    else down, its (x, y) setpoint unchanged. It returns to the formation altitude once
    every drone it yields to is back beyond D̄ + ``hysteresis``.
    """

    name = "paper"

    def __init__(self, n: int, safety_distance: float = 0.8, hop: float = 0.4, hysteresis: float = 0.05,
                 **_: float) -> None:
        self.n = n
        self.safety = float(safety_distance)
        self.hop = float(hop)
        self.hysteresis = float(hysteresis)
        self._lower = np.tril(np.ones((n, n), dtype=bool), -1)  # [i, j]: j < i, so i yields to j
        self.reset(np.zeros((n, 3)))

    def reset(self, positions: np.ndarray) -> None:
        self.offset = np.zeros(self.n)     # (n,) current altitude offset of each drone
        self.events: list[dict] = []

    def _react(self, t: float, positions: np.ndarray, h: np.ndarray, active: np.ndarray) -> None:
        """Trigger and release the altitude offsets of the drones flagged ``active`` (n,)."""
        yields = (h < self.safety) & self._lower & active[:, None] & active[None, :]
        trig = yields.any(axis=1) & (self.offset == 0.0)
        if trig.any():
            hh = np.where(yields, h, np.inf)
            for i in np.flatnonzero(trig):
                j = int(np.argmin(hh[i]))
                up = positions[i, 2] >= positions[j, 2]
                self.offset[i] = self.hop if up else -self.hop
                self.events.append({"t": t, "drone": int(i), "other": j, "action": "up" if up else "down"})
        held = self.offset != 0.0
        if held.any():
            clear = ~((h < self.safety + self.hysteresis) & self._lower).any(axis=1)
            for i in np.flatnonzero(held & clear):
                self.offset[i] = 0.0
                self.events.append({"t": t, "drone": int(i), "other": -1, "action": "release"})

    def update(self, t: float, positions: np.ndarray, pos_d: np.ndarray, formation_alt: float):
        h = _horizontal_distances(positions)
        self._react(t, positions, h, np.ones(self.n, dtype=bool))
        pos_d = pos_d.copy()
        pos_d[:, 2] += self.offset
        return pos_d, np.zeros(self.n, dtype=bool)


CLIMB, CROSS, FORMED = 0, 1, 2


class LayeredRule(PaperRule):
    """Ours (the default): altitude layers for the transition, then the paper's rule.

    Why: at 2–4 m/s closing speed the paper's 0.8 m trigger leaves 0.1–0.2 s, while a
    0.4 m altitude hop needs about 0.5 s, so the printed rule lets drones touch while the
    swarm forms up (SPEC §4, measured). What is the paper's: altitude changes only, the
    0.8 m safety distance, the 0.4 m step, higher index yields, and the reactive rule once
    formed. What is ours:

    1. climb — follower k first climbs in place to its own layer, formation altitude + k·hop;
    2. cross — it crosses to its slot on that layer; it holds its (x, y) while a drone of
       lower index (or one not crossing) is within D̄ horizontally and within ``hop`` vertically;
    3. drop — within ``arrive`` of its slot it drops to the formation altitude, but only when
       no drone within D̄ horizontally is between its layer and the formation altitude;
    4. formed — the paper's reactive rule among formed drones and the leader.
    """

    name = "layers"

    def __init__(self, n: int, safety_distance: float = 0.8, hop: float = 0.4, hysteresis: float = 0.05,
                 arrive: float = 0.2, climb_tolerance: float = 0.15, **_: float) -> None:
        self.arrive = float(arrive)
        self.climb_tol = float(climb_tolerance)
        super().__init__(n, safety_distance, hop, hysteresis)

    def reset(self, positions: np.ndarray) -> None:
        super().reset(positions)
        self.phase = np.full(self.n, CLIMB, dtype=np.int64)
        self.phase[0] = FORMED                      # the leader flies its own trajectory
        self.start_xy = positions[:, :2].copy()     # (n, 2) where each follower climbs in place
        self.hold_xy = positions[:, :2].copy()      # (n, 2) position held while waiting
        self.layer_index = np.arange(self.n, dtype=float)

    def update(self, t: float, positions: np.ndarray, pos_d: np.ndarray, formation_alt: float):
        if (self.phase == FORMED).all():
            return super().update(t, positions, pos_d, formation_alt)
        h = _horizontal_distances(positions)
        pos_d = pos_d.copy()
        hold = np.zeros(self.n, dtype=bool)
        layer = formation_alt + self.hop * self.layer_index          # (n,)
        z = positions[:, 2]
        # 1. climb in place
        climbing = self.phase == CLIMB
        done = climbing & (z >= layer - self.climb_tol)
        for i in np.flatnonzero(done):
            self.phase[i] = CROSS
            self.events.append({"t": t, "drone": int(i), "other": -1, "action": "cross"})
        climbing = self.phase == CLIMB
        pos_d[climbing, :2] = self.start_xy[climbing]
        pos_d[climbing, 2] = layer[climbing]
        hold |= climbing
        # 2. cross on the layer, holding (x, y) for a lower-index or non-crossing drone nearby
        crossing = self.phase == CROSS
        if crossing.any():
            near = (h < self.safety) & (np.abs(z[:, None] - z[None, :]) < self.hop)
            idx = np.arange(self.n)
            priority = (idx[None, :] < idx[:, None]) | (self.phase[None, :] != CROSS)
            blocked = crossing & (near & priority).any(axis=1)
            free = crossing & ~blocked
            self.hold_xy[free] = positions[free, :2]
            pos_d[crossing, 2] = layer[crossing]
            pos_d[blocked, :2] = self.hold_xy[blocked]
            hold |= blocked
            # 3. drop when over the slot and nobody is underneath
            at_slot = crossing & (np.hypot(*(positions[:, :2] - pos_d[:, :2]).T) < self.arrive)
            for i in np.flatnonzero(at_slot):
                below = (h[i] < self.safety) & (z <= z[i] + 0.05) & (z >= formation_alt - self.hop)
                if not below.any():
                    self.phase[i] = FORMED
                    self.events.append({"t": t, "drone": int(i), "other": -1, "action": "drop"})
        formed = self.phase == FORMED
        self._react(t, positions, h, formed)
        pos_d[formed, 2] += self.offset[formed]
        return pos_d, hold


ANTI_COLLISION_RULES = {"layers": LayeredRule, "paper": PaperRule, "off": NoRule}
AntiCollision = LayeredRule | PaperRule | NoRule


def make_rule(name: str, n: int, where: str = "formation.anti_collision", **params: float):
    """Build an anti-collision rule by name (``layers`` default, ``paper``, ``off``)."""
    if name not in ANTI_COLLISION_RULES:
        raise UserError(f"unknown rule {name!r}; choose one of {', '.join(ANTI_COLLISION_RULES)}", where=where)
    return ANTI_COLLISION_RULES[name](n, **params)
