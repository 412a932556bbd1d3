"""Anti-collision by altitude changes (paper Fig. 5, §4, §5.3; docs/interpretations.md §4,
docs/anticollision.md): the registry of the named rules, ``"auto"`` and :func:`make_rule`.

The parts: one parameter record (:mod:`.rule_params`, :class:`RuleParams`, whose presets the
named rules are), the rules' interface and the paper's rule (:mod:`.rules`), the planner's phase
machine, layers and limited paths (:mod:`.planner`, :class:`LayeredRule`), the separation step
(:mod:`.separation`: Fig. 5, the jet-aware offsets, never-through, early hold, and the
:class:`~.separation.SeparationFilter` interface), the jet-aware rule (:mod:`.jet_aware`) and the
compiled kernels (:mod:`.layered`). This module re-exports what the chunk driver reads.
"""

from __future__ import annotations

from typing import Any

from ..errors import UserError
from ..physics.params import DEFAULT_PARAMS, QuadParams
from .jet_aware import JetAwareRule
from .layered import any_below, horizontal_distances, idle_record, merge_rows, react_needed
from .planner import CLIMB, CROSS, FORMED, CompensatedRule, G, LayeredRule
from .rule_params import PRESETS, RuleParams
from .rules import NoRule, PaperRule, Rule

#: Centre distance (m) under which two paper drones' keep-out discs overlap in plan view (the
#: default record: :meth:`RuleParams.overlap`): a stand-in only; a rule's own is ``rule.overlap``.
OVERLAP_M = RuleParams().overlap(DEFAULT_PARAMS)

ANTI_COLLISION_RULES: dict[str, type[Rule]] = {
    "layers": LayeredRule,
    "paper": PaperRule,
    "off": NoRule,
    "jet-aware": JetAwareRule,
}
AntiCollision = LayeredRule | PaperRule | NoRule | JetAwareRule


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
    "any_below",
    "horizontal_distances",
    "idle_record",
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


def make_rule(
    name: str,
    n: int,
    where: str = "formation.anti_collision",
    *,
    vehicle: QuadParams = DEFAULT_PARAMS,
    **params: Any,
) -> Rule:
    """Build an anti-collision rule by name (``layers``, ``paper``, ``off``, ``jet-aware``; resolve
    ``"auto"`` first with :func:`resolve_rule`) for drones of parameters ``vehicle`` (the run's,
    ``Scenario.params``): its preset (:data:`PRESETS`) with its sizes scaled to the vehicle
    (:meth:`RuleParams.for_vehicle`), then ``params``, any fields of :class:`RuleParams` in metres
    as written (a scenario's ``[formation]`` keys and ``[controller] downwash_feedforward``;
    :class:`UserError` naming ``where`` for an unknown one)."""
    if name not in ANTI_COLLISION_RULES:
        raise UserError(f"unknown rule {name!r}; choose one of {', '.join(ANTI_COLLISION_RULES)}", where=where)
    record = PRESETS[name].for_vehicle(vehicle).with_overrides(params, where=where.rsplit(".", 1)[0])
    return ANTI_COLLISION_RULES[name](n, record, vehicle=vehicle)
