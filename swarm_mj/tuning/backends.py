"""Where the tuner's population is evaluated: in this process, in local worker processes or on a
Ray cluster (:func:`make_population_cost`).

Each backend is a batched cost ``(m, 12) → (m,)`` for :func:`swarm_mj.tuning.fpa.fpa`; each worker
runs :func:`~swarm_mj.tuning.evaluator.evaluate_batch` on a contiguous chunk, and results are
gathered in order, so the costs — and the whole tune — are the same whatever the number of
workers (optional extra ``swarm-mj[ray]`` for Ray).
"""

from __future__ import annotations

import multiprocessing as mp
import signal
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures import TimeoutError as FuturesTimeout
from typing import Protocol

import numpy as np

from ..errors import UserError
from ..parallel import RAY_INSTALL_HINT, default_workers, import_ray, init_ray
from .evaluator import StepCostSettings, evaluate_batch

__all__ = [
    "InProcessCost",
    "PopulationCost",
    "ProcessPoolCost",
    "RAY_INSTALL_HINT",
    "RayCost",
    "default_workers",
    "make_population_cost",
]


class PopulationCost(Protocol):
    """A batched cost for :func:`~swarm_mj.tuning.fpa`: ``cost(X (m, 12)) -> (m,)``."""

    backend: str
    workers: int

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
    """The whole population in batched models in this process (``--workers 1``)."""

    backend = "in-process"
    workers = 1

    def __init__(self, settings: StepCostSettings = StepCostSettings()) -> None:
        self.settings = settings

    def __call__(self, X: np.ndarray) -> np.ndarray:
        return evaluate_batch(X, self.settings)


def _worker_init() -> None:
    # Ctrl-C goes to the whole process group: only the parent handles it (and terminates us).
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _pool_context() -> mp.context.BaseContext:
    """``fork`` where the platform has it: the workers start at once, inherit the compiled
    kernels, and a script calling :func:`tune_gains` needs no ``if __name__ == "__main__"``
    guard. Each worker builds its own MuJoCo models after the fork (none is shared).
    Elsewhere ``spawn``."""
    methods = mp.get_all_start_methods()
    return mp.get_context("fork" if "fork" in methods else "spawn")


def _worker_eval(args: tuple[StepCostSettings, np.ndarray]) -> np.ndarray:
    settings, X = args
    return evaluate_batch(X, settings)


class ProcessPoolCost(_Closing):
    """The population split in ``workers`` contiguous chunks, each evaluated by a local worker
    process in its own batched models (built once per worker and chunk size, then reused).

    A worker that dies (e.g. killed) raises ``BrokenProcessPool`` here instead of hanging.
    """

    backend = "processes"

    def __init__(self, settings: StepCostSettings = StepCostSettings(), workers: int | None = None) -> None:
        self.settings = settings
        self.workers = default_workers() if workers is None else int(workers)
        if self.workers < 1:
            raise UserError(f"workers must be >= 1, got {workers!r}")
        self._pool: ProcessPoolExecutor | None = ProcessPoolExecutor(
            self.workers, mp_context=_pool_context(), initializer=_worker_init
        )

    def __call__(self, X: np.ndarray) -> np.ndarray:
        if self._pool is None:
            raise RuntimeError("this ProcessPoolCost is closed")
        X = np.asarray(X, dtype=float)
        futures = [self._pool.submit(_worker_eval, (self.settings, c)) for c in _chunks(X, self.workers)]
        results = []
        for f in futures:  # in chunk order: the same result whatever the timing
            while True:  # a timed wait keeps Ctrl-C responsive in the parent
                try:
                    results.append(f.result(timeout=0.5))
                    break
                except FuturesTimeout:
                    continue
        return np.concatenate(results) if results else np.empty(0)

    def close(self) -> None:
        pool, self._pool = getattr(self, "_pool", None), None
        if pool is None:
            return
        procs = list((getattr(pool, "_processes", None) or {}).values())
        pool.shutdown(wait=False, cancel_futures=True)
        for proc in procs:  # do not wait for chunks still running (Ctrl-C)
            if proc.is_alive():
                proc.terminate()
        for proc in procs:
            proc.join(timeout=5)


class _RayWorker:
    """A Ray actor holding batched models (built once, reused every iteration)."""

    def __init__(self, settings: StepCostSettings) -> None:
        self.settings = settings

    def evaluate(self, X: np.ndarray) -> np.ndarray:
        return evaluate_batch(X, self.settings)


class RayCost(_Closing):
    """The population split over Ray actors, each evaluating its chunk in its own batched models.

    address: ``"local"`` starts a private Ray instance on this machine (``workers`` CPUs);
    anything else is passed to ``ray.init(address=...)`` (``"auto"``, ``"ray://host:10001"``).
    Every node needs ``swarm-mj[ray]`` installed (same version, for identical results).
    """

    backend = "ray"

    def __init__(
        self, settings: StepCostSettings = StepCostSettings(), address: str = "local", workers: int | None = None
    ) -> None:
        ray = import_ray()
        self._ray = ray
        self.settings = settings
        self._started = init_ray(ray, address, workers)
        cpus = int(ray.cluster_resources().get("CPU", 1))
        self.workers = int(workers) if workers else max(1, cpus)
        if self.workers < 1:
            raise UserError(f"workers must be >= 1, got {workers!r}")
        actor = ray.remote(num_cpus=1)(_RayWorker)
        self._actors = [actor.remote(settings) for _ in range(self.workers)]

    def __call__(self, X: np.ndarray) -> np.ndarray:
        X = np.asarray(X, dtype=float)
        parts = _chunks(X, self.workers)
        refs = [a.evaluate.remote(c) for a, c in zip(self._actors, parts)]
        results = self._ray.get(refs)
        return np.concatenate(results) if results else np.empty(0)

    def close(self) -> None:
        ray = self._ray
        for a in getattr(self, "_actors", []):
            try:
                ray.kill(a)
            except Exception:  # already gone
                pass
        self._actors = []
        if self._started and ray.is_initialized():
            ray.shutdown()
            self._started = False


def make_population_cost(
    settings: StepCostSettings = StepCostSettings(), *, workers: int | None = None, ray_address: str | None = None
) -> InProcessCost | ProcessPoolCost | RayCost:
    """The batched eq.-(25) cost for :func:`~swarm_mj.tuning.fpa`, on the chosen backend.

    ray_address given: Ray (``workers`` actors, default one per cluster CPU);
    else ``workers`` local processes (default: the CPUs available), ``workers=1`` in-process.
    Use it as a context manager (or call ``close()``) to stop the workers.
    """
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, (int, np.integer)) or workers < 1):
        raise UserError(f"workers must be an integer >= 1, got {workers!r}")
    if ray_address is not None:
        return RayCost(settings, ray_address, workers)
    w = default_workers() if workers is None else int(workers)
    if w == 1:
        return InProcessCost(settings)
    return ProcessPoolCost(settings, w)
