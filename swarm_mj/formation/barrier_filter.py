"""The barrier as a separation filter (docs/barrier.md, "the separation filter"): one period of it,
:func:`barrier_step` on its record (what :class:`BarrierFilter` calls and the chunk driver too,
swarm_mj/pipeline/period.py), with the deadlock escape (:func:`_escape_update`)."""

from __future__ import annotations

import numpy as np

from .._jit import jit, warm_module
from ..physics.params import DEFAULT_PARAMS, QuadParams
from .barrier_kernels import filter_accelerations, lane_nominal_kernel, takeoff_wait_kernel
from .barrier_params import BarrierParams, BarrierRecord, new_record
from .separation import Sensed

#: The modules whose ``on_demand`` kernels a :class:`BarrierFilter` compiles (or loads) when it is built,
#: before a run's clock starts (swarm_mj/_jit.py, ``warm_module``).
BARRIER_MODULES = (
    "swarm_mj.formation.keepout",
    "swarm_mj.formation.barrier_qp",
    "swarm_mj.formation.barrier_joint",
    "swarm_mj.formation.barrier_kernels",
    "swarm_mj.formation.barrier_filter",
)


@jit(inline=True, on_demand=True)
def _escape_update(rec, i, guarded, active, pos_d, dt):
    """The deadlock escape of drone i, after its period (docs/barrier.md, "deadlock escape"): a
    guarded drone whose command the filter changes and whose reference has not come
    ``escape_progress_m`` nearer the planner's (horizontally) for ``escape_after_s`` s, farther than
    ``escape_min_m`` from it, escapes: its nominal's altitude is raised by ``escape_height`` × the
    keep-out's vertical radius until its reference is within ``escape_done_m`` of the planner's
    (counted in ``counts[4]``). A free drone, and the leader (not steered), do not escape."""
    if rec.escape_after_s <= 0.0 or not guarded:
        rec.escaping[i] = False
        rec.pressed_s[i] = 0.0
        return
    far = np.sqrt((pos_d[i, 0] - rec.ref[i, 0]) ** 2 + (pos_d[i, 1] - rec.ref[i, 1]) ** 2)
    if rec.escaping[i]:
        if far < rec.escape_done_m:
            rec.escaping[i] = False
            rec.pressed_s[i] = 0.0
    elif active and far > rec.escape_min_m:
        if rec.pressed_s[i] <= 0.0 or far < rec.best_m[i] - rec.escape_progress_m:
            rec.best_m[i] = far  # progress: the clock starts again
            rec.pressed_s[i] = 1e-9
        else:
            rec.pressed_s[i] += dt
            if rec.pressed_s[i] > rec.escape_after_s:
                rec.escaping[i] = True
                rec.counts[4] += 1
    else:
        rec.pressed_s[i] = 0.0


@jit(inline=True)
def _sense(rec, positions, vel, dt):
    """What the filter keeps of the sensed state: where each drone stood at the first call (the take-off
    gate's start), and the accelerations from successive velocities, low-passed (``accel_filter_s``)."""
    n = positions.shape[0]
    if not rec.flags[0]:
        rec.start[:] = positions  # where each drone stands on the ground
        rec.flags[0] = True
    if dt > 0.0 and rec.flags[1] and rec.accel_filter_s > 0.0:
        f = dt / (rec.accel_filter_s + dt)
        for i in range(n):
            for c in range(3):
                raw = (vel[i, c] - rec.prev_vel[i, c]) / dt
                rec.sensed_acc[i, c] += (raw - rec.sensed_acc[i, c]) * f
    rec.prev_vel[:] = vel
    rec.flags[1] = True


@jit(inline=True)
def _nominals(rec, own, steer, positions, vel, pos_d, vel_d, acc_d):
    """Each drone's reference and nominal acceleration, (g, ref, ref_vel, u_nom): the planner's (pos_d,
    vel_d, acc_d) (n, 3) for a free drone; for a guarded one (g (n,)), its own reference (r, ṙ) and the
    guarded nominal (:func:`~.barrier_kernels.lane_nominal_kernel` towards the planner's reference, an
    escaping drone's raised), within the limits. The leader (``own``, not ``steer``) is guarded from where
    it is while its trajectory's reference is beyond ``leader_guard_m``."""
    n = positions.shape[0]
    g = np.zeros(n, dtype=np.bool_)
    ref = pos_d.copy()
    ref_vel = vel_d.copy()
    u_nom = acc_d.copy()
    any_g = False
    for i in range(n):
        g[i] = rec.guarded[i] and own[i]
        if own[i] and not steer[i] and not g[i]:  # the leader, with leader_filters
            far2 = 0.0
            for c in range(3):
                far2 += (pos_d[i, c] - positions[i, c]) ** 2
            if far2 > rec.leader_guard_m * rec.leader_guard_m:  # a reference it cannot fly now (its first):
                g[i] = True  # guarded from where it is, its nominal the PD onto that reference
                rec.ref[i] = positions[i]
                rec.ref_vel[i] = vel[i]
        if g[i]:
            any_g = True
            ref[i] = rec.ref[i]
            ref_vel[i] = rec.ref_vel[i]
    if any_g:  # a guarded drone's nominal: round the leader on a lane towards the planner's reference
        goal = pos_d  # an escaping drone's raised (the deadlock escape): a copy only then
        copied = False
        for i in range(n):
            if rec.escaping[i]:
                if not copied:
                    goal = pos_d.copy()
                    copied = True
                goal[i, 2] += rec.escape_height * rec.radii[2]
        lane_nominal_kernel(ref, ref_vel, positions[0], goal, vel_d, acc_d, rec.radii[0], rec.lane_gains,
                            rec.lanes, g, u_nom)  # fmt: skip
        face = rec.a_h * np.cos(np.pi / 8.0)
        for i in range(n):
            if g[i]:
                nh = max(np.sqrt(u_nom[i, 0] ** 2 + u_nom[i, 1] ** 2), 1e-12)
                s = min(1.0, face / nh)
                u_nom[i, 0] *= s
                u_nom[i, 1] *= s
                u_nom[i, 2] = min(max(u_nom[i, 2], -rec.accel_down), rec.accel_up)
    return g, ref, ref_vel, u_nom


@jit(inline=True)
def _drone_limits(rec, own, steer, wait, positions, ref, ref_vel, vel_d):
    """Which drones filter and take a share of the pairs' constraints, each drone's input limits (a_h,
    a_up, a_down) (n, 3), the ground band's and the ground envelope's included (docs/barrier.md, "near the
    ground"), and its QP metric (a follower the planner descends is changed vertically first):
    (filters, pair_filters, limits, hcost)."""
    n = positions.shape[0]
    filters = np.empty(n, dtype=np.bool_)
    limits = np.empty((n, 3))  # each drone's (a_h, a_up, a_down)
    pair_filters = np.empty(n, dtype=np.bool_)  # the drones that take a share of the pairs' constraints
    hcost = np.ones(n)  # the QP's metric: a follower the planner descends is changed vertically first
    for i in range(n):
        if steer[i] and vel_d[i, 2] < -rec.descent_vz:
            hcost[i] = rec.descent_horizontal_cost
        filters[i] = own[i] and not wait[i]
        # the leader (own, not steered) only with leader_yields: else it flies its nominal, the followers take all
        pair_filters[i] = filters[i] and (steer[i] or rec.leader_yields)
        limits[i, 0] = rec.a_h
        limits[i, 1] = rec.accel_up
        limits[i, 2] = rec.accel_down
        z_low = min(ref[i, 2], positions[i, 2])
        if z_low < rec.ground_band_m:
            limits[i, 2] = 0.0  # near the ground: not pushed down
        elif ref_vel[i, 2] < 0.0 and rec.ground_brake_share > 0.0:
            # the ground envelope (docs/barrier.md, "near the ground"): h = z − band − v²/(2·a_b) ≥ 0
            # (it can still stop above the band braking at a_b), kept by ḣ ≥ −k·h: u_z ≥ a_b·(1 − k·h/|v|),
            # at most accel_up (a drone already past its envelope brakes at its limit: the box stays feasible)
            a_b = rec.ground_brake_share * rec.accel_up
            vz = ref_vel[i, 2]
            h = z_low - rec.ground_band_m - vz * vz / (2.0 * a_b)
            limits[i, 2] = max(min(limits[i, 2], -a_b * (1.0 + rec.gain * h / vz)), -rec.accel_up)
    return filters, pair_filters, limits, hcost


@jit(inline=True)
def _tally(rec, i, t, active, relaxed, reserve, against, joint):
    """Drone i's period in the counts (active, relaxed, on the reserve, in a joint QP) and the record's flags; the first
    period of a relaxed stretch is a relax event in the record's buffer, with the neighbour whose row
    asked most (``against``)."""
    if active:
        rec.counts[0] += 1
    if reserve:
        rec.counts[5] += 1
    if joint:
        rec.counts[6] += 1
    if relaxed:
        rec.counts[1] += 1
        if not rec.was_relaxed[i]:  # the first period of a relaxed stretch: an event
            k = rec.ev_count[0]
            if k < rec.ev_t.shape[0]:
                rec.ev_t[k] = t
                rec.ev_drone[k] = i
                rec.ev_other[k] = against
                rec.ev_count[0] = k + 1
    rec.was_relaxed[i] = relaxed
    rec.active[i] = active


@jit(inline=True)
def _hold_at_gate(rec, i, positions):
    """Drone i waits under the take-off gate: its reference held where it stands (on its start with
    ``gate_holds_start``), at most its start altitude, at rest."""
    rec.ref[i] = positions[i]
    if rec.gate_holds_start:
        rec.ref[i, 0] = rec.start[i, 0]
        rec.ref[i, 1] = rec.start[i, 1]
    rec.ref[i, 2] = min(positions[i, 2], rec.start[i, 2])
    rec.ref_vel[i] = 0.0


@jit(inline=True)
def _advance_guarded(rec, i, u, active, ref, ref_vel, positions, dt, out_p, out_v, out_a):
    """Guarded drone i's reference (r, ṙ) advanced with its filtered command u[i] (its vertical within
    ``vertical_jerk_limit``·dt of the last period's), never below the ground, on the leash; its row of
    the references out."""
    rec.counts[2] += 1
    if rec.vertical_jerk_limit > 0.0 and dt > 0.0:  # a vertical command the drone can follow
        step = rec.vertical_jerk_limit * dt
        lim = min(max(u[i, 2], rec.prev_acc[i, 2] - step), rec.prev_acc[i, 2] + step)
        cut = lim != u[i, 2]
        u[i, 2] = lim
        if cut and active:  # a command the barrier changed, turned slower than it asked
            rec.counts[3] += 1
    far2 = 0.0
    for c in range(3):
        rec.ref_vel[i, c] = ref_vel[i, c] + u[i, c] * dt
        rec.ref[i, c] = ref[i, c] + rec.ref_vel[i, c] * dt
    rec.ref[i, 2] = max(rec.ref[i, 2], 0.0)
    for c in range(3):
        far2 += (rec.ref[i, c] - positions[i, c]) ** 2
    far = np.sqrt(far2)
    if far > rec.leash_m:
        for c in range(3):
            rec.ref[i, c] = positions[i, c] + (rec.ref[i, c] - positions[i, c]) * (rec.leash_m / far)
    for c in range(3):
        out_p[i, c] = rec.ref[i, c]
        out_v[i, c] = rec.ref_vel[i, c]
        out_a[i, c] = u[i, c]


@jit(inline=True)
def _handed_back(rec, i, pos_d, vel_d):
    """Drone i's reference is back on the planner's (within ``release_m``, ``release_mps``)."""
    dp = 0.0
    dv = 0.0
    for c in range(3):
        dp += (rec.ref[i, c] - pos_d[i, c]) ** 2
        dv += (rec.ref_vel[i, c] - vel_d[i, c]) ** 2
    return np.sqrt(dp) <= rec.release_m and np.sqrt(dv) <= rec.release_mps


def _step_samples():
    n = 3
    rec = new_record(BarrierParams(), DEFAULT_PARAMS, n, True)
    pos = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.0, 1.0, 1.0]])
    z = np.zeros((n, 3))
    return [(rec, 0.0, pos, z, 0.0, pos, z, z, np.array([False, True, True]))]


@jit(on_demand=True, samples=_step_samples)
def barrier_step(rec, t, positions, vel, dt, pos_d, vel_d, acc_d, steer):
    """One period of :class:`BarrierFilter` (its docstring states it) on the record ``rec``: the
    references (pos_d, vel_d, acc_d) (n, 3) to fly, from the planner's (pos_d, vel_d, acc_d) (n, 3),
    the sensed ``positions`` and ``vel`` (n, 3) of time ``t``, ``dt`` s after the last call, for the
    drones flagged ``steer`` (n,). Updates the record's state; appends the relax events to its
    buffer (the caller drains it).

    With ``rec.own_row`` = i ≥ 0 (drone i's copy, swarm_mj/formation/own_view.py) only row i is
    computed, bit for bit as with every row: the other rows are the planner's, their QPs unsolved,
    their state (guarded, ref, ref_vel, escape, tallies: ``counts`` then counts drone i alone) left as
    it was. That is exact because row i reads no other row's filter state: the others enter its QP
    (:func:`~.barrier_kernels.filter_accelerations`) through their sensed state (``positions``, ``vel``,
    ``sensed_acc``) and whether they filter (``steer``, the take-off gate's ``wait``/``waited``, computed
    for every row as before), never through their references, nominals, limits or filtered commands;
    and row j ≠ i of the record is read by row j alone, which no later period of it computes. The
    nominals and limits of rows j ≠ i are still computed: restricting them too is exact but measured
    no faster (docs/performance.md); ``_sense`` and the gate must run for every row."""
    n = positions.shape[0]
    own = steer.copy()  # the drones this filter flies: the steered ones, and the leader with leader_filters
    if rec.leader_filters and n > 0:
        own[0] = True
    _sense(rec, positions, vel, dt)
    g, ref, ref_vel, u_nom = _nominals(rec, own, steer, positions, vel, pos_d, vel_d, acc_d)
    wait = np.zeros(n, dtype=np.bool_)
    takeoff_wait_kernel(positions, rec.radii, steer, vel, rec.sensed_acc, True, rec.floor_m, rec.gate_rho,
                        rec.gate_rho_ground, rec.gate_horizon_s, wait, pos_d[0], rec.gate_leader_way,
                        rec.waited)  # fmt: skip
    rec.waited[:] = wait
    filters, pair_filters, limits, hcost = _drone_limits(rec, own, steer, wait, positions, ref, ref_vel, vel_d)
    u, active, relaxed, _, reserve, against, joint = filter_accelerations(
        rec, ref, ref_vel, positions, vel, rec.sensed_acc, u_nom, pair_filters, limits, hcost
    )
    out_p, out_v, out_a = pos_d.copy(), vel_d.copy(), acc_d.copy()
    kept, n_ev = np.empty_like(rec.counts), 0
    for i in range(n):
        if rec.own_row >= 0 and i != rec.own_row:
            continue  # not this record's drone: its row the planner's, its state as it was (see own_row)
        other = rec.tally_row >= 0 and i != rec.tally_row  # a copy computing every row counts its own drone's
        if other:
            kept[:] = rec.counts
            n_ev = rec.ev_count[0]
        _tally(rec, i, t, active[i], relaxed[i], reserve[i], against[i], joint[i])
        g[i] = (g[i] or active[i]) and filters[i]
        if wait[i]:  # the take-off gate: held where it stands, at most its start altitude
            _hold_at_gate(rec, i, positions)
        if g[i]:  # (r, ṙ) advance with the filtered command, never below the ground, on the leash
            _advance_guarded(rec, i, u, active[i], ref, ref_vel, positions, dt, out_p, out_v, out_a)
        if wait[i]:
            for c in range(3):
                out_p[i, c] = rec.ref[i, c]
                out_v[i, c] = 0.0
                out_a[i, c] = 0.0
        back = g[i] and not active[i] and _handed_back(rec, i, pos_d, vel_d)  # handed back to the planner
        rec.guarded[i] = (g[i] and not back) or wait[i]
        _escape_update(rec, i, rec.guarded[i] and steer[i] and not wait[i], active[i], pos_d, dt)  # followers
        if other:  # another drone's row in this copy: its counts and events are not this copy's
            rec.counts[:] = kept
            rec.ev_count[0] = n_ev
    rec.prev_acc[:] = out_a
    return out_p, out_v, out_a


class BarrierFilter:
    """The barrier as a separation step (:class:`~.separation.SeparationFilter`, docs/barrier.md,
    "the separation filter"): it guards any planner's references (pos_d, vel_d, acc_d).

    Each steered drone is either *free* (its references are the planner's, bit for bit) or
    *guarded* (the filter flies its own reference state (r, ṙ)). Every period the nominal
    acceleration is the planner's acc_d for a free drone, and for a guarded one
    :func:`lane_nominal_kernel` towards the planner's reference (acc_d + k_p·(pos_d − r) + k_d·(vel_d − ṙ),
    ``guard_kp``, ``guard_kd``; round the leader on a lane first with ``guard_lanes``; within the
    input limits);
    :func:`filter_accelerations` changes it as little as possible so that (B) holds against every
    sensed drone, on (r, ṙ) (= the planner's (pos_d, vel_d) for a free drone) and on the drone's
    sensed state. A free drone whose nominal the filter changed becomes guarded; (r, ṙ) of a
    guarded drone advance with the filtered command (semi-implicit Euler over ``sensed.dt``, never
    below the ground, within ``leash_m`` of the drone, its vertical command within
    ``vertical_jerk_limit``·dt of the last period's); it becomes free again when the filter leaves
    its nominal unchanged and (r, ṙ) are within ``release_m``, ``release_mps`` of the planner's
    (pos_d, vel_d). A guarded follower pressed without progress for ``escape_after_s`` escapes up
    (the deadlock escape, :func:`_escape_update`). A follower on the ground waits under the take-off
    gate (:func:`takeoff_wait_kernel`).
    The leader filters with ``leader_filters`` (as a steered drone; guarded from where it is while its
    trajectory's reference is beyond ``leader_guard_m``, as at its first period; taking a share of
    each pair only with ``leader_yields``); drones that do not filter
    (the leader without it) keep their references; their acceleration is estimated from the
    sensed velocities, low-passed (``accel_filter_s``).

    One period is :func:`barrier_step` on the filter's record (:meth:`record`): this class calls it,
    and so does the chunk driver (swarm_mj/pipeline/period.py), the same function.

    Invariant: row i of the output depends only on drone i's references and the sensed state of
    the drones within ``sensing_range``; with no drone guarded and no constraint violated, the
    output is the input."""

    def __init__(self, params: BarrierParams | None = None, vehicle: QuadParams = DEFAULT_PARAMS) -> None:
        for module in BARRIER_MODULES:  # the filter's kernels, before a run's clock starts (_jit.jit's on_demand)
            warm_module(module)
        self.barrier = BarrierParams() if params is None else params
        self.vehicle = vehicle
        self.radii = self.barrier.radii(vehicle)
        self.a_h = self.barrier.horizontal_limit(vehicle.g)
        self.own_row = -1  # every drone's row (restrict_to: one drone's copy)
        self.tally_row = -1  # every drone's counts and events (restrict_to: one drone's copy)
        self.reset(0)

    def reset(self, n: int) -> None:
        """Start of a run of n drones: every drone free."""
        self._rec = new_record(self.barrier, self.vehicle, n, True, self.own_row, self.tally_row)
        self.events: list[dict] = []

    def restrict_to(self, i: int) -> None:
        """From now on this is drone i's own copy of the rule (swarm_mj/formation/own_view.py), whose other
        rows are thrown away: its tallies (:attr:`active_periods`...) and events are drone i's alone, and it
        computes row i only (the record's ``own_row``, :func:`barrier_step`; row i the same bit for bit, the
        other rows the planner's references). With ``joint_fallback`` it computes every row, its prediction
        of the others' (a boxed drone's cluster needs the others' references and nominals, docs/barrier.md,
        "the joint fallback")."""
        self.tally_row = int(i)
        self.own_row = -1 if self.barrier.joint_fallback else int(i)
        self._rec = self._rec._replace(own_row=self.own_row, tally_row=self.tally_row)

    def record(self) -> BarrierRecord:
        """The filter's record (its arrays are the filter's state: :func:`barrier_step` updates them)."""
        return self._rec

    def take_events(self) -> None:
        """Move the relax events of the record's buffer to :attr:`events` (``{t, drone, other, action:
        "relax"}``, ``other`` the neighbour whose row asked most beyond the drone's limits)."""
        rec = self._rec
        k = int(rec.ev_count[0])
        for j in range(k):
            t, drone, other = float(rec.ev_t[j]), int(rec.ev_drone[j]), int(rec.ev_other[j])
            self.events.append({"t": t, "drone": drone, "other": other, "action": "relax"})
        rec.ev_count[0] = 0

    @property
    def guarded(self) -> np.ndarray:
        """(n,) bool: the drones whose reference the filter flies."""
        return self._rec.guarded

    @property
    def active(self) -> np.ndarray:
        """(n,) bool: the drones whose command a barrier constraint changed at the last period (a
        per-period trace of where the filter acts; :attr:`active_periods` counts them)."""
        return self._rec.active

    @property
    def active_periods(self) -> int:
        """Drone-periods in which a barrier constraint changed the command."""
        return int(self._rec.counts[0])

    @property
    def relaxed_periods(self) -> int:
        """Drone-periods in which the constraints were relaxed."""
        return int(self._rec.counts[1])

    @property
    def guarded_periods(self) -> int:
        """Drone-periods flown on the filter's own reference."""
        return int(self._rec.counts[2])

    @property
    def reserve_periods(self) -> int:
        """Drone-periods in which no input within the limits met the constraints and the reserve's wider tilt
        was tried (docs/barrier.md, "the reserve"); those it did not rescue are relaxed too."""
        return int(self._rec.counts[5])

    @property
    def joint_periods(self) -> int:
        """Drone-periods whose command came from a boxed drone's cluster QP (docs/barrier.md, "the joint
        fallback"); a cluster whose QP has no solution keeps the split's commands and is not counted."""
        return int(self._rec.counts[6])

    @property
    def escapes(self) -> int:
        """Deadlock escapes started (docs/barrier.md, "deadlock escape")."""
        return int(self._rec.counts[4])

    @property
    def rate_limited_periods(self) -> int:
        """Drone-periods in which the vertical jerk limit turned a command the barrier had changed
        slower than it asked (there (B) holds for the flown reference only as far as the limit let it)."""
        return int(self._rec.counts[3])

    def __call__(
        self, sensed: Sensed, pos_d: np.ndarray, vel_d: np.ndarray, acc_d: np.ndarray, steer: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(pos_d, vel_d, acc_d) (n, 3) to fly (:class:`~.separation.SeparationFilter`; :func:`barrier_step`)."""
        c = np.ascontiguousarray
        positions = c(sensed.positions, dtype=np.float64)
        n = positions.shape[0]
        if self._rec.guarded.shape[0] != n:
            self.reset(n)
        out = barrier_step(
            self._rec, float(sensed.t), positions, c(sensed.velocities, dtype=np.float64), float(sensed.dt),
            c(pos_d, dtype=np.float64), c(vel_d, dtype=np.float64), c(acc_d, dtype=np.float64),
            c(steer, dtype=np.bool_),
        )  # fmt: skip
        self.take_events()
        return out
