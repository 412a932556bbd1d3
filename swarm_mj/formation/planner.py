"""The planner of the anti-collision (ours; docs/interpretations.md §4, docs/anticollision.md): the
phase machine (climb, cross, formed) of :class:`LayeredRule`, its layers and its limited paths;
the separation it applies comes from :mod:`.separation`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .._jit import Bound
from ..physics.params import DEFAULT_PARAMS
from ..pipeline.records import Rule as FormedRecord
from ..trajectories import Reference, joined_from_rest
from .layered import (
    advance_altitude_kernel,
    advance_paths_kernel,
    any_below,
    estimate_velocities,
    formed_paths,
    formed_update,
    path_limits,
    slotted,
)
from .rule_params import LayersParams
from .rules import PaperRule, pair_distances, rownorm
from .separation import Sensed, closest_approach, descending_onto, hold_above, seen_within


def _stoppable_speed(room: float, accel: float, lag: float, room_min: float, share: float) -> float:
    """Largest v with v²/(2·share·accel) + v·lag ≤ room (room floored at ``room_min``): the speed
    from which a path braking at share·accel (``braking_share``), after ``lag`` s, stops within ``room``."""
    k = 1.0 / (2.0 * share * accel)
    room = max(room, room_min)
    return float((-lag + np.sqrt(lag * lag + 4.0 * k * room)) / (2.0 * k))


CLIMB, CROSS, FORMED = 0, 1, 2
G = DEFAULT_PARAMS.g  # m/s², paper Table 1 (docs/interpretations.md §1)


def leader_start(
    p: LayersParams, trajectory: Callable[[np.ndarray], Reference], start: np.ndarray
) -> Callable[[np.ndarray], Reference]:
    """The reference the planner has the leader fly from ``start`` (3,) (docs/barrier.md, "the leader's
    start"): ``trajectory`` joined from rest (:func:`~swarm_mj.trajectories.joined_from_rest`), its
    position over ``p.leader_join_s`` and its altitude over ``p.leader_climb_s``; with both 0 the
    trajectory itself, from the first period (the paper's step)."""
    if p.leader_join_s <= 0.0 and p.leader_climb_s <= 0.0:
        return trajectory
    return joined_from_rest(trajectory, start, p.leader_join_s, p.leader_climb_s)


@dataclass
class PlanStep:
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
    """Ours (``anti_collision = "layers"``, the default under the paper's physics): the planner,
    altitude layers for the transition from the start to the slot, then the paper's rule
    (docs/interpretations.md §4; why, and what was measured: docs/anticollision.md).

    **What is the paper's** (Fig. 5, §4): collisions are avoided by changes of altitude while
    each follower keeps aiming at its (x, y) slot; D̄ = ``safety_distance``; the step ``hop``;
    the higher index yields and a follower always yields to the leader; once a follower has
    joined the formation, the printed reaction (:func:`~.separation.fig5_react`) among formed
    followers and the leader protects it.

    **The phase machine** (ours), per follower k (1-based), each decision from the leader's
    position and the drones within ``sensing_range`` (3D); the phases only go forward
    (climb → cross → formed):

    1. *climb* — in place, to its own layer, formation altitude + k·``hop``. Invariant: its
       altitude target never rises into a drone above it that is (or, over ``horizon``, is
       predicted to be) within D̄ + ``approach_margin`` horizontally (2·keep-out +
       ``hover_pass_margin`` for a hovering follower), nor into the leader when level: it waits
       ``hop`` under it (no higher than it is), or climbs over when it can no longer stop below
       (``late_margin``) and the other is not straight overhead. Waiting under one that stays,
       it steps aside (``aside_margin``).
    2. *cross* — within ``climb_tolerance`` of its layer, to its slot on the layer along a
       limited path. Invariant: it is asked to brake to rest while a drone it gives way to (the
       leader, a lower index, any drone not crossing) is predicted within D̄ before it could stop
       (``reaction_time``), in an altitude band it sweeps (``clearance``); with ``crossing_brake``
       off (``barrier``'s preset) it never brakes, and the separation filter separates.
    3. *drop* — within ``arrive`` of its slot (and its path too) it joins the formation, only
       when no drone in transit is (or will be) within D̄ under it; descending, it holds
       ``transit_hold_m`` (``hop``; under ``barrier`` the filter's keep-out height) above any drone
       in transit within D̄ below (:func:`~.separation.hold_above`).
    4. *formed* — the paper's reaction.

    **Limited paths**: every follower's references are the position, velocity and acceleration
    of jerk-limited paths (:func:`~.layered.advance_paths_kernel`,
    :func:`~.layered.advance_altitude_kernel`, whose docstrings state their limits).
    Assumptions: a drone tracks its path (the controller's error stays well under ``hop``), and
    the speed caps let it stop within what it senses: climbing, ``hop`` + ``approach_margin``
    under a drone first seen straight above; crossing, D̄ + ``approach_margin`` short of one
    first seen ahead (:func:`_stoppable_speed`).

    A reference-level separation filter (:class:`~.separation.SeparationFilter`, e.g. a barrier
    certificate) may be set as ``rule.separation_filter``: :meth:`references` passes it the
    planner's references of the steered drones.
    """

    name = "layers"
    Params = LayersParams
    params: LayersParams

    def __init__(self, n: int, params: LayersParams | None = None, **overrides: Any) -> None:
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
        self.transit_hold_m = p.hop  # (m) a descending formed follower's least height over a drone in transit below
        self.footprint = p.keep_out(self.vehicle)  # (m) keep-out radius: rotor span + outline_margin
        self.overlap = p.overlap(self.vehicle)  # (m) keep-out discs overlap in plan view under this centre distance
        # No faster than it can stop within what it sees (``sensing_range``, 3D): climbing, hop +
        # approach_margin under a drone first seen straight above; crossing, D̄ + approach_margin
        # short of a drone first seen ahead. Braking at a, with the acceleration turning round in
        # ``lag`` s: v²/(2·braking_share·a) + v·lag ≤ room.
        ad = p.descent_accel
        room_up = p.sensing_range - p.hop - p.approach_margin
        lag_up = (p.climb_accel + ad) / self.jerk + 1.0 / self.k_v
        v_up = _stoppable_speed(room_up, ad, lag_up, p.stop_room_min, p.braking_share)
        self.z_up = (min(p.climb_speed, v_up), p.climb_accel)
        self.z_down = (p.descent_speed, ad)
        # (speed, accel) of the descents of the followers that have joined the formation
        self.z_down_formed = (p.descent_speed, min(p.formed_descent_accel, ad))
        a_h = min(self.a_max, G * self.tan_tilt)
        room = p.sensing_range - p.safety_distance - p.approach_margin
        lag = 2.0 * self.a_max / self.jerk + 1.0 / self.k_v
        self.v_max = min(self.v_max, _stoppable_speed(room, a_h, lag, p.stop_room_min, p.braking_share))
        # what the path kernels read (layered.PathLimits): the record's fields and these derived ones
        self._limits = path_limits(
            p, v_max=self.v_max, tan_tilt=self.tan_tilt, g=G, v_up=self.z_up[0], a_down_formed=self.z_down_formed[1]
        )

    #: the formed step checks the jet-aware separation's conditions too (:func:`~.layered.formed_update`)
    jet_aware_checks = False

    def reset(self, positions: np.ndarray) -> None:
        super().reset(positions)
        positions = np.asarray(positions, dtype=float)
        n = self.n
        self.phase = np.full(n, CLIMB, dtype=np.int64)
        self.phase[0] = FORMED  # the leader flies its own trajectory
        self._all_formed = bool((self.phase == FORMED).all())  # phases change only in update()
        self.start_xy = positions[:, :2].copy()  # (n, 2) where each follower climbs in place
        self.path_p = positions[:, :2].copy()  # (n, 2) crossing path: position
        self.path_v = np.zeros((n, 2))  # (n, 2) crossing path: velocity
        self.path_a = np.zeros((n, 2))  # (n, 2) crossing path: acceleration
        self.blocked = np.zeros(n, dtype=bool)  # (n,) braking for another drone (updated in place)
        self.asides = np.zeros(n, dtype=np.int64)  # (n,) times stepped out from under a drone
        self.layer_index = np.arange(n, dtype=float)
        self.zp = positions[:, 2].copy()  # (n,) altitude path: position
        self.zv = np.zeros(n)  # (n,) altitude path: velocity
        self.za = np.zeros(n)  # (n,) altitude path: acceleration
        self._prev_pos = np.array(positions, dtype=float)  # (n, 3) updated in place
        self._prev_t = np.full(1, np.nan)  # (1,) (s) time of the last update (NaN: none yet)
        self._dt = np.zeros(1)  # (1,) (s) the dt of the last update
        self.vel = np.zeros((n, 3))  # (n, 3) velocities estimated from positions
        self._sensed_vel = np.zeros((n, 3))  # (n, 3) the view's velocities (sense_velocities)
        self._vel_sensed = np.zeros(1, dtype=bool)  # (1,) vel is _sensed_vel (a sensing model)
        self._all = np.ones(n, dtype=bool)  # (n,) every drone (read-only)
        self._followers = np.ones(n, dtype=bool)  # (n,) the drones the rule steers (read-only)
        self._followers[0] = False
        # the jet-aware separation's (read by the formed step when ``jet_aware_checks``)
        self._slot_h = np.full((n, n), np.inf)  # (n, n) horizontal distances of the setpoints
        self._formation_alt = np.full(1, np.inf)  # (1,) (m) offsets are kept floor_clearance above the floor
        self.slot_of = np.arange(n, dtype=np.int64)  # (n,) drone i flies to slot slot_of[i] (layered.slotted)
        self._record: FormedRecord | None = None
        # the compiled formed step and paths bound to the record (no re-typing of its fields per call: _jit.Bound)
        self._formed_update = Bound(formed_update)
        self._formed_paths_call = Bound(formed_paths)

    def record(self) -> FormedRecord:
        """The formed step's record (:class:`~swarm_mj.pipeline.records.Rule`) over this rule's own
        arrays, built once per :meth:`reset`: what :func:`~.layered.formed_update` reads and
        updates, on either driver of the control period."""
        if self._record is None:
            self._record = FormedRecord(
                on=True,
                jet_aware=self.jet_aware_checks,
                safety=float(self.safety),
                overlap=float(self.overlap),
                offset=self.offset,
                prev_pos=self._prev_pos,
                vel=self.vel,
                prev_t=self._prev_t,
                dt=self._dt,
                formation_alt=self._formation_alt,
                slot_h=self._slot_h,
                path_p=self.path_p,
                path_v=self.path_v,
                path_a=self.path_a,
                blocked=self.blocked,
                zp=self.zp,
                zv=self.zv,
                za=self.za,
                limits=self._limits,
                vel_d=self.vel_d,
                acc_d=self.acc_d,
                steer=self._followers,
                slot_of=self.slot_of,
                sensed_vel=self._sensed_vel,
                vel_sensed=self._vel_sensed,
            )
        return self._record

    def sense_velocities(self, vel: np.ndarray) -> None:
        """Under a sensing model: the velocities (n, 3) of this copy's drone's view (what it believes every
        drone flies, its own included), used from now on instead of differencing positions (paper §4's
        estimate, which would turn the view's position noise into velocity noise: docs/sensing.md)."""
        self._sensed_vel[:] = vel
        self._vel_sensed[0] = True

    def compiled_ready(self) -> bool:
        """Its compiled formed step (:func:`~.layered.formed_update`, the chunk driver's) is all it would
        do now: every follower formed, a first update behind it, and (``jet_aware_checks``) no two slots
        within D̄ horizontally."""
        return (
            self._all_formed
            and not np.isnan(self._prev_t[0])
            and not (self.jet_aware_checks and any_below(self._slot_h, self.safety))
        )

    def references(
        self,
        t: float,
        positions: np.ndarray,
        pos_d: np.ndarray,
        vel_d: np.ndarray,
        acc_d: np.ndarray,
        formation_alt: float,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`Rule.references`, then the ``separation_filter`` (if any) on the steered drones."""
        pos_d, vel_d, acc_d = super().references(t, positions, pos_d, vel_d, acc_d, formation_alt)
        f = self.separation_filter
        if f is None:
            return pos_d, vel_d, acc_d
        seen = seen_within(positions, self.sensing_range)
        sensed = Sensed(
            t=float(t),
            positions=positions,
            velocities=self.vel,
            seen=seen,
            keep_out=self.footprint,
            dt=float(self._dt[0]),
        )
        out = f(sensed, pos_d, vel_d, acc_d, self._followers)
        self.take_separation_events()
        return out

    # ------------------------------------------------------------------ helpers
    def _approach(self, positions: np.ndarray, horizon: float) -> np.ndarray:
        """(n, n) predicted closest approach of each pair over ``horizon`` s
        (:func:`~.separation.closest_approach`, with the estimated velocities)."""
        return closest_approach(positions, self.vel, horizon)

    def _vertical_overlap(self, z: np.ndarray, tau: float) -> np.ndarray:
        """(n, n) the altitude bands swept over the next ``tau`` s (estimated vertical
        velocity), widened by ``clearance``, overlap."""
        z2 = z + self.vel[:, 2] * tau
        lo, hi = np.minimum(z, z2) - 0.5 * self.clearance, np.maximum(z, z2) + 0.5 * self.clearance
        return (lo[None, :] < hi[:, None]) & (lo[:, None] < hi[None, :])

    def _advance_paths(self, dt: float, goal: np.ndarray, goal_vel: np.ndarray) -> None:
        """Move every follower's horizontal path towards ``goal`` (n, 2), which moves at
        ``goal_vel`` (n, 2): speed ≤ ``max_speed`` relative to the goal with a braking
        profile v = √(2·braking_share·a·e), acceleration ≤ ``max_accel``; blocked drones brake to rest."""
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
            self._limits,
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
        advance_altitude_kernel(
            float(dt),
            np.ascontiguousarray(target, dtype=np.float64),
            np.ascontiguousarray(target_vel, dtype=np.float64),
            self.zp,
            self.zv,
            self.za,
            self._limits,
            self.z_down[1],
        )

    def _advance_altitude_two(self, dt: float, target: np.ndarray, target_vel: np.ndarray) -> None:
        """The altitude paths when ``formed_descent_accel`` < ``descent_accel`` (6. of
        :class:`JetAwareRule`): the followers that have joined the formation descend with at most
        ``formed_descent_accel``, the others with ``descent_accel`` (the kernel moves each drone on
        its own: two calls on the two groups give each row what one call with its own limit would)."""
        joined = self.phase == FORMED  # the leader's row too (its path is not flown)
        ad, ad_joined = self.z_down[1], self.z_down_formed[1]
        target = np.asarray(target, dtype=np.float64)
        target_vel = np.asarray(target_vel, dtype=np.float64)
        for rows, a_down in ((np.flatnonzero(joined), ad_joined), (np.flatnonzero(~joined), ad)):
            if rows.size == 0:
                continue
            zp, zv, za = self.zp[rows], self.zv[rows], self.za[rows]  # (k,) copies
            advance_altitude_kernel(float(dt), target[rows], target_vel[rows], zp, zv, za, self._limits, a_down)
            self.zp[rows], self.zv[rows], self.za[rows] = zp, zv, za

    # ------------------------------------------------------------------ the rule
    def _update_formed(
        self, t: float, positions: np.ndarray, pos_d: np.ndarray, formation_alt: float, dt: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """4. *formed* for the whole swarm (every follower formed, nobody in transit) while Fig. 5
        has work to do: the paper's reactive rule among all drones, then the paths towards the slots
        and formation_alt + offset (:meth:`_formed_paths`)."""
        h = pair_distances(positions)
        self._react(t, positions, h, self._all)
        return self._formed_paths(dt, pos_d, formation_alt, self.offset)

    def _formed_paths(
        self, dt: float, pos_d: np.ndarray, formation_alt: float, offset: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """The formed swarm's paths towards the slots pos_d (n, 3) and formation_alt + offset (n,)
        (:func:`~.layered.formed_paths`)."""
        out = self._formed_paths_call(
            self.record(),
            float(dt),
            np.ascontiguousarray(pos_d, dtype=np.float64),
            float(formation_alt),
            np.ascontiguousarray(offset, dtype=np.float64),
        )
        return out, self._followers

    def update(
        self, t: float, positions: np.ndarray, pos_d: np.ndarray, formation_alt: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """Climb / cross / drop (ours) for followers not yet formed, Fig. 5 for the others. Once every
        follower is formed, the compiled formed step (:func:`~.layered.formed_update`, what the chunk
        driver flies too) decides, and the Python reaction (:meth:`_update_formed`) flies only the
        periods where Fig. 5 has work to do."""
        if self._all_formed:
            busy, out = self._formed_update(
                self.record(),
                np.ascontiguousarray(positions, dtype=np.float64),
                np.ascontiguousarray(pos_d, dtype=np.float64),
                float(t),
                float(formation_alt),
            )
            if not busy:
                return out, self._followers
            pos_d = self.slots(pos_d)
            return self._update_formed(t, positions, pos_d, formation_alt, self._estimate_velocities(t, positions))
        pos_d = self.slots(pos_d)
        dt = self._estimate_velocities(t, positions)
        s = self._sense(t, positions, pos_d, formation_alt, dt)
        self._climb(s)
        self._cross(s)
        self._drop(s)
        self._formed(s)
        return self._fly_paths(s)

    def slots(self, pos_d: np.ndarray) -> np.ndarray:
        """Each drone's slot (n, 3): row ``slot_of[i]`` of the setpoints pos_d (n, 3) for drone i
        (:func:`~.layered.slotted`); pos_d itself when every drone flies to its own."""
        if self._own_slots:
            return pos_d
        return slotted(np.ascontiguousarray(pos_d, dtype=np.float64), self.slot_of)

    @property
    def _own_slots(self) -> bool:
        return bool((self.slot_of == np.arange(self.n)).all())

    # ------------------------------------------------------------------ its steps
    def _estimate_velocities(self, t: float, positions: np.ndarray) -> float:
        """The step dt since the last update and every drone's velocity estimated from its
        successive positions (:func:`~.layered.estimate_velocities`)."""
        pos = np.ascontiguousarray(positions, dtype=np.float64)
        dt = float(estimate_velocities(float(t), pos, self._prev_pos, self.vel, self._prev_t, self._dt))
        if self._vel_sensed[0]:
            self.vel[:] = self._sensed_vel
        return dt

    def _sense(self, t: float, positions: np.ndarray, pos_d: np.ndarray, formation_alt: float, dt: float) -> PlanStep:
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
        seen = seen_within(positions, self.sensing_range)  # (n, n)
        soon = np.where(seen, self._approach(positions, self.horizon), np.inf)  # (n, n)
        return PlanStep(
            t=t,
            positions=positions,
            pos_d=pos_d.copy(),
            formation_alt=formation_alt,
            dt=dt,
            steer=steer,
            h=pair_distances(positions),
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

    def _climb(self, s: PlanStep) -> None:
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
        slow = rownorm(self.vel[:, :2]) < p.hover_speed  # (n,), the leader too
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
        z_stop = self.zp + vz * vz / (2.0 * p.braking_share * self.z_down[1])  # where it could stop
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
        there = rownorm(positions[:, :2] - self.start_xy) < p.at_start
        aside = stuck.any(axis=1) & there & wait
        for i in np.flatnonzero(aside):
            j = int(np.argmin(np.where(stuck[i], h[i], np.inf)))
            away = positions[i, :2] - positions[j, :2]
            away /= max(float(np.linalg.norm(away)), 1e-9)
            self.start_xy[i] = positions[j, :2] + (radius[0, j] + p.aside_margin) * away
            self.asides[i] += 1
            self.events.append({"t": s.t, "drone": int(i), "other": j, "action": "aside"})

    def _cross(self, s: PlanStep) -> None:
        """2. *cross* (ours): the horizontal goals — its start while climbing, its slot (moving with
        the leader) after — and, crossing on the layer, braking to rest (``blocked``) while a drone
        it gives way to (the leader, a lower index, any drone not crossing) is in conflict; with
        ``crossing_brake`` off it never brakes (a separation filter separates: docs/barrier.md)."""
        n = self.n
        positions = s.positions
        climbing = self.phase == CLIMB
        crossing = self.phase == CROSS
        s.goal = s.pos_d[:, :2].copy()  # (n, 2) slots
        s.goal_vel = np.broadcast_to(self.vel[0, :2], (n, 2)).copy()  # (n, 2) their velocity
        s.goal[climbing] = self.start_xy[climbing]
        s.goal_vel[climbing] = 0.0
        p = self.params
        if not crossing.any() or not p.crossing_brake:
            self.blocked[:] = False
            return
        self.blocked &= crossing
        speed = rownorm(self.vel[:, :2])
        horizon_i = np.minimum(speed / self.a_max + p.reaction_time, p.conflict_horizon_max)  # (n,) stop + react
        gap = closest_approach(positions, self.vel, horizon_i[:, None])  # (n, n) over each one's horizon
        near = (gap < self.safety) & s.seen
        gives_way = (s.idx[None, :] < s.idx[:, None]) | (self.phase[None, :] != CROSS)
        conflict = near & s.vband & gives_way  # in conflict: predicted within D̄ in a band it sweeps
        blocked = crossing & conflict.any(axis=1)
        for i in np.flatnonzero(blocked & ~self.blocked):
            self.events.append({"t": s.t, "drone": int(i), "other": int(np.argmax(conflict[i])), "action": "hold"})
        self.blocked[:] = blocked

    def _drop(self, s: PlanStep) -> None:
        """3. *drop* (ours): a crossing follower within ``arrive`` of its slot (and its path too)
        joins the formation — and so descends to the formation altitude — when nothing is under it."""
        crossing = self.phase == CROSS
        if not crossing.any():
            return
        there = (
            crossing
            & (rownorm(s.positions[:, :2] - s.goal) < self.arrive)
            & (rownorm(self.path_p - s.goal) < self.arrive)
        )
        for i in np.flatnonzero(there):
            # still in transit and (now or soon) within D̄ under it: it waits
            under = (s.soon[i] < self.safety) & (self.phase != FORMED) & (s.z < s.z[i] + self.clearance)
            if not under.any():
                self.phase[i] = FORMED
                self.blocked[i] = False
                self.events.append({"t": s.t, "drone": int(i), "other": -1, "action": "drop"})

    def _formed(self, s: PlanStep) -> None:
        """4. *formed* (the paper's, Fig. 5): the reactive rule among formed drones and the leader
        sets the altitude offset of each formed follower; ours: one still descending never descends
        onto a drone in transit within D̄ (now or soon) below it, it waits ``transit_hold_m`` above it
        (docs/interpretations.md §4's failure case)."""
        z = s.z
        formed = self.phase == FORMED
        self._react(s.t, s.positions, s.h, formed)
        formed[0] = False
        s.z_target[formed] = s.formation_alt + self.offset[formed]
        if not s.in_transit:
            return
        below = descending_onto(z, s.z_target, formed, self.phase != FORMED, s.soon < self.safety, self.clearance)
        s.z_target = hold_above(z, s.z_target, below, self.transit_hold_m)

    def _fly_paths(self, s: PlanStep) -> tuple[np.ndarray, np.ndarray]:
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


#: The layered rule; the name stays for the chunk driver's rule check. What the ``compensated`` rule
#: was (the layered rule with the downwash feedforward) is ``layers`` with ``[controller]
#: downwash_feedforward = true``.
CompensatedRule = LayeredRule
