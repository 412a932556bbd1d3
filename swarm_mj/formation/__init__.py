"""Formation layer (paper §4, docs/interpretations.md §4): polygon slots around the leader and anti-collision.

The named rules and :func:`~.anticollision.make_rule` are in :mod:`.anticollision` (the table itself in
:mod:`swarm_mj.pipeline.registry`, which imports the rules' modules: this package's init imports neither,
so that either can be imported first).
"""

from .barrier import BarrierFilter
from .planner import LayeredRule
from .rule_params import PRESETS, BaseParams, ControllerParams, JetAwareParams, LayersParams, PaperParams
from .rules import NoRule, PaperRule, Rule
from .separation import Sensed, SeparationFilter
from .slots import DiameterSchedule, polygon_offsets, slot_positions

__all__ = [
    "BarrierFilter",
    "BaseParams",
    "ControllerParams",
    "JetAwareParams",
    "LayersParams",
    "LayeredRule",
    "NoRule",
    "PRESETS",
    "PaperParams",
    "PaperRule",
    "Rule",
    "Sensed",
    "SeparationFilter",
    "DiameterSchedule",
    "polygon_offsets",
    "slot_positions",
]
