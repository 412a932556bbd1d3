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

**Take-off gate.** A follower still on the ground (below ``floor_m``) stays there while its ρ to a
drone of lower index or to an airborne one is below ``gate_rho``: the barrier cannot push a drone on
the ground sideways, and lifting off inside a keep-out would start the pair with h < 0, where (B)
only brings h back exponentially.

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
is the jet-aware planner with it. **The lane rule** (:class:`BarrierRule`, ``"barrier-lanes"``, the
first version): the same filter with no planner, flying every follower from its start on a nominal
that goes round the leader on two lanes (:func:`lane_nominal_kernel`), so that followers do not meet
the leader or each other head-on.
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace
from typing import Any, NamedTuple

import numpy as np

from .._jit import jit, warm_module
from ..errors import UserError
from ..physics.params import DEFAULT_PARAMS, QuadParams
from .jet_aware import JetAwareRule
from .layered import estimate_velocities
from .rule_params import PRESETS, RuleParams, check_overrides
from .rule_params import param_field as _p
from .rules import Rule
from .separation import Sensed, seen_within
from .slots import capt_assignment

#: Ratio of the keep-out's vertical to its horizontal radius: Preiss et al. (Crazyswarm, ICRA 2017)
#: 0.3/0.12 = 2.5, the Crazyflie firmware 0.9/0.3 = 3 (docs/barrier.md, "keep-out").
DOWNWASH_MULTIPLE = 3.0


def keepout_radii(
    vehicle: QuadParams = DEFAULT_PARAMS,
    rotor_radius: float | None = None,
    downwash_multiple: float = DOWNWASH_MULTIPLE,
    margin: float = 0.0,
) -> np.ndarray:
    """Radii (a, a, c) (3,) of the pairwise keep-out of a vehicle (m): a = 2·(L + r_rotor) + 2·margin,
    the centre distance at which two level drones' rotor tips touch (plus each drone's margin);
    c = downwash_multiple·2·(L + r_rotor) + 2·margin (docs/barrier.md, "keep-out"). ``rotor_radius``:
    the vehicle's own by default."""
    span = float(vehicle.L) + float(vehicle.rotor_radius if rotor_radius is None else rotor_radius)
    a = 2.0 * span + 2.0 * margin
    c = float(downwash_multiple) * 2.0 * span + 2.0 * margin
    return np.array([a, a, c])


#: Where a scenario sets the filter's parameters (:class:`BarrierParams`): a table of its own, because
#: two of its names (``max_tilt_deg``, ``sensing_range``) are also the planner's (:class:`RuleParams`).
BARRIER_TABLE = "formation.barrier"


@dataclass(frozen=True)
class BarrierParams:
    """The filter's parameters: each field's unit, admissible range and one-line reason in its
    metadata (docs/barrier.md, "parameters", gives the long reasons and the measurements). A
    scenario sets any of them in its ``[formation.barrier]`` table (:data:`BARRIER_TABLE`), validated
    from the metadata like :class:`RuleParams` (:func:`~.rule_params.check_overrides`); a bad value
    is one :class:`UserError` naming the key."""

    downwash_multiple: float = _p(
        DOWNWASH_MULTIPLE, "–", "keep-out vertical / horizontal radius (Crazyswarm 2.5, Crazyflie 3)"
    )
    tracking_margin_m: float = _p(
        0.02, "m", "keep-out inflated by twice this for the real drone's tracking error", 0.0, open_lo=False
    )
    gain: float = _p(3.0, "1/s", "k of (B): α(s) = k·s for both orders (critically damped)")
    max_tilt_deg: float = _p(30.0, "deg", "horizontal limit (g − accel_down)·tan(this)", 0.0, 89.0)
    accel_up: float = _p(3.0, "m/s²", "vertical acceleration limit up")
    accel_down: float = _p(2.0, "m/s²", "vertical acceleration limit down (below g)", 0.0, 9.8)
    tiebreak: float = _p(0.25, "m/s²", "keep-right acceleration of the deadlock tie-break", 0.0, open_lo=False)
    relax_weight: float = _p(100.0, "", "w, the cost of the slack δ when the constraints are infeasible")
    sensing_range: float = _p(
        4.0, "m", "a drone filters against the drones within this 3D distance (default: the scenario's)"
    )
    leader_filters: bool = _p(
        True, "", "drone 0's references pass the filter (its guarded approach; its share with leader_yields)", None
    )
    nominal_kp: float = _p(4.0, "1/s²", "the nominal's PD towards the reference: position gain")
    nominal_kd: float = _p(4.0, "1/s", "the nominal's PD: velocity gain (critically damped at 2 rad/s with kp 4)")
    floor_m: float = _p(0.1, "m", "a pair of drones both below this altitude (on the ground) is not filtered", None)
    priority_share: float = _p(
        0.0, "–", "the lower index's share of a burden (b > 0); room is split in halves", 0.0, 1.0, open_lo=False
    )
    leash_m: float = _p(0.1, "m", "a guarded reference is kept within this of the drone")
    leader_guard_m: float = _p(
        0.25, "m", "with leader_filters: a leader farther than this from its trajectory's reference is guarded"
    )
    accel_filter_s: float = _p(
        0.05, "s", "time constant of the estimated accelerations (0: taken as 0)", 0.0, open_lo=False
    )
    lanes: bool = _p(True, "", "`barrier-lanes`: its nominal goes round the leader on two lanes", None)
    guard_kp: float = _p(6.25, "1/s²", "`barrier`: the guarded nominal's PD onto the planner's reference, position")
    guard_kd: float = _p(5.0, "1/s", "… velocity gain (critically damped at 2.5 rad/s with guard_kp 6.25)")
    guard_lanes: bool = _p(
        False, "", "`barrier`: a guarded drone's nominal goes round the leader on the lanes (else straight)", None
    )
    lane_speed: float = _p(2.0, "m/s", "speed along a lane")
    arrive_angle: float = _p(0.15, "rad", "within this angle of its slot's ray a drone leaves its lane", 0.0, 3.14)
    lane_turn_gain: float = _p(2.0, "1/s", "lane speed ≤ this·r·|angle left| (it stops on its slot's ray)")
    gate_rho: float = _p(1.2, "", "a grounded follower lifts off only at ρ ≥ this from the drones it yields to")
    lane_inner: float = _p(1.2, "", "counter-clockwise lane: keep-out radii beyond the slot's distance")
    lane_outer: float = _p(2.4, "", "clockwise lane: keep-out radii beyond the slot's distance (> lane_inner)")
    both_states: bool = _p(True, "", "each constraint also on the drone's sensed state, not only its reference", None)
    release_m: float = _p(
        0.02, "m", "a guarded drone is handed back within this of the planner's reference", 0.0, open_lo=False
    )
    release_mps: float = _p(0.05, "m/s", "… and within this of the planner's velocity", 0.0, open_lo=False)
    ground_band_m: float = _p(0.5, "m", "no downward acceleration to a drone below this altitude", 0.0, open_lo=False)
    ground_brake_share: float = _p(
        0.8,
        "",
        "share of accel_up a descent counts on to stop above ground_band_m (0: no envelope)",
        0.0,
        1.0,
        open_lo=False,
    )
    gate_horizon_s: float = _p(
        1.5, "s", "the take-off gate predicts the other drones over this horizon", 0.0, open_lo=False
    )
    gate_holds_start: bool = _p(
        True, "", "the take-off gate holds a follower where it stood (else where it is now)", None
    )
    gate_leader_way: bool = _p(
        False, "", "the take-off gate also holds a follower near the leader's way to its reference", None
    )
    leader_yields: bool = _p(
        False, "", "with leader_filters: the leader takes half of each pair's room (else the followers take all)", None
    )
    vertical_jerk_limit: float = _p(
        60.0,
        "m/s³",
        "`barrier`: a guarded drone's vertical acceleration reference turns ≤ this·dt a period (0: off)",
        0.0,
        open_lo=False,
    )
    descent_horizontal_cost: float = _p(
        16.0,
        "–",
        "`barrier`: a descending follower's cost of a horizontal change of its command over a vertical one",
        1.0,
        open_lo=False,
    )
    descent_vz: float = _p(0.1, "m/s", "`barrier`: a follower whose planner's reference sinks faster descends")
    assign_slots: bool = _p(
        True, "", "`barrier`'s planner gives each follower a slot so that no two straight paths cross (CAPT)", None
    )
    escape_after_s: float = _p(
        3.0, "s", "a guarded follower pressed this long without escape_progress_m escapes up (0: off)", 0.0,
        open_lo=False,
    )  # fmt: skip
    escape_progress_m: float = _p(
        0.05, "m", "… the progress towards the planner's reference (horizontal) that restarts that clock"
    )
    escape_min_m: float = _p(
        0.3, "m", "… counted only while it is farther than this from the planner's reference", 0.0, open_lo=False
    )
    escape_height: float = _p(1.05, "–", "… its nominal's altitude raised by this × the keep-out's vertical radius")
    escape_done_m: float = _p(0.1, "m", "… until it is within this of the planner's reference (horizontal)")
    transit_hold: float = _p(
        1.05, "–", "`barrier`: a formed follower holds this × the keep-out's height above a drone in transit", 0.0,
        open_lo=False,
    )  # fmt: skip

    def __post_init__(self) -> None:
        """Every field in its range (the metadata), and lane_outer > lane_inner; else one UserError."""
        check_overrides({f.name: getattr(self, f.name) for f in fields(self)}, BARRIER_TABLE, record=BarrierParams)
        if self.lane_outer <= self.lane_inner:
            raise UserError(
                f"must exceed lane_inner ({self.lane_inner!r}), got {self.lane_outer!r}",
                where=f"{BARRIER_TABLE}.lane_outer",
            )

    def radii(self, vehicle: QuadParams = DEFAULT_PARAMS) -> np.ndarray:
        """The filter's keep-out radii (3,): the vehicle's, inflated by the tracking margin."""
        return keepout_radii(vehicle, downwash_multiple=self.downwash_multiple, margin=self.tracking_margin_m)

    def horizontal_limit(self, g: float = 9.81) -> float:
        """Radius of the horizontal acceleration disc (m/s²): (g − a_down)·tan θ_max, what the tilt
        limit allows at the lowest thrust the vertical limit leaves."""
        return float((g - self.accel_down) * np.tan(np.radians(self.max_tilt_deg)))


# ------------------------------------------------------------------------------------------ kernels
_TOL = 1e-9  # feasibility tolerance of a constraint, relative to (1 + |b|)
_LAM_TOL = 1e-9  # a multiplier counts as non-negative above −this·(1 + max |λ|)


@jit
def _solve_small(G: np.ndarray, r: np.ndarray, s: int, x: np.ndarray, M: np.ndarray) -> bool:
    """Solve G[:s, :s]·x = r[:s] by Gaussian elimination with partial pivoting (M (4, 5) the
    caller's work buffer); False if singular."""
    scale = 0.0
    for i in range(s):
        for j in range(s):
            M[i, j] = G[i, j]
            scale = max(scale, abs(G[i, j]))
        M[i, s] = r[i]
    if scale == 0.0:
        return False
    for c in range(s):
        p = c
        for i in range(c + 1, s):
            if abs(M[i, c]) > abs(M[p, c]):
                p = i
        if abs(M[p, c]) <= 1e-10 * scale:
            return False
        if p != c:
            for j in range(s + 1):
                tmp = M[c, j]
                M[c, j] = M[p, j]
                M[p, j] = tmp
        for i in range(c + 1, s):
            f = M[i, c] / M[c, c]
            for j in range(c, s + 1):
                M[i, j] -= f * M[c, j]
    for i in range(s - 1, -1, -1):
        acc = M[i, s]
        for j in range(i + 1, s):
            acc -= M[i, j] * x[j]
        x[i] = acc / M[i, i]
    return True


@jit
def _kkt_point(w0, A, b, m, idx, s, w, lam, G, r, M) -> bool:
    """Whether the projection w of w0 onto {w: A[idx[k]]·w = b[idx[k]], k < s} is the optimum of
    argmin ‖w − w0‖² s.t. A[:m]·w ≥ b[:m]: w − w0 = A_Sᵀλ with every λ ≥ 0 (within _LAM_TOL) and
    every constraint satisfied (within _TOL): the KKT conditions, sufficient for this convex QP.
    G (4, 4), r (4,), M (4, 5): work buffers."""
    d = w0.shape[0]
    for k in range(s):
        rk = b[idx[k]]
        for c in range(d):
            rk -= A[idx[k], c] * w0[c]
        r[k] = rk
        for l2 in range(s):
            g = 0.0
            for c in range(d):
                g += A[idx[k], c] * A[idx[l2], c]
            G[k, l2] = g
    if s > 0 and not _solve_small(G, r, s, lam, M):
        return False
    big = 0.0
    for k in range(s):
        big = max(big, abs(lam[k]))
    for k in range(s):
        if lam[k] < -_LAM_TOL * (1.0 + big):
            return False  # a constraint pulls the wrong way: not the optimum's active set
    for c in range(d):
        v = w0[c]
        for k in range(s):
            v += A[idx[k], c] * lam[k]
        w[c] = v
    for k in range(m):
        v = 0.0
        for c in range(d):
            v += A[k, c] * w[c]
        if v < b[k] - _TOL * (1.0 + abs(b[k])):
            return False
    return True


@jit(on_demand=True, samples=lambda: [(np.zeros(3), np.array([[1.0, 0.0, 0.0]]), np.array([1.0]))])
def project_polyhedron(w0: np.ndarray, A: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, bool]:
    """argmin ‖w − w0‖² subject to A·w ≥ b (A (m, d), d ≤ 4), exactly, and whether it is feasible.

    The optimum w* satisfies w* − w0 = A_Sᵀλ, λ ≥ 0, over its active set S; by Carathéodory a
    linearly independent subset S' ⊆ S (|S'| ≤ d) with λ ≥ 0 carries the same combination, so w*
    is the projection of w0 onto the affine set A_S'·w = b_S'. Conversely, a projection onto such
    an affine set whose multipliers are all ≥ 0 and which satisfies every constraint satisfies the
    KKT conditions, sufficient for this strictly convex QP: it is w* (unique). The subsets are
    tried by size (w0 itself first, then single rows, pairs, …), and the first that passes is
    returned. Returns (w0, False) when none passes (then the set is empty)."""
    m, d = A.shape
    w0c = w0.copy()
    cand = np.empty(d)
    lam = np.empty(4)
    idx = np.empty(4, dtype=np.int64)
    G = np.empty((4, 4))
    r = np.empty(4)
    M = np.empty((4, 5))
    if _kkt_point(w0c, A, b, m, idx, 0, cand, lam, G, r, M):
        return w0c, True
    for s in range(1, min(d, m) + 1):
        for k in range(s):  # the first subset of s rows, then the next in lexicographic order
            idx[k] = k
        while True:
            if _kkt_point(w0c, A, b, m, idx, s, cand, lam, G, r, M):
                return cand.copy(), True
            k = s - 1
            while k >= 0 and idx[k] == m - s + k:
                k -= 1
            if k < 0:
                break
            idx[k] += 1
            for j in range(k + 1, s):
                idx[j] = idx[j - 1] + 1
    return w0c, False


@jit
def _pair_row(p: np.ndarray, v: np.ndarray, radii: np.ndarray, gain: float, A: np.ndarray):
    """:func:`pair_constraint` with share 1, its A written into ``A`` (3,): returns (b, h, ḣ)."""
    h = -1.0
    hd = 0.0
    qd2 = 0.0
    for c in range(3):
        q = p[c] / radii[c]
        qd = v[c] / radii[c]
        h += q * q
        hd += 2.0 * q * qd
        qd2 += qd * qd
        A[c] = 2.0 * q / radii[c]
    b = -2.0 * qd2 - 2.0 * gain * hd - gain * gain * h
    return b, h, hd


@jit(on_demand=True, samples=lambda: [(np.array([1.0, 0, 0]), np.zeros(3), np.ones(3), 3.0, 0.5)])
def pair_constraint(p: np.ndarray, v: np.ndarray, radii: np.ndarray, gain: float, share: float):
    """One drone's half-space of (B) for a pair: (A (3,), b_share, h, ḣ) with A·u_i ≥ b_share.

    p = p_i − p_j, v = v_i − v_j (3,); q = S·p, S = diag(1/radii); h = ‖q‖² − 1, ḣ = 2 qᵀq̇;
    A = 2·S·q; b = −2‖q̇‖² − 2k·ḣ − k²·h; b_share = share·b (plus nothing for the other drone:
    its share is its own constraint, or 0 taken for its acceleration when it does not filter)."""
    A = np.empty(3)
    b, h, hd = _pair_row(p, v, radii, gain, A)
    return A, share * b, h, hd


@jit
def _limit_rows(A: np.ndarray, b: np.ndarray, a_h: float, a_up: float, a_down: float) -> int:
    """Write the input limits as 10 rows of A·u ≥ b (A (m, d), columns ≥ 3 zero): an octagon inscribed
    in the disc ‖u_xy‖ ≤ a_h, and −a_down ≤ u_z ≤ a_up. Returns the number of rows (10)."""
    face = a_h * np.cos(np.pi / 8.0)
    for k in range(8):
        ang = k * np.pi / 4.0
        for c in range(A.shape[1]):
            A[k, c] = 0.0
        A[k, 0] = -np.cos(ang)
        A[k, 1] = -np.sin(ang)
        b[k] = -face
    for k in range(8, 10):
        for c in range(A.shape[1]):
            A[k, c] = 0.0
    A[8, 2] = -1.0
    b[8] = -a_up
    A[9, 2] = 1.0
    b[9] = -a_down
    return 10


#: cos, sin of the octagon's vertex angles (k + ½)·π/4 (constants of the compiled code)
_VERTEX_COS = np.cos((np.arange(8) + 0.5) * np.pi / 4.0)
_VERTEX_SIN = np.sin((np.arange(8) + 0.5) * np.pi / 4.0)


@jit
def _min_over_limits(a: np.ndarray, a_h: float, a_up: float, a_down: float) -> float:
    """min of a·u (a (3,)) over the limit polytope of :func:`_limit_rows` (its 16 vertices)."""
    best = np.inf
    for k in range(8):
        v = a_h * (a[0] * _VERTEX_COS[k] + a[1] * _VERTEX_SIN[k])
        best = min(best, v)
    return best + min(a[2] * a_up, -a[2] * a_down)


def _filter_samples():
    z = np.zeros((2, 3))
    pos = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 1.0]])
    rec = _record(BarrierParams(), DEFAULT_PARAMS, 2, True)
    lim = np.tile([3.9, 5.0, 3.0], (2, 1))
    return [(rec, pos, z, pos, z, z, z, np.ones(2, dtype=np.bool_), lim, np.ones(2))]


@jit(on_demand=True, samples=_filter_samples)
def filter_accelerations(
    rec: BarrierRecord,
    pos: np.ndarray,
    vel: np.ndarray,
    sensed_pos: np.ndarray,
    sensed_vel: np.ndarray,
    sensed_acc: np.ndarray,
    u_nom: np.ndarray,
    filters: np.ndarray,
    limits: np.ndarray,
    hcost: np.ndarray,
):
    """The decentralised barrier filter of the module docstring, for n drones at once.

    rec: the filter's record (:class:`BarrierRecord`), of which it reads the parameters only:
    ``radii`` (the filter's keep-out), ``gain`` (k), ``tiebreak``, ``relax_weight``,
    ``sensing_range``, ``floor_m``, ``priority_share``, ``both_states``.
    pos, vel (n, 3): each drone's own (reference) state; sensed_pos, sensed_vel, sensed_acc (n, 3):
    what the others sense of it (the acceleration only enters the constraint against a drone that
    does not filter, A·u_i ≥ b + A·a_j, as it does not give way); u_nom (n, 3) nominal
    accelerations; filters (n,) bool: which drones filter (a drone that does not keeps u_nom and its
    neighbours take all of each pair's constraint); limits (n, 3): each drone's input limits
    (a_h, a_up, a_down) (m/s²); hcost (n,) ≥ 1: each drone's cost of a horizontal change of its
    command relative to a vertical one, the QP's metric ‖diag(√c, √c, 1)·(u − u_nom)‖² (1: the
    plain projection; docs/barrier.md, "the descent's metric").
    ``priority_share``: the share of a burden (b > 0) the lower index of a pair of filtering drones
    takes (½: equal; room, b ≤ 0, is split in halves). A pair whose two drones are both below
    ``floor_m`` (on the ground, sensed_pos) is not filtered. ``both_states``: each neighbour's
    constraint is also imposed on the drone's sensed state (sensed_pos[i], sensed_vel[i]), so that a
    drone that lags its reference is kept out too (docs/barrier.md, "tracking").
    Returns u (n, 3), active (n,) (a barrier constraint changed the command), relaxed (n,) (the
    constraints were infeasible within the limits and relaxed), n_constraints (n,) (the neighbour
    constraints kept after the exact pruning)."""
    radii, gain, tiebreak, relax_weight = rec.radii, rec.gain, rec.tiebreak, rec.relax_weight
    floor, priority_share, both_states = rec.floor_m, rec.priority_share, rec.both_states
    n = pos.shape[0]
    u = u_nom.copy()
    active = np.zeros(n, dtype=np.bool_)
    relaxed = np.zeros(n, dtype=np.bool_)
    kept = np.zeros(n, dtype=np.int64)
    m_max = 2 * n + 10
    A = np.zeros((m_max, 3))
    b = np.zeros(m_max)
    A4 = np.zeros((m_max + 1, 4))
    b4 = np.zeros(m_max + 1)
    p = np.empty(3)
    v = np.empty(3)
    a = np.empty(3)
    un = np.empty(3)
    r2 = rec.sensing_range * rec.sensing_range
    for i in range(n):
        if not filters[i]:
            continue
        m = 0
        violated = False
        for c in range(3):
            un[c] = u_nom[i, c]
        for j in range(n):
            if j == i:
                continue
            turned = False
            for src in range(2 if both_states else 1):
                d2 = 0.0
                for c in range(3):
                    if src == 0:  # the drone's own (reference) state
                        p[c] = pos[i, c] - sensed_pos[j, c]
                        v[c] = vel[i, c] - sensed_vel[j, c]
                    else:  # its sensed (real) state
                        p[c] = sensed_pos[i, c] - sensed_pos[j, c]
                        v[c] = sensed_vel[i, c] - sensed_vel[j, c]
                    d2 += p[c] * p[c]
                if d2 > r2 or (sensed_pos[i, 2] < floor and sensed_pos[j, 2] < floor):
                    continue
                bs, h, hd = _pair_row(p, v, radii, gain, a)
                # the split (docs/barrier.md): against a drone that does not filter, all of it; a burden
                # (b > 0) by priority, the lower index taking priority_share; room (b ≤ 0) in halves
                if not filters[j]:
                    share = 1.0
                elif bs > 0.0:
                    share = priority_share if i < j else 1.0 - priority_share
                else:
                    share = 0.5
                bs *= share
                if not filters[j]:
                    bs += a[0] * sensed_acc[j, 0] + a[1] * sensed_acc[j, 1] + a[2] * sensed_acc[j, 2]
                lhs = a[0] * u_nom[i, 0] + a[1] * u_nom[i, 1] + a[2] * u_nom[i, 2]
                if lhs >= bs and _min_over_limits(a, limits[i, 0], limits[i, 1], limits[i, 2]) >= bs:
                    continue  # no input within the limits can violate it, nor does the nominal: redundant
                if lhs < bs:
                    violated = True
                    if tiebreak > 0.0 and not turned:  # keep right: ẑ × n̂, n̂ from j to i (horizontal)
                        turned = True
                        nh = np.sqrt(p[0] * p[0] + p[1] * p[1])
                        if nh > 1e-9:
                            un[0] += tiebreak * (-p[1] / nh)
                            un[1] += tiebreak * (p[0] / nh)
                for c in range(3):
                    A[m, c] = a[c]
                b[m] = bs
                m += 1
        kept[i] = m
        if not violated:
            continue  # the nominal satisfies every barrier constraint: unchanged
        active[i] = True
        ml = _limit_rows(A[m:], b[m:], limits[i, 0], limits[i, 1], limits[i, 2])
        sh = np.sqrt(hcost[i])  # the metric diag(sh, sh, 1): w = (sh·u_x, sh·u_y, u_z)
        if sh != 1.0:
            for k in range(m + ml):
                A[k, 0] /= sh
                A[k, 1] /= sh
            un[0] *= sh
            un[1] *= sh
        w, ok = project_polyhedron(un, A[: m + ml], b[: m + ml])
        if not ok:
            # relaxation: A·u + ‖A‖·δ ≥ b, δ ≥ 0, cost ‖u − un‖² + w·δ², in w = (u, √w·δ); the rows
            # are those just tried (in the drone's metric), the limits' (after row m) without δ
            sw = np.sqrt(relax_weight)
            for k in range(m + ml):
                for c in range(3):
                    A4[k, c] = A[k, c]
                A4[k, 3] = np.sqrt(A[k, 0] ** 2 + A[k, 1] ** 2 + A[k, 2] ** 2) / sw if k < m else 0.0
                b4[k] = b[k]
            A4[m + ml, :] = 0.0
            A4[m + ml, 3] = 1.0
            b4[m + ml] = 0.0
            w0 = np.zeros(4)
            for c in range(3):
                w0[c] = un[c]
            w4, ok4 = project_polyhedron(w0, A4[: m + ml + 1], b4[: m + ml + 1])
            relaxed[i] = True
            for c in range(3):
                w[c] = w4[c]
        u[i, 0] = w[0] / sh
        u[i, 1] = w[1] / sh
        u[i, 2] = w[2]
    return u, active, relaxed, kept


def apply_filter(
    bp: BarrierParams,
    pos: np.ndarray,
    vel: np.ndarray,
    u_nom: np.ndarray,
    filters: np.ndarray,
    sensed: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
    vehicle: QuadParams = DEFAULT_PARAMS,
    limits: np.ndarray | None = None,
    hcost: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`filter_accelerations` with the parameters of ``bp`` (the separation step's entry point).

    pos, vel, u_nom (n, 3); filters (n,) bool; sensed: (positions, velocities, accelerations) (n, 3)
    the others sense (default: pos, vel and zero); limits (n, 3): each drone's (a_h, a_up, a_down)
    (default: ``bp``'s for every drone); hcost (n,): each drone's cost of a horizontal change
    (default 1: the plain projection). Returns (u, active, relaxed, n_constraints)."""
    c = np.ascontiguousarray
    sp, sv, sa = (pos, vel, np.zeros_like(pos)) if sensed is None else sensed
    n = pos.shape[0]
    if limits is None:
        limits = np.tile([bp.horizontal_limit(vehicle.g), bp.accel_up, bp.accel_down], (n, 1))
    f8 = np.float64
    return filter_accelerations(
        _record(bp, vehicle, n, True),  # the filter reads its parameters only
        *(c(x, dtype=f8) for x in (pos, vel, sp, sv, sa, u_nom)),
        c(filters, dtype=np.bool_),
        c(limits, dtype=f8),
        np.ones(n) if hcost is None else c(hcost, dtype=f8),
    )


@jit
def lane_nominal_kernel(
    ref: np.ndarray,
    ref_vel: np.ndarray,
    leader: np.ndarray,
    pos_d: np.ndarray,
    vel_d: np.ndarray,
    acc_d: np.ndarray,
    radius: float,
    gains: np.ndarray,
    lanes: bool,
    rows: np.ndarray,
    u: np.ndarray,
) -> None:
    """The guarded nominal accelerations of the drones flagged ``rows`` (n,) into ``u`` (n, 3) (other
    rows untouched): the PD onto the reference, acc_d + k_p·(pos_d − r) + k_d·(vel_d − ṙ), and, with
    ``lanes``, a two-lane roundabout round the leader (docs/barrier.md, "The lane rule").

    In the leader's frame (horizontal), a follower whose reference is more than ``arrive_angle``
    round the leader from it flies round on a lane, the shorter way: counter-clockwise on the ring
    of radius D_k + ``lane_inner``·``radius`` (D_k the reference's distance from the leader),
    clockwise on D_k + ``lane_outer``·``radius`` (``radius`` the keep-out's horizontal radius: the
    formed ring and the two lanes are a keep-out apart, so traffic in opposite directions does not
    meet head-on), at ``lane_speed`` (at most ``lane_turn_gain``·r·|angle left|, so that it stops on
    its slot's ray), pulled onto its lane radially at k_p/k_d; the others fly the PD, radially in
    from the lane (the formed ring is not crossed). The vertical is the PD in both. Row 0 (the
    leader) never goes round on a lane. ``gains`` (7,): k_p, k_d, lane_speed, arrive_angle,
    lane_turn_gain, lane_inner, lane_outer (:func:`_guard_gains`)."""
    kp, kd, speed, arrive, turn, inner, outer = gains[0], gains[1], gains[2], gains[3], gains[4], gains[5], gains[6]
    for i in range(ref.shape[0]):
        if not rows[i]:
            continue
        for c in range(3):  # straight to the slot
            u[i, c] = acc_d[i, c] + kp * (pos_d[i, c] - ref[i, c]) + kd * (vel_d[i, c] - ref_vel[i, c])
        if not lanes or i == 0:
            continue
        ox, oy = ref[i, 0] - leader[0], ref[i, 1] - leader[1]  # offset from the leader
        kx, ky = pos_d[i, 0] - leader[0], pos_d[i, 1] - leader[1]  # the slot's
        gap = (np.arctan2(ky, kx) - np.arctan2(oy, ox) + np.pi) % (2.0 * np.pi) - np.pi  # the shorter way, rad
        if abs(gap) <= arrive:
            continue
        r = max(np.sqrt(ox * ox + oy * oy), 1e-9)
        rx, ry = ox / r, oy / r  # radial
        sgn = 1.0 if gap > 0.0 else -1.0
        tx, ty = -ry * sgn, rx * sgn  # the way to go
        lane = np.sqrt(kx * kx + ky * ky) + (inner if gap > 0.0 else outer) * radius
        v_t = min(speed, turn * r * abs(gap))  # slowing onto the slot's ray
        pull = (kp / kd) * (lane - r)
        u[i, 0] = acc_d[i, 0] + kd * (vel_d[i, 0] + v_t * tx + pull * rx - ref_vel[i, 0])
        u[i, 1] = acc_d[i, 1] + kd * (vel_d[i, 1] + v_t * ty + pull * ry - ref_vel[i, 1])


def _guard_gains(bp: BarrierParams) -> np.ndarray:
    """The (7,) gains of :func:`lane_nominal_kernel` for :class:`BarrierFilter`'s guarded nominal:
    its PD ``guard_kp``, ``guard_kd`` and the lanes' ``lane_speed``, ``arrive_angle``,
    ``lane_turn_gain``, ``lane_inner``, ``lane_outer``."""
    return np.array(
        [bp.guard_kp, bp.guard_kd, bp.lane_speed, bp.arrive_angle, bp.lane_turn_gain, bp.lane_inner, bp.lane_outer]
    )


@jit
def takeoff_wait_kernel(
    positions: np.ndarray,
    radii: np.ndarray,
    filters: np.ndarray,
    velocities: np.ndarray,
    accelerations: np.ndarray,
    predict: bool,
    floor: float,
    gate_rho: float,
    horizon: float,
    wait: np.ndarray,
    leader_goal: np.ndarray,
    use_goal: bool,
) -> None:
    """The take-off gate (module docstring), into ``wait`` (n,) bool: a filtering drone on the ground
    (below ``floor``) whose ρ (``radii`` (3,)) to a drone of lower index or to an airborne drone is
    below ``gate_rho`` holds where it is (and does not filter this period). With ``predict``: also
    when that airborne drone is predicted within ``gate_rho`` (at its ``velocities`` and
    ``accelerations`` (n, 3), sampled every 0.25 s over ``horizon`` s; a grounded one is taken where
    it stands). ``use_goal``: also inside the keep-out of the leader's way, the segment from drone 0
    to its reference ``leader_goal`` (3,)."""
    n = positions.shape[0]
    for i in range(n):
        wait[i] = False
        if not filters[i] or positions[i, 2] >= floor:
            continue
        for j in range(n):
            if j == i or not (j < i or positions[j, 2] >= floor):
                continue
            rho2 = 0.0
            for c in range(3):
                q = (positions[i, c] - positions[j, c]) / radii[c]
                rho2 += q * q
            k = 1
            while predict and positions[j, 2] >= floor and 0.25 * k < horizon + 1e-9:
                tau = 0.25 * k  # every 0.25 s over the horizon, the other drone straight on
                d2 = 0.0
                for c in range(3):
                    ahead = positions[j, c] + (tau * velocities[j, c] + 0.5 * tau * tau * accelerations[j, c])
                    q = (positions[i, c] - ahead) / radii[c]
                    d2 += q * q
                rho2 = min(rho2, d2)
                k += 1
            if use_goal and j == 0:  # the leader's way to its reference, sampled every tenth
                w2 = 1e9
                for k in range(1, 11):
                    d2 = 0.0
                    for c in range(3):
                        on = positions[0, c] + 0.1 * k * (leader_goal[c] - positions[0, c])
                        q = (positions[i, c] - on) / radii[c]
                        d2 += q * q
                    w2 = min(w2, d2)
                if np.sqrt(w2) < 1.0:
                    wait[i] = True
                    break
            if np.sqrt(rho2) < gate_rho:
                wait[i] = True
                break


def _own_keys(overrides: dict[str, Any]) -> dict[str, Any]:
    """The keys of ``overrides`` that only :class:`BarrierParams` has (popped); the names it shares
    with :class:`RuleParams` (``max_tilt_deg``, ``sensing_range``) stay the planner's."""
    own = set(BarrierParams.__dataclass_fields__) - set(RuleParams.__dataclass_fields__)
    return {k: overrides.pop(k) for k in list(overrides) if k in own}


def barrier_params(record: RuleParams, table: dict[str, Any]) -> BarrierParams:
    """The filter's parameters: the defaults of :class:`BarrierParams` with ``table`` (a scenario's
    ``[formation.barrier]``, validated: one :class:`UserError` naming the key), its ``sensing_range``
    the rule's (``record``, the scenario's ``sensing_range``) unless the table sets it."""
    values = check_overrides(table, BARRIER_TABLE, record=BarrierParams)
    values.setdefault("sensing_range", float(record.sensing_range))
    return BarrierParams(**values)


#: The lane rule's own defaults (docs/barrier.md, "The lane rule"): the filter as the lane rule flew it
#: before it ran on :func:`barrier_step` (a leader that yields, the gate on present positions, no
#: vertical jerk limit, no deadlock escape); a scenario's ``[formation.barrier]`` still sets them.
LANE_RULE_DEFAULTS: dict[str, Any] = {
    "leader_yields": True,
    "gate_horizon_s": 0.0,
    "gate_holds_start": False,
    "vertical_jerk_limit": 0.0,
    "escape_after_s": 0.0,
}


class BarrierRule(Rule):
    """``anti_collision = "barrier-lanes"`` (docs/barrier.md, "The lane rule"): no planner; the
    formation's slots are the references, and :class:`BarrierFilter` flies every follower from its
    start on its own reference with the lane nominal.

    The same filter as ``barrier``'s (:func:`barrier_step`, one compiled period), configured from
    :class:`BarrierParams` as the lane rule: its nominal goes round the leader on the lanes
    (``lanes``; :func:`lane_nominal_kernel`) with the PD ``nominal_kp``, ``nominal_kd``, and every
    follower starts *guarded* (its reference (r, ṙ) where it stands), so that it goes to its slot
    on that nominal, not on a step of the reference; its defaults differ from ``barrier``'s where
    :data:`LANE_RULE_DEFAULTS` says. A follower whose reference reaches its slot
    (within ``release_m``, ``release_mps``) flies the slot, and is guarded again when it would
    violate a constraint, as under ``barrier``. The filter's relax events are this rule's events
    (``{t, drone, other: -1, action: "relax"}``)."""

    name = "barrier-lanes"
    #: a scenario's ``[formation.barrier]`` table sets its filter (:func:`~.anticollision.make_rule`)
    takes_barrier_params = True

    def __init__(
        self, n: int, params: RuleParams | None = None, *, barrier: dict[str, Any] | None = None, **overrides: Any
    ) -> None:
        """``params``/``overrides``: the anti-collision record's fields (its ``downwash_feedforward``,
        ``sensing_range``); ``barrier`` and the keys only :class:`BarrierParams` has among
        ``overrides`` set the filter (:func:`barrier_params`)."""
        own = _own_keys(overrides)
        super().__init__(n, params, **overrides)
        self.barrier = barrier_params(self.params, {**LANE_RULE_DEFAULTS, **own, **(barrier or {})})
        bp = self.barrier
        lanes = replace(bp, guard_lanes=bp.lanes, guard_kp=bp.nominal_kp, guard_kd=bp.nominal_kd)
        self.barrier_filter = BarrierFilter(lanes, self.vehicle)
        self.separation_filter = self.barrier_filter
        self.events: list[dict] = []
        self.vel_d = np.zeros((n, 3))
        self.acc_d = np.zeros((n, 3))
        self._followers = np.arange(n) > 0  # (n,) the drones the filter steers (read-only)
        self.footprint = float(self.params.keep_out(self.vehicle))  # (m) Sensed.keep_out, as the planner's

    def reset(self, positions: np.ndarray) -> None:
        positions = np.asarray(positions, dtype=float)
        self.events = []
        self.barrier_filter.reset(self.n)
        rec = self.barrier_filter.record()
        rec.guarded[1:] = True  # every follower on the filter's reference from where it stands
        rec.ref[:] = positions
        self.vel = np.zeros((self.n, 3))  # (n, 3) velocities estimated from successive positions
        self._prev_pos = positions.copy()  # (n, 3)
        self._prev_t = np.full(1, np.nan)  # (1,) s (NaN: no update yet)
        self._dt = np.zeros(1)  # (1,) s

    def update(
        self, t: float, positions: np.ndarray, pos_d: np.ndarray, formation_alt: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """With zero formation velocity and acceleration references (see :meth:`references`)."""
        z = np.zeros((self.n, 3))
        pos_out, _, _ = self.references(t, positions, pos_d, z, z, formation_alt)
        return pos_out, self._followers.copy()

    def references(
        self,
        t: float,
        positions: np.ndarray,
        pos_d: np.ndarray,
        vel_d: np.ndarray,
        acc_d: np.ndarray,
        formation_alt: float,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(pos_d, vel_d, acc_d) (n, 3): the filter's references (:meth:`BarrierFilter.__call__`) from
        the formation's, the velocities estimated from successive positions
        (:func:`~.layered.estimate_velocities`, as the planner's)."""
        pos = np.ascontiguousarray(positions, dtype=np.float64)
        dt = float(estimate_velocities(float(t), pos, self._prev_pos, self.vel, self._prev_t, self._dt))
        f = self.barrier_filter
        seen = seen_within(pos, self.params.sensing_range)
        sensed = Sensed(float(t), pos, self.vel, seen, self.footprint, dt)
        out = f(sensed, pos_d, vel_d, acc_d, self._followers)
        self.take_separation_events()
        self.vel_d, self.acc_d = out[1], out[2]
        return out


class BarrierRecord(NamedTuple):
    """:class:`BarrierFilter` as a record (its parameters and its state) for :func:`barrier_step`, the
    one compiled step both drivers call (docs/design.md, "The control period, written once");
    ``on`` False: no filter (a stand-in of the same types, :func:`barrier_off`)."""

    on: bool
    radii: np.ndarray  # (3,) the filter's keep-out radii (m)
    lane_gains: np.ndarray  # (7,) lane_nominal_kernel's gains (_guard_gains: the guarded nominal's PD)
    a_h: float  # horizontal acceleration limit (m/s²)
    accel_up: float  # vertical limits (m/s²)
    accel_down: float
    gain: float  # k of (B) (1/s)
    tiebreak: float  # m/s²
    relax_weight: float
    sensing_range: float  # m
    floor_m: float  # m
    priority_share: float
    both_states: bool
    lanes: bool  # the params' guard_lanes: a guarded drone's nominal on the lanes
    accel_filter_s: float  # s
    gate_rho: float
    gate_horizon_s: float  # s
    leash_m: float  # m
    leader_guard_m: float  # m
    release_m: float  # m
    release_mps: float  # m/s
    ground_band_m: float  # m
    ground_brake_share: float  # share of accel_up the ground envelope counts on
    gate_holds_start: bool
    leader_filters: bool  # drone 0 filters too (its trajectory's references are its nominal)
    gate_leader_way: bool  # the take-off gate also keeps off the leader's way to its reference
    leader_yields: bool  # with leader_filters: the leader takes its share of each pair's constraint
    vertical_jerk_limit: float  # m/s³ (0: off)
    descent_horizontal_cost: float  # a descending follower's QP metric, horizontal / vertical
    descent_vz: float  # m/s: the planner's sink rate above which a follower descends
    escape_after_s: float  # s (0: no escape)
    escape_progress_m: float  # m
    escape_min_m: float  # m
    escape_height: float  # × the keep-out's vertical radius
    escape_done_m: float  # m
    guarded: np.ndarray  # (n,) bool: the filter flies this drone's reference
    ref: np.ndarray  # (n, 3) r of a guarded drone
    ref_vel: np.ndarray  # (n, 3) ṙ
    sensed_acc: np.ndarray  # (n, 3) low-passed accelerations from the sensed velocities
    prev_acc: np.ndarray  # (n, 3) the acceleration references returned by the last call
    prev_vel: np.ndarray  # (n, 3) the sensed velocities of the last call
    start: np.ndarray  # (n, 3) where each drone stood on the ground (the first call's positions)
    was_relaxed: np.ndarray  # (n,) bool: relaxed at the last call
    active: np.ndarray  # (n,) bool: a barrier constraint changed the drone's command at the last call
    flags: np.ndarray  # (2,) bool: start taken, prev_vel taken
    escaping: np.ndarray  # (n,) bool: the drone escapes up (its nominal's altitude raised)
    pressed_s: np.ndarray  # (n,) s the drone has been pressed without progress (0: not counting)
    best_m: np.ndarray  # (n,) m its least horizontal distance to the planner's reference since then
    counts: np.ndarray  # (5,) int64: active, relaxed, guarded, rate-limited drone-periods; escapes
    ev_t: np.ndarray  # (cap,) time of each relax event not yet handed to Python
    ev_drone: np.ndarray  # (cap,) int64 its drone
    ev_count: np.ndarray  # (1,) int64 events held


#: Relax events a record holds per drone before Python takes them (the chunk driver hands back
#: before a period that could overflow it).
EVENTS_PER_DRONE = 8


def _record(bp: BarrierParams, vehicle: QuadParams, n: int, on: bool) -> BarrierRecord:
    """A fresh record of n drones (every drone free, no state taken yet). Its scalar parameters are
    the fields of ``bp`` of the same name (as float or bool, their declared types), but ``lanes``:
    the record's is ``bp.guard_lanes`` (``bp.lanes`` is the lane rule's own)."""
    cast = {"float": float, "bool": bool}
    kw: dict[str, Any] = {
        f.name: cast[str(f.type)](getattr(bp, f.name))
        for f in fields(bp)
        if f.name in BarrierRecord._fields and f.name != "lanes"
    }
    cap = EVENTS_PER_DRONE * max(n, 1)
    return BarrierRecord(
        on=on,
        radii=bp.radii(vehicle),
        lane_gains=_guard_gains(bp),
        a_h=bp.horizontal_limit(vehicle.g),
        lanes=bool(bp.guard_lanes),
        guarded=np.zeros(n, dtype=np.bool_),
        ref=np.zeros((n, 3)),
        ref_vel=np.zeros((n, 3)),
        sensed_acc=np.zeros((n, 3)),
        prev_acc=np.zeros((n, 3)),
        prev_vel=np.zeros((n, 3)),
        start=np.zeros((n, 3)),
        was_relaxed=np.zeros(n, dtype=np.bool_),
        active=np.zeros(n, dtype=np.bool_),
        flags=np.zeros(2, dtype=np.bool_),
        escaping=np.zeros(n, dtype=np.bool_),
        pressed_s=np.zeros(n),
        best_m=np.zeros(n),
        counts=np.zeros(5, dtype=np.int64),
        ev_t=np.zeros(cap),
        ev_drone=np.zeros(cap, dtype=np.int64),
        ev_count=np.zeros(1, dtype=np.int64),
        **kw,
    )


def barrier_off(n: int) -> BarrierRecord:
    """The stand-in record of a run without a barrier filter (``on`` False; the same types, so the
    chunk driver has one signature with or without the filter)."""
    return _record(BarrierParams(), DEFAULT_PARAMS, n, False)


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


def _step_samples():
    n = 3
    rec = _record(BarrierParams(), DEFAULT_PARAMS, n, True)
    pos = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.0, 1.0, 1.0]])
    z = np.zeros((n, 3))
    return [(rec, 0.0, pos, z, 0.0, pos, z, z, np.array([False, True, True]))]


@jit(on_demand=True, samples=_step_samples)
def barrier_step(rec, t, positions, vel, dt, pos_d, vel_d, acc_d, steer):
    """One period of :class:`BarrierFilter` (its docstring states it) on the record ``rec``: the
    references (pos_d, vel_d, acc_d) (n, 3) to fly, from the planner's (pos_d, vel_d, acc_d) (n, 3),
    the sensed ``positions`` and ``vel`` (n, 3) of time ``t``, ``dt`` s after the last call, for the
    drones flagged ``steer`` (n,). Updates the record's state; appends the relax events to its
    buffer (the caller drains it)."""
    n = positions.shape[0]
    own = steer.copy()  # the drones this filter flies: the steered ones, and the leader with leader_filters
    if rec.leader_filters and n > 0:
        own[0] = True
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
    wait = np.zeros(n, dtype=np.bool_)
    takeoff_wait_kernel(positions, rec.radii, steer, vel, rec.sensed_acc, True, rec.floor_m, rec.gate_rho,
                        rec.gate_horizon_s, wait, pos_d[0], rec.gate_leader_way)  # fmt: skip
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
    u, active, relaxed, _ = filter_accelerations(
        rec, ref, ref_vel, positions, vel, rec.sensed_acc, u_nom, pair_filters, limits, hcost
    )
    out_p, out_v, out_a = pos_d.copy(), vel_d.copy(), acc_d.copy()
    for i in range(n):
        if active[i]:
            rec.counts[0] += 1
        if relaxed[i]:
            rec.counts[1] += 1
            if not rec.was_relaxed[i]:  # the first period of a relaxed stretch: an event
                k = rec.ev_count[0]
                if k < rec.ev_t.shape[0]:
                    rec.ev_t[k] = t
                    rec.ev_drone[k] = i
                    rec.ev_count[0] = k + 1
        rec.was_relaxed[i] = relaxed[i]
        rec.active[i] = active[i]
        g[i] = (g[i] or active[i]) and filters[i]
        if wait[i]:  # the take-off gate: held where it stands, at most its start altitude
            rec.ref[i] = positions[i]
            if rec.gate_holds_start:
                rec.ref[i, 0] = rec.start[i, 0]
                rec.ref[i, 1] = rec.start[i, 1]
            rec.ref[i, 2] = min(positions[i, 2], rec.start[i, 2])
            rec.ref_vel[i] = 0.0
        if g[i]:  # (r, ṙ) advance with the filtered command, never below the ground, on the leash
            rec.counts[2] += 1
            if rec.vertical_jerk_limit > 0.0 and dt > 0.0:  # a vertical command the drone can follow
                step = rec.vertical_jerk_limit * dt
                lim = min(max(u[i, 2], rec.prev_acc[i, 2] - step), rec.prev_acc[i, 2] + step)
                cut = lim != u[i, 2]
                u[i, 2] = lim
                if cut and active[i]:  # a command the barrier changed, turned slower than it asked
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
        if wait[i]:
            for c in range(3):
                out_p[i, c] = rec.ref[i, c]
                out_v[i, c] = 0.0
                out_a[i, c] = 0.0
        back = g[i] and not active[i]  # handed back to the planner: unchanged and back on its path
        if back:
            dp = 0.0
            dv = 0.0
            for c in range(3):
                dp += (rec.ref[i, c] - pos_d[i, c]) ** 2
                dv += (rec.ref_vel[i, c] - vel_d[i, c]) ** 2
            back = np.sqrt(dp) <= rec.release_m and np.sqrt(dv) <= rec.release_mps
        rec.guarded[i] = (g[i] and not back) or wait[i]
        _escape_update(rec, i, rec.guarded[i] and steer[i] and not wait[i], active[i], pos_d, dt)  # followers
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
        warm_module(__name__)  # the filter's kernels, before a run's clock starts (_jit.jit's on_demand)
        self.barrier = BarrierParams() if params is None else params
        self.vehicle = vehicle
        self.radii = self.barrier.radii(vehicle)
        self.a_h = self.barrier.horizontal_limit(vehicle.g)
        self.reset(0)

    def reset(self, n: int) -> None:
        """Start of a run of n drones: every drone free."""
        self._rec = _record(self.barrier, self.vehicle, n, True)
        self.events: list[dict] = []

    def record(self) -> BarrierRecord:
        """The filter's record (its arrays are the filter's state: :func:`barrier_step` updates them)."""
        return self._rec

    def take_events(self) -> None:
        """Move the relax events of the record's buffer to :attr:`events` (``{t, drone, other: -1,
        action: "relax"}``)."""
        rec = self._rec
        k = int(rec.ev_count[0])
        for j in range(k):
            self.events.append({"t": float(rec.ev_t[j]), "drone": int(rec.ev_drone[j]), "other": -1, "action": "relax"})
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


class BarrierPlannerRule(JetAwareRule):
    """``anti_collision = "barrier"`` (docs/barrier.md): the jet-aware planner (its preset with the
    descents at half the speed and no crossing brake, ``PRESETS["barrier"]``; its altitude
    separation, a formed follower held ``transit_hold`` × the keep-out's height above a drone in
    transit under it) with :class:`BarrierFilter` as its separation step, its followers flying to
    slots assigned at the first update (``assign_slots``: :func:`~.slots.capt_assignment`, so that
    no two straight paths cross). The filter's own parameters are :class:`BarrierParams` (keys of it
    among ``overrides`` set them)."""

    name = "barrier"
    #: a scenario's ``[formation.barrier]`` table sets its filter (:func:`~.anticollision.make_rule`)
    takes_barrier_params = True

    def __init__(
        self, n: int, params: RuleParams | None = None, *, barrier: dict[str, Any] | None = None, **overrides: Any
    ) -> None:
        """As :class:`~.jet_aware.JetAwareRule`; ``barrier`` and the keys only :class:`BarrierParams`
        has among ``overrides`` set the filter (:func:`barrier_params`)."""
        own = _own_keys(overrides)
        vehicle = overrides.get("vehicle", DEFAULT_PARAMS)  # the run's vehicle: its keep-out (Rule keeps it too)
        record = PRESETS[self.name].for_vehicle(vehicle) if params is None else params
        record = record.with_overrides({k: v for k, v in overrides.items() if k != "vehicle"}, where="")
        self.barrier_filter = BarrierFilter(barrier_params(record, {**own, **(barrier or {})}), vehicle)
        super().__init__(n, record, vehicle=vehicle)
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
    "DOWNWASH_MULTIPLE",
    "BARRIER_TABLE",
    "BarrierFilter",
    "BarrierParams",
    "BarrierPlannerRule",
    "BarrierRecord",
    "BarrierRule",
    "LANE_RULE_DEFAULTS",
    "barrier_off",
    "barrier_params",
    "barrier_step",
    "apply_filter",
    "filter_accelerations",
    "keepout_radii",
    "pair_constraint",
    "project_polyhedron",
]
