"""Safety barrier certificates for the swarm (docs/barrier.md): a downwash-aware ellipsoidal keep-out,
its control-barrier constraint per pair of drones, and the per-drone filter that changes a nominal
acceleration command as little as possible so that every constraint holds.

The functional core is independent of the rule classes: :func:`keepout_radii` (the keep-out of a
vehicle), :func:`pair_constraint` (one barrier constraint) and :func:`filter_accelerations` (the
decentralised filter, compiled), configured by one frozen record, :class:`BarrierParams`.

**Keep-out.** Drones i and j are apart when the centre offset p = p_i − p_j lies outside the
ellipsoid of radii (a, a, c): with q = S·p, S = diag(1/a, 1/a, 1/c), the *normalised ellipsoidal
distance* is ρ = ‖q‖ (ρ = 1 on the ellipsoid). a = 2·(L + r_rotor) is the centre distance at which
two level drones' rotor tips touch; c = ``downwash_multiple``·a, taller than wide, because a drone
below another sits in its downwash (Preiss et al., Crazyswarm, ICRA 2017: radii 0.12, 0.12, 0.3 m;
the Crazyflie firmware: 0.3, 0.3, 0.9 m — a ratio of 2.5 to 3).

**Barrier.** h = ρ² − 1 = pᵀ S² p − 1 ≥ 0 outside the keep-out. Under double-integrator dynamics
(p̈_i = u_i) it has relative degree two: ḣ = 2 qᵀq̇, ḧ = 2 q̇ᵀq̇ + 2 (S q)ᵀ (u_i − u_j). The
exponential (second-order) control-barrier condition with the class-K functions α(s) = k·s,

    ḧ + 2k·ḣ + k²·h ≥ 0,                                                        (B)

keeps ψ1 = ḣ + k·h and h non-negative for all time if both are at the start (Nguyen & Sreenath,
ACC 2016; Wang, Ames & Egerstedt, IEEE T-RO 2017, whose decentralised split is used): (B) is linear
in the relative acceleration, A·(u_i − u_j) ≥ b with A = 2 S q and b = −2‖q̇‖² − 2k·ḣ − k²·h; drone i
enforces A·u_i ≥ s_ij·b and drone j enforces −A·u_j ≥ (1 − s_ij)·b, so that their sum is (B). Room
(b ≤ 0) is split in halves (Wang et al.'s equal split); a burden (b > 0) by priority, the lower
index taking ``priority_share`` (b is symmetric in i, j, so both drones split the same way). The
leader filters too (``leader_filters``); against a drone that does not filter (the leader with it
off, which flies its trajectory) a follower takes all of it, A·u_i ≥ b + A·â_j, â_j the leader's
acceleration estimated from its positions (low-passed).

**Filter (per drone, each period).** u_i = argmin ‖W_i·(u − u_nom,i)‖² subject to every neighbour's
constraint and the vehicle's limits (the horizontal acceleration within an octagon inscribed in the
tilt-limit disc of radius (g − a_down)·tan θ_max, the vertical one within [−a_down, a_up]); W_i = I,
or diag(√c, √c, 1) for a follower its planner descends (c = ``descent_horizontal_cost``). It
acts only when the nominal command violates a barrier constraint (otherwise u_i = u_nom,i exactly,
the controller saturating as before). The QP is solved exactly: its solution is the projection of
u_nom onto the affine hull of a linearly independent subset (at most 3) of its active constraints
(KKT with Carathéodory), so the feasible candidate of least cost over all such subsets is the
optimum (:func:`project_polyhedron`). A neighbour's constraint that no input within the limits can
violate is dropped first (exactly: its minimum over the limits' vertices).

**Infeasible.** When no input within the limits satisfies every constraint, the barrier constraints
are relaxed by a common slack δ ≥ 0 in metres per second squared along each constraint's normal,
A·u ≥ b − δ·‖A‖, with cost ‖u − u_nom‖² + w·δ² (the limits stay hard: they are physics); the
drone's ``relaxed`` flag is set and counted.

**Deadlock tie-break.** Two drones flying head-on at each other are stopped by (B) face to face
(the nominal and the constraint's normal are collinear). When a drone's nominal violates the
constraint of a neighbour (pushes into it), a *keep-right* acceleration of ``tiebreak``
m/s², horizontal and perpendicular to the line joining them (ẑ × n̂, n̂ from j to i), is added to
its nominal before filtering: each of the two sees the other on its own left, so they pass
each other (the roundabout rule); a follower pressed against the keep-out of a drone that does
not give way (the leader) slides round it the same way.

**Deadlock escape.** Pressed into the corner of two keep-outs, a drone is left only the line where
the two constraints' planes meet (vertical beside two tall keep-outs at its altitude), along which
neither its nominal nor the horizontal tie-break moves it. A guarded follower that the filter keeps
changing and whose reference has not come ``escape_progress_m`` nearer the planner's (horizontally)
for ``escape_after_s`` escapes: its nominal's altitude is raised by ``escape_height`` × the
keep-out's vertical radius until it is within ``escape_done_m`` of the planner's reference. Only
the nominal changes; the constraints and the limits filter it as any command.

**Take-off gate.** A follower still on the ground (below ``floor_m``) stays there while its ρ to an
airborne drone is below ``gate_rho`` (now or predicted), or to a grounded drone of lower index below
``gate_rho_ground``: the barrier cannot push a drone on the ground sideways, and lifting off inside a
keep-out would start the pair with h < 0, where (B) only brings h back exponentially. Two grounded
drones at ρ ≥ ``gate_rho_ground`` ≥ 1 lift off together: at rest, outside each other's keep-out
(h ≥ 0, ḣ = 0, so ψ₁ ≥ 0: assumption (5) holds), and the barrier keeps them apart from there.

**Tracking.** The filter works on the reference each drone's controller tracks (kept within
``leash_m`` of the drone); the real, lagged drone is off it by its tracking error, for which the
filter's keep-out is the vehicle's inflated by twice ``tracking_margin_m`` (docs/barrier.md gives
the measured error and why the margin is smaller).

**Vertical jerk limit.** The reference of a guarded drone advances with the filtered command whose
vertical component turns by at most ``vertical_jerk_limit``·dt from the last period's: the
backstepping controller turns a vertical command that chatters into thrust and tilt swings it
cannot follow (its attitude saturates and the drone runs off its reference, docs/barrier.md,
"jerk limit"). Where the limit cuts a command the barrier changed, (B) holds for the flown
reference only as far as the limit allowed; those drone-periods are counted
(:attr:`BarrierFilter.rate_limited_periods`), and the measured keep-out time is what tells.

**The separation filter** (:class:`BarrierFilter`, a :class:`~.separation.SeparationFilter`): the
filter guarding any planner's references; ``anti_collision = "barrier"`` (:class:`BarrierPlannerRule`)
is the jet-aware planner with it.

**The modules.** The keep-out and the pair's constraint: :mod:`.keepout`; the QP and the input limits:
:mod:`.barrier_qp`; the parameters and the filter's record: :mod:`.barrier_params`; the filter's
kernels: :mod:`.barrier_kernels`; one period of the filter and :class:`BarrierFilter`:
:mod:`.barrier_filter`; the rule: this module, which re-exports the public names of the others.
"""

from __future__ import annotations

from typing import Any, cast

import numpy as np

from ..physics.params import DEFAULT_PARAMS
from .barrier_filter import BarrierFilter, barrier_step
from .barrier_kernels import apply_filter, filter_accelerations, lane_nominal_kernel, takeoff_wait_kernel
from .barrier_params import (
    BARRIER_TABLE,
    EVENTS_PER_DRONE,
    BarrierParams,
    BarrierRecord,
    barrier_off,
    barrier_params,
    own_keys,
)
from .barrier_qp import project_polyhedron
from .jet_aware import JetAwareRule
from .keepout import DOWNWASH_MULTIPLE, keepout_radii, pair_constraint
from .rule_params import CONTROLLER_KEYS, PRESETS, JetAwareParams
from .slots import capt_assignment


class BarrierPlannerRule(JetAwareRule):
    """``anti_collision = "barrier"`` (docs/barrier.md): the jet-aware planner (its preset with the
    descents at half the speed and no crossing brake, ``PRESETS["barrier"]``; its altitude
    separation, a formed follower held ``transit_hold`` × the keep-out's height above a drone in
    transit under it) with :class:`BarrierFilter` as its separation step, its followers flying to
    slots assigned at the first update (``assign_slots``: :func:`~.slots.capt_assignment`, so that
    no two straight paths cross). Its record is its planner's, :class:`~.rule_params.JetAwareParams`;
    the filter's own parameters are :class:`BarrierParams` (keys of it among ``overrides`` set them)."""

    name = "barrier"
    #: a scenario's ``[formation.barrier]`` table sets its filter (:func:`~.anticollision.make_rule`)
    takes_barrier_params = True

    def __init__(
        self, n: int, params: JetAwareParams | None = None, *, barrier: dict[str, Any] | None = None, **overrides: Any
    ) -> None:
        """As :class:`~.jet_aware.JetAwareRule`; ``barrier`` and the keys only :class:`BarrierParams`
        has among ``overrides`` set the filter (:func:`barrier_params`)."""
        own = own_keys(overrides)
        vehicle = overrides.pop("vehicle", DEFAULT_PARAMS)  # the run's vehicle: its keep-out (Rule keeps it too)
        asked = {k: overrides.pop(k) for k in CONTROLLER_KEYS if k in overrides}  # the controller's (Rule's)
        record = cast(JetAwareParams, PRESETS[self.name]).for_vehicle(vehicle) if params is None else params
        record = record.with_overrides(overrides, where="")
        self.barrier_filter = BarrierFilter(barrier_params(record, {**own, **(barrier or {})}), vehicle)
        super().__init__(n, record, vehicle=vehicle, **asked)
        self.separation_filter = self.barrier_filter
        bp = self.barrier_filter.barrier
        # the hold over a drone in transit, out of the filter's keep-out (docs/barrier.md, "the planner's hold")
        self.transit_hold_m = bp.transit_hold * float(bp.radii(vehicle)[2])

    def reset(self, positions: np.ndarray) -> None:
        super().reset(positions)
        self.barrier_filter.reset(self.n)
        self._assign = self.barrier_filter.barrier.assign_slots and self.n > 2

    def update(
        self, t: float, positions: np.ndarray, pos_d: np.ndarray, formation_alt: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """The jet-aware planner's update; at the first, with ``assign_slots``, each follower's slot
        (``slot_of``) from :func:`~.slots.capt_assignment` of the followers' positions and the slots
        (docs/barrier.md, "slot assignment")."""
        if self._assign:
            self._assign = False
            sigma = capt_assignment(np.asarray(positions)[1:, :2], np.asarray(pos_d)[1:, :2])
            self.slot_of[1:] = 1 + sigma
        return super().update(t, positions, pos_d, formation_alt)


__all__ = [
    "BARRIER_TABLE",
    "DOWNWASH_MULTIPLE",
    "EVENTS_PER_DRONE",
    "BarrierFilter",
    "BarrierParams",
    "BarrierPlannerRule",
    "BarrierRecord",
    "apply_filter",
    "barrier_off",
    "barrier_params",
    "barrier_step",
    "filter_accelerations",
    "keepout_radii",
    "lane_nominal_kernel",
    "pair_constraint",
    "project_polyhedron",
    "takeoff_wait_kernel",
]
