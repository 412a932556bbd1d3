"""Formation layer (paper §4, docs/interpretations.md §4): polygon slots around the leader and anti-collision."""

from .anticollision import (
    ANTI_COLLISION_RULES,
    AntiCollision,
    LayeredRule,
    NoRule,
    PaperRule,
    Rule,
    make_rule,
)
from .barrier import BarrierFilter, BarrierRule  # registers "barrier" and "barrier-lanes" in ANTI_COLLISION_RULES
from .rule_params import PRESETS, RuleParams
from .separation import Sensed, SeparationFilter
from .slots import DiameterSchedule, polygon_offsets, slot_positions

__all__ = [
    "ANTI_COLLISION_RULES",
    "AntiCollision",
    "BarrierFilter",
    "BarrierRule",
    "LayeredRule",
    "NoRule",
    "PRESETS",
    "PaperRule",
    "Rule",
    "RuleParams",
    "Sensed",
    "SeparationFilter",
    "make_rule",
    "DiameterSchedule",
    "polygon_offsets",
    "slot_positions",
]
