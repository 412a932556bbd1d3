"""Gain tuning (SPEC §6): a general Flower Pollination Algorithm optimiser and the ISE cost
of eq. (25) over the step manoeuvre, evaluated for a whole population in batched MuJoCo
models, in-process, over local worker processes or over a Ray cluster."""

from .constraints import StepBars
from .cost import (BatchEvaluator, StepCheck, StepCostSettings, TuneOptions, TuneOutcome, evaluate_batch,
                   make_population_cost, step_check, step_ise, table4_ise, tune_gains)
from .fpa import FPAResult, fpa, levy_steps, random_search

__all__ = ["FPAResult", "fpa", "levy_steps", "random_search",
           "BatchEvaluator", "StepBars", "StepCheck", "StepCostSettings", "TuneOptions", "TuneOutcome", "evaluate_batch",
           "make_population_cost", "step_check", "step_ise", "table4_ise", "tune_gains"]
