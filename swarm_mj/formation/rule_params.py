"""Each anti-collision rule's parameter record (docs/interpretations.md §4; the long reasons and the
measurements behind each value: docs/anticollision.md).

A rule reads its numbers from its own frozen record, which holds exactly the fields it reads, each
with its unit, its admissible range and a one-line reason in the field's metadata (the default is
written there once). The records extend one another as the rules do:

* :class:`BaseParams`: no field (the ``off`` rule's record), the methods every record has;
* :class:`PaperParams`: Fig. 5's D̄, ``hop`` and ``hysteresis`` (``paper``);
* :class:`LayersParams`: and the planner's (``layers``; sensing, paths, phases, outline);
* :class:`JetAwareParams`: and the jet-aware separation's (``jet-aware``, and ``barrier``, whose
  planner it is; the barrier filter's own record is :class:`~.barrier_params.BarrierParams`).

What a rule asks of the controller is :class:`ControllerParams` (``downwash_feedforward``, a
``[controller]`` key), its default per rule in :data:`CONTROLLER_PRESETS`.

A scenario's ``[formation]`` keys are the fields of every rule's record (:data:`PARAM_KEYS`, the
union; :func:`check_overrides` validates them from the metadata, and an unknown key is one
:class:`~swarm_mj.errors.UserError` naming it); the rule flown takes those of its own record, and a
key only another rule reads is accepted and left out. The named rules' records are
:data:`PRESETS`: each its rule's own record type with a few fields changed.

The vehicle's geometry is not a parameter: the keep-out radius of a drone is its arm plus its
rotor radius (:func:`vehicle_outline`), from the vehicle's parameters, plus ``outline_margin``.
The fields that are vehicle sizes (:data:`SIZE_KEYS`: ``outline_margin``, ``overlap_spare``,
``hover_pass_margin``) hold the paper drone's value and scale with the vehicle's
rotor span (:meth:`BaseParams.for_vehicle`); the others (D̄, the layers, altitudes, tolerances,
braking margins) are not sizes of the vehicle (docs/anticollision.md, "The vehicle's sizes").

The compiled path kernels read theirs from :class:`~swarm_mj.formation.layered.PathLimits`, whose
fields named as fields of :class:`LayersParams` are taken from it (:func:`~swarm_mj.formation.layered.path_limits`).
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields, replace
from typing import Any, Protocol, Self, TypeAlias

import numpy as np

from ..errors import UserError, unknown_key
from ..physics.params import DEFAULT_PARAMS, QuadParams
from ..starts import MAX_RANGE_M
from ..table_fields import finite


def _p(
    default: Any,
    unit: str,
    why: str,
    lo: float | None = 0.0,
    hi: float | None = None,
    *,
    open_lo: bool = True,
    table: str = "formation",
    size: bool = False,
):
    """A record field: its default, unit, one-line reason, range (``lo`` < v (or ≤ when not
    ``open_lo``) ≤ ``hi``; None: unbounded), the scenario table that sets it, and whether it is a
    vehicle size (``size``: its default is the paper drone's, scaled by :meth:`BaseParams.for_vehicle`)."""
    meta = {"unit": unit, "why": why, "lo": lo, "hi": hi, "open_lo": open_lo, "table": table, "size": size}
    return field(default=default, metadata=meta)


#: The field maker, for another parameter record validated the same way (the barrier filter's
#: ``BarrierParams``, :func:`check_overrides` with ``record=``).
param_field = _p


@dataclass(frozen=True)
class BaseParams:
    """What every rule's record is: fields made by :func:`_p`, validated from their metadata. It has
    none itself: the record of ``off``, which reads nothing."""

    @property
    def keys(self) -> tuple[str, ...]:
        return tuple(f.name for f in fields(self))

    def with_overrides(self, overrides: dict[str, Any], where: str = "formation") -> Self:
        """A copy with ``overrides``, fields of this record (validated by :func:`check_overrides`)."""
        return replace(self, **check_overrides(overrides, where, record=type(self))) if overrides else self

    def for_vehicle(self, vehicle: QuadParams) -> Self:
        """A copy whose vehicle sizes (its fields among :data:`SIZE_KEYS`) are scaled by the vehicle's
        rotor span over the paper drone's, ``(L + r) / (L₀ + r₀)`` (docs/anticollision.md, "The
        vehicle's sizes"); the record itself for the paper's drone (a ratio of exactly 1), so that
        its runs are unchanged bit for bit. Apply a scenario's overrides after this: what a
        scenario writes is in metres, as written."""
        sizes = [f.name for f in fields(self) if f.metadata["size"]]
        scale = vehicle.rotor_span / DEFAULT_PARAMS.rotor_span
        if scale == 1.0 or not sizes:
            return self
        return replace(self, **{k: getattr(self, k) * scale for k in sizes})


@dataclass(frozen=True)
class PaperParams(BaseParams):
    """The paper's reaction (Fig. 5, §4): what ``paper`` reads."""

    safety_distance: float = _p(0.8, "m", "paper: D̄, the horizontal distance under which the higher index yields")
    hop: float = _p(0.4, "m", "paper: the altitude change of a yielding drone; also the spacing of the layers")
    hysteresis: float = _p(0.05, "m", "a yielding drone returns once beyond D̄ + this (the paper does not say when)")


@dataclass(frozen=True)
class LayersParams(PaperParams):
    """The planner's (ours, docs/interpretations.md §4): what ``layers`` reads beside Fig. 5's."""

    # --- sensing and prediction
    sensing_range: float = _p(
        4.0, "m", "a drone decides from the drones within this 3D distance (and the leader)", 0.0, MAX_RANGE_M
    )
    horizon: float = _p(1.0, "s", "closest approach predicted over this horizon (straight-line relative motion)")
    hover_speed: float = _p(0.5, "m/s", "a drone slower than this horizontally counts as hovering")
    # --- the planner's limited paths
    max_speed: float = _p(4.0, "m/s", "horizontal path speed on the layers (capped to stop within the sensing range)")
    max_accel: float = _p(6.0, "m/s²", "horizontal path acceleration on the layers")
    climb_speed: float = _p(4.0, "m/s", "altitude path speed up (capped to stop within the sensing range)")
    climb_accel: float = _p(8.0, "m/s²", "altitude path acceleration up (more thrust)")
    descent_speed: float = _p(1.5, "m/s", "altitude path speed down")
    descent_accel: float = _p(5.0, "m/s²", "altitude path acceleration down: eq. (18)'s thrust stays off its floor")
    formed_descent_accel: float = _p(5.0, "m/s²", "descent acceleration once joined (≤ descent_accel)")
    jerk: float = _p(120.0, "m/s³", "paths' jerk limit: the acceleration reference turns round smoothly")
    velocity_gain: float = _p(15.0, "1/s", "paths' velocity loop gain (the acceleration asked per m/s of error)")
    max_tilt_deg: float = _p(30.0, "deg", "horizontal path acceleration ≤ (g + z̈)·tan(this)", 0.0, 89.0)
    braking_share: float = _p(0.8, "", "share of its acceleration limit a path plans to brake with", 0.0, 1.0)
    path_approach_gain: float = _p(3.0, "1/s", "a horizontal path's final approach: speed ≤ this · distance")
    altitude_approach_gain: float = _p(4.0, "1/s", "an altitude path's final approach: speed ≤ this · distance")
    thrust_floor: float = _p(1.0, "m/s²", "least vertical specific force the tilt limit of a path is taken from")
    # --- the planner's phases (climb, cross, drop)
    arrive: float = _p(0.2, "m", "a crossing follower this close to its slot (and its path) drops")
    climb_tolerance: float = _p(0.35, "m", "a climbing follower this close under its layer starts crossing")
    clearance: float = _p(0.3, "m", "vertical band: drones closer in altitude than this count as level")
    approach_margin: float = _p(0.2, "m", "kept beyond D̄ (or hop) from a moving drone when climbing, and when stopping")
    stop_room_min: float = _p(0.1, "m", "least room the sensing-range speed cap works with")
    above_margin: float = _p(0.05, "m", "a drone counts as above a climbing one when higher by more than this")
    late_margin: float = _p(0.1, "m", "a climbing follower that cannot stop this far under its wait climbs over")
    hover_min: float = _p(0.3, "m", "a follower waiting under a drone lifts off the ground to this height")
    airborne_min: float = _p(0.2, "m", "a follower higher than this is airborne (it may step aside)")
    at_start: float = _p(0.1, "m", "a follower within this of its climbing point is there (it may step aside)")
    aside_margin: float = _p(0.2, "m", "a follower steps aside to this beyond its radius from a hovering drone")
    hover_pass_margin: float = _p(
        0.1, "m", "a climbing drone passes a hovering one 2·outline + this apart (a size)", size=True
    )
    reaction_time: float = _p(0.3, "s", "a crossing drone's conflict horizon: its time to stop plus this")
    conflict_horizon_max: float = _p(2.0, "s", "longest conflict horizon of a crossing drone")
    crossing_brake: bool = _p(
        True, "", "a crossing follower brakes for a drone it gives way to (off: a separation filter separates)", None
    )
    # --- the leader's start (docs/barrier.md, "the leader's start")
    leader_join_s: float = _p(
        0.0,
        "s",
        "the leader's position joins its trajectory from rest over this (0: a step, the paper's)",
        0.0,
        open_lo=False,
    )
    leader_climb_s: float = _p(
        0.0, "s", "the leader's altitude joins its trajectory's from rest over this (0: a step)", 0.0, open_lo=False
    )
    # --- the vehicle's outline
    outline_margin: float = _p(
        0.01, "m", "keep-out radius = arm + rotor radius + this (a size)", 0.0, open_lo=False, size=True
    )
    overlap_spare: float = _p(
        0.02, "m", "outlines overlap in plan view under 2·keep-out + this (a size)", 0.0, open_lo=False, size=True
    )

    def keep_out(self, vehicle: QuadParams) -> float:
        """Keep-out radius (m) of a drone in plan view: :func:`vehicle_outline` + ``outline_margin``."""
        return vehicle_outline(vehicle) + self.outline_margin

    def overlap(self, vehicle: QuadParams) -> float:
        """Centre distance (m) under which two drones' keep-out discs overlap in plan view, with
        ``overlap_spare`` to spare: a formed drone never changes altitude through one that close."""
        return 2.0 * self.keep_out(vehicle) + self.overlap_spare


@dataclass(frozen=True)
class JetAwareParams(LayersParams):
    """The jet-aware separation's (docs/interpretations.md §4): what ``jet-aware`` (and ``barrier``'s
    planner) reads beside the planner's."""

    floor_clearance: float = _p(0.5, "m", "lowest altitude a stacked offset sends a yielding follower to")
    closing_min: float = _p(0.5, "m/s", "never-through predicts only for pairs closing faster than this")
    crossing_hold: float = _p(0.2, "m", "a descending formed follower holds over a crossing drone from D̄ + this")
    max_hops_up: int = _p(3, "hops", "highest stacked offset, in hops above the formation", 1.0, 20.0, open_lo=False)
    max_hops_down: int = _p(2, "hops", "lowest stacked offset, in hops below the formation", 0.0, 20.0, open_lo=False)


@dataclass(frozen=True)
class ControllerParams:
    """What a rule asks of the controller (``[controller]`` keys, beside ``wind_feedforward``): not a
    rule's parameter, though its default is the rule's (:data:`CONTROLLER_PRESETS`)."""

    downwash_feedforward: bool = _p(
        False, "", "the controller compensates the others' predicted downwash", None, table="controller"
    )

    def with_overrides(self, overrides: dict[str, Any], where: str = "controller") -> ControllerParams:
        """A copy with ``overrides``, fields of this record (validated by :func:`check_overrides`)."""
        return replace(self, **check_overrides(overrides, where, record=ControllerParams)) if overrides else self


#: The rules' records, each the one before it and more (a rule outside this module may bring its
#: own: its class's ``Params``, e.g. ``StaggerParams``, whose fields are among these).
RULE_RECORDS: tuple[type[BaseParams], ...] = (BaseParams, PaperParams, LayersParams, JetAwareParams)


class OwnRecord(Protocol):
    """A rule's own parameter record outside :data:`RULE_RECORDS`: a ``NamedTuple`` its compiled step
    reads (stagger's), whose fields are among :data:`PARAM_KEYS` (a scenario's keys fill it)."""

    _fields: tuple[str, ...]

    def _replace(self, **kwargs: Any) -> Self: ...


#: A rule's parameter record: one of :data:`RULE_RECORDS`, or a rule's own (:class:`OwnRecord`).
RuleRecord: TypeAlias = BaseParams | OwnRecord
_FIELDS = {f.name: f for rec in (*RULE_RECORDS, ControllerParams) for f in fields(rec)}
#: The keys a scenario may set (the union of every rule's record's fields and the controller's), and
#: the table of each; the controller's.
PARAM_KEYS: tuple[str, ...] = tuple(_FIELDS)
PARAM_TABLE: dict[str, str] = {k: f.metadata["table"] for k, f in _FIELDS.items()}
CONTROLLER_KEYS: tuple[str, ...] = tuple(f.name for f in fields(ControllerParams))
#: The fields that are vehicle sizes (metres on the paper's drone, scaled by :meth:`BaseParams.for_vehicle`).
SIZE_KEYS: tuple[str, ...] = tuple(k for k, f in _FIELDS.items() if f.metadata["size"])


def record_keys(record: RuleRecord) -> tuple[str, ...]:
    """The fields of a rule's record (a dataclass of this module's or a rule's own ``NamedTuple``)."""
    return tuple(f.name for f in fields(record)) if isinstance(record, BaseParams) else tuple(record._fields)


def vehicle_outline(vehicle: QuadParams = DEFAULT_PARAMS) -> float:
    """Centre to rotor tip (m) in plan view: the arm L plus the rotor radius
    (:attr:`~swarm_mj.physics.params.QuadParams.rotor_span`, the drawn rotor discs of ``assets/quadrotor.xml``)."""
    return float(vehicle.rotor_span)


def check_overrides(overrides: dict[str, Any], where: str = "formation", record: type | None = None) -> dict[str, Any]:
    """``overrides`` validated against the metadata of ``record``'s fields (by default the union of
    :data:`PARAM_KEYS`; any frozen record whose fields are made by :func:`_p`): known keys, type (bool,
    integer or number), finite and in range; :class:`UserError` naming ``where.key`` otherwise (an
    unknown key's points to ``record.DOCS``, docs/anticollision.md by default). Returns them
    converted (floats as float, integers as int)."""
    by_name = _FIELDS if record is None else {f.name: f for f in fields(record)}
    out: dict[str, Any] = {}
    for key, v in overrides.items():
        w = f"{where}.{key}" if where else key
        f = by_name.get(key)
        if f is None:
            raise unknown_key(key, by_name, where=where or None, see=getattr(record, "DOCS", "docs/anticollision.md"))
        m = f.metadata
        if f.type in ("bool", bool):
            if not isinstance(v, (bool, np.bool_)):
                raise UserError(f"must be true or false, got {v!r}", where=w)
            out[key] = bool(v)
            continue
        integer = f.type in ("int", int)
        if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
            raise UserError(f"must be {'an integer' if integer else 'a number'}, got {v!r}", where=w)
        if not finite(v):
            raise UserError(f"must be finite, got {v!r}", where=w)
        if integer and float(v) != int(v):
            raise UserError(f"must be an integer, got {v!r}", where=w)
        lo, hi = m["lo"], m["hi"]
        unit = f" {m['unit']}" if m["unit"] else ""
        if lo is not None and (v <= lo if m["open_lo"] else v < lo):
            bound = "positive" if lo == 0.0 and m["open_lo"] else f"{'>' if m['open_lo'] else '>='} {lo:g}{unit}"
            raise UserError(f"must be {bound}, got {v!r}", where=w)
        if hi is not None and v > hi:
            raise UserError(f"must be <= {hi:g}{unit}, got {v!r}", where=w)
        out[key] = int(v) if integer else float(v)
    return out


#: The named rules' records, each its rule's own record type (``off`` reads nothing; a rule outside
#: this module, e.g. ``stagger``, flies its class's ``Params()``).
_JET_AWARE = JetAwareParams(max_speed=3.0, max_accel=4.0, formed_descent_accel=3.0)
PRESETS: dict[str, BaseParams] = {
    "paper": PaperParams(),
    "layers": LayersParams(),
    "jet-aware": _JET_AWARE,
    # the barrier filter's planner (its own parameters are barrier.BarrierParams): jet-aware's, its
    # descents at 0.75 m/s, not 1.5 (docs/barrier.md, "the planner's descent": a follower descending
    # past its ring neighbours is pushed sideways by their tall keep-outs, less the slower it goes),
    # without the crossing brake (docs/barrier.md, "the planner's crossing brake": the filter
    # separates, and the brake's on-off chatter drove the lagged drones' limit cycle), the leader's
    # start joined from rest, its altitude over 2.5 s and its position over 4 s (docs/barrier.md, "the
    # leader's start": its dash at the limits made the filter infeasible for followers lifting off)
    "barrier": replace(_JET_AWARE, descent_speed=0.75, crossing_brake=False, leader_join_s=4.0, leader_climb_s=2.5),
    "off": BaseParams(),
}
#: What each rule asks of the controller unless a scenario's ``[controller]`` says otherwise: the
#: jet-aware rules the downwash feedforward (docs/anticollision.md, 1. of the jet-aware rule). The
#: layered rule with it, once the ``compensated`` rule, is ``layers`` with ``[controller]
#: downwash_feedforward = true``.
CONTROLLER_PRESETS: dict[str, ControllerParams] = {
    "jet-aware": ControllerParams(downwash_feedforward=True),
    "barrier": ControllerParams(downwash_feedforward=True),
}


def describe() -> list[tuple[str, str, str, str]]:
    """(key, default, unit, reason) of every key a scenario may set (:data:`PARAM_KEYS`), for docs
    and ``--help`` text."""
    return [(k, repr(f.default), f.metadata["unit"], f.metadata["why"]) for k, f in _FIELDS.items()]
