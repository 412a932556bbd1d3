"""Anti-collision by altitude changes (paper Fig. 5, §4, §5.3; docs/interpretations.md §4): the rules'
interface, the paper's rule and ``ANTI_COLLISION_RULES``. The layered rule (:class:`LayeredRule`, the
default under the paper's physics) and the rules built on it (:class:`JetAwareRule`, the default
under downwash; :class:`ClearanceRule`, the layered rule kept out of each other's downwash,
``clearance``, opt-in; :class:`CompensatedRule`) follow; ``"auto"`` picks the default for the
physics (:func:`resolve_rule`); :meth:`LayeredRule.update` is the
transition as a sequence of steps (sense, climb, cross, drop, formed, fly the paths).

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
the downwash-aware ``clearance`` (:class:`ClearanceRule`).

Decentralised (docs/interpretations.md §4): a drone's decision uses only its own state, the leader's position
(through its slot and the formation altitude) and the positions of drones within its
sensing range (velocities of neighbours are estimated from their successive positions).
No rule reads another drone's internal state; the layered rule uses the other drones'
indices (the priority of Fig. 5: higher index yields) and whether they are still in
transit to their slot, which a drone broadcasts or which its neighbours can tell from
its altitude (a formed drone flies at the formation altitude).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .._jit import jit
from ..errors import UserError
from .layered import advance_altitude_kernel, advance_paths_kernel, formed_step_kernel


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


@jit(samples=lambda: [(np.full((2, 2), np.inf), 0.8)])
def any_below(h: np.ndarray, limit: float) -> bool:
    """Some pair (i, j), j < i, of the distances h (n, n) is below ``limit``."""
    for i in range(h.shape[0]):
        for j in range(i):
            if h[i, j] < limit:
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


# --------------------------------------------------------------------------- the layered rule and the rules built on it
CLIMB, CROSS, FORMED = 0, 1, 2
G = 9.81  # m/s², paper Table 1 (docs/interpretations.md §1)
HOVER_MIN_M = 0.3  # a waiting follower lifts off the ground to this height when there is room
FOOTPRINT_M = 0.35  # centre to rotor tip: L + rotor radius = 0.25 + 0.09 m (docs/interpretations.md §1), rounded


@dataclass
class _Step:
    """What one step of the layered rule's transition (:meth:`LayeredRule.update`) works from and
    on, shared by its steps (n drones; index 0 is the leader)."""

    t: float
    positions: np.ndarray  # (n, 3)
    pos_d: np.ndarray  # (n, 3) the setpoints, a copy the steps adjust
    formation_alt: float
    dt: float
    steer: np.ndarray  # (n,) the drones the rule steers: every follower
    h: np.ndarray  # (n, n) horizontal distances
    z: np.ndarray  # (n,) altitudes
    layer: np.ndarray  # (n,) each follower's layer
    z_target: np.ndarray  # (n,) altitude target of the altitude paths
    z_target_vel: np.ndarray  # (n,) its velocity
    idx: np.ndarray  # (n,) drone indices (the priority: higher index yields)
    in_transit: bool  # some follower is not formed yet
    seen: np.ndarray  # (n, n) drone i sees drone j (within sensing_range; the leader always)
    soon: np.ndarray  # (n, n) smallest horizontal distance over the horizon, +inf if unseen
    vband: np.ndarray  # (n, n) swept altitude bands overlap, and seen
    goal: np.ndarray = field(init=False)  # (n, 2) horizontal goals, set by the cross step
    goal_vel: np.ndarray = field(init=False)  # (n, 2) their velocity


class LayeredRule(PaperRule):
    """Ours (``anti_collision = "layers"``, the default under the paper's physics): altitude layers for the transition
    from the start to the slot, then the paper's rule.

    **Why not the printed rule alone** (docs/interpretations.md §4, and measured here in MuJoCo with
    ``swarm-mj stress``): drones close at 2–4 m/s while forming up, so the 0.8 m trigger
    leaves 0.1–0.2 s, and a 0.4 m altitude hop takes about 0.5 s: the printed rule lets them
    touch.

    **What is the paper's** (Fig. 5, §4): collisions are avoided by changes of altitude
    while each follower keeps aiming at its (x, y) slot; the safety distance D̄ = 0.8 m;
    the 0.4 m step (``hop``); the higher index yields and a follower always yields to the
    leader; once a follower has joined the formation, the printed reactive rule
    (:class:`PaperRule`) among formed followers and the leader is what protects it.

    **What is ours**, per follower k (1-based), each decision using only the leader's
    position and the drones within ``sensing_range`` (3D):

    1. *climb* — in place, to its own layer: formation altitude + k·``hop`` (docs/interpretations.md §4's
       design). It does not climb into a drone above it that is (or, predicted over
       ``horizon`` s, will be) within D̄ + 0.2 m horizontally — 2·FOOTPRINT + 0.1 m for a
       follower that hovers — nor into the leader when level with it: it waits ``hop``
       under it (no higher than it is: it does not chase a climbing drone), or climbs over
       if it can no longer stop below and the other is not straight overhead. Waiting under
       one that stays (a hovering leader, a follower over its slot), it steps aside.
    2. *cross* — once within ``climb_tolerance`` of its layer, it flies to its slot on the
       layer along a limited path (speed ≤ ``max_speed``, acceleration ≤ ``max_accel`` and
       ≤ what ``max_tilt_deg`` of tilt gives at the current thrust, jerk ≤ ``jerk``) whose
       position, velocity and acceleration go to the controller. Why: unshaped, the
       backstepping loop flies a 4 m transfer at 5 m/s and 45–60° of tilt, nothing can stop
       it within D̄, and tilted rotors reach 0.3 m up or down, most of a layer. It brakes to
       rest while a drone it gives way to — the leader, a lower index, or any drone not
       crossing — is predicted within D̄ horizontally before it could stop, in an altitude
       band it sweeps (``clearance``).
    3. *drop* — within ``arrive`` of its slot it descends to the formation altitude, but
       only when no drone still in transit is (or will be) within D̄ under it, and while
       descending it never comes within ``hop`` above one (docs/interpretations.md §4: the one failure of the
       layered design on the independent model was a drone dropping through another's
       layer).
    4. *formed* — the paper's reactive rule.

    Every follower's altitude also follows a limited path (see :meth:`_advance_altitude`:
    a 1 m step down puts eq. (18)'s thrust on its floor and the drone flies off sideways).
    Speeds are capped so that a drone can stop within what it senses (climbing, ``hop``
    under a drone first seen straight above; crossing, D̄ + 0.2 m short of one first seen
    ahead): with ``sensing_range`` = 4 m the caps are the 4 m/s defaults; at 2 m they fall to
    2.7 m/s (climb) and 2.35 m/s (cross), and then the leader, which climbs at 3.5 m/s and
    yields to nobody, catches followers climbing beside its path (measured: 5 of 100 random
    starts touch at 2 m, 0 of 300 at 4 m).

    Settling (every leader distance within 5 cm of D) is a horizontal criterion, so a
    follower counts as in place while still on its layer; the drop comes after.
    """

    name = "layers"

    def __init__(
        self,
        n: int,
        safety_distance: float = 0.8,
        hop: float = 0.4,
        hysteresis: float = 0.05,
        arrive: float = 0.2,
        climb_tolerance: float = 0.35,
        clearance: float = 0.3,
        max_speed: float = 4.0,
        max_accel: float = 6.0,
        horizon: float = 1.0,
        climb_speed: float = 4.0,
        climb_accel: float = 8.0,
        descent_speed: float = 1.5,
        descent_accel: float = 5.0,
        jerk: float = 120.0,
        velocity_gain: float = 15.0,
        max_tilt_deg: float = 30.0,
        sensing_range: float = 4.0,
        **_: float,
    ) -> None:
        self.arrive = float(arrive)
        self.climb_tol = float(climb_tolerance)
        self.clearance = float(clearance)
        self.v_max = float(max_speed)
        self.a_max = float(max_accel)
        self.horizon = float(horizon)
        self.z_up = (float(climb_speed), float(climb_accel))
        self.z_down = (float(descent_speed), float(descent_accel))
        self.z_down_formed = self.z_down  # (speed, accel) of descents once every follower is formed
        self.jerk = float(jerk)
        self.k_v = float(velocity_gain)
        self.tan_tilt = float(np.tan(np.radians(max_tilt_deg)))
        self.sensing_range = float(sensing_range)
        # No faster than it can stop within what it sees (``sensing_range``, 3D): climbing, hop
        # under a drone first seen straight above; crossing, D̄ + 0.2 m short of a drone first
        # seen ahead. Braking at a, with the acceleration turning round in ``lag`` s:
        # v²/(2·0.8·a) + v·lag ≤ room.
        ad = self.z_down[1]
        self.z_up = (
            min(
                self.z_up[0],
                _stoppable_speed(
                    self.sensing_range - float(hop) - 0.2, ad, (self.z_up[1] + ad) / self.jerk + 1.0 / self.k_v
                ),
            ),
            self.z_up[1],
        )
        a_h = min(self.a_max, G * self.tan_tilt)
        self.v_max = min(
            self.v_max,
            _stoppable_speed(
                self.sensing_range - float(safety_distance) - 0.2, a_h, 2.0 * self.a_max / self.jerk + 1.0 / self.k_v
            ),
        )
        super().__init__(n, safety_distance, hop, hysteresis)

    def reset(self, positions: np.ndarray) -> None:
        super().reset(positions)
        n = self.n
        self.phase = np.full(n, CLIMB, dtype=np.int64)
        self.phase[0] = FORMED  # the leader flies its own trajectory
        self._all_formed = bool((self.phase == FORMED).all())  # phases change only in update()
        self.start_xy = positions[:, :2].copy()  # (n, 2) where each follower climbs in place
        self.path_p = positions[:, :2].copy()  # (n, 2) crossing path: position
        self.path_v = np.zeros((n, 2))  # (n, 2) crossing path: velocity
        self.path_a = np.zeros((n, 2))  # (n, 2) crossing path: acceleration
        self.blocked = np.zeros(n, dtype=bool)  # (n,) braking for another drone
        self.asides = np.zeros(n, dtype=np.int64)  # (n,) times stepped out from under a drone
        self.layer_index = np.arange(n, dtype=float)
        self.zp = positions[:, 2].copy()  # (n,) altitude path: position
        self.zv = np.zeros(n)  # (n,) altitude path: velocity
        self.za = np.zeros(n)  # (n,) altitude path: acceleration
        self._prev_pos = np.array(positions, dtype=float)  # (n, 3) updated in place
        self._prev_t: float | None = None
        self.vel = np.zeros((n, 3))  # (n, 3) velocities estimated from positions
        self._all = np.ones(n, dtype=bool)  # (n,) every drone (read-only)
        self._followers = np.ones(n, dtype=bool)  # (n,) the drones the rule steers (read-only)
        self._followers[0] = False

    # ------------------------------------------------------------------ helpers
    def _approach(self, positions: np.ndarray, horizon: float) -> np.ndarray:
        """(n, n) smallest horizontal distance of each pair over the next ``horizon`` s,
        predicting the relative motion as a straight line (velocities estimated from
        positions); +inf on the diagonal."""
        d = positions[None, :, :2] - positions[:, None, :2]  # (n, n, 2) j − i
        dv = self.vel[None, :, :2] - self.vel[:, None, :2]  # (n, n, 2)
        vv = np.einsum("ijk,ijk->ij", dv, dv)
        tc = np.clip(-np.einsum("ijk,ijk->ij", d, dv) / np.maximum(vv, 1e-9), 0.0, horizon)
        m = d + tc[:, :, None] * dv
        out = np.sqrt(np.einsum("ijk,ijk->ij", m, m))
        np.fill_diagonal(out, np.inf)
        return out

    def _vertical_overlap(self, z: np.ndarray, tau: float) -> np.ndarray:
        """(n, n) the altitude bands swept over the next ``tau`` s (estimated vertical
        velocity), widened by ``clearance``, overlap."""
        z2 = z + self.vel[:, 2] * tau
        lo, hi = np.minimum(z, z2) - 0.5 * self.clearance, np.maximum(z, z2) + 0.5 * self.clearance
        return (lo[None, :] < hi[:, None]) & (lo[:, None] < hi[None, :])

    def _advance_paths(self, dt: float, goal: np.ndarray, goal_vel: np.ndarray) -> None:
        """Move every follower's horizontal path towards ``goal`` (n, 2), which moves at
        ``goal_vel`` (n, 2): speed ≤ ``max_speed`` relative to the goal with a braking
        profile v = √(2·0.8·a·e), acceleration ≤ ``max_accel``; blocked drones brake to rest."""
        if dt <= 0.0:
            self.path_a[:] = 0.0
            return
        advance_paths_kernel(
            float(dt),
            np.ascontiguousarray(goal, dtype=np.float64),
            np.ascontiguousarray(goal_vel, dtype=np.float64),
            self.path_p,
            self.path_v,
            self.path_a,
            self.blocked,
            self.za,
            self.a_max,
            self.jerk,
            self.k_v,
            self.v_max,
            self.tan_tilt,
            G,
        )

    def _advance_altitude(self, dt: float, target: np.ndarray, target_vel: np.ndarray) -> None:
        """Move the altitude paths (n,) towards ``target`` (n,) (moving at ``target_vel`` (n,)).

        Why a path and not a step: the backstepping thrust (eq. 18) falls to its floor when a
        drone is told to drop by a metre at once, and with U1 at the floor the desired roll
        and pitch of eqs. (21)–(22) saturate at 45° (measured: a follower dropping 1.1 m as a
        step flew off sideways at 10 m/s). So upward accelerations (more thrust) may reach
        ``climb_accel``, downward ones (less thrust) only ``descent_accel``; the speed is
        capped at ``climb_speed`` up and ``descent_speed`` down.
        """
        if dt <= 0.0:
            self.za[:] = 0.0
            return
        (vu, au), (vd, ad) = self.z_up, self.z_down
        advance_altitude_kernel(
            float(dt),
            np.ascontiguousarray(target, dtype=np.float64),
            np.ascontiguousarray(target_vel, dtype=np.float64),
            self.zp,
            self.zv,
            self.za,
            vu,
            au,
            vd,
            ad,
            self.jerk,
            self.k_v,
        )

    # ------------------------------------------------------------------ the rule
    def _update_formed(
        self, t: float, positions: np.ndarray, pos_d: np.ndarray, formation_alt: float, dt: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """4. *formed* for the whole swarm (every follower formed, nobody in transit): the paper's
        reactive rule (Fig. 5) and the paths to the slots, in one compiled kernel."""
        return _update_formed_impl(self, t, positions, pos_d, formation_alt, dt)

    def update(
        self, t: float, positions: np.ndarray, pos_d: np.ndarray, formation_alt: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """Climb / cross / drop (ours) for followers not yet formed, Fig. 5 for the others."""
        dt = self._estimate_velocities(t, positions)
        if self._all_formed:
            return self._update_formed(t, positions, pos_d, formation_alt, dt)
        s = self._sense(t, positions, pos_d, formation_alt, dt)
        self._climb(s)
        self._cross(s)
        self._drop(s)
        self._formed(s)
        return self._fly_paths(s)

    # ------------------------------------------------------------------ its steps
    def _estimate_velocities(self, t: float, positions: np.ndarray) -> float:
        """The step dt since the last update and every drone's velocity estimated from its
        successive positions (decentralised: no drone reads another's velocity)."""
        dt = 0.0 if self._prev_t is None else float(t - self._prev_t)
        if dt > 0.0:
            np.subtract(positions, self._prev_pos, out=self.vel)
            self.vel /= dt
        self._prev_t = float(t)
        self._prev_pos[:] = positions
        return dt

    def _sense(self, t: float, positions: np.ndarray, pos_d: np.ndarray, formation_alt: float, dt: float) -> _Step:
        """What this step of the transition works from (ours): each follower's layer and altitude
        target, and who sees whom within ``sensing_range`` (the leader's position it always has:
        the slots are built from it), with the predicted approaches and the swept altitude bands."""
        n = self.n
        z = positions[:, 2]
        layer = formation_alt + self.hop * self.layer_index  # (n,)
        steer = np.ones(n, dtype=bool)
        steer[0] = False  # the leader: its trajectory
        self.vel_d[:] = 0.0
        self.acc_d[:] = 0.0
        # (computed even when nobody is in transit, which cannot happen here: every step that reads
        # these then does nothing, as before)
        rel = positions[None, :, :] - positions[:, None, :]
        seen = np.einsum("ijk,ijk->ij", rel, rel) < self.sensing_range**2  # (n, n)
        seen[:, 0] = True
        np.fill_diagonal(seen, False)
        soon = np.where(seen, self._approach(positions, self.horizon), np.inf)  # (n, n)
        return _Step(
            t=t,
            positions=positions,
            pos_d=pos_d.copy(),
            formation_alt=formation_alt,
            dt=dt,
            steer=steer,
            h=_horizontal_distances(positions),
            z=z,
            layer=layer,
            z_target=layer.copy(),
            z_target_vel=np.full(n, float(self.vel[0, 2])),  # layers move with the leader
            idx=np.arange(n),
            in_transit=bool((self.phase != FORMED).any()),
            seen=seen,
            soon=soon,
            vband=self._vertical_overlap(z, self.horizon) & seen,
        )

    def _ready_to_cross(self, s: _Step, climbing: np.ndarray) -> np.ndarray:
        """(n,) climbing followers within ``climb_tolerance`` of their layer (ours)."""
        return climbing & (s.z >= s.layer - self.climb_tol)

    def _wait_floor(self) -> np.ndarray:
        """(n,) the highest a follower waiting under a drone waits at (ours): where it is, lifting
        off the ground to ``HOVER_MIN_M``."""
        return np.maximum(self.zp, HOVER_MIN_M)

    def _stuck_under(self, stuck: np.ndarray, slow: np.ndarray) -> np.ndarray:
        """(n, n) the drones a waiting follower steps aside from (ours): every one it is stuck under."""
        return stuck

    def _climb(self, s: _Step) -> None:
        """1. *climb* (ours): in place to its layer; never through a drone within D̄ above (it waits
        ``hop`` below, climbs over when too late to stop, steps aside from one that hovers there).
        Followers that reach their layer switch to the crossing."""
        z, h, layer = s.z, s.h, s.layer
        climbing = self.phase == CLIMB
        ready = self._ready_to_cross(s, climbing)
        for i in np.flatnonzero(ready):
            self.phase[i] = CROSS
            self.events.append({"t": s.t, "drone": int(i), "other": -1, "action": "cross"})
        climbing = self.phase == CLIMB
        if not climbing.any():
            return
        # drones it must not climb into: above it (up to its layer) and, horizontally,
        # within D̄ + 0.2 m now or soon if they move, within 2·FOOTPRINT + 0.1 m if they
        # hover (a drone climbing in place passes a hovering one that close unharmed);
        # the leader, which yields to nobody, also when about level with it
        hovering = _rownorm(self.vel[:, :2]) < 0.5  # (n,)
        hovering[0] = False  # the leader may set off any time: always D̄ + 0.2 m
        radius = np.where(hovering, 2.0 * FOOTPRINT_M + 0.1, self.safety + 0.2)[None, :]  # (1, n)
        vertical = (z[None, :] > z[:, None] + 0.05) & (z[None, :] < layer[:, None] + self.clearance)
        vertical[:, 0] |= z[0] > z - self.clearance  # the leader: level counts
        above = (s.soon < radius) & vertical
        above &= climbing[:, None]
        zmin = np.where(above, z[None, :], np.inf).min(axis=1)  # (n,) lowest such drone
        # below it: wait (brake as hard as it can) no higher than now — it does not chase a
        # climbing drone from below — and hop under it, or on the ground. About level with
        # it already: climb over it, unless it is straight above (footprints overlap).
        z_wait = np.maximum(np.minimum(self._wait_floor(), zmin - self.hop), 0.0)
        overhead = (above & (h < 2.0 * FOOTPRINT_M)).any(axis=1)
        vz = np.maximum(self.zv, 0.0)
        z_stop = self.zp + vz * vz / (1.6 * self.z_down[1])  # where it could stop
        late = z_stop > np.maximum(zmin - self.hop, 0.0) + 0.1
        over = np.isfinite(zmin) & late & ~overhead
        wait = np.isfinite(zmin) & ~over
        s.z_target[wait] = np.minimum(layer[wait], z_wait[wait])
        s.z_target_vel[wait] = 0.0
        s.z_target[over] = np.maximum(layer[over], zmin[over] + self.hop)
        # waiting, airborne, under a drone that hovers there (the leader hovering, or a
        # follower over its slot): step aside, 0.2 m beyond the radius it keeps from it
        slow = _rownorm(self.vel[:, :2]) < 0.5  # (n,), the leader too
        stuck = above & (h < radius) & slow[None, :] & (z[:, None] > 0.2)
        stuck = self._stuck_under(stuck, slow)
        positions = s.positions
        there = _rownorm(positions[:, :2] - self.start_xy) < 0.1
        aside = stuck.any(axis=1) & there & wait
        for i in np.flatnonzero(aside):
            j = int(np.argmin(np.where(stuck[i], h[i], np.inf)))
            away = positions[i, :2] - positions[j, :2]
            away /= max(float(np.linalg.norm(away)), 1e-9)
            self.start_xy[i] = positions[j, :2] + (radius[0, j] + 0.2) * away
            self.asides[i] += 1
            self.events.append({"t": s.t, "drone": int(i), "other": j, "action": "aside"})

    def _conflicts(self, s: _Step, gap: np.ndarray, near: np.ndarray, gives_way: np.ndarray) -> np.ndarray:
        """(n, n) the drones a crossing follower brakes for (ours): one it gives way to, predicted
        within D̄ (``near``) in an altitude band it sweeps."""
        return near & s.vband & gives_way

    def _cross(self, s: _Step) -> None:
        """2. *cross* (ours): the horizontal goals — its start while climbing, its slot (moving with
        the leader) after — and, crossing on the layer, braking to rest (``blocked``) while a drone
        it gives way to (the leader, a lower index, any drone not crossing) is in conflict."""
        n = self.n
        positions = s.positions
        climbing = self.phase == CLIMB
        crossing = self.phase == CROSS
        s.goal = s.pos_d[:, :2].copy()  # (n, 2) slots
        s.goal_vel = np.broadcast_to(self.vel[0, :2], (n, 2)).copy()  # (n, 2) their velocity
        s.goal[climbing] = self.start_xy[climbing]
        s.goal_vel[climbing] = 0.0
        self.blocked &= crossing
        if not crossing.any():
            return
        speed = _rownorm(self.vel[:, :2])
        horizon_i = np.minimum(speed / self.a_max + 0.3, 2.0)  # (n,) time to stop + reaction
        d = positions[None, :, :2] - positions[:, None, :2]
        dv = self.vel[None, :, :2] - self.vel[:, None, :2]
        vv = np.einsum("ijk,ijk->ij", dv, dv)
        tc = np.clip(-np.einsum("ijk,ijk->ij", d, dv) / np.maximum(vv, 1e-9), 0.0, horizon_i[:, None])
        m = d + tc[:, :, None] * dv
        gap = np.sqrt(np.einsum("ijk,ijk->ij", m, m))
        near = (gap < self.safety) & s.seen
        gives_way = (s.idx[None, :] < s.idx[:, None]) | (self.phase[None, :] != CROSS)
        conflict = self._conflicts(s, gap, near, gives_way)
        blocked = crossing & conflict.any(axis=1)
        for i in np.flatnonzero(blocked & ~self.blocked):
            self.events.append({"t": s.t, "drone": int(i), "other": int(np.argmax(conflict[i])), "action": "hold"})
        self.blocked = blocked

    def _under(self, s: _Step, i: int) -> np.ndarray:
        """(n,) the drones that keep follower ``i`` from dropping (ours): still in transit and (now
        or soon) within D̄ under it."""
        return (s.soon[i] < self.safety) & (self.phase != FORMED) & (s.z < s.z[i] + self.clearance)

    def _drop(self, s: _Step) -> None:
        """3. *drop* (ours): a crossing follower within ``arrive`` of its slot (and its path too)
        joins the formation — and so descends to the formation altitude — when nothing is under it."""
        crossing = self.phase == CROSS
        if not crossing.any():
            return
        there = (
            crossing
            & (_rownorm(s.positions[:, :2] - s.goal) < self.arrive)
            & (_rownorm(self.path_p - s.goal) < self.arrive)
        )
        for i in np.flatnonzero(there):
            if not self._under(s, int(i)).any():
                self.phase[i] = FORMED
                self.blocked[i] = False
                self.events.append({"t": s.t, "drone": int(i), "other": -1, "action": "drop"})

    def _formed(self, s: _Step) -> None:
        """4. *formed* (the paper's, Fig. 5): the reactive rule among formed drones and the leader
        sets the altitude offset of each formed follower; ours: one still descending never descends
        onto a drone in transit within D̄ (now or soon) below it, it waits ``hop`` above it
        (docs/interpretations.md §4's failure case)."""
        z = s.z
        formed = self.phase == FORMED
        self._react(s.t, s.positions, s.h, formed)
        formed[0] = False
        s.z_target[formed] = s.formation_alt + self.offset[formed]
        if not s.in_transit:
            return
        below = (
            (s.soon < self.safety)
            & formed[:, None]
            & (self.phase[None, :] != FORMED)
            & (z[None, :] < z[:, None])
            & (z[None, :] > s.z_target[:, None] - self.clearance)
        )
        s.z_target = self._hold_above(z, s.z_target, below)

    def _hold_above(self, z: np.ndarray, z_target: np.ndarray, below: np.ndarray) -> np.ndarray:
        """``z_target`` (n,) raised to ``hop`` above the highest drone j flagged in ``below`` (n, n)
        [i, j] for each drone i (altitudes ``z`` (n,)); rows with no flag unchanged."""
        if not below.any():
            return z_target
        zmax = np.where(below, z[None, :], -np.inf).max(axis=1)  # (n,) highest such drone
        return np.where(np.isfinite(zmax), np.maximum(z_target, zmax + self.hop), z_target)

    def _fly_paths(self, s: _Step) -> tuple[np.ndarray, np.ndarray]:
        """Every follower flies limited paths (ours): horizontal, to ``goal``, and vertical, to
        ``z_target`` (see :meth:`_advance_paths`, :meth:`_advance_altitude`); their position,
        velocity and acceleration are the controller's references."""
        self._advance_paths(s.dt, s.goal, s.goal_vel)
        self._advance_altitude(s.dt, s.z_target, s.z_target_vel)
        pos_d = s.pos_d
        pos_d[1:, :2] = self.path_p[1:]
        self.vel_d[1:, :2] = self.path_v[1:]
        self.acc_d[1:, :2] = self.path_a[1:]
        pos_d[1:, 2] = self.zp[1:]
        self.vel_d[1:, 2] = self.zv[1:]
        self.acc_d[1:, 2] = self.za[1:]
        self._all_formed = bool((self.phase == FORMED).all())
        return pos_d, s.steer


def jet_clearance(dz: np.ndarray, margin: float = 0.0) -> np.ndarray:
    """Horizontal centre distance (m) at which a drone |dz| m below another (either way round) is
    clear of the upper one's jet: the jet's edge at that depth plus the lower drone's rotor span
    (:func:`swarm_mj.metrics.in_jet`, the turbulent jet of Bauersfeld et al.), plus ``margin``."""
    from ..metrics import DRONE_RADIUS_M, JET_R0_M, JET_REACH_M, JET_SPREAD

    return JET_R0_M + JET_SPREAD * np.minimum(np.abs(dz), JET_REACH_M) + DRONE_RADIUS_M + margin


class ClearanceRule(LayeredRule):
    """``anti_collision = "clearance"`` (opt-in): the layered rule made downwash-aware by horizontal
    clearance (the default under downwash is :class:`JetAwareRule`).

    **Why** (issue 15; ``swarm-mj stress --aero realistic``, docs/interpretations.md): the layered
    rule (``layers``) keeps drones apart by stacking them — a follower crossing on its layer passes
    straight over the drones below, followers on their layers are above the leader's path — and
    under the turbulent-jet downwash of Bauersfeld et al. (RA-L 2024; ``--aero realistic``) the
    drone below sinks: over 20 starts (``tools/aero_compare.py``) a worst downwash dip of 1.86 m,
    7 crashes and a start with contacts; with the feedforward (5.) alone (``compensated``) 10 of
    100 starts still lose a drone (a drone 0.4 m under another's near jet, or tilting for its
    crossing while its thrust is low, tips over); with all of 1.–5., 2 of 100 (and 0 contacts, 0
    crashes, a worst dip of 0.021 m on every bundled swarm scenario), at the cost of settling: a
    median of 5.05 s over 100 starts, against 4.12 s for ``compensated``. The jet's push is still
    a tenth of a drone's weight 6 m down, so no altitude separation is enough.

    **What is the paper's** (Fig. 5, §4): as in :class:`LayeredRule` (altitude changes while each
    follower keeps aiming at its slot; D̄ = 0.8 m, the 0.4 m hop; the higher index yields and a
    follower always yields to the leader; once formed, the printed reactive rule).

    **What is the layered rule's** (ours, :class:`LayeredRule`): climb in place to a layer of its
    own, cross on it along a limited path, drop over the slot; the layers are what keeps two
    drones from touching.

    **What is new here** (ours), each decision from the leader's position and the drones within
    ``sensing_range``, with the jet clearance :func:`jet_clearance` (the jet's horizontal reach at
    the two drones' vertical separation plus the rotor span of the one below, plus
    ``jet_margin``):

    1. *take off* — a follower still on the ground stays there while a drone it gives way to (the
       leader, a lower index; not a formed one that hovers there: it would wait for ever) is, or
       is predicted over ``horizon`` s to be, above its start within the jet clearance (the leader
       sets off at full tilt over the followers).
    2. *climb* — waiting under a drone it must not climb into, it waits no higher than it is (the
       layered rule waited ``hop`` under it, in its jet, lifting off the ground to do so).
    3. *cross* — it also brakes for a drone crossing on a layer up to ``jet_depth`` above or below
       (the next layer) that moves and is predicted within the jet clearance (the near jet of a
       drone 0.4 m up tips the one below over: measured, a follower flew off), and its path goes
       round one that hovers there (braking, or over its slot) by the side point ``jet clearance +
       0.1`` m out from it; paths are gentler (tilt ≤ ``max_tilt_deg`` = 25°, the layered rule's
       30° with the rotors' lag of ``--aero realistic`` flipped a drone now and then).
    4. *drop* — it descends from its layer only when no airborne drone, formed or not, is (or will
       be) within the jet clearance under it (towards a formed drone or the leader the clearance
       is capped just short of the distance between their slots, so that slots closer than that
       stay reachable).
    5. *feedforward* — crossing on the layers still passes over lower drones further down
       (keeping every drone out of every jet costs seconds of settling: drones wait for each other
       or go round the formed ones), so the controller compensates the downwash force it predicts
       from the drones' positions, attitudes and thrust commands
       (:class:`~swarm_mj.policy.DownwashFeedforward`: the simulator's jet model, as Bauersfeld et
       al. compensate it in their §VI), the way it compensates the wind (eqs. 23–24). Only when
       the physics has downwash (``--aero realistic``).
    """

    name = "clearance"
    downwash_feedforward = True

    def __init__(
        self,
        n: int,
        safety_distance: float = 0.8,
        hop: float = 0.4,
        hysteresis: float = 0.05,
        jet_margin: float = 0.1,
        jet_depth: float = 0.5,
        max_tilt_deg: float = 25.0,
        descent_accel: float = 5.0,
        **kw: float,
    ) -> None:
        super().__init__(
            n, safety_distance, hop, hysteresis, max_tilt_deg=max_tilt_deg, descent_accel=descent_accel, **kw
        )
        self.jet_margin = float(jet_margin)
        self.jet_depth = float(jet_depth)

    def reset(self, positions: np.ndarray) -> None:
        super().reset(positions)
        self.holding = np.zeros(self.n, dtype=bool)  # (n,) held on the ground (1.)
        self.side = np.zeros(self.n, dtype=np.int64)  # (n,) side it goes round a hovering drone (+1: left)

    def _go_round(
        self, positions: np.ndarray, goal: np.ndarray, movers: np.ndarray, obstacle: np.ndarray, radius: np.ndarray
    ) -> np.ndarray:
        """Goals (n, 2): for each of ``movers`` (n,) whose straight line to ``goal`` (n, 2) passes
        within ``radius`` (n, n) of a drone flagged ``obstacle`` (n, n), a point at least 1 m along
        the way to the side point of the nearest such drone (``radius`` + 0.1 m out from it, square
        to the line), on the side it is already off the line (kept until it is past)."""
        out = goal.copy()
        for i in np.flatnonzero(movers):
            p = positions[i, :2]
            e = goal[i] - p
            L = float(np.hypot(*e))
            if L < 0.3:
                self.side[i] = 0
                continue
            u = e / L
            d = positions[:, :2] - p  # (n, 2)
            along = d @ u
            perp = d[:, 0] * u[1] - d[:, 1] * u[0]  # > 0: right of the line
            rad = radius[i] + 0.1
            block = obstacle[i] & (along > -0.1) & (along < L + 0.1) & (np.abs(perp) < rad)
            if not block.any():
                self.side[i] = 0
                continue
            j = int(np.argmin(np.where(block, along, np.inf)))
            if self.side[i] == 0:
                self.side[i] = 1 if perp[j] < 0.0 else -1  # pass on the far side
                self.events.append({"t": self._prev_t, "drone": int(i), "other": j, "action": "round"})
            normal = np.array([-u[1], u[0]]) * self.side[i]  # left (+1) or right (−1)
            aim = positions[j, :2] + normal * rad[j] - p
            out[i] = p + aim / max(float(np.hypot(*aim)), 1e-9) * max(float(np.hypot(*aim)), 1.0)
        return out

    # ------------------------------------------------------------------ its steps (the layered rule's, adjusted)
    def _sense(self, t: float, positions: np.ndarray, pos_d: np.ndarray, formation_alt: float, dt: float) -> _Step:
        """The layered rule's, plus (ours) the vertical separations and the jet clearance of every
        pair: towards a formed drone or the leader capped just short of the distance between their
        slots (4. of the class docstring)."""
        s = super()._sense(t, positions, pos_d, formation_alt, dt)
        n, z, idx = self.n, s.z, s.idx
        self._dz = z[None, :] - z[:, None]  # (n, n) z_j − z_i
        self._jet = jet_clearance(self._dz, self.jet_margin)  # (n, n)
        slot_gap = _rownorm((s.pos_d[None, :, :2] - s.pos_d[:, None, :2]).reshape(-1, 2)).reshape(n, n)
        self._jet_c = np.where(
            (self.phase == FORMED)[None, :] | (idx[None, :] == 0), np.minimum(self._jet, slot_gap - 0.05), self._jet
        )  # (n, n)
        return s

    def _ready_to_cross(self, s: _Step, climbing: np.ndarray) -> np.ndarray:
        """The layered rule's, and (ours) only once its climb has slowed (|ż| < 1 m/s): braking a
        climb takes the thrust down to m·(g − 5 m/s²), and tilting then for the crossing, with the
        rotors' lag, flipped drones."""
        return super()._ready_to_cross(s, climbing) & (np.abs(self.zv) < 1.0)

    def _wait_floor(self) -> np.ndarray:
        """(n,) ours (2. of the class docstring): a waiting follower waits no higher than it is (the
        layered rule lifted it off the ground, into the jet of the drone above)."""
        return self.zp

    def _stuck_under(self, stuck: np.ndarray, slow: np.ndarray) -> np.ndarray:
        """The layered rule's, less formed drones that move (ours)."""
        return stuck & ~((self.phase == FORMED) & ~slow)[None, :]

    def _climb(self, s: _Step) -> None:
        """1.–2. of the class docstring: the layered rule's climb (with the steps above), then the
        take-off hold (:meth:`_take_off`)."""
        super()._climb(s)
        self._take_off(s)

    def _take_off(self, s: _Step) -> None:
        """1. *take off* (ours): a follower still on the ground stays there while a drone it gives way
        to is (or is predicted to be) above its start within the jet clearance (the leader setting
        off overhead); not for a formed drone hovering there: it would wait for ever (airborne, the
        follower steps aside)."""
        if not s.in_transit:
            return
        idx = s.idx
        ground = (self.phase == CLIMB) & (s.z < HOVER_MIN_M)
        staying = (self.phase == FORMED) & (_rownorm(self.vel[:, :2]) < 0.5)
        overhead = (
            s.seen
            & (s.soon < self._jet)
            & (self._dz > 0.05)
            & ((idx[None, :] < idx[:, None]) | (idx[None, :] == 0))
            & ~staying[None, :]
        )
        hold = ground & overhead.any(axis=1)
        s.z_target[hold] = np.minimum(s.z_target[hold], 0.0)
        s.z_target_vel[hold] = 0.0
        for i in np.flatnonzero(hold & ~self.holding):
            self.events.append({"t": s.t, "drone": int(i), "other": int(np.argmax(overhead[i])), "action": "wait"})
        self.holding = hold

    def _conflicts(self, s: _Step, gap: np.ndarray, near: np.ndarray, gives_way: np.ndarray) -> np.ndarray:
        """3. *cross*: the layered rule's conflicts, and (ours) a drone crossing on a layer up to
        ``jet_depth`` above or below that moves, within the jet clearance (the near jet of a drone
        0.4 m up tips the one below over)."""
        hover = _rownorm(self.vel[:, :2]) < 0.5  # (n,)
        near_jet = (
            (gap < self._jet_c)
            & s.seen
            & (np.abs(self._dz) < self.jet_depth)
            & (self.phase[None, :] == CROSS)
            & ~hover[None, :]
        )
        return ((near & s.vband) | near_jet) & gives_way

    def _under(self, s: _Step, i: int) -> np.ndarray:
        """4. *drop* (ours): any airborne drone, formed or not, (now or soon) within the jet
        clearance (at least D̄) under it; one on the ground is held by it (and waits for this one)."""
        return (
            (s.soon[i] < np.maximum(self.safety, self._jet_c[i]))
            & (s.z < s.z[i] + self.clearance)
            & (s.z > HOVER_MIN_M)
        )

    def _drop(self, s: _Step) -> None:
        """4. *drop* (the layered rule's, with :meth:`_under`), then 3.'s going round (ours): a
        crossing follower goes round a drone that hovers on the next layer (braking, or waiting to
        drop) within the jet clearance of its line to the slot (:meth:`_go_round`)."""
        super()._drop(s)
        crossing = self.phase == CROSS
        if crossing.any():
            hover = _rownorm(self.vel[:, :2]) < 0.5
            obstacle = s.seen & (hover & (self.phase == CROSS))[None, :] & (np.abs(self._dz) < self.jet_depth)
            s.goal = self._go_round(s.positions, s.goal, crossing, obstacle, self._jet_c)


def _update_formed_impl(
    rule: LayeredRule, t: float, positions: np.ndarray, pos_d: np.ndarray, formation_alt: float, dt: float
) -> tuple[np.ndarray, np.ndarray]:
    """:meth:`LayeredRule.update` once every follower is formed (nobody in transit): the same
    steps with the climb / cross / drop parts, which then do nothing, left out — the reactive
    rule (Fig. 5, among all drones), then the horizontal and altitude paths towards the slots
    and formation_alt + offset in one compiled kernel (:func:`~swarm_mj.formation.layered.formed_step_kernel`)."""
    h = _horizontal_distances(positions)
    rule._react(t, positions, h, rule._all)  # 4. Fig. 5 among all drones
    return _formed_step(rule, dt, positions, pos_d, formation_alt, rule.offset)


class CompensatedRule(LayeredRule):
    """``anti_collision = "compensated"``: today's layered rule (:class:`LayeredRule`, the paths
    unchanged) with the downwash feedforward of :class:`ClearanceRule` (5.): under ``--aero
    realistic`` the controller compensates the downwash force it predicts; under the paper's
    physics it is the layered rule, bit for bit."""

    name = "compensated"
    downwash_feedforward = True


#: Lowest altitude (m) a yielding follower of :class:`JetAwareRule` is sent to (above the floor's
#: ground effect and a hop clear of a drone taking off under it).
FLOOR_CLEARANCE_M = 0.5
#: Closing speed (m/s) under which :class:`JetAwareRule`'s never-through check (4.) takes two drones'
#: present horizontal distance, not the one predicted over ``horizon``: in a formed swarm the
#: velocities estimated from positions jitter by a few cm/s, and over 1 s that closed the 8 cm
#: between neighbouring outlines (eight followers at D = 1 m, 0.77 m apart) and held descents for
#: seconds. Over the 20 eight-follower stress starts the median form-up settling went 8.89 s → 6.96 s
#: and the one start with a contact has none (0.2 m/s: 7.7 s and 3 contacts; no prediction at all:
#: 6.6 s); five followers, 100 starts: 4.72 s → 4.60 s, still no contact.
CLOSING_MIN_MPS = 0.5
#: Added to D̄ (m): how far out :class:`JetAwareRule` holds a descending formed follower above a drone
#: still crossing below it (7. of its docstring; the layered rule's hold starts at D̄). Measured
#: (``swarm-mj stress --aero realistic``): the one contact in 100 eight-follower starts (seeds
#: 0–99; seed 94: a follower crossing at 2.9 m/s towards one descending onto its layer, held too
#: late) is gone, none in 300 five-follower ones, and the median settling of the 20 eight-follower
#: stress starts went 4.84 s → 4.60 s. At 0.3 m the same, but the bundled ``lemniscate`` settled in
#: 5.16 s instead of 4.3 s (a follower held over a crossing one that passed 1.05 m away).
CROSSING_HOLD_M = 0.2
#: Centre distance (m) under which two drones' outlines (rotor tip to rotor tip, 2·FOOTPRINT_M)
#: overlap in plan view, with 2 cm to spare: a drone never changes altitude through one that close.
OVERLAP_M = 2.0 * FOOTPRINT_M + 0.02


class JetAwareRule(CompensatedRule):
    """``anti_collision = "jet-aware"``, the default wherever the physics has downwash
    (``--aero realistic``; ``"auto"`` picks it, docs/interpretations.md §4): the layered rule made
    downwash-aware and its formed phase made to settle.

    **Why** (issue 15, measured with ``swarm-mj stress --aero realistic``): under the turbulent-jet
    downwash of Bauersfeld et al. (RA-L 2024), the rotor lag and the solid ground, the layered rule
    (``layers``) lost drones: over 100 starts of five followers 6 starts with contacts, 41 crashes
    and a worst dip of 2.2 m. Most crashes were not the jets': a drone tilting at low thrust
    saturated a rotor at zero and, with the rotors' lag, lost its attitude (fixed in the
    controller: :func:`~swarm_mj.mixing.attitude_priority`, and the rotor-lag compensation of
    :mod:`swarm_mj.control.lag`). What is left is the rule's: with that controller, over the same
    100 starts, ``layers`` still had a start with a contact and a worst dip of 0.136 m (a follower
    crossing 0.4 m over another), this rule none and 0.021 m (median settling 3.97 s; eight
    followers: no contact, 0 crashes, 0.026 m, 4.60 s; ``report/stress*_realistic*.json``).

    **What is the paper's** (Fig. 5, §4): as in :class:`LayeredRule` (altitude changes while each
    follower keeps aiming at its slot; D̄ = 0.8 m, the 0.4 m hop; the higher index yields and a
    follower always yields to the leader).

    **What is the layered rule's** (ours, :class:`LayeredRule`): climb in place to a layer of its
    own, cross on it along a limited path, drop over the slot.

    **What is new here** (ours):

    1. *feedforward* (:class:`CompensatedRule`'s) — crossing on the layers passes over lower drones, so the controller
       compensates the downwash force it predicts from the drones' positions, attitudes and thrust
       commands (:class:`~swarm_mj.policy.DownwashFeedforward`: the simulator's jet model, as
       Bauersfeld et al. compensate it in their §VI), the way it compensates the wind (eqs. 23–24).
    2. *yield by the slots* — two followers whose slots are closer than D̄ (eight followers at
       D = 1 m: neighbours 0.77 m apart) would trigger and release the printed rule for ever as
       they hover about D̄ apart, each hop a transient; they are given their altitude offsets from
       the slots instead, once, before they drop (the printed rule applied to where they are going).
    3. *stacked offsets* — a yielding drone takes the altitude offset nearest the formation
       altitude that is at least ``hop`` from the offset of every drone it yields to (up first when
       it is above the other: the printed rule's ±``hop`` when it yields to one drone at the
       formation altitude), never one lower than ``FLOOR_CLEARANCE_M`` above the floor. As
       printed, two drones that both yield upwards to a third end at the same altitude, within D̄
       of each other (measured: a contact).
    4. *never through* — a formed follower never changes altitude through a drone whose outline
       overlaps its own in plan view (now, or predicted over ``horizon`` when the two close faster
       than ``CLOSING_MIN_MPS``): it holds ``hop`` above or below it until they are apart.
    5. *gentler crossings* — speed ≤ ``max_speed`` = 3 m/s and acceleration ≤ ``max_accel`` =
       4 m/s² on the layers (the layered rule's 4 and 6): with the rotors' lag a drone braking
       for another overshoots the path's tilt (43–57° measured at the contacts), its rotors then
       reach 0.25 m up or down, and two drones crossing on neighbouring layers, 0.4 m apart,
       touched. Measured over 400 random starts under ``--aero realistic`` (five followers, seeds
       0–99 and 200–399; eight, seeds 0–99): 3 starts with a contact, against 10 at 4 m/s and
       6 m/s², for 0.2–0.4 s more settling with five followers.
    6. *gentler formed descents* — a follower that has joined the formation (dropped over its slot)
       descends with at most ``formed_descent_accel`` = 3 m/s² (the layered rule's 5), during the
       transition as well as once every follower is formed: at 5 m/s² the thrust left, m·(g − 5),
       turns any horizontal correction into a 45–55° tilt (the controller asks for its 45° limit
       with 7 cm of position error), which the lagged rotors ring at about 2.5 Hz next to the
       formed neighbours, and which tips their jets onto them and onto the leader. The climbing,
       waiting and crossing followers keep 5 m/s² (applied to them too, the re-timed crossings gave
       3 of the 100 five-follower stress starts a contact). Measured (``swarm-mj stress --aero
       realistic``): eight followers, 20 starts, median settling 5.58 s → 4.84 s (3.5 m/s² from the
       drop: 5.06 s; 3.5 m/s² once all are formed, the previous form of this step: 5.58 s; before
       it, 6.96 s); five followers, 100 starts, 4.43 s → 3.97 s; no contact in either.
    7. *early hold over a crossing drone* — a formed follower still descending holds ``hop`` above
       a drone crossing below it from D̄ + ``CROSSING_HOLD_M`` = 1.0 m out (now or predicted over
       ``horizon``), not from D̄: a follower crossing at up to 3 m/s towards one descending onto
       its layer closed the last 0.2 m before the hold had turned the descent round (seed 94 of
       the eight-follower starts: a contact at 0.43 m). The layered rule's hold (4. *formed* of
       :class:`LayeredRule`) stays, for every drone in transit.
    """

    name = "jet-aware"

    def __init__(
        self, n: int, max_speed: float = 3.0, max_accel: float = 4.0, formed_descent_accel: float = 3.0, **kw: float
    ) -> None:
        super().__init__(n, max_speed=max_speed, max_accel=max_accel, **kw)
        self.z_down_formed = (self.z_down[0], min(float(formed_descent_accel), self.z_down[1]))

    def reset(self, positions: np.ndarray) -> None:
        super().reset(positions)
        self._slot_h = np.full((self.n, self.n), np.inf)  # (n, n) horizontal distances of the setpoints
        self._slot_yield = False
        self._formation_alt = np.inf  # (set by update) offsets are kept FLOOR_CLEARANCE_M above the floor

    def update(
        self, t: float, positions: np.ndarray, pos_d: np.ndarray, formation_alt: float
    ) -> tuple[np.ndarray, np.ndarray]:
        self.set_slots(pos_d)
        self._formation_alt = float(formation_alt)
        return super().update(t, positions, pos_d, formation_alt)

    def set_slots(self, pos_d: np.ndarray) -> None:
        """The setpoints (n, 3) whose horizontal distances 2. of the class docstring reads (row 0:
        the leader's reference); :meth:`update` sets them every step."""
        self._slot_h = _horizontal_distances(pos_d)
        self._slot_yield = any_below(self._slot_h, self.safety)  # some slots within D̄ of each other

    def _react(self, t: float, positions: np.ndarray, h: np.ndarray, active: np.ndarray) -> None:
        """2.–3. of the class docstring, in index order (a drone's offset depends on those of the
        drones it yields to, which have lower indices)."""
        if not self._slot_yield and not react_needed(self.offset, h, self.safety):
            return
        slot = (self._slot_h < self.safety) & self._lower  # (n, n) [i, j]: i yields to j by the slots
        hop = self.hop
        # candidate offsets, none that would put the drone within FLOOR_CLEARANCE_M of the floor
        low = FLOOR_CLEARANCE_M - self._formation_alt
        cands = tuple(o for o in (0.0, hop, -hop, 2.0 * hop, -2.0 * hop, 3.0 * hop) if o >= low or o == 0.0)
        for i in range(1, self.n):
            if not active[i]:
                continue
            cur = float(self.offset[i])
            reach = self.safety + (self.hysteresis if cur != 0.0 else 0.0)
            yields = active[:i] & ((h[i, :i] < reach) | slot[i, :i])
            js = np.flatnonzero(yields)
            if js.size == 0:
                if cur != 0.0:
                    self.offset[i] = 0.0
                    self.events.append({"t": t, "drone": i, "other": -1, "action": "release"})
                continue
            others = self.offset[js]
            if bool(np.all(np.abs(cur - others) >= hop - 1e-9)):
                continue  # its offset still keeps it clear of every drone it yields to
            j = int(js[np.argmin(h[i, js])])
            up = positions[i, 2] >= positions[j, 2]
            order = sorted(cands, key=lambda o: (abs(o), (o < 0.0) if up else (o > 0.0)))
            # (every candidate taken, when it yields to six or more drones at once: above them all)
            new = next((o for o in order if bool(np.all(np.abs(o - others) >= hop - 1e-9))), float(others.max()) + hop)
            if new != cur:
                self.offset[i] = new
                self.events.append({"t": t, "drone": i, "other": j, "action": "up" if new > cur else "down"})

    def _through(self, positions: np.ndarray, z_target: np.ndarray, formed: np.ndarray, soon: np.ndarray) -> np.ndarray:
        """4. of the class docstring: ``z_target`` (n,) of the ``formed`` (n,) followers held ``hop``
        clear of every drone whose outline overlaps theirs in plan view (``soon`` (n, n))."""
        near = (soon < OVERLAP_M) & formed[:, None]
        if not near.any():
            return z_target
        z = positions[:, 2]
        above = z[None, :] > z[:, None]  # [i, j]: j above i
        lo = np.where(near & ~above, z[None, :] + self.hop, -np.inf).max(axis=1)
        hi = np.where(near & above, z[None, :] - self.hop, np.inf).min(axis=1)
        held = np.where(lo > hi, z, np.minimum(np.maximum(z_target, lo), hi))
        return np.where(formed, held, z_target)

    def _closing(self, positions: np.ndarray, h: np.ndarray, soon: np.ndarray) -> np.ndarray:
        """``soon`` (n, n) where two drones close faster than ``CLOSING_MIN_MPS``, else their present
        horizontal distance ``h`` (n, n) (unseen pairs, +inf in ``soon``, stay +inf)."""
        d = positions[None, :, :2] - positions[:, None, :2]  # (n, n, 2) j − i
        dv = self.vel[None, :, :2] - self.vel[:, None, :2]
        closing = -np.einsum("ijk,ijk->ij", d, dv) / np.maximum(h, 1e-9)  # (n, n) > 0: approaching
        return np.where(np.isinf(soon) | (closing > CLOSING_MIN_MPS), soon, h)

    def _formed(self, s: _Step) -> None:
        super()._formed(s)
        formed = self.phase == FORMED
        formed[0] = False
        s.z_target = self._through(s.positions, s.z_target, formed, self._closing(s.positions, s.h, s.soon))
        if s.in_transit:
            s.z_target = self._over_crossing(s.z, s.soon, s.z_target, formed)

    def _over_crossing(self, z: np.ndarray, soon: np.ndarray, z_target: np.ndarray, formed: np.ndarray) -> np.ndarray:
        """7. of the class docstring: ``z_target`` (n,) of the ``formed`` (n,) followers held ``hop``
        above every crossing drone below them (altitudes ``z`` (n,)) that is, or is predicted to be
        (``soon`` (n, n)), within D̄ + ``CROSSING_HOLD_M`` horizontally."""
        below = (
            (soon < self.safety + CROSSING_HOLD_M)
            & formed[:, None]
            & (self.phase[None, :] == CROSS)
            & (z[None, :] < z[:, None])
            & (z[None, :] > z_target[:, None] - self.clearance)
        )
        return self._hold_above(z, z_target, below)

    def _advance_altitude(self, dt: float, target: np.ndarray, target_vel: np.ndarray) -> None:
        """The layered rule's altitude paths, with 6. of the class docstring: the followers that have
        joined the formation descend with at most ``formed_descent_accel``, the others with the
        layered rule's ``descent_accel`` (the kernel moves each drone on its own: two calls on the
        two groups give each row what one call with its own limit would)."""
        joined = self.phase == FORMED  # the leader's row too (its path is not flown)
        if dt <= 0.0 or self.z_down_formed == self.z_down:
            return super()._advance_altitude(dt, target, target_vel)
        (vu, au), (vd, ad), (_, ad_joined) = self.z_up, self.z_down, self.z_down_formed
        target = np.asarray(target, dtype=np.float64)
        target_vel = np.asarray(target_vel, dtype=np.float64)
        for rows, a_down in ((np.flatnonzero(joined), ad_joined), (np.flatnonzero(~joined), ad)):
            if rows.size == 0:
                continue
            zp, zv, za = self.zp[rows], self.zv[rows], self.za[rows]  # (k,) copies
            advance_altitude_kernel(
                float(dt), target[rows], target_vel[rows], zp, zv, za, vu, au, vd, a_down, self.jerk, self.k_v
            )
            self.zp[rows], self.zv[rows], self.za[rows] = zp, zv, za

    def _update_formed(
        self, t: float, positions: np.ndarray, pos_d: np.ndarray, formation_alt: float, dt: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """The layered rule's formed step (one compiled kernel) with 4. of the class docstring."""
        h = _horizontal_distances(positions)
        self._react(t, positions, h, self._all)
        offset = self.offset
        if (h[1:] < OVERLAP_M).any():
            soon = self._closing(positions, h, self._approach(positions, self.horizon))
            z_t = self._through(positions, formation_alt + offset, self._followers, soon)
            offset = z_t - formation_alt
        return _formed_step(self, dt, positions, pos_d, formation_alt, offset)


def _formed_step(
    rule: LayeredRule, dt: float, positions: np.ndarray, pos_d: np.ndarray, formation_alt: float, offset: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The paths towards the slots and formation_alt + offset (n,), in one compiled kernel
    (:func:`~swarm_mj.formation.layered.formed_step_kernel`)."""
    (vu, au), (vd, ad) = rule.z_up, rule.z_down_formed
    out = np.empty((rule.n, 3))
    formed_step_kernel(
        dt,
        np.ascontiguousarray(pos_d, dtype=np.float64),
        float(formation_alt),
        np.ascontiguousarray(offset, dtype=np.float64),
        rule.vel[0],
        rule.path_p,
        rule.path_v,
        rule.path_a,
        rule.blocked,
        rule.zp,
        rule.zv,
        rule.za,
        rule.a_max,
        rule.jerk,
        rule.k_v,
        rule.v_max,
        rule.tan_tilt,
        G,
        vu,
        au,
        vd,
        ad,
        out,
        rule.vel_d,
        rule.acc_d,
    )
    return out, rule._followers


ANTI_COLLISION_RULES: dict[str, type[Rule]] = {
    "layers": LayeredRule,
    "paper": PaperRule,
    "off": NoRule,
    "clearance": ClearanceRule,
    "compensated": CompensatedRule,
    "jet-aware": JetAwareRule,
}
AntiCollision = LayeredRule | PaperRule | NoRule | ClearanceRule | CompensatedRule | JetAwareRule


__all__ = [
    "ANTI_COLLISION_RULES",
    "AUTO",
    "AntiCollision",
    "CLIMB",
    "CROSS",
    "CROSSING_HOLD_M",
    "FOOTPRINT_M",
    "FORMED",
    "FLOOR_CLEARANCE_M",
    "OVERLAP_M",
    "G",
    "HOVER_MIN_M",
    "ClearanceRule",
    "CompensatedRule",
    "JetAwareRule",
    "LayeredRule",
    "NoRule",
    "PaperRule",
    "Rule",
    "horizontal_distances",
    "jet_clearance",
    "make_rule",
    "merge_rows",
    "react_needed",
    "resolve_rule",
]


#: The rule a scenario flies when it names none (or names ``"auto"``): see :func:`resolve_rule`.
AUTO = "auto"


def resolve_rule(name: str, downwash: bool) -> str:
    """The rule ``name`` stands for: ``"auto"`` is ``"jet-aware"`` when the physics has downwash
    (``--aero realistic``) and ``"layers"`` under the paper's physics (the reproduction, unchanged:
    docs/interpretations.md §4); any other name is itself."""
    if name == AUTO:
        return "jet-aware" if downwash else "layers"
    return name


def make_rule(name: str, n: int, where: str = "formation.anti_collision", **params: Any) -> Rule:
    """Build an anti-collision rule by name (``layers``, ``paper``, ``off``, ``clearance``,
    ``compensated``, ``jet-aware``; resolve ``"auto"`` first with :func:`resolve_rule`)."""
    if name not in ANTI_COLLISION_RULES:
        raise UserError(f"unknown rule {name!r}; choose one of {', '.join(ANTI_COLLISION_RULES)}", where=where)
    return ANTI_COLLISION_RULES[name](n, **params)
