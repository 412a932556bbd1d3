"""Anti-collision by altitude changes (paper Fig. 5, §4, §5.3; docs/interpretations.md §4,
docs/anticollision.md): ``"auto"`` and :func:`make_rule` (the named rules are
:data:`swarm_mj.pipeline.registry.ANTI_COLLISION_RULES`, re-exported here).

The parts: each rule's parameter record (:mod:`.rule_params`: :class:`PaperParams`,
:class:`LayersParams`, :class:`JetAwareParams`, the named rules' :data:`PRESETS`), the rules'
interface and the paper's rule (:mod:`.rules`), the planner's phase machine, layers and limited
paths (:mod:`.planner`, :class:`LayeredRule`), the separation step
(:mod:`.separation`: Fig. 5, the jet-aware offsets, never-through, early hold, and the
:class:`~.separation.SeparationFilter` interface), the jet-aware rule (:mod:`.jet_aware`) and the
compiled kernels (:mod:`.layered`). This module re-exports what the chunk driver reads.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from ..errors import UserError
from ..physics.params import DEFAULT_PARAMS, QuadParams
from ..pipeline.registry import ANTI_COLLISION_RULES
from .jet_aware import JetAwareRule
from .layered import any_below, horizontal_distances, idle_record, merge_rows, react_needed
from .planner import CLIMB, CROSS, FORMED, CompensatedRule, G, LayeredRule
from .rule_params import (
    CONTROLLER_KEYS,
    PRESETS,
    BaseParams,
    JetAwareParams,
    LayersParams,
    PaperParams,
    RuleRecord,
    check_overrides,
    record_keys,
)
from .rules import NoRule, PaperRule, Rule

#: Centre distance (m) under which two paper drones' keep-out discs overlap in plan view (the
#: planner's default record: :meth:`LayersParams.overlap`): a stand-in only; a rule's own is ``rule.overlap``.
OVERLAP_M = LayersParams().overlap(DEFAULT_PARAMS)

AntiCollision = LayeredRule | PaperRule | NoRule | JetAwareRule


__all__ = [
    "ANTI_COLLISION_RULES",
    "AUTO",
    "AUTO_CHOICE",
    "AntiCollision",
    "CLIMB",
    "CROSS",
    "FORMED",
    "OVERLAP_M",
    "G",
    "CompensatedRule",
    "JetAwareParams",
    "JetAwareRule",
    "LayeredRule",
    "LayersParams",
    "NoRule",
    "PRESETS",
    "PaperParams",
    "PaperRule",
    "Rule",
    "any_below",
    "horizontal_distances",
    "idle_record",
    "make_rule",
    "merge_rows",
    "react_needed",
    "resolve_rule",
    "rule_record",
]


#: The rule a scenario flies when it names none (or names ``"auto"``): see :func:`resolve_rule`.
AUTO = "auto"


#: What ``"auto"`` flies, by whether the physics has downwash (the physics preset: ``--aero
#: realistic`` has, the paper's has not), and the one-line reason the run's summary prints. The
#: measurements behind each choice: docs/barrier.md, "auto".
AUTO_CHOICE: dict[bool, tuple[str, str]] = {
    False: (
        "layers",
        "no downwash in this physics: the paper's reaction with the planner, contact-free on the fresh stress "
        "starts, the paper's reproduction (docs/barrier.md, auto)",
    ),
    True: (
        "barrier",
        "downwash: the keep-out held (0 s, no contact or crash on the fresh stress starts, against 676 s and a "
        "contact for jet-aware), every start settled, at 0.93x (five) to 1.29x (twelve) jet-aware's, relaxed in "
        "1 of 620 starts (docs/barrier.md, auto)",
    ),
}


def resolve_rule(name: str, downwash: bool) -> str:
    """The rule ``name`` stands for: ``"auto"`` is :data:`AUTO_CHOICE`'s for the physics (``downwash``:
    ``"barrier"`` under ``--aero realistic``, ``"layers"`` under the paper's physics, the
    reproduction: docs/interpretations.md §4; why: docs/barrier.md, "auto"); any other name is itself."""
    if name == AUTO:
        return AUTO_CHOICE[bool(downwash)][0]
    return name


def rule_record(name: str, vehicle: QuadParams = DEFAULT_PARAMS, values: dict[str, Any] | None = None) -> RuleRecord:
    """The parameter record rule ``name`` (a key of :data:`ANTI_COLLISION_RULES`) flies with: its own
    record type, its preset (:data:`PRESETS`; a rule outside them, its class's ``Params()``) with its
    sizes scaled to ``vehicle`` (:meth:`~.rule_params.BaseParams.for_vehicle`), then those of
    ``values`` that are its fields (validated already: :func:`~.rule_params.check_overrides`). The
    other keys of ``values`` (another rule's, the controller's) are not its: they are left out."""
    base = PRESETS[name].for_vehicle(vehicle) if name in PRESETS else ANTI_COLLISION_RULES[name].Params()
    own = {k: v for k, v in (values or {}).items() if k in record_keys(base)}
    if not own:
        return base
    return replace(base, **own) if isinstance(base, BaseParams) else base._replace(**own)


def make_rule(
    name: str,
    n: int,
    where: str = "formation.anti_collision",
    *,
    vehicle: QuadParams = DEFAULT_PARAMS,
    barrier: dict[str, Any] | None = None,
    **params: Any,
) -> Rule:
    """Build an anti-collision rule by name (``layers``, ``paper``, ``off``, ``jet-aware``; resolve
    ``"auto"`` first with :func:`resolve_rule`) for drones of parameters ``vehicle`` (the run's,
    ``Scenario.params``). ``params``: a scenario's ``[formation]`` keys (in metres as written) and
    ``[controller] downwash_feedforward``, validated against every rule's keys (:class:`UserError`
    naming ``where``'s table for an unknown one or a bad value); the rule's record is
    :func:`rule_record` (its preset with the keys that are its fields: a key only another rule reads
    is accepted and left out) and the controller's keys its ``controller_params``. ``barrier``: a
    scenario's ``[formation.barrier]`` table, for the rules with a barrier filter
    (``takes_barrier_params``: ``barrier``; docs/barrier.md); another rule has no use for it and
    flies without it (a scenario with the table may fly ``--anti-collision jet-aware`` or a sweep
    over the rules)."""
    if name not in ANTI_COLLISION_RULES:
        raise UserError(f"unknown rule {name!r}; choose one of {', '.join(ANTI_COLLISION_RULES)}", where=where)
    values = check_overrides(params, where=where.rsplit(".", 1)[0])
    record = rule_record(name, vehicle, values)
    asked = {k: values[k] for k in CONTROLLER_KEYS if k in values}
    cls: Any = ANTI_COLLISION_RULES[name]
    if barrier and getattr(cls, "takes_barrier_params", False):
        return cls(n, record, vehicle=vehicle, barrier=barrier, **asked)
    return cls(n, record, vehicle=vehicle, **asked)
