"""ISE cost of paper eq. (25) over the step manoeuvre, for a whole FPA population at once.

The cost of a gain vector α1..α12 (paper Table 4 layout) is

    ISE = ∫_0^t_sim 3e_x² + 3e_y² + e_z² + 2e_φ² + 2e_θ² + e_ψ² dt          (eq. 25)

over the step of SPEC §3 (from rest on the ground at the origin to x = y = z = 1 m,
ψ = 25°, t_sim = 10 s), with the errors sampled at the control period T = 0.01 s
(left rectangle rule, :func:`swarm_mj.metrics.ise`):

* e_x, e_y, e_z = reference − position (m);
* e_φ, e_θ = commanded − actual angle (rad), the commanded angles being the
  controller's φ_d, θ_d of eqs. (21)–(22) at that sample (``Backstepping.att_d``);
* e_ψ = ψ_d − ψ wrapped to [−π, π).

A candidate that diverges gets ``+inf`` (SPEC §6), never an exception: a non-finite state
or input, |roll| or |pitch| beyond ``max_tilt_deg`` (80° by default: a flip, well past the
≈ 51° pitch the step normally reaches, SPEC §2), the drone below ``floor_z`` or farther than
``max_distance`` from the origin.

**One model for the population.** A batch of m candidates flies as m independent drones in
ONE MuJoCo model (``build_world(m, collisions=False)``: contacts off, so the copies may all
start at the same point and fly through each other), stepped by one ``Sim.step`` per control
period with one vectorised ``Backstepping.compute`` (gains (m, 12)). The copies do not
interact: a free body's dynamics depend only on its own state and inputs, so a candidate's
cost does not depend on which batch it is in (tested: batched == alone). A copy that
diverges is parked at rest at the start with zero input for the rest of the run, so that
NaN never reaches MuJoCo (which would reset the *whole* ``MjData`` on a bad acceleration).

**Beyond one process.** :func:`make_population_cost` returns a batched cost ``(m, 12) →
(m,)`` for :func:`swarm_mj.tuning.fpa` that evaluates in-process (``workers=1``), splits
the population over local worker processes (each chunk one batched model), or over a Ray
cluster (``ray_address``; optional extra ``swarm-mj[ray]``). Chunks are contiguous and
results are gathered in order, so the costs — and the whole tune — are the same whatever
the number of workers.
"""

from __future__ import annotations

import math
import multiprocessing as mp
import os
import signal
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any, Protocol

import numpy as np

from ..control.backstepping import TABLE4_GAINS, Backstepping
from ..errors import UserError
from ..metrics import ise
from ..params import DEFAULT_PARAMS, QuadParams
from ..sim import Sim
from ..state import body_rates_to_euler_rates, quat_to_euler, wrap_angle
from ..world import INTEGRATORS, build_world

__all__ = [
    "StepCostSettings",
    "BatchEvaluator",
    "PopulationCost",
    "InProcessCost",
    "ProcessPoolCost",
    "RayCost",
    "RAY_INSTALL_HINT",
    "default_workers",
    "evaluate_batch",
    "make_population_cost",
    "step_ise",
    "table4_ise",
]

RAY_INSTALL_HINT = "pip install 'swarm-mj[ray]'"


# --------------------------------------------------------------------------- settings


@dataclass(frozen=True)
class StepCostSettings:
    """The manoeuvre and the divergence limits of the cost (SPEC §3, §6). Hashable, picklable.

    target (3,) m and yaw_deg: the step set-point; start (3,) m: rest on the ground.
    """

    t_sim: float = 10.0
    control_period: float = 0.01
    timestep: float = 0.005
    integrator: str = "RK4"
    target: tuple[float, float, float] = (1.0, 1.0, 1.0)
    yaw_deg: float = 25.0
    start: tuple[float, float, float] = (0.0, 0.0, 0.0)
    max_tilt_deg: float = 80.0
    floor_z: float = -0.5
    max_distance: float = 100.0
    attitude_map: str = "exact"
    params: QuadParams = field(default=DEFAULT_PARAMS)

    def __post_init__(self) -> None:
        for name in ("t_sim", "control_period", "timestep", "max_tilt_deg", "max_distance"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise UserError(f"{name.replace('_', '-')} must be a positive number, got {v!r}")
        if self.max_tilt_deg >= 90.0:
            raise UserError(f"max-tilt-deg must be below 90, got {self.max_tilt_deg!r}")
        if self.integrator not in INTEGRATORS:
            raise UserError(f"unknown integrator {self.integrator!r}; choose one of {sorted(INTEGRATORS)}")
        if self.attitude_map not in ("exact", "paper"):
            raise UserError(f"attitude_map must be 'exact' or 'paper', got {self.attitude_map!r}")
        object.__setattr__(self, "target", tuple(float(v) for v in self.target))
        object.__setattr__(self, "start", tuple(float(v) for v in self.start))
        if len(self.target) != 3 or len(self.start) != 3:
            raise UserError("target and start must be three numbers (x, y, z) in metres")
        if self.n_samples < 1:
            raise UserError(f"t-sim {self.t_sim} s is shorter than one control period {self.control_period} s")

    @property
    def n_samples(self) -> int:
        """K: control periods simulated (samples of the ISE)."""
        return int(round(self.t_sim / self.control_period))

    def as_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["params"] = asdict(self.params)
        d["target"], d["start"] = list(self.target), list(self.start)
        return d


# --------------------------------------------------------------------------- one batched model


class BatchEvaluator:
    """m independent copies of one drone in ONE MuJoCo model, flying the step together.

    ``evaluate(gains (m, 12)) -> (m,)`` ISE of eq. (25), ``inf`` for a diverged copy.
    The model is built once and reused (``Sim.reset`` between batches).
    """

    def __init__(self, m: int, settings: StepCostSettings = StepCostSettings()) -> None:
        if not isinstance(m, (int, np.integer)) or m < 1:
            raise UserError(f"batch size must be an integer >= 1, got {m!r}")
        s = settings
        self.m = int(m)
        self.settings = s
        starts = np.tile(np.asarray(s.start, float), (self.m, 1))          # (m, 3) all at the same point
        # collisions=False: contacts are off, so the overlapping copies never touch.
        self.world = build_world(self.m, positions=starts, collisions=False, floor=False, params=s.params,
                                 timestep=s.timestep, integrator=s.integrator)
        self.sim = Sim(self.world, s.control_period, floor_z=s.floor_z, max_distance=s.max_distance)
        self.K = s.n_samples
        self._pos_d = np.tile(np.asarray(s.target, float), (self.m, 1))   # (m, 3) step set-point
        self._zero3 = np.zeros((self.m, 3))                                # (m, 3) v_d = a_d = 0
        self._yaw_d = np.full(self.m, np.deg2rad(s.yaw_deg))               # (m,)
        self._max_tilt = np.deg2rad(s.max_tilt_deg)
        self._park_qpos = self.sim.qpos.copy()                             # (m, 7) the start, at rest
        self._errors = np.empty((self.K, self.m, 6))                       # (K, m, 6) e_x..e_ψ
        #: (m,) control period at which each copy of the last batch diverged (-1: never).
        self.diverged_at = np.full(self.m, -1, dtype=np.int64)

    def _kill(self, alive: np.ndarray, bad: np.ndarray, k: int) -> None:
        """Mark copies newly ``bad`` (m,) as diverged at control period k (``alive`` updated in place)."""
        newly = bad & alive
        if newly.any():
            alive &= ~bad
            self.diverged_at[newly] = k

    def evaluate(self, gains: np.ndarray) -> np.ndarray:
        """ISE (m,) of eq. (25) for gains (m, 12); ``inf`` where a copy diverged."""
        g = np.asarray(gains, dtype=float)
        if g.shape != (self.m, 12):
            raise UserError(f"gains must have shape ({self.m}, 12), got {g.shape}")
        m, sim, s = self.m, self.sim, self.settings
        alive = np.isfinite(g).all(axis=1) & (g > 0).all(axis=1)          # (m,)
        self.diverged_at[:] = -1
        self.diverged_at[~alive] = 0
        g = np.where(alive[:, None], g, TABLE4_GAINS)                     # placeholders for the dead
        ctl = Backstepping(m, g, params=s.params, control_period=s.control_period,
                           attitude_map=s.attitude_map)
        sim.reset()
        pos_d, zero3, yaw_d, max_tilt = self._pos_d, self._zero3, self._yaw_d, self._max_tilt
        errors = self._errors
        qpos, qvel, pos = sim.qpos, sim.qvel, sim.pos
        with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
            for k in range(self.K + 1):
                quat, omega = sim.quat, sim.omega
                rpy = quat_to_euler(quat)                                  # (m, 3)
                # Divergence (SPEC §6), on the state at every sample and at the end of the run.
                bad = ~(np.isfinite(qpos).all(axis=1) & np.isfinite(qvel).all(axis=1)
                        & (np.abs(rpy[:, 0]) <= max_tilt) & (np.abs(rpy[:, 1]) <= max_tilt)
                        & (pos[:, 2] >= s.floor_z) & (np.abs(pos) <= s.max_distance).all(axis=1))
                if k == self.K:
                    self._kill(alive, bad, k)
                    break
                rate = body_rates_to_euler_rates(rpy, omega)               # (m, 3)
                U = ctl.compute(rpy, rate, pos, sim.vel, pos_d, zero3, zero3, yaw_d, omega_body=omega)  # (m, 4)
                bad |= ~np.isfinite(U).all(axis=1)
                e = errors[k]                                              # (m, 6)
                np.subtract(pos_d, pos, out=e[:, 0:3])
                np.subtract(ctl.att_d[:, 0:2], rpy[:, 0:2], out=e[:, 3:5])
                e[:, 5] = wrap_angle(yaw_d - rpy[:, 2])
                self._kill(alive, bad, k)
                if not alive.all():
                    if not alive.any():
                        break
                    dead = ~alive
                    U[dead] = 0.0                                          # no input ...
                    qpos[dead] = self._park_qpos[dead]                     # ... parked at rest
                    qvel[dead] = 0.0
                sim.step(U)
        cost = ise(errors, s.control_period)                               # (m,) eq. (25)
        cost[~alive] = np.inf
        cost[~np.isfinite(cost)] = np.inf
        return cost


_EVALUATORS: dict[tuple[StepCostSettings, int], BatchEvaluator] = {}


def evaluate_batch(gains: np.ndarray, settings: StepCostSettings = StepCostSettings()) -> np.ndarray:
    """ISE (m,) for gains (m, 12) in one batched model, reusing a cached model of that size.

    This is what each worker runs on its chunk; in-process it is the whole population.
    """
    g = np.atleast_2d(np.asarray(gains, dtype=float))
    if g.ndim != 2 or g.shape[1] != 12:
        raise UserError(f"gains must have shape (m, 12), got {np.shape(gains)}")
    if g.shape[0] == 0:
        return np.empty(0)
    key = (settings, g.shape[0])
    ev = _EVALUATORS.get(key)
    if ev is None:
        if len(_EVALUATORS) >= 8:   # bounded: a few chunk sizes per tune
            _EVALUATORS.pop(next(iter(_EVALUATORS)))
        ev = _EVALUATORS[key] = BatchEvaluator(g.shape[0], settings)
    return ev.evaluate(g)


def step_ise(gains: np.ndarray, settings: StepCostSettings = StepCostSettings()) -> np.ndarray | float:
    """ISE of eq. (25) over the step for gains (12,) → float, or (m, 12) → (m,) in one batched model."""
    g = np.asarray(gains, dtype=float)
    out = evaluate_batch(g, settings)
    return float(out[0]) if g.ndim == 1 else out


def table4_ise(settings: StepCostSettings = StepCostSettings()) -> float:
    """ISE of the paper's Table 4 gains under the same cost."""
    return float(step_ise(TABLE4_GAINS, settings))


# --------------------------------------------------------------------------- parallel backends


class PopulationCost(Protocol):
    """A batched cost for :func:`~swarm_mj.tuning.fpa`: ``cost(X (m, 12)) -> (m,)``."""

    backend: str
    workers: int

    def __call__(self, X: np.ndarray) -> np.ndarray: ...

    def close(self) -> None: ...


def default_workers() -> int:
    """Local worker processes by default: the CPUs this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


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
    """The whole population in one batched model in this process (``--workers 1``)."""

    backend = "in-process"
    workers = 1

    def __init__(self, settings: StepCostSettings = StepCostSettings()) -> None:
        self.settings = settings

    def __call__(self, X: np.ndarray) -> np.ndarray:
        return evaluate_batch(X, self.settings)


def _worker_init() -> None:
    # Ctrl-C goes to the whole process group: only the parent handles it (and terminates us).
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _worker_eval(args: tuple[StepCostSettings, np.ndarray]) -> np.ndarray:
    settings, X = args
    return evaluate_batch(X, settings)


class ProcessPoolCost(_Closing):
    """The population split in ``workers`` contiguous chunks, one batched model per local process."""

    backend = "processes"

    def __init__(self, settings: StepCostSettings = StepCostSettings(), workers: int | None = None) -> None:
        self.settings = settings
        self.workers = default_workers() if workers is None else int(workers)
        if self.workers < 1:
            raise UserError(f"workers must be >= 1, got {workers!r}")
        ctx = mp.get_context("spawn")    # a fresh interpreter: no inherited MuJoCo or thread state
        self._pool = ctx.Pool(self.workers, initializer=_worker_init)

    def __call__(self, X: np.ndarray) -> np.ndarray:
        X = np.asarray(X, dtype=float)
        parts = _chunks(X, self.workers)
        pending = self._pool.map_async(_worker_eval, [(self.settings, c) for c in parts], chunksize=1)
        while True:   # a timed wait keeps Ctrl-C responsive in the parent
            try:
                results = pending.get(timeout=0.5)
                break
            except mp.TimeoutError:
                continue
        return np.concatenate(results) if results else np.empty(0)

    def close(self) -> None:
        pool, self._pool = getattr(self, "_pool", None), None
        if pool is not None:
            pool.terminate()
            pool.join()


def _import_ray():
    try:
        import ray  # noqa: PLC0415 - optional extra, imported only when asked for
    except ImportError:
        raise UserError(f"--ray needs Ray, which is not installed: {RAY_INSTALL_HINT}") from None
    return ray


class _RayWorker:
    """A Ray actor holding batched models (built once, reused every iteration)."""

    def __init__(self, settings: StepCostSettings) -> None:
        self.settings = settings

    def evaluate(self, X: np.ndarray) -> np.ndarray:
        return evaluate_batch(X, self.settings)


class RayCost(_Closing):
    """The population split over Ray actors, one batched model each.

    address: ``"local"`` starts a private Ray instance on this machine (``workers`` CPUs);
    anything else is passed to ``ray.init(address=...)`` (``"auto"``, ``"ray://host:10001"``).
    Every node needs ``swarm-mj[ray]`` installed (same version, for identical results).
    """

    backend = "ray"

    def __init__(self, settings: StepCostSettings = StepCostSettings(), address: str = "local",
                 workers: int | None = None) -> None:
        ray = _import_ray()
        self._ray = ray
        self.settings = settings
        self._started = False
        if not ray.is_initialized():
            try:
                if address == "local":
                    ray.init(num_cpus=workers or default_workers(), include_dashboard=False,
                             log_to_driver=False, configure_logging=False)
                else:
                    ray.init(address=address, log_to_driver=False, configure_logging=False)
            except Exception as exc:  # connection refused, bad address, ...
                raise UserError(f"cannot start or reach the Ray cluster at {address!r}: {exc}") from None
            self._started = True
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


def make_population_cost(settings: StepCostSettings = StepCostSettings(), *, workers: int | None = None,
                         ray_address: str | None = None) -> InProcessCost | ProcessPoolCost | RayCost:
    """The batched eq.-(25) cost for :func:`~swarm_mj.tuning.fpa`, on the chosen backend.

    ray_address given: Ray (``workers`` actors, default one per cluster CPU);
    else ``workers`` local processes (default: the CPUs available), ``workers=1`` in-process.
    Use it as a context manager (or call ``close()``) to stop the workers.
    """
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, (int, np.integer))
                                or workers < 1):
        raise UserError(f"workers must be an integer >= 1, got {workers!r}")
    if ray_address is not None:
        return RayCost(settings, ray_address, workers)
    w = default_workers() if workers is None else int(workers)
    if w == 1:
        return InProcessCost(settings)
    return ProcessPoolCost(settings, w)


# --------------------------------------------------------------------------- helpers for callers


def split_sizes(m: int, parts: int) -> Sequence[int]:
    """Sizes of the contiguous chunks a population of m is split into over ``parts`` workers."""
    return [len(c) for c in _chunks(np.empty((m, 0)), parts)]


Evaluator = Callable[[np.ndarray], np.ndarray]
