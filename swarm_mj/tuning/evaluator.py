"""The tuner's evaluator: the ISE cost of paper eq. (25) over the step manoeuvre, for a whole FPA
population at once, flown by the simulator's step pipeline over copies.

The cost of a gain vector α1..α12 (paper Table 4 layout) is

    ISE = ∫_0^t_sim 3e_x² + 3e_y² + e_z² + 2e_φ² + 2e_θ² + e_ψ² dt          (eq. 25)

over the step of docs/interpretations.md §3 (from rest on the ground at the origin to x = y = z = 1 m,
ψ = 25°, t_sim = 10 s), with the errors sampled at the control period T = 0.01 s
(left rectangle rule, :func:`swarm_mj.metrics.ise`):

* e_x, e_y, e_z = reference − position (m);
* e_φ, e_θ = commanded − actual angle (rad), the commanded angles being the
  controller's φ_d, θ_d of eqs. (21)–(22) at that sample (``Backstepping.att_d``);
* e_ψ = ψ_d − ψ wrapped to [−π, π).

A candidate that diverges gets ``+inf`` (docs/interpretations.md §6), never an exception: a non-finite state
or input, |roll| or |pitch| beyond ``max_tilt_deg`` (80° by default: a flip, well past the
≈ 51° pitch the step normally reaches, docs/interpretations.md §2), the drone below ``floor_z`` or farther than
``max_distance`` from the origin.

**The step bars as constraints** (default, ``StepCostSettings.bars``; :mod:`.constraints`).
The ISE alone weighs a slow tail lightly (seed 1 on it alone: y settles in 2.05 s, past the
controller's 2.0 s bar), so by default the tune ranks candidates by Deb's feasibility rules:
those meeting the bars (overshoot, 2 % settling, steady-state error, tilt, measured from the
same run as the ISE with the definitions of ``swarm-mj run step``'s summary) by ISE, before
those that do not, by how far they miss. ``bars=None`` is eq. (25) alone, as in the paper.

**The simulator's pipeline over copies, one controller call.** A batch of m candidates flies
as m copies of one drone in ``Sim(world, T, n_copies=b)`` (:class:`~swarm_mj.sim.Sim`: the
same saturation, force stages, ``mj_step`` and health mask as every run), the world built by
``build_world(b, collisions=False)`` — contacts off, so the copies all start at the same
point and fly through each other — in blocks of at most :data:`DEFAULT_BLOCK` copies per
MuJoCo model (MuJoCo's site motors cost O(copies²) per model; see there), all m driven by ONE
vectorised ``Backstepping.compute`` (gains (m, 12)). The copies do not interact: a free
body's dynamics depend only on its own state and inputs, so a candidate's cost does not
depend on its batch, block or worker (tested: batched == alone, bit for bit on the
development machine; and == eq. (25) from ``runner.run`` to 1e-9). A copy that the health
mask flags (:meth:`Sim.health`, with the tilt limit) or whose input is not finite is parked
(:meth:`Sim.park`): held at rest at the start with zero input for the rest of the run, so
that NaN never reaches MuJoCo (which resets the *whole* ``MjData`` on a bad acceleration).

The backends that spread a population over processes or a Ray cluster are in
:mod:`.backends`; the tune itself in :mod:`.driver`.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from .._jit import jit
from ..control.backstepping import Backstepping
from ..control.lag import AttitudePredictor
from ..errors import UserError
from ..metrics import ise, step_metrics_batch
from ..mixing import attitude_priority
from ..observation import attitude_kernel
from ..paper import TABLE4_GAINS
from ..params import DEFAULT_PARAMS, QuadParams
from ..sim import Sim
from ..world import INTEGRATORS, build_world
from .constraints import AXES, StepBars, ranked_cost, step_violation

__all__ = [
    "DEFAULT_BLOCK",
    "BatchEvaluator",
    "StepCheck",
    "StepCostSettings",
    "evaluate_batch",
    "step_check",
    "step_ise",
    "table4_ise",
]


# --------------------------------------------------------------------------- settings


@dataclass(frozen=True)
class StepCostSettings:
    """The manoeuvre and the divergence limits of the cost (docs/interpretations.md §3, §6). Hashable, picklable.

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
    #: rotor time constant (s): > 0 flies the step with first-order rotor lag and the controller of a
    #: lagged run (attitude-priority mixing, the attitude predicted τ + T ahead; docs/aero.md), as
    #: ``swarm-mj tune --vehicle`` does under the vehicle's lag (docs/vehicles.md); 0: the paper's
    motor_tau: float = 0.0
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
        tau = self.motor_tau
        if isinstance(tau, bool) or not isinstance(tau, (int, float)) or not math.isfinite(tau) or tau < 0:
            raise UserError(f"motor-tau must be a time constant >= 0 s, got {tau!r}")
        if 0 < tau < self.timestep:
            raise UserError(f"motor-tau must be 0 or at least the physics timestep {self.timestep:g} s, got {tau:g}")
        object.__setattr__(self, "target", tuple(float(v) for v in self.target))
        object.__setattr__(self, "start", tuple(float(v) for v in self.start))
        if len(self.target) != 3 or len(self.start) != 3:
            raise UserError("target and start must be three numbers (x, y, z) in metres")
        if self.n_samples < 1:
            raise UserError(f"t-sim {self.t_sim} s is shorter than one control period {self.control_period} s")
        if self.bars is not None:
            longest = max(self.bars.settling(ax) for ax in AXES)
            if self.t_sim < longest:
                raise UserError(
                    f"t-sim {self.t_sim:g} s is shorter than the longest settling bar ({longest:g} s): "
                    f"no candidate could meet the step bars; give a longer t-sim or --constraints none"
                )

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


def _record_samples():
    return [(np.zeros((2, 7)), np.zeros((2, 3)), 0, np.zeros((2, 2, 4)), np.zeros(2))]


@jit(samples=_record_samples)
def record_kernel(qpos: np.ndarray, rpy: np.ndarray, k: int, track: np.ndarray, tilt: np.ndarray) -> None:
    """One sample of the batch, all copies in one pass: x, y, z, ψ of qpos (m, 7) and rpy (m, 3) into
    track[k] (m, 4), and the running max |roll|, |pitch| (rad) in tilt (m,)."""
    for i in range(qpos.shape[0]):
        for j in range(3):
            track[k, i, j] = qpos[i, j]
        track[k, i, 3] = rpy[i, 2]
        t = max(abs(rpy[i, 0]), abs(rpy[i, 1]))
        if not t <= tilt[i]:  # NaN propagates, like np.maximum
            tilt[i] = t


def _error_samples():
    z3 = np.zeros((2, 3))
    return [(z3, np.zeros((2, 7)), z3, z3, np.zeros(2), np.zeros((2, 4)), np.zeros((2, 6)), np.zeros(2, np.bool_))]


@jit(samples=_error_samples)
def error_kernel(
    pos_d: np.ndarray,
    qpos: np.ndarray,
    att_d: np.ndarray,
    rpy: np.ndarray,
    yaw_d: np.ndarray,
    U: np.ndarray,
    e: np.ndarray,
    bad: np.ndarray,
) -> None:
    """The errors of eq. (25) at one sample, e (m, 6) = (p_d − p, φ_d − φ, θ_d − θ, wrap(ψ_d − ψ));
    marks copies with a non-finite input U (m, 4) as bad (m,)."""
    for i in range(qpos.shape[0]):
        for j in range(3):
            e[i, j] = pos_d[i, j] - qpos[i, j]
        e[i, 3] = att_d[i, 0] - rpy[i, 0]
        e[i, 4] = att_d[i, 1] - rpy[i, 1]
        e[i, 5] = (yaw_d[i] - rpy[i, 2] + np.pi) % (2.0 * np.pi) - np.pi  # wrap to [−π, π)
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

    def __init__(self, m: int, settings: StepCostSettings = StepCostSettings(), *, block: int = DEFAULT_BLOCK) -> None:
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
                starts = np.tile(np.asarray(s.start, float), (b, 1))  # (b, 3) all at the same point
                # collisions=False: contacts are off, so the overlapping copies never touch.
                worlds[b] = build_world(
                    b,
                    positions=starts,
                    collisions=False,
                    floor=False,
                    params=s.params,
                    timestep=s.timestep,
                    integrator=s.integrator,
                    motor_tau=s.motor_tau,
                )
            self.sims.append(
                Sim(
                    worlds[b],
                    s.control_period,
                    n_copies=b,
                    floor_z=s.floor_z,
                    max_distance=s.max_distance,
                    max_tilt=np.deg2rad(s.max_tilt_deg),
                )
            )
        self.K = s.n_samples
        self._pos_d = np.tile(np.asarray(s.target, float), (self.m, 1))  # (m, 3) step set-point
        self._zero3 = np.zeros((self.m, 3))  # (m, 3) v_d = a_d = 0
        self._yaw_d = np.full(self.m, np.deg2rad(s.yaw_deg))  # (m,)
        self._qpos = np.empty((self.m, 7))  # (m, 7) gathered state
        self._qvel = np.empty((self.m, 6))  # (m, 6)
        self._codes = np.zeros(self.m, dtype=np.int8)  # (m,) the health mask
        self._errors = np.empty((self.K, self.m, 6))  # (K, m, 6) e_x..e_ψ
        self._track = np.zeros((self.K + 1, self.m, 4))  # (K+1, m, 4) x, y, z, ψ
        self._t = np.arange(self.K + 1) * s.control_period  # (K+1,) sample times
        self.max_tilt_deg = np.zeros(self.m)  # (m,) of the last batch
        self.violation = np.zeros(self.m)  # (m,) of the last batch
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

    def _health(self) -> np.ndarray:
        """The health mask (m,) of all copies (:meth:`Sim.health` of each block): True where unhealthy."""
        codes = self._codes
        for sim, sl in zip(self.sims, self.slices):
            sim.health(out=codes[sl])
        return codes != 0

    def _kill(self, alive: np.ndarray, bad: np.ndarray, k: int) -> bool:
        """Mark copies newly ``bad`` (m,) as diverged at control period k (``alive`` updated in place);
        True if there were any."""
        newly = bad & alive
        if newly.any():
            alive &= ~bad
            self.diverged_at[newly] = k
            return True
        return False

    def evaluate(self, gains: np.ndarray) -> np.ndarray:
        """ISE (m,) of eq. (25) for gains (m, 12); ``inf`` where a copy diverged."""
        g = np.asarray(gains, dtype=float)
        if g.shape != (self.m, 12):
            raise UserError(f"gains must have shape ({self.m}, 12), got {g.shape}")
        m, s = self.m, self.settings
        alive = np.isfinite(g).all(axis=1) & (g > 0).all(axis=1)  # (m,)
        self.diverged_at[:] = -1
        self.diverged_at[~alive] = 0
        g = np.where(alive[:, None], g, TABLE4_GAINS)  # placeholders for the dead
        ctl = Backstepping(m, g, params=s.params, control_period=s.control_period, attitude_map=s.attitude_map)
        lagged = s.motor_tau > 0  # the controller of a run with rotor lag (Scenario.lag_horizons, mixer "auto")
        T, p = s.control_period, s.params
        predictor = AttitudePredictor(m, s.motor_tau + T, s.motor_tau, T) if lagged else None
        for sim in self.sims:
            sim.reset()
        pos_d, zero3, yaw_d = self._pos_d, self._zero3, self._yaw_d
        errors, track = self._errors, self._track
        tilt = np.zeros(m)  # (m,) max |roll|, |pitch| (rad)
        blocks = list(zip(self.sims, self.slices))
        must_park = not alive.all()  # invalid gains: parked from the start
        with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
            for k in range(self.K + 1):
                qpos, qvel = self._gather()
                # Angles and rates, the record of x, y, z, ψ and the health mask (docs/interpretations.md
                # §6) at every sample and at the end of the run.
                rpy, rate = attitude_kernel(qpos, qvel)
                record_kernel(qpos, rpy, k, track, tilt)
                bad = self._health()
                if k == self.K:
                    self._kill(alive, bad, k)
                    break
                pos, vel, omega = qpos[:, 0:3], qvel[:, 0:3], qvel[:, 3:6]
                if predictor is None:
                    U = ctl.compute(rpy, rate, pos, vel, pos_d, zero3, zero3, yaw_d, omega_body=omega)  # (m, 4)
                else:
                    rpy_p, rate_p, omega_p = predictor(rpy, rate, omega)
                    U = ctl.compute(rpy_p, rate_p, pos, vel, pos_d, zero3, zero3, yaw_d, omega_body=omega_p)
                    U = attitude_priority(U, p.f_min, p.f_max, p.unmix_t, p.mix_t)
                error_kernel(pos_d, qpos, ctl.att_d, rpy, yaw_d, U, errors[k], bad)
                if self._kill(alive, bad, k) or must_park:
                    if not alive.any():
                        break
                    for sim, sl in blocks:  # no input, held at the start
                        if not alive[sl].all():
                            sim.park(~alive[sl])
                    must_park = False
                for sim, sl in blocks:
                    sim.step(U[sl])
        cost = ise(errors, s.control_period)  # (m,) eq. (25)
        cost[~alive] = np.inf
        cost[~np.isfinite(cost)] = np.inf
        self.max_tilt_deg = np.where(alive, np.rad2deg(tilt), np.inf)
        with np.errstate(invalid="ignore", over="ignore"):
            target = (*s.target, np.deg2rad(s.yaw_deg))
            self.step = {
                ax: {
                    key: np.where(alive, v, np.nan)
                    for key, v in step_metrics_batch(self._t, track[:, :, i], target[i], track[0, :, i]).items()
                }
                for i, ax in enumerate(AXES)
            }
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
        if len(_EVALUATORS) >= 8:  # bounded: a few chunk sizes per tune
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
    step: dict[str, dict[str, float]]  # axis -> overshoot_pct, settling_s, steady_state_error
    max_tilt_deg: float
    violation: float  # 0: every bar met (against ``bars``)
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
    return StepCheck(
        cost,
        step,
        float(ev.max_tilt_deg[0]),
        float(ev.violation[0]),
        settings.bars if settings.bars is not None else StepBars(),
    )


def table4_ise(settings: StepCostSettings = StepCostSettings()) -> float:
    """ISE of the paper's Table 4 gains under the same cost."""
    return float(step_ise(TABLE4_GAINS, settings))
