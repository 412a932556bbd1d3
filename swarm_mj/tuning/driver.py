"""The tune: FPA (paper §3.2, Fig. 3, Table 2) over the gains α1..α12 on the step cost of
:mod:`.evaluator`, on a backend of :mod:`.backends` (:func:`tune_gains`)."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import UserError
from ..paper import TABLE2_FPA, TABLE4_GAINS
from .backends import make_population_cost
from .constraints import decode_cost
from .evaluator import StepCheck, StepCostSettings, step_check, table4_ise
from .fpa import FPAResult, fpa

__all__ = ["INITS", "TuneCallback", "TuneOptions", "TuneOutcome", "tune_gains"]


INITS = ("table4", "random")


@dataclass(frozen=True)
class TuneOptions:
    """FPA settings of a tune (paper Table 2 defaults; docs/interpretations.md §6: a small positive lower bound).

    init: ``"table4"`` puts the paper's Table 4 gains (the designed controller the FPA is to
    improve, paper §3.2) in the initial population beside N − 1 uniform flowers, so the tune
    starts from a candidate that meets the step bars; ``"random"``: all N uniform (Fig. 3).
    """

    population: int = TABLE2_FPA.population
    iterations: int = TABLE2_FPA.iterations
    p: float = TABLE2_FPA.p
    gamma: float = TABLE2_FPA.gamma
    lower: float = 0.1
    upper: float = 12.0
    seed: int = 0
    init: str = "table4"

    def __post_init__(self) -> None:
        for name, minimum in (("population", 4), ("iterations", 1)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < minimum:
                raise UserError(f"{name} must be an integer >= {minimum}, got {v!r}")
        if not (_finite(self.p) and 0.0 <= self.p <= 1.0):
            raise UserError(f"switch probability p must be in [0, 1], got {self.p!r}")
        if not (_finite(self.gamma) and self.gamma > 0.0):
            raise UserError(f"step size gamma must be a number > 0, got {self.gamma!r}")
        if not (_finite(self.lower) and _finite(self.upper)):
            raise UserError(f"bounds must be finite numbers, got lower={self.lower!r}, upper={self.upper!r}")
        if self.lower <= 0.0:
            raise UserError(f"lower bound must be > 0 (the gains must be positive, paper: α_s > 0), got {self.lower!r}")
        if self.lower >= self.upper:
            raise UserError(f"bounds inverted: lower {self.lower!r} must be below upper {self.upper!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, (int, np.integer)) or self.seed < 0:
            raise UserError(f"seed must be an integer >= 0, got {self.seed!r}")
        if self.init not in INITS:
            raise UserError(f"init must be one of {', '.join(INITS)}, got {self.init!r}")
        if self.init == "table4" and not (self.lower <= TABLE4_GAINS.min() and TABLE4_GAINS.max() <= self.upper):
            raise UserError(
                f"init table4 needs bounds that hold the Table 4 gains "
                f"[{TABLE4_GAINS.min():g}, {TABLE4_GAINS.max():g}], got [{self.lower:g}, {self.upper:g}]; "
                f"widen them or use init random"
            )

    @property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(lower (12,), upper (12,)) box of α1..α12."""
        return np.full(12, float(self.lower)), np.full(12, float(self.upper))

    @property
    def x0(self) -> np.ndarray | None:
        """The flowers placed in the initial population (k, 12), or None."""
        return TABLE4_GAINS[None, :].copy() if self.init == "table4" else None


def _finite(v: Any) -> bool:
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool) and math.isfinite(v)


@dataclass(frozen=True)
class TuneOutcome:
    """A finished (or interrupted: ``complete`` False) tune.

    Costs are the tune's ranked costs (:func:`~swarm_mj.tuning.constraints.ranked_cost`): the
    ISE where the bars are met (or without bars), else ``INFEASIBLE + violation``.
    """

    result: FPAResult | None  # the FPA result at the end; None in per-iteration snapshots
    best_x: np.ndarray  # (12,) best gains found
    best_cost: float  # its ranked cost
    initial_cost: float  # ranked cost of the initial population's best
    table4_ise: float  # ISE of paper Table 4 gains, same cost
    history: np.ndarray  # (iterations done + 1,) ranked best cost after each iteration
    options: TuneOptions
    settings: StepCostSettings
    backend: str
    workers: int
    wall_s: float
    complete: bool
    check: StepCheck | None = None  # at the end: best_x flown through the step (ISE, metrics, bars)
    threads: int = 1  # the evaluator's threads (in each worker)

    def _decode(self, cost: float) -> tuple[bool, float]:
        """(feasible, ISE or violation) of a ranked cost; without bars every finite cost is an ISE."""
        if self.settings.bars is None:
            return math.isfinite(cost), float(cost)
        return decode_cost(cost)

    @property
    def best_feasible(self) -> bool:
        """best_x meets the bars (always True for a tune without bars, unless it diverged)."""
        return self._decode(self.best_cost)[0]

    @property
    def initial_feasible(self) -> bool:
        return self._decode(self.initial_cost)[0]

    @property
    def best_ise(self) -> float:
        """Plain ISE of eq. (25) of best_x (NaN in a snapshot whose best misses the bars)."""
        if self.check is not None:
            return self.check.ise
        ok, v = self._decode(self.best_cost)
        return v if ok else float("nan")

    @property
    def initial_ise(self) -> float:
        """ISE of the initial population's best (NaN if it misses the bars)."""
        ok, v = self._decode(self.initial_cost)
        return v if ok else float("nan")

    @property
    def history_ise(self) -> np.ndarray:
        """(iterations done + 1,) best ISE after each iteration (NaN while none meets the bars)."""
        return np.array([v if ok else np.nan for ok, v in map(self._decode, self.history)])

    @property
    def improvement_pct(self) -> float:
        """(initial − final) / initial best ISE, in % (paper Table 3: 10.7–35.5 %); NaN when
        the initial population has no candidate meeting the bars (nothing to compare with)."""
        a, b = self.initial_ise, self.best_ise
        if not (math.isfinite(a) and a > 0 and math.isfinite(b) and self.best_feasible):
            return float("nan")
        return 100.0 * (a - b) / a

    @property
    def meets_bars(self) -> bool | None:
        """best_x meets the step bars (the default bars if the tune had none); None in a
        snapshot of a tune without bars (not checked until the end)."""
        if self.check is not None:
            return self.check.meets_bars
        return self.best_feasible if self.settings.bars is not None else None

    @property
    def beats_table4(self) -> bool:
        """A lower ISE than Table 4's, meeting the bars where the tune had them."""
        return bool(self.best_feasible and self.best_ise < self.table4_ise)


TuneCallback = Callable[["TuneOutcome"], None]


def tune_gains(
    options: TuneOptions = TuneOptions(),
    settings: StepCostSettings = StepCostSettings(),
    *,
    workers: int | None = None,
    threads: int | None = None,
    ray_address: str | None = None,
    on_iteration: TuneCallback | None = None,
) -> TuneOutcome:
    """Tune α1..α12 by FPA (paper §3.2, Fig. 3, Table 2) on the ISE of eq. (25) over the step,
    subject to ``settings.bars`` (Deb's feasibility rules, :mod:`.constraints`) when set.

    ``on_iteration(outcome)`` is called after the initial population (iteration 0) and after
    every iteration with the best so far (``complete`` False until the end) — e.g. to write
    the gains file, so that an interruption leaves the best gains found. A Ctrl-C propagates
    (KeyboardInterrupt) after the workers are stopped. The final outcome carries ``check``:
    the best gains flown through the step once more, with their step metrics.
    ``workers``, ``threads``, ``ray_address``: where the population is evaluated
    (:func:`~swarm_mj.tuning.backends.make_population_cost`; by default one worker process per
    usable CPU); the tune is the same whatever they are.
    """
    import time

    t0 = time.perf_counter()
    t4 = table4_ise(settings)  # in-process: same cost, bitwise, whatever the backend
    with make_population_cost(settings, workers=workers, threads=threads, ray_address=ray_address) as cost:

        def progress(iteration: int, best_x: np.ndarray, best_cost: float, history: np.ndarray) -> None:
            if on_iteration is not None:
                on_iteration(
                    TuneOutcome(
                        result=None,
                        best_x=best_x,
                        best_cost=float(best_cost),
                        initial_cost=float(history[0]),
                        table4_ise=t4,
                        history=history,
                        options=options,
                        settings=settings,
                        backend=cost.backend,
                        workers=cost.workers,
                        wall_s=time.perf_counter() - t0,
                        complete=False,
                        threads=cost.threads,
                    )
                )

        res = fpa(
            cost,
            options.bounds,
            population=options.population,
            iterations=options.iterations,
            p=options.p,
            gamma=options.gamma,
            seed=options.seed,
            x0=options.x0,
            callback=progress,
        )
        backend, n_workers, n_threads = cost.backend, cost.workers, cost.threads
    check = step_check(res.best_x, settings)
    return TuneOutcome(
        result=res,
        best_x=res.best_x,
        best_cost=float(res.best_cost),
        initial_cost=float(res.initial_best_cost),
        table4_ise=t4,
        history=res.history,
        options=options,
        settings=settings,
        backend=backend,
        workers=n_workers,
        wall_s=time.perf_counter() - t0,
        complete=True,
        check=check,
        threads=n_threads,
    )
