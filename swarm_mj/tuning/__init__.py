"""Gain tuning (docs/interpretations.md §6): a general Flower Pollination Algorithm optimiser
(:mod:`.fpa`) and the ISE cost of eq. (25) over the step manoeuvre (:mod:`.evaluator`), evaluated
for a whole population by the simulator's pipeline over copies, in-process, over local worker
processes or over a Ray cluster (:mod:`.backends`); the tune itself is :mod:`.driver`."""

from .backends import make_population_cost
from .constraints import StepBars
from .driver import TuneOptions, TuneOutcome, tune_gains
from .evaluator import (
    BatchEvaluator,
    StepCheck,
    StepCostSettings,
    evaluate_batch,
    step_check,
    step_ise,
    table4_ise,
)
from .fpa import FPAResult, fpa, levy_steps, random_search

__all__ = [
    "FPAResult",
    "fpa",
    "levy_steps",
    "random_search",
    "BatchEvaluator",
    "StepBars",
    "StepCheck",
    "StepCostSettings",
    "TuneOptions",
    "TuneOutcome",
    "evaluate_batch",
    "make_population_cost",
    "step_check",
    "step_ise",
    "table4_ise",
    "tune_gains",
]
