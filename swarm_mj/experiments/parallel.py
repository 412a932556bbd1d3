"""The one executor for experiments, and what the parallel backends share.

:func:`map_ordered` is ``[fn(x) for x in items]`` spread over worker processes, or over a Ray
cluster, with the results in item order. The sweeps, the stress test and the report run through
it (``sweep``, ``stress``, ``report``); :class:`Executor` is the same with workers kept alive
across calls, which the tuner's backends (``tuning.backends``) map the population's chunks over
once per FPA iteration. Both guarantee:

* **spawn** start method: each worker is a fresh interpreter (no inherited MuJoCo, Numba or
  thread state, the same on Linux and macOS);
* **CPU affinity**: the default worker count is the CPUs this process may use
  (``os.sched_getaffinity``), not the machine's count, so a ``taskset`` or a container quota is
  respected;
* **Ctrl-C**: workers ignore SIGINT (it reaches the whole process group); the parent alone
  handles it, cancels what is queued, terminates its own workers by handle and re-raises
  :class:`KeyboardInterrupt`, which the command line turns into exit status 130;
* **ordered, deterministic results**: each item's result depends only on the item, and the list
  comes back in item order whatever the completion order, so results do not depend on the number
  of workers or the backend;
* **optional progress**: a :class:`~swarm_mj.output.progress.Progress` that says what it waits for while the
  workers start and is advanced once per completed item,
  and ``on_result(index, result)`` called in this process in completion order (e.g. to print a line).

``fn`` must be a module-level function (it is pickled by reference), and, as with any spawn
pool, a script that starts workers needs the ``if __name__ == "__main__":`` guard.

:class:`ThreadTeam` is the same idea on threads of this process, for the copies axis: one function
over a few parts (the tuner's groups of candidates, the vector environment's groups of model
blocks), the first part on the calling thread, the others on a pool of threads; it returns when
every part is done. Each part touches only its own models and rows, so the results are the same
bit for bit whatever the number of threads (MuJoCo's ``mj_step`` and the ``nogil`` kernels release
the GIL, so the parts' physics runs on as many cores).
"""

from __future__ import annotations

import os
import platform
import signal
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np

from ..errors import UserError

if TYPE_CHECKING:
    from ..output.progress import Progress

T = TypeVar("T")
R = TypeVar("R")

RAY_INSTALL_HINT = "pip install 'swarm-mj[ray]'"


def default_workers() -> int:
    """Local worker processes by default: the CPUs this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def check_count(name: str, v: Any) -> int:
    """``v`` as an int if it is an integer >= 1 (a count of workers, threads, copies); else one UserError line."""
    if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
        raise UserError(f"{name} must be an integer >= 1, got {v!r}")
    return int(v)


#: Memory (bytes) one run of a many-run request holds to the end: its item (a stress case, a sweep
#: task) and its result row, about 2.5 KiB each measured (tracemalloc), with room for a contact log
#: and the JSON written at the end.
BYTES_PER_RUN = 16 * 1024


def check_run_count(n_runs: int, where: str) -> None:
    """``n_runs`` runs' items and results (:data:`BYTES_PER_RUN` each) fit in the share of the available
    memory a run's log may take (:data:`~swarm_mj.scenario.MEMORY_SHARE`), checked before they are
    built: one :class:`UserError` naming ``where`` otherwise (``stress --starts 4000000000``)."""
    from ..scenario import MEMORY_SHARE, available_memory_bytes

    need = n_runs * BYTES_PER_RUN
    avail = available_memory_bytes()
    if avail is not None and need > MEMORY_SHARE * avail:
        raise UserError(
            f"{n_runs:.3g} runs would hold about {need / 2**30:.3g} GiB to the end, more than "
            f"{MEMORY_SHARE:.0%} of the {avail / 2**30:.3g} GiB of memory available: fly fewer",
            where=where,
        )


class ThreadTeam:
    """``threads`` threads running one function over parts (module docstring): :meth:`run` calls
    ``fn(part)`` for each part, the first on the calling thread and the others on a pool of
    ``threads`` - 1 threads, started at the first run with more than one part and kept until
    :meth:`close` (or until the team is garbage-collected: an idle pool's threads then end). A
    ``with`` block closes it, so that no thread outlives it (the tuner: a process that forks workers
    must have no other thread, see ``tuning.backends.worker_start_method``)."""

    def __init__(self, threads: int, name: str = "swarm-mj") -> None:
        self.threads = check_count("threads", threads)
        self.name = name
        self._pool: ThreadPoolExecutor | None = None

    def run(self, fn: Callable[[T], object], parts: Sequence[T]) -> None:
        """``fn(part)`` for every part (at most ``threads`` of them), each on its own thread; returns when
        every call has ended, and raises the exception of the first part (in order) that raised."""
        if len(parts) > self.threads:
            raise ValueError(f"{len(parts)} parts for {self.threads} threads")
        if len(parts) <= 1:
            for part in parts:
                fn(part)
            return
        if self._pool is None:
            self._pool = ThreadPoolExecutor(self.threads - 1, thread_name_prefix=self.name)
        futures = [self._pool.submit(fn, part) for part in parts[1:]]
        try:
            fn(parts[0])
        finally:
            for f in futures:  # every call has ended when this returns or raises
                f.exception()
        for f in futures:
            f.result()

    def close(self) -> None:
        """End the pool's threads (waits for them); the team starts a new pool if it runs again."""
        if self._pool is not None:
            self._pool.shutdown(wait=True)
            self._pool = None

    def __enter__(self) -> ThreadTeam:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def import_ray():
    """The ``ray`` module, or one clear UserError naming the extra to install."""
    try:
        import ray  # noqa: PLC0415 - optional extra, imported only when asked for
    except ImportError:
        raise UserError(f"--ray needs Ray, which is not installed: {RAY_INSTALL_HINT}") from None
    return ray


def init_ray(ray, address: str, workers: int | None = None) -> bool:
    """Start a local Ray (``address == "local"``) or connect to a cluster, unless one is up.

    Returns True when this call started it (the caller then shuts it down).
    """
    if ray.is_initialized():
        return False
    try:
        if address == "local":
            ray.init(
                num_cpus=workers or default_workers(),
                include_dashboard=False,
                log_to_driver=False,
                configure_logging=False,
            )
        else:
            ray.init(address=address, log_to_driver=False, configure_logging=False)
    except Exception as exc:  # noqa: BLE001 - connection refused, bad address, ...
        raise UserError(f"cannot start or reach the Ray cluster at {address!r}: {exc}") from None
    return True


def machine_description() -> dict[str, Any]:
    """CPU model, cores, Python / MuJoCo / NumPy versions and platform of this machine."""
    import mujoco

    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {
        "cpu": cpu,
        "cores": os.cpu_count(),
        "usable_cores": default_workers(),
        "python": platform.python_version(),
        "mujoco": mujoco.__version__,
        "numpy": np.__version__,
        "platform": platform.platform(),
    }


# --------------------------------------------------------------------------- the executor


def _worker_init() -> None:
    """Worker initializer: Ctrl-C reaches the whole process group; only the parent handles it."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def resolve_workers(workers: int | None, n_items: int | None = None) -> int:
    """The worker count: ``workers`` (>= 1, else one clear UserError) or :func:`default_workers`,
    at most ``n_items``."""
    w = default_workers() if workers is None else int(workers)
    if w < 1:
        raise UserError(f"--workers must be >= 1, got {workers}")
    return max(1, min(w, n_items)) if n_items is not None else w


def backend_name(workers: int, ray_address: str | None) -> str:
    """``"ray"``, ``"in-process"`` (one worker) or ``"processes"``."""
    return "ray" if ray_address else ("in-process" if workers == 1 else "processes")


def map_ordered(
    fn: Callable[[T], R],
    items: Iterable[T],
    *,
    workers: int | None = None,
    ray_address: str | None = None,
    progress: Progress | None = None,
    on_result: Callable[[int, R], None] | None = None,
) -> list[R]:
    """``[fn(x) for x in items]`` in worker processes (or on Ray), results in item order.

    ``workers``: local processes (default: the CPUs this process may use, at most one per item;
    1 runs in this process, with no pool). ``ray_address``: ``"local"``, ``"auto"`` or
    ``"ray://host:port"`` runs the items as Ray tasks instead (extra ``swarm-mj[ray]``).
    ``progress`` is advanced and ``on_result(index, result)`` called as each item completes.
    Ctrl-C stops the workers and propagates as KeyboardInterrupt. The workers last this one call;
    :class:`Executor` keeps them across calls.
    """
    items = list(items)
    if not items:
        return []
    if ray_address and progress is not None:
        progress.note(f"starting or reaching Ray at {ray_address}")
    w = workers if ray_address else resolve_workers(workers, len(items))
    with Executor(w, ray_address=ray_address) as ex:
        return ex.map(fn, items, progress=progress, on_result=on_result)


class Executor:
    """:func:`map_ordered` with workers kept alive across calls (the same guarantees: spawn, CPU
    affinity, SIGINT-shielded workers, ordered results, optional Ray).

    For a caller that maps many times, e.g. the tuner, once per FPA iteration: each worker starts
    (and builds whatever it caches, such as batched models) once, not once per call. Local worker
    processes start on the first :meth:`map`; Ray is started or reached at construction. Use it as
    a context manager, or call :meth:`close`, to stop the workers (and a Ray instance it started).
    After Ctrl-C or a failed item inside :meth:`map` the local workers are terminated at once; a
    later :meth:`map` starts fresh ones.

    ``workers``: local processes (default: the CPUs this process may use; 1 runs in this process,
    with no pool); with ``ray_address``, the worker count reported in :attr:`workers` (default:
    the cluster's CPUs). ``start_method``: how local workers start (``"spawn"``, the default: a
    fresh interpreter; ``"fork"``: a copy of this process, with its imports and compiled kernels
    already loaded, for a caller whose process holds no threads or GL context, e.g. the tuner).
    """

    def __init__(
        self, workers: int | None = None, *, ray_address: str | None = None, start_method: str = "spawn"
    ) -> None:
        self.ray_address = ray_address
        self.start_method = start_method
        self._pool: Any = None
        self._ray: Any = None
        self._ray_started = False
        self._remote: dict[Callable, Any] = {}
        self._closed = False
        if ray_address:
            if workers is not None and int(workers) < 1:
                raise UserError(f"--workers must be >= 1, got {workers}")
            ray = import_ray()
            self._ray_started = init_ray(ray, ray_address, workers)
            self._ray = ray
            self.workers = int(workers) if workers else max(1, int(ray.cluster_resources().get("CPU", 1)))
        else:
            self.workers = resolve_workers(workers)

    @property
    def backend(self) -> str:
        """``"ray"``, ``"in-process"`` or ``"processes"`` (:func:`backend_name`)."""
        return backend_name(self.workers, self.ray_address)

    def __enter__(self) -> Executor:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def map(
        self,
        fn: Callable[[T], R],
        items: Iterable[T],
        *,
        progress: Progress | None = None,
        on_result: Callable[[int, R], None] | None = None,
    ) -> list[R]:
        """``[fn(x) for x in items]`` on this executor's workers, results in item order
        (``progress`` and ``on_result`` as in :func:`map_ordered`)."""
        if self._closed:
            raise RuntimeError("this Executor is closed")
        items = list(items)
        results: list[Any] = [None] * len(items)
        if not items:
            return results

        def done(i: int, r: Any) -> None:
            results[i] = r
            if progress is not None:
                progress.advance()
            if on_result is not None:
                on_result(i, r)

        if self._ray is not None:
            self._map_ray(fn, items, done)
        elif self.workers == 1:
            for i, x in enumerate(items):
                done(i, fn(x))
        else:
            self._map_processes(fn, items, progress, done)
        return results

    def _map_processes(
        self, fn: Callable, items: list, progress: Progress | None, done: Callable[[int, Any], None]
    ) -> None:
        import multiprocessing as mp
        from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

        if self._pool is None:
            if progress is not None:
                progress.note(f"starting {self.workers} worker processes (each loads MuJoCo and the compiled kernels)")
            self._pool = ProcessPoolExecutor(
                max_workers=self.workers, mp_context=mp.get_context(self.start_method), initializer=_worker_init
            )
        ok = False
        try:
            futs = {self._pool.submit(fn, x): i for i, x in enumerate(items)}
            pending = set(futs)
            while pending:
                finished, pending = wait(pending, return_when=FIRST_COMPLETED)
                for f in sorted(finished, key=lambda f: futs[f]):
                    done(futs[f], f.result())
            ok = True
        finally:
            if not ok:  # Ctrl-C or a failed item: stop now, not after the queue
                self._terminate_pool()

    def _terminate_pool(self) -> None:
        pool, self._pool = self._pool, None
        if pool is None:
            return
        procs = list((getattr(pool, "_processes", None) or {}).values())
        pool.shutdown(wait=False, cancel_futures=True)
        for p in procs:  # our own workers, by handle
            if p.is_alive():
                p.terminate()
        for p in procs:
            p.join(timeout=5)

    def _map_ray(self, fn: Callable, items: list, done: Callable[[int, Any], None]) -> None:
        ray = self._ray
        remote = self._remote.get(fn)
        if remote is None:
            remote = self._remote[fn] = ray.remote(num_cpus=1)(fn)
        refs = [remote.remote(x) for x in items]
        index = {r: i for i, r in enumerate(refs)}
        pending = list(refs)
        while pending:
            finished, pending = ray.wait(pending, num_returns=1)
            for r in finished:
                done(index[r], ray.get(r))

    def close(self) -> None:
        """Stop the local workers (without waiting for running items) and shut down a Ray
        instance this executor started."""
        self._closed = True
        pool, self._pool = self._pool, None
        if pool is not None:
            pool.shutdown(wait=True, cancel_futures=True)
        self._remote.clear()
        ray, self._ray = self._ray, None
        if ray is not None and self._ray_started and ray.is_initialized():
            ray.shutdown()
        self._ray_started = False
