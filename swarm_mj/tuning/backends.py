"""Where the tuner's population is evaluated: in this process, in local worker processes or on a
Ray cluster (:func:`make_population_cost`).

Each backend is a batched cost ``(m, 12) → (m,)`` for :func:`swarm_mj.tuning.fpa.fpa`; the population
is split in contiguous chunks, each worker runs :func:`~swarm_mj.tuning.evaluator.evaluate_batch` on
one, and the results are concatenated in order, so the costs — and the whole tune — are the same
whatever the number of workers. The workers are the experiments' one executor,
:class:`swarm_mj.experiments.parallel.Executor` (spawn processes kept alive across the FPA iterations, CPU
affinity, Ctrl-C, optional extra ``swarm-mj[ray]`` for Ray).
"""

from __future__ import annotations

import multiprocessing
import sys
import threading
from typing import Protocol

import numpy as np

from ..errors import UserError
from ..experiments.parallel import RAY_INSTALL_HINT, Executor, check_count, default_workers
from .evaluator import StepCostSettings, evaluate_batch


def worker_start_method() -> str:
    """How the tuner's local worker processes start: ``"fork"`` where the platform has it (Linux) and
    this process runs no other thread, else ``"spawn"``. A forked worker is a copy of this process with
    MuJoCo, the compiled kernels and the evaluator already loaded, ready in milliseconds, where a
    spawned one first imports and loads them (about 1.5 s of CPU each; docs/physics_step.md, "The
    tuner on every core"). The evaluator's own threads end with each call, so ``swarm-mj tune``
    forks from a single-threaded process; a caller with threads of its own (a notebook kernel)
    gets spawned workers, which never inherit a lock another thread held."""
    forkable = sys.platform.startswith("linux") and "fork" in multiprocessing.get_all_start_methods()
    return "fork" if forkable and threading.active_count() == 1 else "spawn"


__all__ = [
    "InProcessCost",
    "PopulationCost",
    "ProcessPoolCost",
    "RAY_INSTALL_HINT",
    "RayCost",
    "worker_start_method",
    "default_workers",
    "make_population_cost",
]


class PopulationCost(Protocol):
    """A batched cost for :func:`~swarm_mj.tuning.fpa`: ``cost(X (m, 12)) -> (m,)``."""

    backend: str
    workers: int
    threads: int

    def __call__(self, X: np.ndarray) -> np.ndarray: ...

    def close(self) -> None: ...


def _chunks(X: np.ndarray, parts: int) -> list[np.ndarray]:
    """Contiguous, nearly equal, non-empty chunks of the rows of X (m, d), in order."""
    return [c for c in np.array_split(X, min(parts, max(len(X), 1))) if len(c)]


class _Closing:
    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:  # pragma: no cover - overridden
        pass


class InProcessCost(_Closing):
    """The whole population in batched models in this process, flown by ``threads`` threads
    (default: the CPUs this process may use; :class:`~swarm_mj.tuning.evaluator.BatchEvaluator`)."""

    backend = "in-process"
    workers = 1

    def __init__(self, settings: StepCostSettings = StepCostSettings(), threads: int | None = None) -> None:
        self.settings = settings
        self.threads = default_workers() if threads is None else check_count("threads", threads)

    def __call__(self, X: np.ndarray) -> np.ndarray:
        return evaluate_batch(X, self.settings, self.threads)


def _worker_eval(args: tuple[StepCostSettings, np.ndarray, int]) -> np.ndarray:
    settings, X, threads = args
    return evaluate_batch(X, settings, threads)


class _ExecutorCost(_Closing):
    """The population split in ``workers`` contiguous chunks, mapped over an :class:`Executor`
    (kept for every call) and concatenated in chunk order."""

    backend: str
    workers: int
    threads: int = 1  # the evaluator's threads in each worker
    settings: StepCostSettings
    _ex: Executor | None

    def __call__(self, X: np.ndarray) -> np.ndarray:
        if self._ex is None:
            raise RuntimeError(f"this {type(self).__name__} is closed")
        X = np.asarray(X, dtype=float)
        parts = _chunks(X, self.workers)
        results = self._ex.map(_worker_eval, [(self.settings, c, self.threads) for c in parts])
        return np.concatenate(results) if results else np.empty(0)

    def close(self) -> None:
        ex, self._ex = getattr(self, "_ex", None), None
        if ex is not None:
            ex.close()


class ProcessPoolCost(_ExecutorCost):
    """The population split in ``workers`` contiguous chunks, each evaluated by a local worker
    process in its own batched models (built once per worker and chunk size, then reused: the
    workers live as long as this object).

    A worker that dies (e.g. killed) raises ``BrokenProcessPool`` here instead of hanging.
    """

    backend = "processes"

    def __init__(
        self, settings: StepCostSettings = StepCostSettings(), workers: int | None = None, threads: int = 1
    ) -> None:
        self.settings = settings
        self.workers = default_workers() if workers is None else int(workers)
        if self.workers < 1:
            raise UserError(f"workers must be >= 1, got {workers!r}")
        self.threads = check_count("threads", threads)
        self.start_method = worker_start_method()
        self._ex = Executor(self.workers, start_method=self.start_method)


class RayCost(_ExecutorCost):
    """The population split in ``workers`` chunks, each a Ray task evaluating its chunk in the
    batched models cached by the Ray worker process that runs it.

    address: ``"local"`` starts a private Ray instance on this machine (``workers`` CPUs);
    anything else is passed to ``ray.init(address=...)`` (``"auto"``, ``"ray://host:10001"``).
    Every node needs ``swarm-mj[ray]`` installed (same version, for identical results).
    """

    backend = "ray"

    def __init__(
        self,
        settings: StepCostSettings = StepCostSettings(),
        address: str = "local",
        workers: int | None = None,
        threads: int = 1,
    ) -> None:
        if workers is not None and int(workers) < 1:
            raise UserError(f"workers must be >= 1, got {workers!r}")
        self.settings = settings
        self.threads = check_count("threads", threads)
        self._ex = Executor(workers, ray_address=address)
        self.workers = self._ex.workers


def make_population_cost(
    settings: StepCostSettings = StepCostSettings(),
    *,
    workers: int | None = None,
    threads: int | None = None,
    ray_address: str | None = None,
) -> InProcessCost | ProcessPoolCost | RayCost:
    """The batched eq.-(25) cost for :func:`~swarm_mj.tuning.fpa`, on the chosen backend.

    Default (``workers`` and ``threads`` None): one local worker process per usable CPU, started by
    :func:`worker_start_method`, one thread each (in this process where there is one CPU);
    ``workers`` > 1: that many local processes, each with ``threads`` threads (default 1);
    ``workers`` 1, or only ``threads`` given: in this process on ``threads`` threads (default: the
    usable CPUs); ray_address given: Ray (``workers`` actors, default one per cluster CPU;
    ``threads`` each, default 1). Processes beat threads on the tune (docs/physics_step.md, "The
    tuner on every core": the threads hand the GIL over many times per control period).
    The costs are the same whatever the backend, workers and threads.
    Use it as a context manager (or call ``close()``) to stop the workers.
    """
    if workers is not None:
        check_count("workers", workers)
    if threads is not None:
        check_count("threads", threads)
    if ray_address is not None:
        return RayCost(settings, ray_address, workers, threads or 1)
    if workers is None and threads is None:
        workers = default_workers()
    if workers is None or workers == 1:
        return InProcessCost(settings, threads)
    return ProcessPoolCost(settings, int(workers), threads or 1)
