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

**The step bars as constraints** (default, ``StepCostSettings.bars``; :mod:`.constraints`).
The ISE alone weighs a slow tail lightly (seed 1 on it alone: y settles in 2.05 s, past the
controller's 2.0 s bar), so by default the tune ranks candidates by Deb's feasibility rules:
those meeting the bars (overshoot, 2 % settling, steady-state error, tilt, measured from the
same run as the ISE with the definitions of ``swarm-mj run step``'s summary) by ISE, before
those that do not, by how far they miss. ``bars=None`` is eq. (25) alone, as in the paper.

**Batched models, one controller call.** A batch of m candidates flies as m independent
drones built by ``build_world(b, collisions=False)`` — contacts off, so the copies all start
at the same point and fly through each other — in blocks of at most :data:`DEFAULT_BLOCK`
copies per MuJoCo model (MuJoCo's site motors cost O(copies²) per model; see there), each
block stepped by one ``Sim.step`` per control period, all m driven by ONE vectorised
``Backstepping.compute`` (gains (m, 12)). The copies
do not interact: a free body's dynamics depend only on its own state and inputs, so a
candidate's cost does not depend on its batch, block or worker (tested: batched == alone,
bit for bit on the development machine; and == eq. (25) from ``runner.run`` to 1e-9). A copy
that diverges is parked at rest at the start with zero input for the rest of the run, so
that NaN never reaches MuJoCo (which resets the *whole* ``MjData`` on a bad acceleration).

**Beyond one process.** :func:`make_population_cost` returns a batched cost ``(m, 12) →
(m,)`` for :func:`swarm_mj.tuning.fpa` that evaluates in-process (``workers=1``), splits
the population over local worker processes (each chunk its own batched models), or over a Ray
cluster (``ray_address``; optional extra ``swarm-mj[ray]``). Chunks are contiguous and
results are gathered in order, so the costs — and the whole tune — are the same whatever
the number of workers.
"""

from __future__ import annotations

import math
import multiprocessing as mp
import signal
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures import TimeoutError as FuturesTimeout
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from typing import Any, Protocol

import mujoco
import numpy as np

from ..control.backstepping import TABLE4_GAINS, Backstepping
from ..errors import UserError
from ..metrics import ise, step_metrics_batch
from ..parallel import RAY_INSTALL_HINT, default_workers, import_ray, init_ray  # noqa: F401 (re-exported)
from ..params import DEFAULT_PARAMS, QuadParams
from ..sim import Sim
from .._jit import jit
from ..kernels import drone_state
from ..state import _body_rates_to_euler_rates, _quat_to_euler
from ..world import INTEGRATORS, build_world
from .constraints import AXES, StepBars, decode_cost, ranked_cost, step_violation
from .fpa import FPAResult, fpa

__all__ = [
    "StepCostSettings",
    "TuneOptions",
    "TuneOutcome",
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
    #: the step bars as constraints of the tune (Deb's rules, :mod:`.constraints`); None: ISE only
    bars: StepBars | None = field(default=StepBars())

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
        if self.bars is not None:
            longest = max(self.bars.settling(ax) for ax in AXES)
            if self.t_sim < longest:
                raise UserError(f"t-sim {self.t_sim:g} s is shorter than the longest settling bar ({longest:g} s): "
                                f"no candidate could meet the step bars; give a longer t-sim or --constraints none")

    @property
    def n_samples(self) -> int:
        """K: control periods simulated (samples of the ISE)."""
        return int(round(self.t_sim / self.control_period))

    def as_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["params"] = asdict(self.params)
        d["bars"] = None if self.bars is None else self.bars.as_dict()
        d["target"], d["start"] = list(self.target), list(self.start)
        return d


# --------------------------------------------------------------------------- one batched model


#: Copies per MuJoCo model. MuJoCo's site transmission (the thrust motor U1 on the site
#: "com"; U2..U4 are on the free joint, see ``build_world(torque_motors=...)``) builds a dense
#: 3×nv Jacobian per actuator and forward pass, i.e. O(m²) work for m copies in one model. A
#: batch is therefore flown as blocks of at most this many copies, each its own model and
#: ``Sim``, all driven by ONE vectorised controller call (measured per batch of 50: blocks of
#: 13–25 copies cost the same, one model of 50 20 % more).
DEFAULT_BLOCK = 20


@jit
def _sample_kernel(qpos: np.ndarray, qvel: np.ndarray, k: int, track: np.ndarray, tilt: np.ndarray,
                   max_tilt: float, floor_z: float, max_distance: float):
    """One sample of the batch, all copies in one pass: Euler angles rpy (m, 3) and rates (m, 3)
    from qpos (m, 7), qvel (m, 6) (the conversions of :mod:`swarm_mj.state`); records x, y, z, ψ
    in track[k] (m, 4) and the running max |roll|, |pitch| in tilt (m,); returns bad (m,): a
    non-finite state, a tilt beyond max_tilt, below floor_z or beyond max_distance (SPEC §6)."""
    m = qpos.shape[0]
    rpy = _quat_to_euler(qpos[:, 3:7])
    bad = np.zeros(m, dtype=np.bool_)
    for i in range(m):
        ok = (drone_state(qpos, qvel, i, floor_z, max_distance) == 0
              and abs(rpy[i, 0]) <= max_tilt and abs(rpy[i, 1]) <= max_tilt)
        for j in range(3):
            track[k, i, j] = qpos[i, j]
        track[k, i, 3] = rpy[i, 2]
        t = max(abs(rpy[i, 0]), abs(rpy[i, 1]))
        if not t <= tilt[i]:              # NaN propagates, like np.maximum
            tilt[i] = t
        bad[i] = not ok
    rate = _body_rates_to_euler_rates(rpy, qvel[:, 3:6])
    return rpy, rate, bad


@jit
def _error_kernel(pos_d: np.ndarray, qpos: np.ndarray, att_d: np.ndarray, rpy: np.ndarray, yaw_d: np.ndarray,
                  U: np.ndarray, e: np.ndarray, bad: np.ndarray) -> None:
    """The errors of eq. (25) at one sample, e (m, 6) = (p_d − p, φ_d − φ, θ_d − θ, wrap(ψ_d − ψ));
    marks copies with a non-finite input U (m, 4) as bad (m,)."""
    for i in range(qpos.shape[0]):
        for j in range(3):
            e[i, j] = pos_d[i, j] - qpos[i, j]
        e[i, 3] = att_d[i, 0] - rpy[i, 0]
        e[i, 4] = att_d[i, 1] - rpy[i, 1]
        e[i, 5] = (yaw_d[i] - rpy[i, 2] + np.pi) % (2.0 * np.pi) - np.pi     # wrap to [−π, π)
        for j in range(4):
            if not np.isfinite(U[i, j]):
                bad[i] = True


class BatchEvaluator:
    """m independent copies of one drone flying the step together, in blocks of ONE model each.

    ``evaluate(gains (m, 12)) -> (m,)`` ISE of eq. (25), ``inf`` for a diverged copy; after it,
    ``step`` holds each copy's step metrics (``{axis: {overshoot_pct, settling_s,
    steady_state_error}}``, (m,) arrays, the definitions of ``swarm-mj run step``'s summary),
    ``max_tilt_deg`` (m,) its largest |roll| or |pitch| and ``violation`` (m,) its violation of
    ``settings.bars`` (0: all met). ``ranked(gains)`` is the cost the tune minimises: the ISE,
    ranked by Deb's feasibility rules when ``settings.bars`` is set (:mod:`.constraints`).
    The models are built once and reused (``Sim.reset`` between batches). ``block`` copies
    at most per model (see :data:`DEFAULT_BLOCK`); ``block >= m`` gives one model for all.
    """

    def __init__(self, m: int, settings: StepCostSettings = StepCostSettings(), *,
                 block: int = DEFAULT_BLOCK) -> None:
        if not isinstance(m, (int, np.integer)) or m < 1:
            raise UserError(f"batch size must be an integer >= 1, got {m!r}")
        if not isinstance(block, (int, np.integer)) or block < 1:
            raise UserError(f"block must be an integer >= 1, got {block!r}")
        s = settings
        self.m = int(m)
        self.settings = s
        n_blocks = -(-self.m // int(block))
        sizes = [len(c) for c in np.array_split(np.arange(self.m), n_blocks)]
        bounds = np.cumsum([0] + sizes)
        self.slices = [slice(int(a), int(b)) for a, b in zip(bounds[:-1], bounds[1:])]
        worlds = {}
        self.sims: list[Sim] = []
        for b in sizes:
            if b not in worlds:
                starts = np.tile(np.asarray(s.start, float), (b, 1))        # (b, 3) all at the same point
                # collisions=False: contacts are off, so the overlapping copies never touch.
                worlds[b] = build_world(b, positions=starts, collisions=False, floor=False, params=s.params,
                                        timestep=s.timestep, integrator=s.integrator)
            self.sims.append(Sim(worlds[b], s.control_period, floor_z=s.floor_z, max_distance=s.max_distance))
        self.K = s.n_samples
        self._pos_d = np.tile(np.asarray(s.target, float), (self.m, 1))   # (m, 3) step set-point
        self._zero3 = np.zeros((self.m, 3))                                # (m, 3) v_d = a_d = 0
        self._yaw_d = np.full(self.m, np.deg2rad(s.yaw_deg))               # (m,)
        self._max_tilt = np.deg2rad(s.max_tilt_deg)
        self._park_qpos = np.concatenate([sim.qpos for sim in self.sims])  # (m, 7) the start, at rest
        self._qpos = np.empty((self.m, 7))                                 # (m, 7) gathered state
        self._qvel = np.empty((self.m, 6))                                 # (m, 6)
        self._errors = np.empty((self.K, self.m, 6))                       # (K, m, 6) e_x..e_ψ
        self._track = np.zeros((self.K + 1, self.m, 4))                    # (K+1, m, 4) x, y, z, ψ
        self._t = np.arange(self.K + 1) * s.control_period                 # (K+1,) sample times
        self.max_tilt_deg = np.zeros(self.m)                               # (m,) of the last batch
        self.violation = np.zeros(self.m)                                  # (m,) of the last batch
        self.step: dict[str, dict[str, np.ndarray]] = {}
        #: (m,) control period at which each copy of the last batch diverged (-1: never).
        self.diverged_at = np.full(self.m, -1, dtype=np.int64)

    def _gather(self) -> tuple[np.ndarray, np.ndarray]:
        """Current qpos (m, 7) and qvel (m, 6) of all copies (views when there is one block)."""
        if len(self.sims) == 1:
            return self.sims[0].qpos, self.sims[0].qvel
        np.concatenate([sim.qpos for sim in self.sims], out=self._qpos)
        np.concatenate([sim.qvel for sim in self.sims], out=self._qvel)
        return self._qpos, self._qvel

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
        m, s = self.m, self.settings
        alive = np.isfinite(g).all(axis=1) & (g > 0).all(axis=1)          # (m,)
        self.diverged_at[:] = -1
        self.diverged_at[~alive] = 0
        g = np.where(alive[:, None], g, TABLE4_GAINS)                     # placeholders for the dead
        ctl = Backstepping(m, g, params=s.params, control_period=s.control_period,
                           attitude_map=s.attitude_map)
        for sim in self.sims:
            sim.reset()
        pos_d, zero3, yaw_d, max_tilt = self._pos_d, self._zero3, self._yaw_d, self._max_tilt
        errors, track = self._errors, self._track
        tilt = np.zeros(m)                                                 # (m,) max |roll|, |pitch| (rad)
        blocks = list(zip(self.sims, self.slices))
        with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
            for k in range(self.K + 1):
                qpos, qvel = self._gather()
                # Angles, rates, the record of x, y, z, ψ and divergence (SPEC §6) at every sample
                # and at the end of the run.
                rpy, rate, bad = _sample_kernel(qpos, qvel, k, track, tilt, max_tilt, s.floor_z, s.max_distance)
                if k == self.K:
                    self._kill(alive, bad, k)
                    break
                pos, vel, omega = qpos[:, 0:3], qvel[:, 0:3], qvel[:, 3:6]
                U = ctl.compute(rpy, rate, pos, vel, pos_d, zero3, zero3, yaw_d, omega_body=omega)  # (m, 4)
                _error_kernel(pos_d, qpos, ctl.att_d, rpy, yaw_d, U, errors[k], bad)
                self._kill(alive, bad, k)
                if not alive.all():
                    if not alive.any():
                        break
                    dead = ~alive
                    U[dead] = 0.0                                          # no input ...
                    for sim, sl in blocks:                                 # ... parked at rest
                        d = dead[sl]
                        if d.any():
                            sim.qpos[d] = self._park_qpos[sl][d]
                            sim.qvel[d] = 0.0
                for sim, sl in blocks:
                    sim.step(U[sl])
        cost = ise(errors, s.control_period)                               # (m,) eq. (25)
        cost[~alive] = np.inf
        cost[~np.isfinite(cost)] = np.inf
        self.max_tilt_deg = np.where(alive, np.rad2deg(tilt), np.inf)
        with np.errstate(invalid="ignore", over="ignore"):
            target = (*s.target, np.deg2rad(s.yaw_deg))
            self.step = {ax: {key: np.where(alive, v, np.nan) for key, v in
                              step_metrics_batch(self._t, track[:, :, i], target[i], track[0, :, i]).items()}
                         for i, ax in enumerate(AXES)}
            bars = s.bars if s.bars is not None else StepBars()
            self.violation = np.where(alive, step_violation(self.step, self.max_tilt_deg, bars, s.t_sim), np.inf)
        return cost

    def ranked(self, gains: np.ndarray) -> np.ndarray:
        """The tune's cost (m,): ISE of eq. (25), ranked by Deb's rules on ``settings.bars`` if set."""
        cost = self.evaluate(gains)
        return cost if self.settings.bars is None else ranked_cost(cost, self.violation)


_EVALUATORS: dict[tuple[StepCostSettings, int], BatchEvaluator] = {}


def _evaluator(m: int, settings: StepCostSettings) -> BatchEvaluator:
    """A cached batched model of m copies (built once per worker, size and settings)."""
    key = (settings, m)
    ev = _EVALUATORS.get(key)
    if ev is None:
        if len(_EVALUATORS) >= 8:   # bounded: a few chunk sizes per tune
            _EVALUATORS.pop(next(iter(_EVALUATORS)))
        ev = _EVALUATORS[key] = BatchEvaluator(m, settings)
    return ev


def evaluate_batch(gains: np.ndarray, settings: StepCostSettings = StepCostSettings()) -> np.ndarray:
    """The tune's cost (m,) for gains (m, 12) in one batched model (``BatchEvaluator.ranked``):
    the ISE of eq. (25), ranked by Deb's rules when ``settings.bars`` is set.

    This is what each worker runs on its chunk; in-process it is the whole population.
    """
    g = np.atleast_2d(np.asarray(gains, dtype=float))
    if g.ndim != 2 or g.shape[1] != 12:
        raise UserError(f"gains must have shape (m, 12), got {np.shape(gains)}")
    if g.shape[0] == 0:
        return np.empty(0)
    return _evaluator(g.shape[0], settings).ranked(g)


def step_ise(gains: np.ndarray, settings: StepCostSettings = StepCostSettings()) -> np.ndarray | float:
    """ISE of eq. (25) over the step for gains (12,) → float, or (m, 12) → (m,) in one batched model
    (the plain ISE, whatever ``settings.bars``)."""
    g = np.asarray(gains, dtype=float)
    g2 = np.atleast_2d(g)
    if g2.ndim != 2 or g2.shape[1] != 12 or g2.shape[0] == 0:
        raise UserError(f"gains must have shape (12,) or (m, 12), got {g.shape}")
    out = _evaluator(g2.shape[0], settings).evaluate(g2)
    return float(out[0]) if g.ndim == 1 else out


@dataclass(frozen=True)
class StepCheck:
    """One gain set flown through the step: its ISE, step metrics and the bars' verdict."""

    ise: float
    step: dict[str, dict[str, float]]      # axis -> overshoot_pct, settling_s, steady_state_error
    max_tilt_deg: float
    violation: float                       # 0: every bar met (against ``bars``)
    bars: StepBars

    @property
    def meets_bars(self) -> bool:
        return self.violation == 0.0


def step_check(gains: np.ndarray, settings: StepCostSettings = StepCostSettings()) -> StepCheck:
    """Fly gains (12,) through the step once: ISE, step metrics, tilt and the bars' verdict
    (``settings.bars``, or the default bars when the tune ran without them)."""
    g = np.asarray(gains, dtype=float).reshape(1, 12)
    ev = _evaluator(1, settings)
    cost = float(ev.evaluate(g)[0])
    step = {ax: {k: float(v[0]) for k, v in ev.step[ax].items()} for ax in AXES}
    return StepCheck(cost, step, float(ev.max_tilt_deg[0]), float(ev.violation[0]),
                     settings.bars if settings.bars is not None else StepBars())


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
            self.workers, mp_context=_pool_context(), initializer=_worker_init)

    def __call__(self, X: np.ndarray) -> np.ndarray:
        if self._pool is None:
            raise RuntimeError("this ProcessPoolCost is closed")
        X = np.asarray(X, dtype=float)
        futures = [self._pool.submit(_worker_eval, (self.settings, c)) for c in _chunks(X, self.workers)]
        results = []
        for f in futures:                 # in chunk order: the same result whatever the timing
            while True:                   # a timed wait keeps Ctrl-C responsive in the parent
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
        for proc in procs:                # do not wait for chunks still running (Ctrl-C)
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

    def __init__(self, settings: StepCostSettings = StepCostSettings(), address: str = "local",
                 workers: int | None = None) -> None:
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


# --------------------------------------------------------------------------- the whole tune


INITS = ("table4", "random")


@dataclass(frozen=True)
class TuneOptions:
    """FPA settings of a tune (paper Table 2 defaults; SPEC §6: a small positive lower bound).

    init: ``"table4"`` puts the paper's Table 4 gains (the designed controller the FPA is to
    improve, paper §3.2) in the initial population beside N − 1 uniform flowers, so the tune
    starts from a candidate that meets the step bars; ``"random"``: all N uniform (Fig. 3).
    """

    population: int = 50
    iterations: int = 14
    p: float = 0.04
    gamma: float = 0.02
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
            raise UserError(f"lower bound must be > 0 (the gains must be positive, paper: α_s > 0), "
                            f"got {self.lower!r}")
        if self.lower >= self.upper:
            raise UserError(f"bounds inverted: lower {self.lower!r} must be below upper {self.upper!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, (int, np.integer)) or self.seed < 0:
            raise UserError(f"seed must be an integer >= 0, got {self.seed!r}")
        if self.init not in INITS:
            raise UserError(f"init must be one of {', '.join(INITS)}, got {self.init!r}")
        if self.init == "table4" and not (self.lower <= TABLE4_GAINS.min() and TABLE4_GAINS.max() <= self.upper):
            raise UserError(f"init table4 needs bounds that hold the Table 4 gains "
                            f"[{TABLE4_GAINS.min():g}, {TABLE4_GAINS.max():g}], got [{self.lower:g}, {self.upper:g}]; "
                            f"widen them or use init random")

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

    result: FPAResult | None          # the FPA result at the end; None in per-iteration snapshots
    best_x: np.ndarray                # (12,) best gains found
    best_cost: float                  # its ranked cost
    initial_cost: float               # ranked cost of the initial population's best
    table4_ise: float                 # ISE of paper Table 4 gains, same cost
    history: np.ndarray               # (iterations done + 1,) ranked best cost after each iteration
    options: TuneOptions
    settings: StepCostSettings
    backend: str
    workers: int
    wall_s: float
    complete: bool
    check: StepCheck | None = None    # at the end: best_x flown through the step (ISE, metrics, bars)

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


def tune_gains(options: TuneOptions = TuneOptions(), settings: StepCostSettings = StepCostSettings(), *,
               workers: int | None = None, ray_address: str | None = None,
               on_iteration: TuneCallback | None = None) -> TuneOutcome:
    """Tune α1..α12 by FPA (paper §3.2, Fig. 3, Table 2) on the ISE of eq. (25) over the step,
    subject to ``settings.bars`` (Deb's feasibility rules, :mod:`.constraints`) when set.

    ``on_iteration(outcome)`` is called after the initial population (iteration 0) and after
    every iteration with the best so far (``complete`` False until the end) — e.g. to write
    the gains file, so that an interruption leaves the best gains found. A Ctrl-C propagates
    (KeyboardInterrupt) after the workers are stopped. The final outcome carries ``check``:
    the best gains flown through the step once more, with their step metrics.
    """
    import time

    t0 = time.perf_counter()
    t4 = table4_ise(settings)      # in-process: same cost, bitwise, whatever the backend
    with make_population_cost(settings, workers=workers, ray_address=ray_address) as cost:
        def progress(iteration: int, best_x: np.ndarray, best_cost: float, history: np.ndarray) -> None:
            if on_iteration is not None:
                on_iteration(TuneOutcome(None, best_x, float(best_cost), float(history[0]), t4, history, options,
                                         settings, cost.backend, cost.workers, time.perf_counter() - t0, False))

        res = fpa(cost, options.bounds, population=options.population, iterations=options.iterations,
                  p=options.p, gamma=options.gamma, seed=options.seed, x0=options.x0, callback=progress)
        backend, n_workers = cost.backend, cost.workers
    check = step_check(res.best_x, settings)
    return TuneOutcome(res, res.best_x, float(res.best_cost), float(res.initial_best_cost), t4, res.history,
                       options, settings, backend, n_workers, time.perf_counter() - t0, True, check)
