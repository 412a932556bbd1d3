"""The tuner's cost, its backends and the tune under their former common name (kept so that
``from swarm_mj.tuning.cost import ...`` goes on working). The code is in :mod:`.evaluator`
(eq. (25) over the step, batched), :mod:`.backends` (in-process, processes, Ray) and
:mod:`.driver` (the FPA tune)."""

from __future__ import annotations

from .backends import (
    RAY_INSTALL_HINT,
    InProcessCost,
    PopulationCost,
    ProcessPoolCost,
    RayCost,
    default_workers,
    make_population_cost,
)
from .constraints import StepBars
from .driver import INITS, TuneCallback, TuneOptions, TuneOutcome, tune_gains
from .evaluator import (
    DEFAULT_BLOCK,
    BatchEvaluator,
    StepCheck,
    StepCostSettings,
    evaluate_batch,
    step_check,
    step_ise,
    table4_ise,
)

__all__ = [
    "StepCostSettings",
    "TuneOptions",
    "TuneOutcome",
    "TuneCallback",
    "INITS",
    "tune_gains",
    "BatchEvaluator",
    "DEFAULT_BLOCK",
    "PopulationCost",
    "InProcessCost",
    "ProcessPoolCost",
    "RayCost",
    "RAY_INSTALL_HINT",
    "default_workers",
    "evaluate_batch",
    "make_population_cost",
    "step_ise",
    "step_check",
    "StepCheck",
    "StepBars",
    "table4_ise",
]
