"""Anti-collision by altitude changes (paper Fig. 5, §4, §5.3; docs/interpretations.md §4): the rules'
interface, the paper's rule and ``ANTI_COLLISION_RULES``. The layered rule (:class:`LayeredRule`, the
default under the paper's physics) and the rules built on it (:class:`JetAwareRule`, the default
under downwash; :class:`CompensatedRule`) follow; ``"auto"`` picks the default for the physics
(:func:`resolve_rule`); :meth:`LayeredRule.update` is the transition as a sequence of steps
(sense, climb, cross, drop, formed, fly the paths). Every rule reads its numbers from one
:class:`~swarm_mj.formation.rule_params.RuleParams` record (``rule.params``): the named rules are
its presets (:data:`PRESETS`), and a scenario's ``[formation]`` table may set any field.

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
drop (the layered rule's transition).

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
from .layered import BRAKING_SHARE, advance_altitude_kernel, advance_paths_kernel, formed_step_kernel
from .rule_params import PRESETS, RuleParams


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

    def __init__(self, n: int, params: RuleParams | None = None, **overrides: Any) -> None:
        """``params``: the record (default: the preset named ``name``, :data:`PRESETS`), with
        ``overrides`` (any of its fields; :class:`UserError` for an unknown key or a bad value)."""
        self.n = n
        base = PRESETS[self.name] if params is None else params
        self.params = base.with_overrides(overrides, where="")

    def reset(self, positions: np.ndarray) -> None:
        """Start of a run with the drones at positions (n, 3)."""
        raise NotImplementedError

    def update(
        self, t: float, positions: np.ndarray, pos_d: np.ndarray, formation_alt: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """Adjusted setpoints pos_d (n, 3) and the drones it steers, steer (n,) bool."""
        raise NotImplementedError

    @property
    def downwash_feedforward(self) -> bool:
        """Whether the controller is to compensate the downwash of the other drones (when the physics
        has one; see :class:`~swarm_mj.policy.DownwashFeedforward`): the record's field."""
        return self.params.downwash_feedforward

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

    def __init__(self, n: int, params: RuleParams | None = None, **overrides: Any) -> None:
        super().__init__(n, params, **overrides)
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


def _stoppable_speed(room: float, accel: float, lag: float, room_min: float) -> float:
    """Largest v with v²/(2·BRAKING_SHARE·accel) + v·lag ≤ room (room floored at ``room_min``): the
    speed from which a path braking at BRAKING_SHARE·accel, after ``lag`` s, stops within ``room``."""
    k = 1.0 / (2.0 * BRAKING_SHARE * accel)
    room = max(room, room_min)
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

    def __init__(self, n: int, params: RuleParams | None = None, **overrides: Any) -> None:
        super().__init__(n, params, **overrides)
        p = self.params
        self.safety = p.safety_distance
        self.hop = p.hop
        self.hysteresis = p.hysteresis
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

    def __init__(self, n: int, params: RuleParams | None = None, **overrides: Any) -> None:
        super().__init__(n, params, **overrides)
        p = self.params
        self.arrive = p.arrive
        self.climb_tol = p.climb_tolerance
        self.clearance = p.clearance
        self.v_max = p.max_speed
        self.a_max = p.max_accel
        self.horizon = p.horizon
        self.jerk = p.jerk
        self.k_v = p.velocity_gain
        self.tan_tilt = float(np.tan(np.radians(p.max_tilt_deg)))
        self.sensing_range = p.sensing_range
        self.footprint = p.keep_out()  # (m) keep-out radius: arm + rotor radius + outline_margin
        self.overlap = p.overlap()  # (m) keep-out discs overlap in plan view under this centre distance
        # No faster than it can stop within what it sees (``sensing_range``, 3D): climbing, hop +
        # approach_margin under a drone first seen straight above; crossing, D̄ + approach_margin
        # short of a drone first seen ahead. Braking at a, with the acceleration turning round in
        # ``lag`` s: v²/(2·BRAKING_SHARE·a) + v·lag ≤ room.
        ad = p.descent_accel
        room_up = p.sensing_range - p.hop - p.approach_margin
        lag_up = (p.climb_accel + ad) / self.jerk + 1.0 / self.k_v
        self.z_up = (min(p.climb_speed, _stoppable_speed(room_up, ad, lag_up, p.stop_room_min)), p.climb_accel)
        self.z_down = (p.descent_speed, ad)
        # (speed, accel) of the descents of the followers that have joined the formation
        self.z_down_formed = (p.descent_speed, min(p.formed_descent_accel, ad))
        a_h = min(self.a_max, G * self.tan_tilt)
        room = p.sensing_range - p.safety_distance - p.approach_margin
        lag = 2.0 * self.a_max / self.jerk + 1.0 / self.k_v
        self.v_max = min(self.v_max, _stoppable_speed(room, a_h, lag, p.stop_room_min))

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
        capped at ``climb_speed`` up and ``descent_speed`` down; the followers that have joined the
        formation descend with at most ``formed_descent_accel`` (:meth:`_advance_altitude_two`).
        """
        if dt <= 0.0:
            self.za[:] = 0.0
            return
        if self.z_down_formed != self.z_down:
            return self._advance_altitude_two(dt, target, target_vel)
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

    def _advance_altitude_two(self, dt: float, target: np.ndarray, target_vel: np.ndarray) -> None:
        """The altitude paths when ``formed_descent_accel`` < ``descent_accel`` (6. of
        :class:`JetAwareRule`): the followers that have joined the formation descend with at most
        ``formed_descent_accel``, the others with ``descent_accel`` (the kernel moves each drone on
        its own: two calls on the two groups give each row what one call with its own limit would)."""
        joined = self.phase == FORMED  # the leader's row too (its path is not flown)
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

    def _climb(self, s: _Step) -> None:
        """1. *climb* (ours): in place to its layer; never through a drone within D̄ above (it waits
        ``hop`` below, climbs over when too late to stop, steps aside from one that hovers there).
        Followers that reach their layer switch to the crossing."""
        z, h, layer = s.z, s.h, s.layer
        climbing = self.phase == CLIMB
        ready = climbing & (z >= layer - self.climb_tol)  # within climb_tolerance of its layer
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
        p = self.params
        slow = _rownorm(self.vel[:, :2]) < p.hover_speed  # (n,), the leader too
        hovering = slow.copy()
        hovering[0] = False  # the leader may set off any time: always D̄ + approach_margin
        pass_hover = 2.0 * self.footprint + p.hover_pass_margin
        radius = np.where(hovering, pass_hover, self.safety + p.approach_margin)[None, :]  # (1, n)
        vertical = (z[None, :] > z[:, None] + p.above_margin) & (z[None, :] < layer[:, None] + self.clearance)
        vertical[:, 0] |= z[0] > z - self.clearance  # the leader: level counts
        above = (s.soon < radius) & vertical
        above &= climbing[:, None]
        zmin = np.where(above, z[None, :], np.inf).min(axis=1)  # (n,) lowest such drone
        # below it: wait (brake as hard as it can) no higher than now — it does not chase a
        # climbing drone from below — and hop under it, or on the ground. About level with
        # it already: climb over it, unless it is straight above (footprints overlap).
        z_wait = np.maximum(np.minimum(np.maximum(self.zp, p.hover_min), zmin - self.hop), 0.0)
        overhead = (above & (h < 2.0 * self.footprint)).any(axis=1)
        vz = np.maximum(self.zv, 0.0)
        z_stop = self.zp + vz * vz / (2.0 * BRAKING_SHARE * self.z_down[1])  # where it could stop
        late = z_stop > np.maximum(zmin - self.hop, 0.0) + p.late_margin
        over = np.isfinite(zmin) & late & ~overhead
        wait = np.isfinite(zmin) & ~over
        s.z_target[wait] = np.minimum(layer[wait], z_wait[wait])
        s.z_target_vel[wait] = 0.0
        s.z_target[over] = np.maximum(layer[over], zmin[over] + self.hop)
        # waiting, airborne, under a drone that hovers there (the leader hovering, or a
        # follower over its slot): step aside, aside_margin beyond the radius it keeps from it
        stuck = above & (h < radius) & slow[None, :] & (z[:, None] > p.airborne_min)
        positions = s.positions
        there = _rownorm(positions[:, :2] - self.start_xy) < p.at_start
        aside = stuck.any(axis=1) & there & wait
        for i in np.flatnonzero(aside):
            j = int(np.argmin(np.where(stuck[i], h[i], np.inf)))
            away = positions[i, :2] - positions[j, :2]
            away /= max(float(np.linalg.norm(away)), 1e-9)
            self.start_xy[i] = positions[j, :2] + (radius[0, j] + p.aside_margin) * away
            self.asides[i] += 1
            self.events.append({"t": s.t, "drone": int(i), "other": j, "action": "aside"})

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
        p = self.params
        horizon_i = np.minimum(speed / self.a_max + p.reaction_time, p.conflict_horizon_max)  # (n,) stop + react
        d = positions[None, :, :2] - positions[:, None, :2]
        dv = self.vel[None, :, :2] - self.vel[:, None, :2]
        vv = np.einsum("ijk,ijk->ij", dv, dv)
        tc = np.clip(-np.einsum("ijk,ijk->ij", d, dv) / np.maximum(vv, 1e-9), 0.0, horizon_i[:, None])
        m = d + tc[:, :, None] * dv
        gap = np.sqrt(np.einsum("ijk,ijk->ij", m, m))
        near = (gap < self.safety) & s.seen
        gives_way = (s.idx[None, :] < s.idx[:, None]) | (self.phase[None, :] != CROSS)
        conflict = near & s.vband & gives_way  # in conflict: predicted within D̄ in a band it sweeps
        blocked = crossing & conflict.any(axis=1)
        for i in np.flatnonzero(blocked & ~self.blocked):
            self.events.append({"t": s.t, "drone": int(i), "other": int(np.argmax(conflict[i])), "action": "hold"})
        self.blocked = blocked

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
            # still in transit and (now or soon) within D̄ under it: it waits
            under = (s.soon[i] < self.safety) & (self.phase != FORMED) & (s.z < s.z[i] + self.clearance)
            if not under.any():
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
    """``anti_collision = "compensated"``: the layered rule (:class:`LayeredRule`, the paths
    unchanged) with ``downwash_feedforward`` on (its preset): under ``--aero realistic`` the
    controller compensates the downwash force it predicts; under the paper's physics it is the
    layered rule, bit for bit. (The same as ``layers`` with ``downwash_feedforward = true``.)"""

    name = "compensated"


#: Centre distance (m) under which two drones' keep-out discs overlap in plan view (the default
#: vehicle and record: :meth:`RuleParams.overlap`); a rule's own is ``rule.overlap``.
OVERLAP_M = RuleParams().overlap()


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
       formation altitude), never one lower than ``floor_clearance`` above the floor. As
       printed, two drones that both yield upwards to a third end at the same altitude, within D̄
       of each other (measured: a contact).
    4. *never through* — a formed follower never changes altitude through a drone whose outline
       overlaps its own in plan view (now, or predicted over ``horizon`` when the two close faster
       than ``closing_min``): it holds ``hop`` above or below it until they are apart.
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
       a drone crossing below it from D̄ + ``crossing_hold`` = 1.0 m out (now or predicted over
       ``horizon``), not from D̄: a follower crossing at up to 3 m/s towards one descending onto
       its layer closed the last 0.2 m before the hold had turned the descent round (seed 94 of
       the eight-follower starts: a contact at 0.43 m). The layered rule's hold (4. *formed* of
       :class:`LayeredRule`) stays, for every drone in transit.
    """

    name = "jet-aware"

    def reset(self, positions: np.ndarray) -> None:
        super().reset(positions)
        self._slot_h = np.full((self.n, self.n), np.inf)  # (n, n) horizontal distances of the setpoints
        self._slot_yield = False
        self._formation_alt = np.inf  # (set by update) offsets are kept floor_clearance above the floor

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
        # candidate offsets, from max_hops_down hops below to max_hops_up above, none that would put
        # the drone within floor_clearance of the floor
        low = self.params.floor_clearance - self._formation_alt
        hops = range(-self.params.max_hops_down, self.params.max_hops_up + 1)
        cands = tuple(o for o in (float(k) * hop for k in hops) if o >= low or o == 0.0)
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
        near = (soon < self.overlap) & formed[:, None]
        if not near.any():
            return z_target
        z = positions[:, 2]
        above = z[None, :] > z[:, None]  # [i, j]: j above i
        lo = np.where(near & ~above, z[None, :] + self.hop, -np.inf).max(axis=1)
        hi = np.where(near & above, z[None, :] - self.hop, np.inf).min(axis=1)
        held = np.where(lo > hi, z, np.minimum(np.maximum(z_target, lo), hi))
        return np.where(formed, held, z_target)

    def _closing(self, positions: np.ndarray, h: np.ndarray, soon: np.ndarray) -> np.ndarray:
        """``soon`` (n, n) where two drones close faster than ``closing_min``, else their present
        horizontal distance ``h`` (n, n) (unseen pairs, +inf in ``soon``, stay +inf)."""
        d = positions[None, :, :2] - positions[:, None, :2]  # (n, n, 2) j − i
        dv = self.vel[None, :, :2] - self.vel[:, None, :2]
        closing = -np.einsum("ijk,ijk->ij", d, dv) / np.maximum(h, 1e-9)  # (n, n) > 0: approaching
        return np.where(np.isinf(soon) | (closing > self.params.closing_min), soon, h)

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
        (``soon`` (n, n)), within D̄ + ``crossing_hold`` horizontally."""
        below = (
            (soon < self.safety + self.params.crossing_hold)
            & formed[:, None]
            & (self.phase[None, :] == CROSS)
            & (z[None, :] < z[:, None])
            & (z[None, :] > z_target[:, None] - self.clearance)
        )
        return self._hold_above(z, z_target, below)

    def _update_formed(
        self, t: float, positions: np.ndarray, pos_d: np.ndarray, formation_alt: float, dt: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """The layered rule's formed step (one compiled kernel) with 4. of the class docstring."""
        h = _horizontal_distances(positions)
        self._react(t, positions, h, self._all)
        offset = self.offset
        if (h[1:] < self.overlap).any():
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
    "compensated": CompensatedRule,
    "jet-aware": JetAwareRule,
}
AntiCollision = LayeredRule | PaperRule | NoRule | CompensatedRule | JetAwareRule


__all__ = [
    "ANTI_COLLISION_RULES",
    "AUTO",
    "AntiCollision",
    "CLIMB",
    "CROSS",
    "FORMED",
    "OVERLAP_M",
    "G",
    "CompensatedRule",
    "JetAwareRule",
    "LayeredRule",
    "NoRule",
    "PRESETS",
    "PaperRule",
    "Rule",
    "RuleParams",
    "horizontal_distances",
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
    """Build an anti-collision rule by name (``layers``, ``paper``, ``off``, ``compensated``,
    ``jet-aware``; resolve ``"auto"`` first with :func:`resolve_rule`): its preset
    (:data:`PRESETS`) with ``params``, any fields of :class:`RuleParams` (a scenario's
    ``[formation]`` keys; :class:`UserError` naming ``where`` for an unknown one)."""
    if name not in ANTI_COLLISION_RULES:
        raise UserError(f"unknown rule {name!r}; choose one of {', '.join(ANTI_COLLISION_RULES)}", where=where)
    return ANTI_COLLISION_RULES[name](n, PRESETS[name].with_overrides(params, where=where.rsplit(".", 1)[0]))
