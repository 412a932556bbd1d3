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
as m copies of one drone in ``Sim(world, T, n_copies=b)`` (:class:`~swarm_mj.physics.sim.Sim`: the
same saturation, force stages, ``mj_step`` and health mask as every run), the world built by
``build_world(b, collisions=False)`` — contacts off, so the copies all start at the same
point and fly through each other — in blocks of at most :data:`DEFAULT_BLOCK` copies per
MuJoCo model (MuJoCo's site motors cost O(copies²) per model; see there), the copies of a thread's
group driven by ONE call per period of the command every run flies, ``period.command``'s Python body
(:func:`swarm_mj._jit.python_body`) on records of the copies: the lag prediction, backstepping with
the gains (m, 12) in its ``Gains`` record, the attitude-priority mixer where the rotors lag
(``Control.priority``; docs/design.md, "The control period, written once"). The copies do not interact: a free
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

from .._jit import jit, python_body
from ..control.backstepping import Backstepping
from ..control.lag import AttitudePredictor
from ..errors import UserError
from ..experiments.parallel import ThreadTeam, check_count, default_workers
from ..metrics import ise, step_metrics_batch
from ..paper import TABLE4_GAINS
from ..physics._mjstep import profiler_paused
from ..physics.mixing import MIXERS
from ..physics.observation import attitude_kernel
from ..physics.params import DEFAULT_PARAMS, QuadParams
from ..physics.sim import Sim
from ..physics.world import INTEGRATORS, build_world
from ..pipeline.period import command as period_command
from ..pipeline.period import fly_chunk
from ..pipeline.records import Feedforward, Obs, Predictor
from ..pipeline.stepper import Clock, NoRefs, no_views, nothing
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
    #: the controller's mixer (swarm_mj/physics/mixing.py ``MIXERS``): ``"auto"`` is attitude priority under
    #: rotor lag and the paper's per-rotor clipping without; a vehicle's own (``tune --vehicle``: the vehicle
    #: file's ``mixer``, the Crazyflie's ``"yaw_last"``), so that the tune flies what ``swarm-mj run`` flies
    mixer: str = "auto"
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
        if self.mixer not in MIXERS:
            raise UserError(f"mixer must be one of {', '.join(MIXERS)}, got {self.mixer!r}")
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
    def mixer_flown(self) -> str:
        """The mixer flown: :attr:`mixer`, with ``"auto"`` resolved as a scenario's
        (:attr:`swarm_mj.scenario.Scenario.mixer_flown`, without a vehicle file's)."""
        if self.mixer != "auto":
            return self.mixer
        return "attitude_priority" if self.motor_tau > 0 else "clip"

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
#: 13–25 copies cost the same, one model of 50 20 % more). 25 rather than fewer: on threads, each
#: block's step hands the GIL over several times per control period (``mj_step`` and every
#: ``nogil`` kernel), and fewer, larger blocks per thread scale better (the tune's 50 candidates
#: on 2 threads: groups of 25 as one model each 1.41x one thread, as two models of 13 and 12
#: 1.09x; docs/physics_step.md, "The tuner on every core").
DEFAULT_BLOCK = 25


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


@dataclass
class _Group:
    """The copies one thread flies: rows ``rows`` of the batch, in blocks ``(sim, slice within the group)``,
    with the group's own gather buffers, health codes and record of x, y, z, ψ."""

    rows: slice
    blocks: list[tuple[Sim, slice]]
    qpos: np.ndarray  # (m_g, 7) gathered state (unused with one block: the views are used)
    qvel: np.ndarray  # (m_g, 6)
    codes: np.ndarray  # (m_g,) int8 health mask
    track: np.ndarray  # (K+1, m_g, 4) x, y, z, ψ


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

    **Threads.** ``threads`` > 1 splits the m copies in that many contiguous groups (at most m),
    each flown by its own thread with its own controller and blocks, for the whole run: the
    copies do not interact, so each copy's result is the same bit for bit whatever the split
    (tested against one thread). MuJoCo releases the GIL in ``mj_step`` and the kernels are
    compiled ``nogil`` (swarm_mj/_jit.py), so the groups' physics runs on as many cores.
    A block whose copies have all diverged is no longer stepped (its copies are parked and
    their cost is already ``inf``).
    """

    def __init__(
        self, m: int, settings: StepCostSettings = StepCostSettings(), *, block: int = DEFAULT_BLOCK, threads: int = 1
    ) -> None:
        self.m = check_count("batch size", m)
        block = check_count("block", block)
        self.threads = min(check_count("threads", threads), self.m)
        s = settings
        self.settings = s
        self.K = s.n_samples
        worlds: dict[int, Any] = {}
        self.sims: list[Sim] = []
        self.slices: list[slice] = []  # each block's rows in the batch
        self.groups: list[_Group] = []
        for rows in np.array_split(np.arange(self.m), self.threads):
            a, mg = int(rows[0]), len(rows)
            sizes = [len(c) for c in np.array_split(np.arange(mg), -(-mg // block))]
            bounds = np.cumsum([0] + sizes)
            blocks = []
            for b, lo, hi in zip(sizes, bounds[:-1], bounds[1:]):
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
                sim = Sim(
                    worlds[b],
                    s.control_period,
                    n_copies=b,
                    floor_z=s.floor_z,
                    max_distance=s.max_distance,
                    max_tilt=np.deg2rad(s.max_tilt_deg),
                )
                blocks.append((sim, slice(int(lo), int(hi))))
                self.sims.append(sim)
                self.slices.append(slice(a + int(lo), a + int(hi)))
            self.groups.append(
                _Group(
                    rows=slice(a, a + mg),
                    blocks=blocks,
                    qpos=np.empty((mg, 7)),
                    qvel=np.empty((mg, 6)),
                    codes=np.zeros(mg, dtype=np.int8),
                    track=np.zeros((self.K + 1, mg, 4)),
                )
            )
        self._pos_d = np.tile(np.asarray(s.target, float), (self.m, 1))  # (m, 3) step set-point
        self._zero3 = np.zeros((self.m, 3))  # (m, 3) v_d = a_d = 0
        self._yaw_d = np.full(self.m, np.deg2rad(s.yaw_deg))  # (m,)
        self._errors = np.empty((self.K, self.m, 6))  # (K, m, 6) e_x..e_ψ
        self._t = np.arange(self.K + 1) * s.control_period  # (K+1,) sample times
        self._stop = False  # set when one thread fails: the others stop at their next period
        # period.command's Python body, made once: its callees are bound at the first flight and every
        # flight passes records of the same types (before, each flight made and bound its own: 2.6 ms)
        self._command = python_body(period_command)
        self.max_tilt_deg = np.zeros(self.m)  # (m,) of the last batch
        self.violation = np.zeros(self.m)  # (m,) of the last batch
        self.step: dict[str, dict[str, np.ndarray]] = {}
        #: (m,) control period at which each copy of the last batch diverged (-1: never).
        self.diverged_at = np.full(self.m, -1, dtype=np.int64)

    @staticmethod
    def _gather(grp: _Group) -> tuple[np.ndarray, np.ndarray]:
        """Current qpos (m_g, 7) and qvel (m_g, 6) of a group's copies (views when it has one block)."""
        if len(grp.blocks) == 1:
            return grp.blocks[0][0].qpos, grp.blocks[0][0].qvel
        np.concatenate([sim.qpos for sim, _ in grp.blocks], out=grp.qpos)
        np.concatenate([sim.qvel for sim, _ in grp.blocks], out=grp.qvel)
        return grp.qpos, grp.qvel

    @staticmethod
    def _health(grp: _Group) -> np.ndarray:
        """The health mask (m_g,) of a group's copies (:meth:`Sim.health` of each block): True where unhealthy."""
        for sim, sl in grp.blocks:
            sim.health(out=grp.codes[sl])
        return grp.codes != 0

    @staticmethod
    def _kill(alive: np.ndarray, bad: np.ndarray, k: int, diverged_at: np.ndarray) -> bool:
        """Mark copies newly ``bad`` as diverged at control period k (``alive``, ``diverged_at`` updated
        in place; all three (m_g,) of one group); True if there were any."""
        newly = bad & alive
        if newly.any():
            alive &= ~bad
            diverged_at[newly] = k
            return True
        return False

    def _fly(self, grp: _Group, g: np.ndarray, alive: np.ndarray, tilt: np.ndarray) -> None:
        """Fly one group's copies through the step: gains g (m, 12) and alive (m,), tilt (m,) of the
        whole batch (the group's rows are written). Each control period is the period every run flies
        (:class:`_GroupPeriod`: ``period.fly_chunk``'s Python body, one period a call, with the tuner's stages)."""
        flight = _GroupPeriod(self, grp, g, alive, tilt)
        flight.observe(0)
        for k in range(self.K):
            if self._stop:
                return
            flight.fly(k)
            if flight.over:  # every copy diverged: nothing left to fly or sample
                return
        flight.kill(self.K)

    def _fly_or_stop(self, grp: _Group, g: np.ndarray, alive: np.ndarray, tilt: np.ndarray) -> None:
        """:meth:`_fly`; an exception (or Ctrl-C) in it stops the other threads at their next period."""
        try:
            self._fly(grp, g, alive, tilt)
        except BaseException:
            self._stop = True
            raise

    def _fly_all(self, g: np.ndarray, alive: np.ndarray, tilt: np.ndarray) -> None:
        """Every group, each on its own thread (the first on this one); the first exception is raised here."""
        self._stop = False
        with ThreadTeam(len(self.groups), "swarm-mj-tune") as team:  # its threads end with this call
            team.run(lambda grp: self._fly_or_stop(grp, g, alive, tilt), self.groups)

    def evaluate(self, gains: np.ndarray) -> np.ndarray:
        """ISE (m,) of eq. (25) for gains (m, 12); ``inf`` where a copy diverged."""
        g = np.asarray(gains, dtype=float)
        if g.shape != (self.m, 12):
            raise UserError(f"gains must have shape ({self.m}, 12), got {g.shape}")
        s = self.settings
        alive = np.isfinite(g).all(axis=1) & (g > 0).all(axis=1)  # (m,)
        self.diverged_at[:] = -1
        self.diverged_at[~alive] = 0
        g = np.where(alive[:, None], g, TABLE4_GAINS)  # placeholders for the dead
        for sim in self.sims:
            sim.reset()
        tilt = np.zeros(self.m)  # (m,) max |roll|, |pitch| (rad)
        # MuJoCo's profiling clock off once for every thread (Sim.step's own pause is per call, and
        # the clock is a global of libmujoco: threads pausing and resuming it would race).
        with profiler_paused(), np.errstate(invalid="ignore", over="ignore", divide="ignore"):
            self._fly_all(g, alive, tilt)
            cost = ise(self._errors, s.control_period)  # (m,) eq. (25)
        track = self.groups[0].track if len(self.groups) == 1 else np.concatenate([gr.track for gr in self.groups], 1)
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


_EVALUATORS: dict[tuple[StepCostSettings, int, int], BatchEvaluator] = {}


class _GroupPeriod:
    """One group's flight of the step, a control period at a time: ``period.fly_chunk``'s Python body
    (docs/design.md, "The control period, written once") with the tuner's stages, by the name the
    period calls: the references are the step's set-point; the command is ``period.command``'s Python
    body on records of the group's copies (backstepping with their gains (m_g, 12), no wind force, no
    feedforward; under rotor lag the controller of a lagged run: the attitude predicted τ + T ahead and
    the attitude-priority mixer, or the mixer the settings name; docs/vehicles.md); the input row is
    eq. (25)'s errors (:func:`error_kernel`, a copy with a non-finite input marked bad); the physics
    parks the copies newly bad, then steps each block with a live copy; the observation gathers the
    blocks' states, records x, y, z, ψ and the tilt (:func:`record_kernel`) and their health. No copy
    stops the period (each is parked instead), so the period is never unhealthy nor its command
    refused."""

    def __init__(self, ev: BatchEvaluator, grp: _Group, g: np.ndarray, alive: np.ndarray, tilt: np.ndarray) -> None:
        s, rows = ev.settings, grp.rows
        m_g = rows.stop - rows.start
        self.ev, self.grp, self.rows = ev, grp, rows
        self.alive, self.tilt, self.diverged_at = alive[rows], tilt[rows], ev.diverged_at[rows]  # views
        ctl = Backstepping(
            m_g, g[rows], params=s.params, control_period=s.control_period, wind_feedforward=False,
            attitude_map=s.attitude_map,
        )  # fmt: skip
        T = s.control_period
        mixer = s.mixer_flown
        self.ctl = ctl.control_record(np.zeros((m_g, 4)), priority=mixer != "clip", yaw_last=mixer == "yaw_last")
        self.pred = (
            AttitudePredictor(m_g, s.motor_tau + T, s.motor_tau, T).record() if s.motor_tau > 0 else Predictor.off(m_g)
        )
        self.ff, self.obs = Feedforward.off(m_g), Obs.empty(m_g)
        self.pos_d, self.zero3, self.yaw_d = ev._pos_d[rows], ev._zero3[rows], ev._yaw_d[rows]
        self.obs.yaw[:] = self.yaw_d  # ψ_d (m_g,); the known wind force obs.wf stays zero
        self.must_park = not self.alive.all()  # invalid gains: parked from the start
        self.over = False  # every copy diverged
        self._k = 0  # the period flown
        self.U: np.ndarray = self.ctl.U_last
        self.qpos = self.rpy = self.bad = np.empty(0)
        self._clock = Clock(T=T)
        self._refs = NoRefs(wind_speed=np.zeros((ev.K + 1, 3)), D=np.zeros(ev.K + 1))  # (no wind, no D)
        self._body = python_body(
            fly_chunk,
            {
                "_period_rules": self._references,
                "_period_inputs": self._inputs,
                "command": self._command,
                "all_finite": _every_command,
                "log_inputs": self._errors,
                "_period_view_log": nothing,
                "drone_views": no_views,
                "hold_wind": nothing,
                "hold_inputs": nothing,  # (each block's Sim.step saturates its copies' command)
                "physics_steps": self._physics,
                "log_outputs": nothing,
                "unhealthy": _never,  # (each copy's health is the observation's; a bad copy is parked)
                "observe_into": self._observe,
                "_period_sense": nothing,
            },
        )

    def fly(self, k: int) -> None:
        """Control period k of the group's copies."""
        self._k = k  # (what the command's first period and the physics' parking read)
        self._body(k, 0, k + 1, False, self._clock, self._refs, self.obs, None, None, None, self.ctl, self.ff,
                   self.pred, None, None, None)  # fmt: skip

    def observe(self, k: int) -> None:
        """Sample k: the copies' states gathered, x, y, z, ψ and the tilt recorded, their health."""
        ev, grp, obs = self.ev, self.grp, self.obs
        qpos, qvel = ev._gather(grp)
        # Angles and rates, the record of x, y, z, ψ and the health mask (docs/interpretations.md §6)
        rpy, rate = attitude_kernel(qpos, qvel)
        record_kernel(qpos, rpy, k, grp.track, self.tilt)
        self.qpos, self.rpy, self.bad = qpos, rpy, ev._health(grp)
        obs.pos[:], obs.vel[:], obs.omega[:] = qpos[:, 0:3], qvel[:, 0:3], qvel[:, 3:6]
        obs.rpy[:], obs.rpy_rate[:] = rpy, rate

    def kill(self, k: int) -> bool:
        """The copies newly bad marked diverged at period k; True if there were any."""
        return self.ev._kill(self.alive, self.bad, k, self.diverged_at)

    # ------------------------------------------------------------------ the stages
    def _references(self, rules, filts, view, obs, t):  # noqa: ANN001, ANN202, ARG002
        return False, self.pos_d, self.zero3, self.zero3

    def _inputs(self, ff, view, obs, k, ctl):  # noqa: ANN001, ANN202, ARG002
        return obs, ff

    def _command(self, ctl, known, pred, seen, pos_d, vel_d, acc_d, first):  # noqa: ANN001, ANN202, ARG002
        self.U = self.ev._command(ctl, known, pred, seen, pos_d, vel_d, acc_d, self._k == 0)  # (m_g, 4)
        return self.U

    def _errors(self, log, k, t, obs, pos_d, att_d, wind_speed, D) -> None:  # noqa: ANN001, ARG002
        error_kernel(pos_d, self.qpos, att_d, self.rpy, self.yaw_d, self.U, self.ev._errors[k, self.rows], self.bad)

    def _physics(self, phys, stages, monitors, kin, xf, xtorque, s0, python_each) -> int:  # noqa: ANN001, ARG002
        alive, blocks, U = self.alive, self.grp.blocks, self.U
        if self.kill(self._k) or self.must_park:
            if not alive.any():
                self.over = True
                return 0
            for sim, sl in blocks:  # no input, held at the start
                if not alive[sl].all():
                    sim.park(~alive[sl])
            self.must_park = False
        for sim, sl in blocks:
            if alive[sl].any():  # a block of diverged copies only: nothing left to fly
                sim.step(U[sl])
        return 0

    def _observe(self, qpos, qvel, T, refs, obs, k) -> None:  # noqa: ANN001, ARG002
        if not self.over:
            self.observe(k)


def _every_command(U: np.ndarray) -> bool:  # noqa: ARG001
    """The period's check of its command where a copy with a non-finite input is parked, not refused."""
    return True


def _never(*args: Any) -> bool:  # noqa: ARG001
    """The period's health check where each copy's health is the observation's."""
    return False


def _evaluator(m: int, settings: StepCostSettings, threads: int = 1) -> BatchEvaluator:
    """A cached batched model of m copies (built once per worker, size, settings and threads)."""
    key = (settings, m, min(threads, m))
    ev = _EVALUATORS.get(key)
    if ev is None:
        if len(_EVALUATORS) >= 8:  # bounded: a few chunk sizes per tune
            _EVALUATORS.pop(next(iter(_EVALUATORS)))
        ev = _EVALUATORS[key] = BatchEvaluator(m, settings, threads=threads)
    return ev


def evaluate_batch(
    gains: np.ndarray, settings: StepCostSettings = StepCostSettings(), threads: int | None = None
) -> np.ndarray:
    """The tune's cost (m,) for gains (m, 12) in one batched model (``BatchEvaluator.ranked``):
    the ISE of eq. (25), ranked by Deb's rules when ``settings.bars`` is set.

    This is what each worker runs on its chunk; in-process it is the whole population.
    ``threads``: the evaluator's threads (default: the CPUs this process may use,
    :func:`swarm_mj.experiments.parallel.default_workers`); the result is the same whatever their number.
    """
    g = np.atleast_2d(np.asarray(gains, dtype=float))
    if g.ndim != 2 or g.shape[1] != 12:
        raise UserError(f"gains must have shape (m, 12), got {np.shape(gains)}")
    t = default_workers() if threads is None else check_count("threads", threads)
    if g.shape[0] == 0:
        return np.empty(0)
    return _evaluator(g.shape[0], settings, t).ranked(g)


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
        ise=cost,
        step=step,
        max_tilt_deg=float(ev.max_tilt_deg[0]),
        violation=float(ev.violation[0]),
        bars=settings.bars if settings.bars is not None else StepBars(),
    )


def table4_ise(settings: StepCostSettings = StepCostSettings()) -> float:
    """ISE of the paper's Table 4 gains under the same cost."""
    return float(step_ise(TABLE4_GAINS, settings))
