"""The barrier filter's parameters (:class:`BarrierParams`, a scenario's ``[formation.barrier]`` table;
docs/barrier.md, "parameters") and its record (:class:`BarrierRecord`: those parameters and the filter's
state, what :func:`~.barrier_filter.barrier_step` reads and updates on either driver of the control period)."""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any, ClassVar, NamedTuple

import numpy as np

from ..errors import UserError
from ..physics.params import DEFAULT_PARAMS, QuadParams
from .keepout import DOWNWASH_MULTIPLE, keepout_radii
from .rule_params import PARAM_KEYS, LayersParams, check_overrides
from .rule_params import param_field as _p

#: Where a scenario sets the filter's parameters (:class:`BarrierParams`): a table of its own, because
#: two of its names (``max_tilt_deg``, ``sensing_range``) are also the planner's (:class:`~.rule_params.LayersParams`).
BARRIER_TABLE = "formation.barrier"


@dataclass(frozen=True)
class BarrierParams:
    """The filter's parameters: each field's unit, admissible range and one-line reason in its
    metadata (docs/barrier.md, "parameters", gives the long reasons and the measurements). A
    scenario sets any of them in its ``[formation.barrier]`` table (:data:`BARRIER_TABLE`), validated
    from the metadata like the rules' records (:func:`~.rule_params.check_overrides`); a bad value
    is one :class:`UserError` naming the key."""

    #: where an unknown key's message points (:func:`~.rule_params.check_overrides`)
    DOCS: ClassVar[str] = "docs/barrier.md"

    downwash_multiple: float = _p(
        DOWNWASH_MULTIPLE, "–", "keep-out vertical / horizontal radius (Crazyswarm 2.5, Crazyflie 3)"
    )
    tracking_margin_m: float = _p(
        0.02, "m", "keep-out inflated by twice this for the real drone's tracking error", 0.0, open_lo=False
    )
    robust_confidence: float = _p(
        0.999,
        "",
        "under a sensing model, the confidence of the measurement-robust margin (docs/sensing.md)",
        0.5,
        0.999999,
    )
    gain: float = _p(3.0, "1/s", "k of (B): α(s) = k·s for both orders (critically damped)")
    max_tilt_deg: float = _p(30.0, "deg", "horizontal limit (g − accel_down)·tan(this)", 0.0, 89.0)
    reserve_tilt_deg: float = _p(
        0.0,
        "deg",
        "where nothing within max_tilt_deg meets the constraints, this tilt is tried before relaxing (0: off)",
        0.0,
        89.0,
        open_lo=False,
    )
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
    guard_kp: float = _p(6.25, "1/s²", "`barrier`: the guarded nominal's PD onto the planner's reference, position")
    guard_kd: float = _p(5.0, "1/s", "… velocity gain (critically damped at 2.5 rad/s with guard_kp 6.25)")
    guard_lanes: bool = _p(
        False, "", "`barrier`: a guarded drone's nominal goes round the leader on the lanes (else straight)", None
    )
    lane_speed: float = _p(2.0, "m/s", "speed along a lane")
    arrive_angle: float = _p(0.15, "rad", "within this angle of its slot's ray a drone leaves its lane", 0.0, 3.14)
    lane_turn_gain: float = _p(2.0, "1/s", "lane speed ≤ this·r·|angle left| (it stops on its slot's ray)")
    gate_rho: float = _p(1.2, "", "a grounded follower lifts off only at ρ ≥ this from the drones it yields to")
    gate_rho_ground: float = _p(
        1.0,
        "",
        "a grounded follower lifts off only at ρ ≥ this from a grounded drone of lower index",
        1.0,
        open_lo=False,
    )
    lane_inner: float = _p(1.2, "", "counter-clockwise lane: keep-out radii beyond the slot's distance")
    lane_outer: float = _p(2.4, "", "clockwise lane: keep-out radii beyond the slot's distance (> lane_inner)")
    both_states: bool = _p(True, "", "each constraint also on the drone's sensed state, not only its reference", None)
    joint_fallback: bool = _p(
        True, "", "where a drone's split has no input within its limits, its cluster's joint QP (else relaxed)", None
    )
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

    def horizontal_limit(self, g: float = 9.81, tilt_deg: float | None = None) -> float:
        """Radius of the horizontal acceleration disc (m/s²): (g − a_down)·tan θ, what the tilt limit θ
        (``max_tilt_deg`` unless given) allows at the lowest thrust the vertical limit leaves."""
        tilt = self.max_tilt_deg if tilt_deg is None else tilt_deg
        return float((g - self.accel_down) * np.tan(np.radians(tilt)))

    def reserve_horizontal_limit(self, g: float = 9.81) -> float:
        """The reserve's horizontal limit (m/s²): (g − accel_down)·tan(reserve_tilt_deg), at least the
        nominal one; 0 without a reserve (``reserve_tilt_deg`` 0)."""
        if self.reserve_tilt_deg <= 0.0:
            return 0.0
        return max(self.horizontal_limit(g, self.reserve_tilt_deg), self.horizontal_limit(g))


def guard_gains(bp: BarrierParams) -> np.ndarray:
    """The (7,) gains of :func:`lane_nominal_kernel` for :class:`BarrierFilter`'s guarded nominal:
    its PD ``guard_kp``, ``guard_kd`` and the lanes' ``lane_speed``, ``arrive_angle``,
    ``lane_turn_gain``, ``lane_inner``, ``lane_outer``."""
    return np.array(
        [bp.guard_kp, bp.guard_kd, bp.lane_speed, bp.arrive_angle, bp.lane_turn_gain, bp.lane_inner, bp.lane_outer]
    )


def own_keys(overrides: dict[str, Any]) -> dict[str, Any]:
    """The keys of ``overrides`` that only :class:`BarrierParams` has (popped); the names it shares
    with the rules' records (:data:`~.rule_params.PARAM_KEYS`: ``max_tilt_deg``, ``sensing_range``)
    stay the planner's."""
    own = set(BarrierParams.__dataclass_fields__) - set(PARAM_KEYS)
    return {k: overrides.pop(k) for k in list(overrides) if k in own}


def barrier_params(record: LayersParams, table: dict[str, Any]) -> BarrierParams:
    """The filter's parameters: the defaults of :class:`BarrierParams` with ``table`` (a scenario's
    ``[formation.barrier]``, validated: one :class:`UserError` naming the key), its ``sensing_range``
    the rule's (``record``, the scenario's ``sensing_range``) unless the table sets it."""
    values = check_overrides(table, BARRIER_TABLE, record=BarrierParams)
    values.setdefault("sensing_range", float(record.sensing_range))
    return BarrierParams(**values)


class BarrierRecord(NamedTuple):
    """:class:`BarrierFilter` as a record (its parameters and its state) for :func:`barrier_step`, the
    one compiled step both drivers call (docs/design.md, "The control period, written once");
    ``on`` False: no filter (a stand-in of the same types, :func:`barrier_off`)."""

    on: bool
    radii: np.ndarray  # (3,) the filter's keep-out radii (m)
    lane_gains: np.ndarray  # (7,) lane_nominal_kernel's gains (guard_gains: the guarded nominal's PD)
    a_h: float  # horizontal acceleration limit (m/s²)
    reserve_a_h: float  # the reserve's horizontal limit (m/s²; 0: no reserve)
    accel_up: float  # vertical limits (m/s²)
    accel_down: float
    gain: float  # k of (B) (1/s)
    tiebreak: float  # m/s²
    relax_weight: float
    sensing_range: float  # m
    floor_m: float  # m
    priority_share: float
    both_states: bool
    joint_fallback: bool  # a boxed drone's cluster solves its constraints together (barrier_joint.py)
    lanes: bool  # the params' guard_lanes: a guarded drone's nominal on the lanes
    accel_filter_s: float  # s
    gate_rho: float
    gate_rho_ground: float  # the gate against a grounded drone of lower index
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
    #: the one drone whose row the filter computes (its copy under a sensing model: swarm_mj/formation/own_view.py);
    #: −1: every drone's. The other rows are returned as the planner's and their state is left as it was.
    own_row: int
    #: the one drone whose counts and events the record keeps (−1: every drone's): a copy under a sensing
    #: model with the joint fallback computes every row (its prediction of the others) and counts its own
    tally_row: int
    guarded: np.ndarray  # (n,) bool: the filter flies this drone's reference
    ref: np.ndarray  # (n, 3) r of a guarded drone
    ref_vel: np.ndarray  # (n, 3) ṙ
    sensed_acc: np.ndarray  # (n, 3) low-passed accelerations from the sensed velocities
    prev_acc: np.ndarray  # (n, 3) the acceleration references returned by the last call
    prev_vel: np.ndarray  # (n, 3) the sensed velocities of the last call
    start: np.ndarray  # (n, 3) where each drone stood on the ground (the first call's positions)
    was_relaxed: np.ndarray  # (n,) bool: relaxed at the last call
    waited: np.ndarray  # (n,) bool: held by the take-off gate at the last call
    active: np.ndarray  # (n,) bool: a barrier constraint changed the drone's command at the last call
    flags: np.ndarray  # (2,) bool: start taken, prev_vel taken
    escaping: np.ndarray  # (n,) bool: the drone escapes up (its nominal's altitude raised)
    pressed_s: np.ndarray  # (n,) s the drone has been pressed without progress (0: not counting)
    best_m: np.ndarray  # (n,) m its least horizontal distance to the planner's reference since then
    counts: np.ndarray  # (7,) int64: active, relaxed, guarded, rate-limited drone-periods; escapes; reserve; joint
    ev_t: np.ndarray  # (cap,) time of each relax event not yet handed to Python
    ev_drone: np.ndarray  # (cap,) int64 its drone
    ev_other: np.ndarray  # (cap,) int64 the neighbour whose row asked most beyond the drone's limits
    ev_count: np.ndarray  # (1,) int64 events held


#: Relax events a record holds per drone before Python takes them (the chunk driver hands back
#: before a period that could overflow it).
EVENTS_PER_DRONE = 8


def new_record(
    bp: BarrierParams, vehicle: QuadParams, n: int, on: bool, own_row: int = -1, tally_row: int | None = None
) -> BarrierRecord:
    """A fresh record of n drones (every drone free, no state taken yet). Its scalar parameters are
    the fields of ``bp`` of the same name (as float or bool, their declared types); its ``lanes`` is
    ``bp.guard_lanes``; ``own_row``: the one drone whose row it computes (−1: every drone's); ``tally_row``: the
    one whose counts and events it keeps (default: ``own_row``)."""
    cast = {"float": float, "bool": bool}
    kw: dict[str, Any] = {
        f.name: cast[str(f.type)](getattr(bp, f.name)) for f in fields(bp) if f.name in BarrierRecord._fields
    }
    cap = EVENTS_PER_DRONE * max(n, 1)
    return BarrierRecord(
        on=on,
        radii=bp.radii(vehicle),
        lane_gains=guard_gains(bp),
        a_h=bp.horizontal_limit(vehicle.g),
        reserve_a_h=bp.reserve_horizontal_limit(vehicle.g),
        lanes=bool(bp.guard_lanes),
        own_row=int(own_row),
        tally_row=int(own_row if tally_row is None else tally_row),
        guarded=np.zeros(n, dtype=np.bool_),
        ref=np.zeros((n, 3)),
        ref_vel=np.zeros((n, 3)),
        sensed_acc=np.zeros((n, 3)),
        prev_acc=np.zeros((n, 3)),
        prev_vel=np.zeros((n, 3)),
        start=np.zeros((n, 3)),
        was_relaxed=np.zeros(n, dtype=np.bool_),
        waited=np.zeros(n, dtype=np.bool_),
        active=np.zeros(n, dtype=np.bool_),
        flags=np.zeros(2, dtype=np.bool_),
        escaping=np.zeros(n, dtype=np.bool_),
        pressed_s=np.zeros(n),
        best_m=np.zeros(n),
        counts=np.zeros(7, dtype=np.int64),
        ev_t=np.zeros(cap),
        ev_drone=np.zeros(cap, dtype=np.int64),
        ev_other=np.full(cap, -1, dtype=np.int64),
        ev_count=np.zeros(1, dtype=np.int64),
        **kw,
    )


def barrier_off(n: int) -> BarrierRecord:
    """The stand-in record of a run without a barrier filter (``on`` False; the same types, so the
    chunk driver has one signature with or without the filter)."""
    return new_record(BarrierParams(), DEFAULT_PARAMS, n, False)
