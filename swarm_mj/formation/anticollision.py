"""Anti-collision by altitude changes (paper Fig. 5, §4, §5.3; docs/interpretations.md §4): the rules'
interface, the paper's rule and ``ANTI_COLLISION_RULES``. The layered rule (:class:`LayeredRule`, the
default) and the rules built on it (:class:`ClearanceRule`, the layered rule kept out of each other's
downwash, ``clearance``, opt-in; :class:`CompensatedRule`) are in :mod:`swarm_mj.formation.layered_rule`
and re-exported here.

Every rule has the same small interface, vectorised over drones (index 0 is the leader):

    rule.reset(positions (n, 3))
    pos_d, steer = rule.update(t, positions (n, 3), pos_d (n, 3), formation_alt)

``pos_d`` are the formation setpoints (slot of each follower, paper §4; the leader's own
reference in row 0) and come back adjusted. ``steer`` (n,) flags the drones whose velocity
and acceleration references the rule sets itself: ``rule.vel_d`` (n, 3) and ``rule.acc_d``
(n, 3) (zero for a drone told to hold its (x, y)); the others keep the formation's
references. ``rule.references(t, positions, pos_d, vel_d, acc_d, formation_alt)`` does both
and returns the controller's references (pos_d, vel_d, acc_d) (n, 3), the steered drones'
rows taken from the rule (what the policy calls; for the formed swarm the layered rule does
it in one compiled kernel). Each rule appends its decisions to ``rule.events`` as dicts
``{t, drone, other, action}``: up, down, release (the paper's rule); cross, hold, aside,
drop (the layered rule's transition); wait (on the ground) and round (going round a drone) of
the default, the downwash-aware ``clearance`` (:class:`ClearanceRule`).

Decentralised (docs/interpretations.md §4): a drone's decision uses only its own state, the leader's position
(through its slot and the formation altitude) and the positions of drones within its
sensing range (velocities of neighbours are estimated from their successive positions).
No rule reads another drone's internal state; the layered rule uses the other drones'
indices (the priority of Fig. 5: higher index yields) and whether they are still in
transit to their slot, which a drone broadcasts or which its neighbours can tell from
its altitude (a formed drone flies at the formation altitude).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .._jit import jit
from ..errors import UserError


@jit(samples=lambda: [(np.zeros(2), np.full((2, 2), np.inf), 0.8)])
def react_needed(offset: np.ndarray, h: np.ndarray, safety: float) -> bool:
    """Fig. 5 has work to do: a drone holds an altitude offset (n,), or two drones are closer
    than ``safety`` horizontally (h (n, n))."""
    for x in offset:
        if x != 0.0:
            return True
    for x in h.flat:
        if x < safety:
            return True
    return False


@jit(samples=lambda: [(np.ones(2, dtype=np.bool_), *([np.zeros((2, 3))] * 4))])
def merge_rows(steer: np.ndarray, rule_vel: np.ndarray, rule_acc: np.ndarray, vel: np.ndarray, acc: np.ndarray):
    """Copies of vel, acc (n, 3) whose rows where steer (n,) is set come from rule_vel, rule_acc."""
    v = vel.copy()
    a = acc.copy()
    for i in range(steer.shape[0]):
        if steer[i]:
            for j in range(3):
                v[i, j] = rule_vel[i, j]
                a[i, j] = rule_acc[i, j]
    return v, a


@jit(samples=lambda: [(np.zeros((2, 3)),)])
def horizontal_distances(pos: np.ndarray) -> np.ndarray:
    """Pairwise horizontal distances (n, n) of positions (n, 3), +inf on the diagonal."""
    n = pos.shape[0]
    h = np.empty((n, n))
    for i in range(n):
        h[i, i] = np.inf
        for j in range(i + 1, n):
            dx = pos[j, 0] - pos[i, 0]
            dy = pos[j, 1] - pos[i, 1]
            d = np.sqrt(dx * dx + dy * dy)
            h[i, j] = d
            h[j, i] = d
    return h


class Rule:
    """What every rule shares: :meth:`references` from the rule's own ``update``.

    A new rule subclasses it with ``name``, ``events``, ``vel_d``, ``acc_d`` (n, 3), ``reset(positions)``
    and ``update(t, positions, pos_d, formation_alt) -> (pos_d, steer)`` (see the module docstring),
    and is registered in :data:`ANTI_COLLISION_RULES` (which makes it a scenario's
    ``formation.anti_collision`` value and a ``--anti-collision`` choice)."""

    name: str
    n: int
    events: list[dict]
    vel_d: np.ndarray  # (n, 3) velocity reference of the steered drones
    acc_d: np.ndarray  # (n, 3) acceleration reference of the steered drones

    def __init__(self, n: int, **params: Any) -> None:
        self.n = n

    def reset(self, positions: np.ndarray) -> None:
        """Start of a run with the drones at positions (n, 3)."""
        raise NotImplementedError

    def update(
        self, t: float, positions: np.ndarray, pos_d: np.ndarray, formation_alt: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """Adjusted setpoints pos_d (n, 3) and the drones it steers, steer (n,) bool."""
        raise NotImplementedError

    #: whether the controller is to compensate the downwash of the other drones (when the physics has
    #: one; see :class:`~swarm_mj.policy.DownwashFeedforward`)
    downwash_feedforward = False

    def references(
        self,
        t: float,
        positions: np.ndarray,
        pos_d: np.ndarray,
        vel_d: np.ndarray,
        acc_d: np.ndarray,
        formation_alt: float,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`update` and the references the controller needs, (pos_d, vel_d, acc_d) (n, 3):
        the drones the rule steers take its velocity and acceleration references."""
        return _merged(self, *self.update(t, positions, pos_d, formation_alt), vel_d, acc_d)


class NoRule(Rule):
    """No anti-collision (``anti_collision = "off"``): setpoints pass through unchanged."""

    name = "off"

    def __init__(self, n: int, **_: float) -> None:
        self.n = n
        self.events: list[dict] = []
        self.vel_d = np.zeros((n, 3))
        self.acc_d = np.zeros((n, 3))

    def reset(self, positions: np.ndarray) -> None:
        self.events = []

    def update(
        self, t: float, positions: np.ndarray, pos_d: np.ndarray, formation_alt: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """Pass the formation setpoints (n, 3) through; steer nobody."""
        return pos_d, np.zeros(self.n, dtype=bool)


def _merged(
    rule, pos_d: np.ndarray, steer: np.ndarray, vel_d: np.ndarray, acc_d: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(pos_d, vel_d, acc_d) with the rows of the steered drones (n,) from rule.vel_d, rule.acc_d."""
    vel_d, acc_d = merge_rows(
        steer,
        rule.vel_d,
        rule.acc_d,
        np.ascontiguousarray(vel_d, dtype=np.float64),
        np.ascontiguousarray(acc_d, dtype=np.float64),
    )
    return pos_d, vel_d, acc_d


def _rownorm(v: np.ndarray) -> np.ndarray:
    """Euclidean norm of each row of v (n, k) (_rownorm(v), without its overhead)."""
    return np.sqrt(np.einsum("ij,ij->i", v, v))


def _clip_norm(v: np.ndarray, limit: float) -> np.ndarray:
    """Rows of v (n, k) scaled down to a norm of at most ``limit``."""
    nrm = _rownorm(v)
    return v * np.minimum(1.0, limit / np.maximum(nrm, 1e-12))[:, None]


def _stoppable_speed(room: float, accel: float, lag: float) -> float:
    """Largest v with v²/(2·0.8·accel) + v·lag ≤ room (room floored at 0.1 m)."""
    k = 1.0 / (1.6 * accel)
    room = max(room, 0.1)
    return float((-lag + np.sqrt(lag * lag + 4.0 * k * room)) / (2.0 * k))


def _horizontal_distances(positions: np.ndarray) -> np.ndarray:
    """Pairwise horizontal distances (n, n), +inf on the diagonal."""
    return horizontal_distances(np.ascontiguousarray(positions, dtype=np.float64))


class PaperRule(Rule):
    """The paper's rule exactly as printed (Fig. 5, §4), with the details docs/interpretations.md §4 fixes.

    When two drones are closer than the safety distance D̄ = 0.8 m in the horizontal
    plane, the one with the higher index yields (a follower always yields to the leader):
    its altitude setpoint moves by ``hop`` = 0.4 m, up if it is not below the other drone,
    else down, its (x, y) setpoint unchanged. It returns to the formation altitude once
    every drone it yields to is back beyond D̄ + ``hysteresis`` (docs/interpretations.md §4: "a little
    hysteresis"; the paper does not say when a drone returns).
    """

    name = "paper"

    def __init__(
        self, n: int, safety_distance: float = 0.8, hop: float = 0.4, hysteresis: float = 0.05, **_: float
    ) -> None:
        self.n = n
        self.safety = float(safety_distance)
        self.hop = float(hop)
        self.hysteresis = float(hysteresis)
        self._lower = np.tril(np.ones((n, n), dtype=bool), -1)  # [i, j]: j < i, so i yields to j
        self.vel_d = np.zeros((n, 3))  # (n, 3) velocity reference of steered drones
        self.acc_d = np.zeros((n, 3))  # (n, 3) acceleration reference of steered drones
        self.reset(np.zeros((n, 3)))

    def reset(self, positions: np.ndarray) -> None:
        self.offset = np.zeros(self.n)  # (n,) current altitude offset of each drone
        self.events: list[dict] = []

    def _react(self, t: float, positions: np.ndarray, h: np.ndarray, active: np.ndarray) -> None:
        """Fig. 5: trigger and release the altitude offsets of the drones flagged ``active`` (n,)."""
        if not react_needed(self.offset, h, self.safety):
            return  # nobody held, nobody inside D̄: nothing to trigger or release
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
            clear = ~((h < self.safety + self.hysteresis) & self._lower & active[None, :]).any(axis=1)
            for i in np.flatnonzero(held & clear):
                self.offset[i] = 0.0
                self.events.append({"t": t, "drone": int(i), "other": -1, "action": "release"})

    def update(
        self, t: float, positions: np.ndarray, pos_d: np.ndarray, formation_alt: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """Fig. 5 on every drone: altitude offsets only, (x, y) setpoints unchanged."""
        h = _horizontal_distances(positions)
        self._react(t, positions, h, np.ones(self.n, dtype=bool))
        pos_d = pos_d.copy()
        pos_d[:, 2] += self.offset
        return pos_d, np.zeros(self.n, dtype=bool)


# The layered rule and the rules built on it live in layered_rule.py, imported here (re-exported)
# once PaperRule and the helpers it uses are defined: swarm_mj.formation imports this module first.
from .layered_rule import (  # noqa: E402
    CLIMB,
    CROSS,
    FOOTPRINT_M,
    FORMED,
    HOVER_MIN_M,
    ClearanceRule,
    CompensatedRule,
    G,
    LayeredRule,
    jet_clearance,
)

ANTI_COLLISION_RULES: dict[str, type[Rule]] = {
    "layers": LayeredRule,
    "paper": PaperRule,
    "off": NoRule,
    "clearance": ClearanceRule,
    "compensated": CompensatedRule,
}
AntiCollision = LayeredRule | PaperRule | NoRule | ClearanceRule | CompensatedRule


__all__ = [
    "ANTI_COLLISION_RULES",
    "AntiCollision",
    "CLIMB",
    "CROSS",
    "FOOTPRINT_M",
    "FORMED",
    "G",
    "HOVER_MIN_M",
    "ClearanceRule",
    "CompensatedRule",
    "LayeredRule",
    "NoRule",
    "PaperRule",
    "Rule",
    "horizontal_distances",
    "jet_clearance",
    "make_rule",
    "merge_rows",
    "react_needed",
]

_Rule = Rule  # the former name


def make_rule(name: str, n: int, where: str = "formation.anti_collision", **params: Any) -> Rule:
    """Build an anti-collision rule by name (``layers`` default, ``paper``, ``off``, ``clearance``,
    ``compensated``)."""
    if name not in ANTI_COLLISION_RULES:
        raise UserError(f"unknown rule {name!r}; choose one of {', '.join(ANTI_COLLISION_RULES)}", where=where)
    return ANTI_COLLISION_RULES[name](n, **params)
