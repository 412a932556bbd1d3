"""Run a scenario: ``SwarmEnv`` + a policy, with a log, a summary and observers (docs/design.md, "one loop").

``run(scenario)`` steps the environment with the backstepping policy, keeps every
control-period sample in preallocated arrays (:class:`RunLog`, time axis first, filled from
each observation and from what the simulator applied over each period), and
returns them with the summary of docs/interpretations.md §7. A Ctrl-C or a divergence stops
the loop; the log of what ran is kept (``RunResult.error`` says why it stopped) so that the
recording can still be written. Ctrl-C is cooperative: while the loop runs, SIGINT only sets
a flag, checked once per control period, so that it never lands inside a compiled kernel.
"""

from __future__ import annotations

import functools
import sys
import time as _time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .._jit import CompileClock, warm_up
from ..choices import gains_name
from ..control.policy import BacksteppingPolicy
from ..env import SwarmEnv
from ..errors import SimulationDiverged, UserError
from ..formation.anticollision import AUTO, AUTO_CHOICE
from ..formation.barrier import keepout_radii
from ..formation.slots import check_formation_fits
from ..metrics import (
    downwash_dip,
    formation_settling,
    jet_geometry,
    keepout_summary,
    leader_distances,
    min_separation,
    norm,
    pair_measures,
    rmse,
    step_metrics,
)
from ..output.interrupt import CooperativeInterrupt
from ..output.progress import Progress
from ..physics.aero.presets import with_aero
from ..physics.params import QuadParams
from ..physics.sim import ForceStage, Sim
from ..pipeline.fast import CHUNK, FastLoop, signature, why_not
from ..pipeline.records import LogRows
from ..pipeline.stepper import StepPeriod
from ..scenario import Scenario, load_scenario
from ..sensing.log import ViewLog, view_summary
from .outcome import flight_outcome

__all__ = [
    "Progress",
    "RunLog",
    "RunResult",
    "run",
    "summarize",
]


_SERIES = ("t", "pos", "vel", "quat", "rpy", "pos_d", "slot", "att_d", "U", "rotor", "wind_speed", "wind_force", "D")


@dataclass
class RunLog:
    """Every control-period sample of a run; k = number of samples (steps + 1)."""

    names: list[str]
    t: np.ndarray  # (k,)
    pos: np.ndarray  # (k, n, 3)
    vel: np.ndarray  # (k, n, 3)
    quat: np.ndarray  # (k, n, 4)
    rpy: np.ndarray  # (k, n, 3)
    pos_d: np.ndarray  # (k, n, 3) commanded position (after anti-collision)
    slot: np.ndarray  # (k, n, 3) formation setpoint (leader: its reference)
    att_d: np.ndarray  # (k, n, 3) commanded (φ_d, θ_d, ψ_d)
    U: np.ndarray  # (k, n, 4) applied U1..U4 over the following period
    rotor: np.ndarray  # (k, n, 4) rotor thrusts F1..F4 over the following period
    wind_speed: np.ndarray  # (k, 3)
    wind_force: np.ndarray  # (k, n, 3) applied wind force over the following period
    D: np.ndarray  # (k,)
    #: (S, k, n, 3) the force (N) of each extra force stage of the simulator over the last physics step
    #: of the following period, in the simulator's stage order; ``forces`` names them
    stage_rows: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 0, 3)))
    forces: dict[str, np.ndarray] = field(default_factory=dict)  # stage name -> (k, n, 3), views of stage_rows
    #: what each drone believed (under a sensing model: swarm_mj.sensing.log); None under the oracle
    views: ViewLog | None = None

    @classmethod
    def allocate(cls, names: list[str], k: int, stages: Sequence[str] = ()) -> RunLog:
        """NaN-filled series for k samples, and zero-filled force rows for the force stages named ``stages``."""
        n = len(names)
        z = lambda *s: np.full(s, np.nan)  # noqa: E731
        shapes: list[tuple[int, ...]] = [(k,), (k, n, 3), (k, n, 3), (k, n, 4), (k, n, 3), (k, n, 3), (k, n, 3)]
        shapes += [(k, n, 3), (k, n, 4), (k, n, 4), (k, 3), (k, n, 3), (k,)]
        if len(set(stages)) != len(stages):
            raise UserError(f"force stages must have distinct names, got {list(stages)}")
        rows = np.zeros((len(stages), k, n, 3))
        series: dict[str, Any] = {f: z(*s) for f, s in zip(_SERIES, shapes, strict=True)}
        return cls(names=names, **series, stage_rows=rows, forces=_named(rows, stages))

    def force(self, name: str) -> np.ndarray:
        """The force (k, n, 3) of the stage ``name``; zeros when the run had no such stage."""
        f = self.forces.get(name)
        return np.zeros_like(self.pos) if f is None else f

    @property
    def downwash(self) -> np.ndarray:
        """(k, n, 3) the downwash force on each drone (docs/aero.md), N; zeros without that stage."""
        return self.force("downwash")

    @property
    def ground_effect(self) -> np.ndarray:
        """(k, n, 3) the ground-effect force on each drone, N; zeros without that stage."""
        return self.force("ground_effect")

    @functools.cached_property
    def rows(self) -> LogRows:
        """The series as one record (what the compiled log rows write: swarm_mj.pipeline.period.log_inputs)."""
        series = {f: getattr(self, f) for f in _SERIES}
        return LogRows(**series, forces=self.stage_rows)

    def applied(self, k: int, sim: Sim) -> None:
        """What the simulator applied over the period after sample k, as that period left it: the held U1..U4,
        the produced rotor thrusts, the wind force, and each extra stage's force by its name (the chunk
        driver's row: swarm_mj.pipeline.period.log_outputs)."""
        self.U[k] = sim.ctrl
        self.rotor[k] = sim.rotor_thrust
        self.wind_force[k] = sim.wind.force
        for name, force in sim.kept_forces():
            if name in self.forces:
                self.forces[name][k] = force

    def hold_last(self, k: int) -> None:
        """Sample k (the last, with no following period) holds the inputs of k − 1 (zero-order hold)."""
        self.U[k], self.rotor[k] = self.U[k - 1], self.rotor[k - 1]
        self.stage_rows[:, k] = self.stage_rows[:, k - 1]

    def truncated(self, k: int) -> RunLog:
        rows = self.stage_rows[:, :k]
        series = {f: getattr(self, f)[:k] for f in _SERIES}
        views = self.views.truncated(k) if self.views is not None else None
        return RunLog(names=self.names, **series, stage_rows=rows, forces=_named(rows, self.forces), views=views)


def _named(rows: np.ndarray, names: Sequence[str] | dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The force rows (S, k, n, 3) by stage name: views rows[j]."""
    return {name: rows[j] for j, name in enumerate(names)}


@dataclass
class RunResult:
    scenario: Scenario
    log: RunLog
    summary: dict
    events: list[dict]
    contact_log: list[tuple[float, int, int]]
    error: BaseException | None = None
    extra: dict = field(default_factory=dict)


def check_keepout_fits(sc: Scenario, rule: object, where: str | None = None) -> None:
    """A rule with a separation filter (``barrier``) must be able to reach the formation at its smallest D:
    one :class:`~swarm_mj.errors.UserError` naming the diameter that fits, before anything flies
    (:func:`~swarm_mj.formation.slots.check_formation_fits`)."""
    filt = getattr(rule, "separation_filter", None)
    if filt is not None and sc.n_drones > 1:
        check_formation_fits(
            sc.n_drones - 1,
            float(np.min(sc.diameter_schedule().values)),
            float(filt.radii[0]),
            f"the {getattr(rule, 'name', 'rule')} filter's keep-out",
            where=where or f"{sc.path}: formation.diameter",
        )


def run(
    scenario: Scenario | str,
    *,
    gains: np.ndarray | None = None,
    anti_collision: str | None = None,
    seed: int | None = None,
    progress: bool | None = None,
    duration: float | None = None,
    aero: str | None = None,
    force_stages: Sequence[ForceStage] = (),
    interrupt: CooperativeInterrupt | None = None,
    fused: bool | None = None,
    make_policy: Callable[..., BacksteppingPolicy] | None = None,
) -> RunResult:
    """Fly a scenario with the backstepping policy and return the log and summary.

    aero: a physics preset (``"paper"``, ``"realistic"``; docs/aero.md) replacing the scenario's.
    ``force_stages``: extra :class:`~swarm_mj.physics.sim.ForceStage` s of the simulator (after drag and wind;
    the preset's aerodynamic stages come after them).
    Never raises for Ctrl-C or divergence: the result carries the error and the log up to it.
    ``interrupt``: a :class:`~swarm_mj.output.interrupt.CooperativeInterrupt` the caller entered earlier
    (``swarm-mj run`` does, before it loads anything), so that a Ctrl-C during its own set-up stops
    this run at its start, with a recording of it.
    ``fused``: fly formed flight through the chunk driver where every stage of the run compiles
    (:mod:`swarm_mj.pipeline.fast`; the same results bit for bit): None when it is compiled (else it is
    compiled in the background for later runs), True compiling it first if needed, False never.
    ``make_policy``: builds the policy from the scenario and the vehicle's parameters instead of
    :class:`BacksteppingPolicy` (e.g. an exported set's, swarm_mj/export/flyback.py); one with a
    ``not_compiled`` reason flies step by step.
    """
    sc = _with_options(scenario, aero=aero, duration=duration, gains=gains, anti_collision=anti_collision)
    # Ctrl-C from here on (compiling, building the world, flying) stops the run cleanly: the loop
    # returns what ran (at least the start) and the CLI writes its recording (exit 130).
    with interrupt or CooperativeInterrupt() as interrupt:
        say = _compile_kernels(progress)
        env = SwarmEnv(sc, terminate_on_contact=False, raise_on_divergence=True, seed=seed, force_stages=force_stages)
        policy = (make_policy or BacksteppingPolicy)(sc, env.params)
        check_keepout_fits(sc, policy.rule)
        log = RunLog.allocate(env.names, env.n_steps + 1, [st.name for st in env.sim.force_stages])
        if env.sensing is not None:
            log.views = ViewLog.allocate(env.n_steps + 1, env.n)
        bar = Progress(env.n_steps, sc.name, progress)
        wall0 = _time.perf_counter()
        compiling = CompileClock().start()  # what Numba compiles in the run is left out of its speed figure
        env.reset()
        # the chunk driver (swarm_mj/pipeline/fast.py) flies chunks of formed flight, when every stage compiles
        reason = "fused=False" if fused is False else (getattr(policy, "not_compiled", None) or why_not(env, policy))
        if reason is not None and fused is not False and say is not None:
            say(f"flying step by step: {reason}")
        fast = FastLoop.build(env, policy, log, compile=bool(fused), announce=say) if reason is None else None
        try:
            k, error = _fly(env, policy, log, fast, bar, interrupt)
        finally:
            bar.close()
            compiling.stop()
    wall = _time.perf_counter() - wall0 - compiling.seconds
    if compiling.seconds >= 0.5 and progress is not False:
        print(f"compiled for {compiling.seconds:.1f} s during the run (not counted in its speed)", file=sys.stderr)
    log = _closed(log, env, k, error)
    summary = summarize(sc, log, env, policy, wall)
    if error is not None:
        summary["stopped"] = f"{type(error).__name__}: {error}".rstrip(": ")
    # of the K flown, the periods the chunk driver flew (swarm_mj/pipeline/fast.py); why none could, if so
    extra = {
        "fused_periods": fast.periods if fast is not None else 0,
        "fused_seconds": fast.seconds if fast is not None else 0.0,  # wall-clock seconds of those periods
        "fast_path": reason or "on",
    }
    return RunResult(
        scenario=sc,
        log=log,
        summary=summary,
        events=list(policy.events),
        contact_log=list(env.sim.contact_log),
        error=error,
        extra=extra,
    )


def _with_options(
    scenario: Scenario | str,
    *,
    aero: str | None,
    duration: float | None,
    gains: np.ndarray | None,
    anti_collision: str | None,
) -> Scenario:
    """The scenario (a name, a path or a :class:`Scenario`) with :func:`run`'s options that are given."""
    sc = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
    sc = with_aero(sc, aero)
    if duration is not None:
        sc = sc.with_overrides(duration=float(duration))
    if gains is not None:
        sc = sc.with_overrides(gains=np.asarray(gains, float), gains_source="override")
    if anti_collision is not None:
        sc = sc.with_overrides(anti_collision=anti_collision)
    return sc


def _compile_kernels(progress: bool | None) -> Callable[[str], None] | None:
    """Compile the control kernels where they are not cached (announced first, then timed on stderr);
    returns the run's announcer of what it does (a line on stderr), None where ``progress`` is False."""
    announced: list[str] = []  # the first run's notice, printed before compiling

    def announce(msg: str) -> None:
        announced.append(msg)
        print(msg, file=sys.stderr, flush=True)

    compile_s = warm_up(announce=None if progress is False else announce)
    if announced:
        print(f"compiled the control kernels in {compile_s:.0f} s (cached for later runs)", file=sys.stderr)
    return None if progress is False else announce


def _fly(
    env: SwarmEnv,
    policy: BacksteppingPolicy,
    log: RunLog,
    fast: FastLoop | None,
    bar: Progress,
    interrupt: CooperativeInterrupt,
) -> tuple[int, BaseException | None]:
    """Fly the reset ``env`` to its last period, logging each sample in ``log``: chunks of formed flight on the
    chunk driver ``fast`` where it is ready, every other period step by step (:class:`StepPeriod`: the same
    period in Python).
    Returns the periods flown and what stopped the run early (a Ctrl-C, a divergence) or None."""
    K, k = env.n_steps, 0
    step = StepPeriod(env, policy, log)  # the periods the chunk driver does not fly: the same period, in Python
    try:
        while True:
            if fast is not None and k < K and fast.ready():
                k = fast.run(min(K, k + CHUNK))
                fast.raise_if_stopped()
                bar.update(k)
                if interrupt.requested:
                    raise KeyboardInterrupt
                if fast.status == 0:  # done: the chunk flew to its end
                    continue
            if k >= K:  # the last sample: its observation and the command computed from it, nothing flown
                step.sample()
                return k, None
            if interrupt.requested:
                raise KeyboardInterrupt
            step.fly_next()
            k += 1
            if k % 50 == 0:
                bar.update(k)
    except (KeyboardInterrupt, SimulationDiverged) as exc:
        return k, exc


def _closed(log: RunLog, env: SwarmEnv, k: int, error: BaseException | None) -> RunLog:
    """The log of a run that flew ``k`` periods: its samples (the last holding the last inputs, with the
    wind's force at its instant) where it ended, the ``k`` before the error where one stopped it."""
    n_samples = k + 1 if error is None else k
    if error is None and k > 0:
        # the last sample has no following period: hold the last inputs (zero-order hold)
        log.hold_last(k)
        log.wind_force[k] = env.wind.drone_forces(k, env.sim.vel)
    return log.truncated(max(n_samples, 1))


def preset_signatures() -> list[tuple]:
    """The chunk driver's compile signatures for the physics presets (paper, realistic), and realistic under a
    sensing model (every preset's is the same signature for six drones), from the records of a short circle
    under each (what ``swarm-mj warm-up`` compiles)."""
    out = []
    for aero, sensing in (("paper", "perfect"), ("realistic", "perfect"), ("realistic", "mocap")):
        sc = with_aero(load_scenario("circle").with_overrides(duration=0.05, sensing=sensing), aero)
        env = SwarmEnv(sc, terminate_on_contact=False, raise_on_divergence=True)
        policy = BacksteppingPolicy(sc, env.params)
        log = RunLog.allocate(env.names, env.n_steps + 1, [st.name for st in env.sim.force_stages])
        if env.sensing is not None:
            log.views = ViewLog.allocate(env.n_steps + 1, env.n)
            env.reset()  # (the sensing stage's record exists from a reset on)
        out.append(signature(FastLoop(env, policy, log)._args(0, 0)))
    return out


def summarize(sc: Scenario, log: RunLog, env: SwarmEnv, policy: BacksteppingPolicy, wall: float) -> dict:
    """The JSON summary (stable keys of the issues; more may be added)."""
    t = log.t
    sim_time = float(t[-1]) if len(t) else 0.0
    # every drone at once (k, n, ...): the references are the followers' slots and the leader's commanded position
    ref = log.slot.copy()
    ref[:, 0] = log.pos_d[:, 0]
    out: dict = {
        "scenario": sc.name,
        "sim_time_s": sim_time,
        "wall_time_s": wall,
        "real_time_factor": sim_time / wall if wall > 0 else float("inf"),
        "n_drones": sc.n_drones,
        "seed": env.seed,
        "gains_source": sc.gains_source,
        **flown_choices(sc),
        "anti_collision_rule": policy.rule.name,
        "wind": bool(sc.wind.enabled),
        "wind_feedforward": bool(sc.wind_feedforward),
        "drones": _drones(sc, log, env, ref),
    }
    out["contacts"] = int(env.sim.contact_events)
    out["contact_steps"] = int(env.sim.contact_steps)
    # Ground contacts and crashes (docs/aero.md); 0 when the preset has no solid ground.
    ground = next((m for m in getattr(env.sim, "monitors", []) if getattr(m, "name", "") == "ground"), None)
    out["aero"] = sc.aero.to_dict()
    # what the controller adds where the rotors lag (docs/interpretations.md §1, §2)
    lag = sc.lag_horizons
    out["controller"] = {
        "mixer": getattr(policy, "mixer", "attitude_priority" if policy.attitude_priority else "clip"),
        "lag_compensation_s": list(lag) if lag is not None else None,
    }
    if sc.anti_collision == AUTO:  # which rule "auto" chose for this physics, and why (docs/barrier.md, "auto")
        out["anti_collision_auto"] = {"rule": policy.rule.name, "why": AUTO_CHOICE[bool(sc.aero.downwash)][1]}
    out["ground_contacts"] = int(ground.ground_contacts) if ground is not None else 0
    out["crashes"] = int(ground.crashes) if ground is not None else 0
    out["flight"] = flight = _flight(log, ref, ground)
    vehicle = policy.controller.params  # the run's vehicle: the keep-out and the jets are its sizes
    radii = keepout_radii(vehicle, rotor_radius=vehicle.rotor_radius)
    dist, rho = pair_measures(log.pos, radii)  # (k, pairs) distances, (k,) keep-out: one pass over the pairs
    out.update(keepout_summary(t, log.pos, radii, rho))  # docs/barrier.md
    if len(t):
        out["downwash_force_max_n"] = (
            float(norm(log.downwash).max()) if "downwash" in log.forces else 0.0
        )  # zeros without that stage
    out.update(_swarm(log, env, policy, dist, on_ground=bool(flight["never_took_off"])))
    out["sensing"] = _sensing(sc, log, policy)
    return out


def _sensing(sc: Scenario, log: RunLog, policy: BacksteppingPolicy) -> dict:
    """The summary's ``sensing``: the model flown (docs/sensing.md), whether each drone decided from its
    own view, the barrier's measurement-robust margin, and what the drones believed against the truth."""
    out: dict = {**sc.sensing.table(), "own_view": bool(getattr(policy, "own_view", False))}
    margin = getattr(policy, "margin", None)
    if margin is not None:
        out["robust_margin"] = margin._asdict()
    if log.views is not None:
        out.update(view_summary(log.views, log.pos))
    return out


def _drones(sc: Scenario, log: RunLog, env: SwarmEnv, ref: np.ndarray) -> dict:
    """Each drone's part of the summary by name: its position and attitude errors (RMSE) over the run and
    once steady (against ``ref``, (k, n, 3)), its rotor thrusts' extremes, its largest tilts, and the
    leader's step response where the trajectory is a step."""
    t = log.t
    steady = t >= sc.steady_after
    e = ref - log.pos  # (k, n, 3)
    att_e = np.rad2deg(log.att_d[:, :, :2] - log.rpy[:, :, :2])  # (k, n, 2) roll, pitch errors (deg)
    errors = _rmse_dicts(e, att_e)
    # t rises, so the steady samples are the last ones: a view of them, not a copy (the same rows, the same sums)
    first = int(np.argmax(steady))
    tail = slice(first, None) if steady[first:].all() else steady
    errors_steady = _rmse_dicts(e[tail], att_e[tail]) if steady.any() else [None] * len(log.names)
    tilt = np.rad2deg(np.abs(log.rpy[:, :, :2]).max(axis=0))  # (n, 2) the largest |roll|, |pitch|
    if len(t) > 1:
        # over time, then over the rotors (n,): the same extrema, along NumPy's fast axis order
        rotor_max, rotor_min = (
            np.nanmax(np.nanmax(log.rotor, axis=0), axis=1),
            np.nanmin(np.nanmin(log.rotor, axis=0), axis=1),
        )
    drones: dict = {}
    for i, name in enumerate(log.names):
        d: dict = {
            "rmse": errors[i],
            "rmse_steady": errors_steady[i],
            "max_rotor_thrust_n": float(rotor_max[i]) if len(t) > 1 else 0.0,
            "min_rotor_thrust_n": float(rotor_min[i]) if len(t) > 1 else 0.0,
            "max_abs_roll_deg": float(tilt[i, 0]),
            "max_abs_pitch_deg": float(tilt[i, 1]),
        }
        if i == 0 and sc.trajectory == "step" and len(t) > 1:
            target = env.reference.pos[0]
            yaw_t = float(env.reference.yaw[0])
            d["step"] = {
                ax: step_metrics(t, log.pos[:, 0, j], float(target[j]), float(log.pos[0, 0, j]))
                for j, ax in enumerate("xyz")
            }
            d["step"]["psi"] = step_metrics(t, log.rpy[:, 0, 2], yaw_t, float(log.rpy[0, 0, 2]))
        drones[name] = d
    return drones


def _swarm(log: RunLog, env: SwarmEnv, policy: BacksteppingPolicy, dist: np.ndarray, on_ground: bool) -> dict:
    """The summary's keys of the swarm (present for one drone too): the least separation (over the pair
    distances ``dist``, (k, pairs)) and where, the formation (:func:`_formation`), the downwash dip
    (:func:`_dip`) and the rule's events (:func:`_events`)."""
    if len(log.names) <= 1:  # the stable keys exist for one drone too
        return {
            "min_separation_m": None,
            "formation": None,
            "downwash_dip_worst_m": 0.0,
            "anti_collision": {
                "rule": policy.rule.name,
                "events": 0,
                "yields": 0,
                "relaxations": 0,
                "relaxations_vs_leader": 0,
                "reserve_periods": 0,
                "joint_periods": 0,
            },
        }
    t = log.t
    sim_time = float(t[-1]) if len(t) else 0.0
    out: dict = {}
    sep, kk, pair = min_separation(log.pos, dist)
    out["min_separation_m"] = sep
    out["min_separation_at_s"] = float(t[int(kk)]) if kk >= 0 else None
    out["min_separation_pair"] = [log.names[pair[0]], log.names[pair[1]]]
    airborne = (log.pos[:, :, 2] > 0.1).all(axis=1)
    if airborne.any():
        out["min_separation_airborne_m"] = min_separation(log.pos[airborne], dist[airborne])[0]
    changes = env.scenario.diameter_schedule().change_times
    out["formation"] = _formation(log, changes[changes <= sim_time], on_ground=on_ground)
    dip = _dip(log, policy.controller.params)
    out["downwash_dip_worst_m"] = dip["worst_m"]
    out["downwash_dip"] = dip
    out["anti_collision"] = _events(policy)
    return out


def _formation(log: RunLog, changes: np.ndarray, on_ground: bool) -> dict:
    """The formation's settling after each D change within the run (``changes``), its largest error once
    settled and its final error; never settled (inf) where a drone never took off (``on_ground``: a
    formation on the ground is no formation, experiments/outcome.py)."""
    lead = leader_distances(log.pos)
    settling, max_err = formation_settling(log.t, lead, log.D, changes)
    if on_ground:
        settling = [float("inf")] * len(settling)
    return {
        "settling_s": settling,
        "change_times_s": changes.tolist(),
        "max_distance_error_m": max_err,
        "final_distance_error_m": float(np.abs(lead[-1] - log.D[-1]).max()),
    }


def _events(policy: BacksteppingPolicy) -> dict:
    """The anti-collision rule's events: all, the altitude yields, the barrier filter's relaxations
    (constraints infeasible within the limits), its drone-periods on the reserve and those flown from a
    cluster's joint QP (docs/barrier.md)."""
    ev = policy.events
    rule = policy.rule
    filters = [getattr(c, "separation_filter", None) for c in getattr(rule, "copies", [rule])]  # each drone's copy
    return {
        "rule": rule.name,
        "events": len(ev),
        "yields": sum(1 for e in ev if e["action"] in ("up", "down")),
        "relaxations": sum(1 for e in ev if e["action"] == "relax"),
        # … of which the row that asked most beyond the drone's limits was its pair with the leader
        "relaxations_vs_leader": sum(1 for e in ev if e["action"] == "relax" and e.get("other") == 0),
        "reserve_periods": sum(int(getattr(f, "reserve_periods", 0)) for f in filters),
        "joint_periods": sum(int(getattr(f, "joint_periods", 0)) for f in filters),
    }


def _dip(log: RunLog, vehicle: QuadParams) -> dict:
    """The worst altitude dip of a drone in another's jet (:func:`~swarm_mj.metrics.downwash_dip`, the
    vehicle's jet), with the drones named."""
    dip = downwash_dip(log.t, log.pos, log.pos_d, log.quat, **jet_geometry(vehicle))
    named = {key: log.names[dip[key]] if dip[key] >= 0 else None for key in ("drone", "above")}
    return {
        "worst_m": dip["worst_m"],
        **named,
        "at_s": dip["t_s"],
        "time_in_jet_s": dip["time_in_jet_s"],
        "below_ref_worst_m": dip["below_ref_worst_m"],
    }


def flown_choices(sc: Scenario) -> dict:
    """What the run flew, by name (swarm_mj/choices.py): the vehicle, the physics preset and the gains with
    where they came from (``origin``: a key of :data:`~swarm_mj.choices.GAINS_ORIGINS`)."""
    return {
        "vehicle": sc.vehicle,
        "physics": sc.aero.model,
        "gains": {"source": gains_name(sc.gains_source), "origin": sc.gains_origin},
    }


def _flight(log: RunLog, ref: np.ndarray, ground: object | None) -> dict:
    """Whether every drone took off, none crashed and none was lost (:func:`~.outcome.flight_outcome`)
    from the log, the references ref (k, n, 3) and the ground monitor's contacts (None: no ground)."""
    crashed = [int(c[1]) for c in getattr(ground, "log", []) if c[4]]
    return flight_outcome(log.t, log.pos[:, :, 2], ref[:, :, 2], log.names, crashed)


def _rmse_dicts(e: np.ndarray, att_e: np.ndarray) -> list[dict]:
    """Each drone's RMSE (eq. 38) of its position errors e (k, n, 3) and attitude errors att_e (k, n, 2) (deg)."""
    r = rmse(e)  # (n, 3)
    ra = rmse(att_e)  # (n, 2)
    return [
        {"x": float(x), "y": float(y), "z": float(z), "roll_deg": float(roll), "pitch_deg": float(pitch)}
        for (x, y, z), (roll, pitch) in zip(r.tolist(), ra.tolist(), strict=True)
    ]
