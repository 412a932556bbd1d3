"""Scenario files: TOML data in ``scenarios/``, validated into dataclasses.

A scenario names the drones and their starts, the leader's trajectory, the D schedule,
the anti-collision rule, the controller gains, the wind, the duration, the control
period, the physics timestep and the seed. Code never branches on a scenario's name.
Every mistake is reported as one :class:`~swarm_mj.errors.UserError` naming the file and
the field, e.g. ``scenarios/x.toml: formation.diameter: D must be positive, got -1 m``,
before anything flies: field types and ranges, trajectory parameters (and the reference they
give: finite, above the ground, within 1 km), start spacing, the duration against the control
period and against the memory its log would take, and seeds in [0, 2**32 − 1].
"""

from __future__ import annotations

import inspect
import os
import tomllib
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from .choices import GainsChoice, VehicleLike, choose_gains, relag, resolve_vehicle
from .control.backstepping import TABLE4_GAINS, check_gains, load_gains
from .errors import UserError
from .formation.anticollision import ANTI_COLLISION_RULES, AUTO, resolve_rule, rule_record
from .formation.barrier import BarrierParams
from .formation.rule_params import PARAM_TABLE, LayersParams, RuleRecord, check_overrides
from .formation.slots import DiameterSchedule
from .physics.aero.presets import PAPER, AeroConfig, parse_aero, preset, vehicle_lag, with_aero
from .physics.mixing import MIXERS
from .physics.params import DEFAULT_PARAMS, QuadParams
from .physics.wind import WindConfig
from .resources import SCENARIOS_DIR
from .scenario_sensing import SensingLike, parse_scenario_sensing, sensing_overrides
from .scenario_toml import scenario_toml as scenario_toml  # re-exported: the stress command writes with it
from .sensing.params import SensingParams
from .starts import (  # noqa: F401 - re-exported: the checks of where drones start live in swarm_mj.starts
    MAX_RANGE_M,
    START_CLEARANCE_M,
    RandomStart,
    check_random_start_feasible,
    check_start_spacing,
    random_follower_starts,
)
from .table_fields import check_keys, choice, finite, flag, number, only_numbers, subtable, vec
from .trajectories import TRAJECTORIES, make_trajectory

#: The controller's ``[controller] lag_compensation`` choices (:attr:`Scenario.lag_horizons`).
LAG_COMPENSATION = ("auto", "on", "off")

#: The top level's ``integrator`` choices (MuJoCo's integrators, swarm_mj/physics/world.py).
INTEGRATORS = ("RK4", "Euler", "implicitfast")

_TOP_KEYS = {
    "name",
    "description",
    "duration",
    "control_period",
    "timestep",
    "integrator",
    "seed",
    "steady_after",
    "leader",
    "followers",
    "formation",
    "controller",
    "wind",
    "aero",
    "vehicle",
    "sensing",
}
_LEADER_KEYS = {"trajectory", "params", "start", "yaw_deg"}
_FOLLOWER_KEYS = {"count", "start", "random_start"}
_RANDOM_KEYS = {"radius", "min_spacing", "seed", "max_tries"}
#: ``[formation]``: the D schedule, the rule, and the fields of every rule's parameter record (the
#: union, :data:`~swarm_mj.formation.rule_params.PARAM_KEYS`, whatever the rule: a key only another
#: rule reads is accepted); ``[controller]``: the ones asked of the controller
#: (:class:`~swarm_mj.formation.rule_params.ControllerParams`).
_RULE_KEYS = {t: {k for k, tk in PARAM_TABLE.items() if tk == t} for t in ("formation", "controller")}
_FORMATION_KEYS = {"diameter", "anti_collision", "barrier", *_RULE_KEYS["formation"]}
_CONTROLLER_KEYS = {"gains", "wind_feedforward", "attitude_map", "mixer", "lag_compensation", *_RULE_KEYS["controller"]}
_VEHICLE_KEYS = {"model"}
#: Where the docs list the ``[formation]`` keys (an unknown key's message points there: they are many).
_FORMATION_DOCS = 'docs/anticollision.md, "Setting a parameter"'


@dataclass(frozen=True)
class Scenario:
    name: str
    description: str
    duration: float
    control_period: float
    timestep: float
    integrator: str
    seed: int
    steady_after: float
    trajectory: str
    trajectory_params: dict[str, Any]
    leader_start: np.ndarray  # (3,)
    leader_yaw_deg: float
    n_followers: int
    follower_starts: np.ndarray | None  # (n_f, 3) or None when random
    random_start: RandomStart | None
    diameter: Any  # float or [[t, D], ...]
    anti_collision: str
    anti_collision_params: dict[str, Any]  # the record's fields the scenario sets (sensing_range aside)
    sensing_range: float
    gains: np.ndarray  # (12,) or (n, 12)
    gains_source: str
    wind_feedforward: bool
    attitude_map: str
    wind: WindConfig
    path: str = ""
    raw: dict = field(default_factory=dict, repr=False, compare=False)
    aero: AeroConfig = PAPER  # physics preset (docs/aero.md); the paper's model by default
    mixer: str = "auto"  # "auto" | "clip" | "attitude_priority" | "yaw_last" (see mixer_flown)
    lag_compensation: str = "auto"  # "auto" | "on" | "off" (see lag_horizons)
    vehicle: str = "paper"  # [vehicle] model: a bundled vehicle's name or a vehicle file (docs/vehicles.md)
    params: QuadParams = DEFAULT_PARAMS  # the vehicle's parameters; the paper's (Table 1) by default
    vehicle_mixer: str | None = None  # the vehicle file's ``mixer``: what mixer = "auto" becomes on it
    #: ``[formation.barrier]``: the barrier filter's parameters the scenario sets (docs/barrier.md)
    barrier_params: dict[str, Any] = field(default_factory=dict)
    #: where ``gains`` came from: a key of :data:`swarm_mj.choices.GAINS_ORIGINS` (choices.choose_gains)
    gains_origin: str = "scenario"
    #: ``[sensing]``: what each drone knows of the others (docs/sensing.md); the oracle by default
    sensing: SensingParams = SensingParams()

    @property
    def start_clearance(self) -> float:
        """Least centre distance between two starts (m): :data:`START_CLEARANCE_M` scaled by the
        vehicle's rotor span over the paper drone's (exactly :data:`START_CLEARANCE_M` for the paper)."""
        return START_CLEARANCE_M * (self.params.rotor_span / DEFAULT_PARAMS.rotor_span)

    @property
    def rule(self) -> str:
        """The anti-collision rule flown: ``anti_collision`` with ``"auto"`` resolved for the physics
        (:func:`~swarm_mj.formation.anticollision.resolve_rule`)."""
        return resolve_rule(self.anti_collision, self.aero.downwash)

    @property
    def rule_params(self) -> RuleRecord:
        """The parameter record the rule flies with, its own record type: :attr:`rule`'s preset with its
        sizes scaled to the vehicle, then the scenario's ``[formation]`` keys that are its fields (and its
        ``sensing_range``), as :func:`~swarm_mj.formation.anticollision.make_rule` builds it
        (:func:`~swarm_mj.formation.anticollision.rule_record`)."""
        return rule_record(self.rule, self.params, {**self.anti_collision_params, "sensing_range": self.sensing_range})

    @property
    def mixer_flown(self) -> str:
        """The controller's mixer: ``"clip"`` (the paper's per-rotor clipping), ``"attitude_priority"``
        (:func:`~swarm_mj.physics.mixing.attitude_priority`) or ``"yaw_last"``
        (:func:`~swarm_mj.physics.mixing.yaw_last`). ``mixer = "auto"`` is the vehicle file's ``mixer``
        where it gives one (the Crazyflie's ``yaw_last``, docs/vehicles.md "Mixer"), else attitude
        priority wherever the rotors have lag (``--aero realistic``) and the paper's per-rotor clipping
        otherwise."""
        if self.mixer != "auto":
            return self.mixer
        if self.vehicle_mixer is not None:
            return self.vehicle_mixer
        return "attitude_priority" if self.aero.motor_tau > 0 else "clip"

    @property
    def attitude_priority_on(self) -> bool:
        """Whether the controller desaturates its rotor commands, torques before thrust
        (:attr:`mixer_flown` ``"attitude_priority"`` or ``"yaw_last"``), rather than clipping each rotor."""
        return self.mixer_flown != "clip"

    @property
    def lag_horizons(self) -> tuple[float, float] | None:
        """(d_att, d_rate) s of the controller's rotor-lag compensation
        (:class:`~swarm_mj.control.lag.AttitudePredictor`: the rotors' time constant plus the control
        period, and the time constant), or None: ``lag_compensation = "auto"`` compensates wherever
        the rotors have lag (``--aero realistic``) and not under the paper's physics."""
        on = self.lag_compensation == "on" or (self.lag_compensation == "auto" and self.aero.motor_tau > 0)
        if not on:
            return None
        return (self.aero.motor_tau + self.control_period, self.aero.motor_tau)

    @property
    def n_drones(self) -> int:
        return 1 + self.n_followers

    @property
    def names(self) -> list[str]:
        return ["leader"] + [f"follower{k}" for k in range(1, self.n_followers + 1)]

    def diameter_schedule(self) -> DiameterSchedule:
        return DiameterSchedule(self.diameter)

    def make_trajectory(self):
        return make_trajectory(self.trajectory, self.trajectory_params, where=f"{self.path}: leader.trajectory")

    def initial_positions(self, seed: int | None = None) -> np.ndarray:
        """(n, 3) start positions: leader first, then followers (random ones drawn with their seed, or with
        ``seed`` when given: a vector environment's copy, swarm_mj/pipeline/swarm.py)."""
        if self.n_followers == 0:
            return self.leader_start[None, :].copy()
        if self.follower_starts is not None:
            return np.vstack([self.leader_start, self.follower_starts])
        assert self.random_start is not None  # followers without explicit starts have random_start (load_scenario)
        return np.vstack(
            [
                self.leader_start,
                random_follower_starts(
                    self.leader_start,
                    self.n_followers,
                    self.random_start if seed is None else replace(self.random_start, seed=int(seed)),
                    where=self.path,
                    clearance=self.start_clearance,
                ),
            ]
        )

    def with_overrides(self, **kw) -> Scenario:
        """A copy with some fields replaced (e.g. ``gains=...``, ``anti_collision="paper"``).

        ``seed=s`` is the scenario's seed s everywhere (``run --seed``, ``sweep``, ``stress``,
        the report): it seeds the wind turbulence **and** re-derives seeded random follower
        starts with seed s (unless ``random_start`` is given too). ``duration`` and ``seed``
        are checked as in a scenario file (:class:`UserError` naming the field).
        ``vehicle=V`` (a bundled name, a vehicle file or a :class:`~swarm_mj.vehicles.Vehicle`) flies V:
        its parameters, mixer, rotor lag and, unless chosen, its gains (:func:`vehicle_overrides`).
        ``gains=`` without ``gains_origin`` are gains given for the run (they win over the vehicle's).
        ``sensing=`` (a preset's name or a record) replaces the ``[sensing]`` table (:func:`sensing_overrides`).
        """
        if "vehicle" in kw:
            kw = {**vehicle_overrides(self, kw.pop("vehicle")), **kw}
        if "sensing" in kw:
            kw = {**sensing_overrides(self, kw.pop("sensing")), **kw}
        if "gains" in kw and "gains_origin" not in kw:
            kw["gains_origin"] = "option"
        if "seed" in kw:
            kw["seed"] = check_seed(kw["seed"], "seed")
            if self.random_start is not None and "random_start" not in kw:
                kw["random_start"] = replace(self.random_start, seed=kw["seed"])
        if "duration" in kw or "control_period" in kw:
            T = float(kw.get("control_period", self.control_period))
            kw["duration"] = check_duration(
                kw.get("duration", self.duration), T, int(kw.get("n_followers", self.n_followers)) + 1, "duration"
            )
        return replace(self, **kw)


#: Largest seed: numpy's legacy and most external generators take 32-bit seeds; one range everywhere.
MAX_SEED = 2**32 - 1

#: Most followers a scenario may hold: the neighbour arrays grow as n², and the model compiles
#: and the random starts are drawn in Python (the paper flies 5).
MAX_FOLLOWERS = 200

#: Most draws of the random starts' rejection sampling.
MAX_TRIES = 1_000_000

#: Share of the available memory a run's log may take before the run is refused.
MEMORY_SHARE = 0.5


def check_seed(v: Any, where: str = "seed") -> int:
    """A seed: an integer in [0, 2**32 − 1] (:class:`UserError` naming ``where`` otherwise)."""
    if isinstance(v, bool) or not isinstance(v, (int, np.integer)):
        raise UserError(f"must be an integer >= 0 and <= {MAX_SEED}, got {v!r}", where=where)
    if not 0 <= int(v) <= MAX_SEED:
        raise UserError(f"must be >= 0 and <= {MAX_SEED}, got {int(v)}", where=where)
    return int(v)


def available_memory_bytes() -> int | None:
    """MemAvailable of /proc/meminfo (Linux), else free physical pages × page size; None if unknown."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return None


def run_log_bytes(n_steps: int, n_drones: int) -> int:
    """Bytes of the arrays a run keeps for ``n_steps`` control periods of ``n_drones`` drones:
    the log (``runner.RunLog``: 33 floats per drone and 5 shared per sample) plus the
    precomputed reference, D schedule and wind series (about 30 floats per sample), float64."""
    return 8 * (int(n_steps) + 1) * (33 * int(n_drones) + 35)


def _gib(b: float) -> str:
    return f"{b / 2**30:.3g} GiB" if b >= 2**30 else f"{b / 2**20:.3g} MiB"


def check_duration(duration: Any, control_period: float, n_drones: int, where: str = "duration") -> float:
    """A run's duration: a finite positive number of seconds, at least one control period, and
    short enough that the run's log (:func:`run_log_bytes`) fits in :data:`MEMORY_SHARE` of the
    available memory. Returns it as a float; :class:`UserError` naming ``where`` otherwise."""
    if isinstance(duration, bool) or not isinstance(duration, (int, float, np.integer, np.floating)):
        raise UserError(f"must be a number of seconds, got {duration!r}", where=where)
    d = float(duration)
    if not np.isfinite(d):
        raise UserError(f"must be a finite number of seconds, got {d}", where=where)
    if d <= 0:
        raise UserError(f"must be positive, got {d:g} s", where=where)
    if d < control_period * (1 - 1e-9):
        raise UserError(
            f"{d:g} s is shorter than one control period ({control_period:g} s): nothing would be simulated",
            where=where,
        )
    steps = d / control_period
    if not np.isfinite(steps):  # d near the largest float (1e308 s): round() would raise
        raise UserError(f"{d:g} s at {control_period:g} s per step is too many steps: shorten the run", where=where)
    n_steps = round(steps)
    need = run_log_bytes(n_steps, n_drones)
    avail = available_memory_bytes()
    if avail is not None and need > MEMORY_SHARE * avail:
        raise UserError(
            f"{d:g} s at {control_period:g} s per step is {n_steps:.3g} steps of {n_drones} drone(s); "
            f"its log would take about {_gib(need)}, more than {MEMORY_SHARE:.0%} of the "
            f"{_gib(avail)} of memory available: shorten the run",
            where=where,
        )
    return d


def check_trajectory_params(name: str, params: dict, where: str) -> None:
    """Every trajectory parameter by type before the trajectory is built: scalars finite
    numbers, points (``target``, ``position``, ``center``) lists of finite numbers of the
    right length. ``where`` is e.g. ``file: leader.params``."""
    sig = inspect.signature(TRAJECTORIES[name])
    for key, v in params.items():
        if key not in sig.parameters:
            raise UserError(
                f"unknown parameter of trajectory {name!r}; allowed: {', '.join(sig.parameters)}",
                where=f"{where}.{key}",
            )
        default = sig.parameters[key].default
        if isinstance(default, (tuple, list)):
            m = len(default)
            if (
                not isinstance(v, list)
                or len(v) != m
                or any(isinstance(x, bool) or not isinstance(x, (int, float)) for x in v)
            ):
                raise UserError(f"must be a list of {m} numbers, got {v!r}", where=f"{where}.{key}")
            if not all(finite(x) for x in v):
                raise UserError(f"must be finite numbers, got {v!r}", where=f"{where}.{key}")
        else:
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                raise UserError(f"must be a number, got {v!r}", where=f"{where}.{key}")
            if not finite(v):
                raise UserError(f"must be finite, got {v!r}", where=f"{where}.{key}")


def check_reference(traj, duration: float, control_period: float, where: str) -> None:
    """The leader's reference is finite and above the ground over the whole run (sampled at up to
    10 001 control instants, ends included): a parameter that makes it overflow (``omega = 1e200``)
    or go underground is refused before anything flies."""
    n = int(round(duration / control_period))
    k = np.unique(np.r_[np.linspace(0, n, min(n + 1, 10001)).round().astype(np.int64), n])
    t = k * control_period
    try:
        with np.errstate(all="ignore"):
            ref = traj(t)
    except (ArithmeticError, ValueError) as exc:  # e.g. omega**2 overflowing a Python float
        raise UserError(f"the reference is not finite ({exc}); check the parameters", where=where) from None
    for f in ("pos", "vel", "acc", "yaw", "yaw_rate", "yaw_acc"):
        a = np.asarray(getattr(ref, f), float)
        bad = ~np.isfinite(a.reshape(len(t), -1)).all(axis=1)
        if bad.any():
            raise UserError(
                f"the reference's {f.replace('_', ' ')} is not finite at t = {t[bad][0]:g} s; check the parameters",
                where=where,
            )
    far = np.linalg.norm(ref.pos, axis=1) > MAX_RANGE_M
    if far.any():
        raise UserError(
            f"the reference goes farther than {MAX_RANGE_M:g} m from the origin (at t = {t[far][0]:g} s), "
            f"where the simulator stops the run",
            where=where,
        )
    z = ref.pos[:, 2]
    if (z < 0).any():
        i = int(np.argmax(z < 0))
        raise UserError(f"the reference goes below the ground (z = {z[i]:g} m at t = {t[i]:g} s)", where=where)


# --------------------------------------------------------------------------- one table, one record
class _Clock(NamedTuple):
    """The top level's timing: the run's duration, control period (T), physics timestep and integrator, and its seed."""

    duration: float
    control_period: float
    timestep: float
    integrator: str
    seed: int


class _Vehicle(NamedTuple):
    """``[vehicle]``: the model as given, its parameters, its file's ``mixer`` and ``gains`` file (or None)."""

    model: str
    params: QuadParams
    mixer: str | None
    gains_file: Path | None


class _Leader(NamedTuple):
    """``[leader]``: the trajectory, its parameters, the start and the yaw."""

    trajectory: str
    params: dict[str, Any]
    start: np.ndarray  # (3,)
    yaw_deg: float


class _Followers(NamedTuple):
    """``[followers]``: how many, and their starts or the rule that draws them (None for none)."""

    n: int
    starts: np.ndarray | None  # (count, 3)
    random_start: RandomStart | None


class _Formation(NamedTuple):
    """``[formation]``: the D schedule, the rule, its parameter record's fields, the sensing range and
    ``[formation.barrier]``."""

    diameter: Any
    anti_collision: str
    rule_params: dict[str, Any]
    sensing_range: float
    barrier: dict[str, Any]


class _Controller(NamedTuple):
    """``[controller]``: the rule's fields asked of the controller, the gains chosen and the switches."""

    rule_params: dict[str, Any]
    gains: GainsChoice
    wind_feedforward: bool
    attitude_map: str
    mixer: str
    lag_compensation: str


def _parse_clock(data: dict, w: str) -> _Clock:
    """The top level's ``duration``, ``control_period`` (at most the duration), ``timestep`` (dividing it),
    ``integrator`` and ``seed``."""
    duration = float(number(data, "duration", None, w, positive=True))
    T = float(number(data, "control_period", 0.01, w, positive=True))
    if T > duration:
        raise UserError(
            f"{T:g} s is longer than the duration ({duration:g} s): nothing would be simulated",
            where=f"{w}control_period",
        )
    dt = float(number(data, "timestep", 0.005, w, positive=True))
    nsub = round(T / dt)
    if nsub < 1 or abs(nsub * dt - T) > 1e-9:
        raise UserError(f"must divide control_period = {T} s (got {dt} s)", where=f"{w}timestep")
    integrator = choice(
        data, "integrator", "RK4", INTEGRATORS, w, "unknown integrator {v!r}; choose RK4, Euler or implicitfast"
    )
    seed = check_seed(data.get("seed", 0), f"{w}seed")
    return _Clock(duration=duration, control_period=T, timestep=dt, integrator=integrator, seed=seed)


def _parse_vehicle(table: Any, base: Path, where: str = "vehicle") -> _Vehicle:
    """The ``[vehicle]`` table: ``model = "paper"`` (the default: Table 1, :data:`DEFAULT_PARAMS`),
    a bundled vehicle's name (``"crazyflie21"``) or a vehicle file (a path, relative to the scenario's
    folder; :func:`swarm_mj.choices.resolve_vehicle`); :class:`UserError` naming the field or the
    vehicle file and key otherwise (docs/vehicles.md)."""
    if table is None:
        return _Vehicle(model="paper", params=DEFAULT_PARAMS, mixer=None, gains_file=None)
    t = check_keys(table, _VEHICLE_KEYS, where)
    model, vehicle, _ = resolve_vehicle(t.get("model", "paper"), base, f"{where}.model")
    return _Vehicle(model=model, params=vehicle.params(), mixer=vehicle.mixer, gains_file=vehicle.gains_file)


def _parse_leader(data: dict, w: str) -> _Leader:
    """``[leader]`` (required): a known trajectory whose parameters give a trajectory, the start, the yaw."""
    if "leader" not in data:
        raise UserError("missing table", where=w + "leader")
    leader = check_keys(data["leader"], _LEADER_KEYS, w + "leader")
    wl = f"{w}leader."
    traj = choice(
        leader, "trajectory", None, sorted(TRAJECTORIES), wl, "unknown trajectory {v!r}; choose one of {choices}"
    )
    tparams = subtable(leader, "params", {}, wl)
    check_trajectory_params(traj, tparams, f"{wl}params")
    make_trajectory(traj, tparams, where=f"{wl}params")  # validates the parameters
    start = vec(leader.get("start", [0.0, 0.0, 0.0]), 3, f"{wl}start")
    return _Leader(trajectory=traj, params=tparams, start=start, yaw_deg=float(number(leader, "yaw_deg", 0.0, wl)))


def _parse_followers(data: dict, w: str, seed: int, path: str, clearance: float) -> _Followers:
    """``[followers]`` (none by default): ``count`` (at most :data:`MAX_FOLLOWERS`; the number of starts by
    default) and either ``start`` (count × [x, y, z]) or ``random_start`` (drawn with ``seed`` unless it
    gives its own, and feasible at ``clearance``)."""
    fol = check_keys(data.get("followers", {"count": 0}), _FOLLOWER_KEYS, w + "followers")
    if "start" in fol and "random_start" in fol:
        raise UserError("give either start or random_start, not both", where=f"{w}followers")
    default_count = len(fol["start"]) if isinstance(fol.get("start"), list) else None
    n_f = int(number(fol, "count", default_count, f"{w}followers.", integer=True, minimum=0))
    if n_f > MAX_FOLLOWERS:
        raise UserError(f"at most {MAX_FOLLOWERS} followers, got {n_f}", where=f"{w}followers.count")
    if n_f == 0:
        return _Followers(n=0, starts=None, random_start=None)
    if "start" in fol:
        starts = vec(fol["start"], None, f"{w}followers.start")
        if starts.shape != (n_f, 3):
            raise UserError(f"must be {n_f} [x, y, z] positions, got shape {starts.shape}", where=f"{w}followers.start")
        return _Followers(n=n_f, starts=starts, random_start=None)
    if "random_start" not in fol:
        raise UserError("followers need start positions or random_start", where=f"{w}followers")
    r = check_keys(fol["random_start"], _RANDOM_KEYS, f"{w}followers.random_start")
    wr = f"{w}followers.random_start."
    rstart = RandomStart(
        radius=float(number(r, "radius", 3.0, wr, positive=True)),
        min_spacing=float(number(r, "min_spacing", 0.6, wr, positive=True)),
        seed=check_seed(r.get("seed", seed), f"{wr}seed"),
        max_tries=int(number(r, "max_tries", 20000, wr, integer=True, minimum=1)),
    )
    if rstart.max_tries > MAX_TRIES:
        raise UserError(f"at most {MAX_TRIES}, got {rstart.max_tries}", where=f"{wr}max_tries")
    check_random_start_feasible(n_f, rstart, path, clearance)
    return _Followers(n=n_f, starts=None, random_start=rstart)


def _parse_formation(data: dict, w: str, path: str) -> _Formation:
    """``[formation]``: the D schedule, the rule (:data:`AUTO` by default), the rule's parameters
    (:func:`~swarm_mj.formation.rule_params.check_overrides`) and ``[formation.barrier]``
    (:class:`~swarm_mj.formation.barrier.BarrierParams`, its checks across fields included)."""
    form = check_keys(data.get("formation", {}), _FORMATION_KEYS, w + "formation", see=_FORMATION_DOCS)
    wf = f"{w}formation."
    diameter = form.get("diameter", 1.0)
    if not only_numbers(diameter):
        raise UserError(f"must be a number or a list of [time, D] pairs, got {diameter!r}", where=f"{wf}diameter")
    DiameterSchedule(diameter, where=f"{wf}diameter")
    rules = (AUTO, *ANTI_COLLISION_RULES)
    rule = choice(form, "anti_collision", AUTO, rules, wf, "unknown rule {v!r}; choose one of {choices}")
    params = check_overrides({k: v for k, v in form.items() if k in _RULE_KEYS["formation"]}, where=f"{w}formation")
    sensing = float(params.pop("sensing_range", LayersParams().sensing_range))
    barrier = subtable(form, "barrier", {}, wf, "must be a table of the barrier filter's parameters")
    barrier = check_overrides(barrier, where=f"{wf}barrier", record=BarrierParams)
    try:
        BarrierParams(**barrier)  # the checks across its fields
    except UserError as exc:
        raise UserError(str(exc), where=path or None) from None
    return _Formation(
        diameter=diameter, anti_collision=rule, rule_params=params, sensing_range=sensing, barrier=barrier
    )


def _parse_gains(g: Any, base: Path, n_drones: int, where: str) -> tuple[np.ndarray, str] | None:
    """``[controller] gains`` (None where absent): ``"table4"``, a gains file (relative to ``base``) or
    12 numbers (or one row of 12 per drone); with their source."""
    if g is None:  # the scenario names none: the vehicle's, else Table 4 (swarm_mj.choices.choose_gains)
        return None
    if isinstance(g, str):
        if g == "table4":
            return TABLE4_GAINS.copy(), "table4"
        gpath = (base / g) if not Path(g).is_absolute() else Path(g)
        try:
            return load_gains(gpath), str(gpath)
        except UserError as exc:
            raise UserError(str(exc), where=where) from None
    if not only_numbers(g):
        raise UserError(f'must be "table4", a gains file or 12 numbers, got {g!r}', where=where)
    return check_gains(g, n_drones, where=where), "inline"


def _parse_controller(data: dict, w: str, base: Path, n_drones: int, vehicle_gains: Path | None) -> _Controller:
    """``[controller]``: the rule's fields asked of the controller, the gains (:func:`_parse_gains`, chosen
    over the vehicle's by :func:`~swarm_mj.choices.choose_gains`), the wind feedforward, the attitude map,
    the mixer and the lag compensation."""
    ctl = check_keys(data.get("controller", {}), _CONTROLLER_KEYS, w + "controller")
    wc = f"{w}controller."
    params = check_overrides({k: v for k, v in ctl.items() if k in _RULE_KEYS["controller"]}, f"{w}controller")
    gains = _parse_gains(ctl.get("gains"), base, n_drones, f"{wc}gains")
    return _Controller(
        rule_params=params,
        gains=choose_gains(scenario=gains, vehicle=vehicle_gains),
        wind_feedforward=flag(ctl, "wind_feedforward", True, wc),
        attitude_map=choice(
            ctl, "attitude_map", "exact", ("exact", "paper"), wc, "must be 'exact' or 'paper', got {v!r}"
        ),
        mixer=choice(ctl, "mixer", "auto", MIXERS, wc),
        lag_compensation=choice(ctl, "lag_compensation", "auto", LAG_COMPENSATION, wc),
    )


def _parse_wind(data: dict, w: str, path: str) -> WindConfig:
    """``[wind]`` (off by default): :meth:`~swarm_mj.physics.wind.WindConfig.from_dict`."""
    return WindConfig.from_dict(subtable(data, "wind", {"enabled": False}, w), where=path)


def _parse_aero(data: dict, w: str, params: QuadParams, dt: float) -> AeroConfig:
    """``[aero]`` (the paper's physics by default): :func:`~swarm_mj.physics.aero.presets.parse_aero` with
    the vehicle's rotor lag, which is 0 or at least the physics timestep ``dt``."""
    aero = vehicle_lag(parse_aero(data.get("aero"), where=f"{w}aero"), data.get("aero"), params)
    if 0 < aero.motor_tau < dt:
        raise UserError(
            f"must be 0 (ideal rotors) or at least the physics timestep {dt:g} s, got {aero.motor_tau:g}",
            where=f"{w}aero.motor_tau",
        )
    return aero


def _check_across(clock: _Clock, leader: _Leader, followers: _Followers, w: str, clearance: float) -> None:
    """The checks across tables, still before anything flies: the duration against the log's memory,
    the leader's reference over the run, the spacing of the starts."""
    duration, T, n_f = clock.duration, clock.control_period, followers.n
    check_duration(duration, T, 1 + n_f, f"{w}duration")
    traj = make_trajectory(leader.trajectory, leader.params, where=f"{w}leader.params")
    check_reference(traj, duration, T, f"{w}leader.params")
    names = ["leader"] + [f"follower{k}" for k in range(1, n_f + 1)]
    if followers.starts is not None:
        check_start_spacing(np.vstack([leader.start, followers.starts]), names, f"{w}followers.start", clearance)
    else:
        check_start_spacing(leader.start[None, :], names[:1], f"{w}leader.start", clearance)


def _parse_labels(data: dict, w: str, path: str, name: str | None) -> tuple[str, str]:
    """The top level's ``name`` (``name`` when given, else the file's stem) and ``description``: strings."""
    for key in ("name", "description"):
        if key in data and not isinstance(data[key], str):
            raise UserError(f"must be a string, got {data[key]!r}", where=f"{w}{key}")
    nm = name or data.get("name") or (Path(path).stem if not path.startswith("<") else "scenario")
    return str(nm), str(data.get("description", ""))


def parse_scenario(data: dict, path: str = "<scenario>", name: str | None = None) -> Scenario:
    """Validate a parsed TOML document into a :class:`Scenario`: each table by its own reader, in the
    order the first mistake is reported, then the checks across tables."""
    base = Path(path).parent if path and not path.startswith("<") else Path.cwd()
    check_keys(data, _TOP_KEYS, path)
    w = f"{path}: "
    clock = _parse_clock(data, w)
    vehicle = _parse_vehicle(data.get("vehicle"), base, f"{w}vehicle")
    clearance = START_CLEARANCE_M * (vehicle.params.rotor_span / DEFAULT_PARAMS.rotor_span)
    steady_after = float(number(data, "steady_after", 10.0, w, minimum=0))
    leader = _parse_leader(data, w)
    followers = _parse_followers(data, w, clock.seed, path, clearance)
    formation = _parse_formation(data, w, path)
    controller = _parse_controller(data, w, base, 1 + followers.n, vehicle.gains_file)
    wind = _parse_wind(data, w, path)
    aero = _parse_aero(data, w, vehicle.params, clock.timestep)
    sensing, sensing_range = parse_scenario_sensing(data, w, formation.sensing_range)
    _check_across(clock, leader, followers, w, clearance)
    label, description = _parse_labels(data, w, path, name)
    return Scenario(
        name=label,
        description=description,
        duration=clock.duration,
        control_period=clock.control_period,
        timestep=clock.timestep,
        integrator=clock.integrator,
        seed=clock.seed,
        steady_after=steady_after,
        trajectory=leader.trajectory,
        trajectory_params=dict(leader.params),
        leader_start=leader.start,
        leader_yaw_deg=leader.yaw_deg,
        n_followers=followers.n,
        follower_starts=followers.starts,
        random_start=followers.random_start,
        diameter=formation.diameter,
        anti_collision=formation.anti_collision,
        anti_collision_params={**formation.rule_params, **controller.rule_params},
        sensing_range=sensing_range,
        gains=controller.gains.gains,
        gains_source=controller.gains.source,
        gains_origin=controller.gains.origin,
        wind_feedforward=controller.wind_feedforward,
        attitude_map=controller.attitude_map,
        mixer=controller.mixer,
        lag_compensation=controller.lag_compensation,
        wind=wind,
        path=path,
        raw=data,
        aero=aero,
        vehicle=vehicle.model,
        params=vehicle.params,
        vehicle_mixer=vehicle.mixer,
        barrier_params=formation.barrier,
        sensing=sensing,
    )


def bundled_scenarios() -> dict[str, Path]:
    """Bundled scenario files by name (file stem)."""
    return {p.stem: p for p in sorted(SCENARIOS_DIR.glob("*.toml"))}


def resolve(name_or_path: str) -> Path:
    """A bundled scenario name or a path to a TOML file."""
    p = Path(name_or_path)
    if p.suffix == ".toml" or p.exists() or "/" in name_or_path:
        if not p.exists():
            raise UserError("scenario file not found", where=str(p))
        if p.is_dir():
            raise UserError("is a folder, not a scenario file", where=str(p))
        return p
    found = bundled_scenarios()
    if name_or_path not in found:
        raise UserError(
            f"unknown scenario {name_or_path!r}; bundled: {', '.join(found) or 'none'} (or give a path to a .toml file)"
        )
    return found[name_or_path]


def load_scenario(name_or_path: str | Path) -> Scenario:
    """Load and validate a scenario by bundled name or path."""
    path = resolve(str(name_or_path))
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise UserError(f"cannot read: {exc}", where=str(path)) from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise UserError(f"TOML syntax error: {exc}", where=str(path)) from None
    return parse_scenario(data, str(path), name=path.stem)


# --------------------------------------------------------------------------- a scenario as flown
def vehicle_overrides(sc: Scenario, vehicle: VehicleLike, where: str = "vehicle") -> dict[str, Any]:
    """The fields of ``sc`` that change when it flies ``vehicle`` (module docstring); a path is relative
    to the working folder. Refuses (:class:`UserError`) starts closer than the new vehicle's clearance."""
    label, v, doc_model = resolve_vehicle(vehicle, Path.cwd(), where)
    params = v.params()
    clearance = START_CLEARANCE_M * (params.rotor_span / DEFAULT_PARAMS.rotor_span)
    at = f"{sc.path or sc.name}: followers.start (flown with vehicle {label})"
    if sc.random_start is not None and sc.follower_starts is None and sc.n_followers > 0:
        check_random_start_feasible(sc.n_followers, sc.random_start, at, clearance)
    else:
        check_start_spacing(sc.initial_positions(), sc.names, at, clearance)
    out: dict[str, Any] = {
        "vehicle": label,
        "params": params,
        "vehicle_mixer": v.mixer,
        "aero": relag(sc.aero, sc.params, params),
    }
    if sc.gains_origin in ("vehicle", "default"):  # not chosen for this run or by the scenario: the vehicle's
        g = choose_gains(vehicle=v.gains_file)
        out |= {"gains": g.gains, "gains_source": g.source, "gains_origin": g.origin}
    if doc_model is not None and isinstance(sc.raw, dict):
        out["raw"] = {**sc.raw, "vehicle": {"model": doc_model}}  # what a sweep's --param re-reads
    return out


def flown(
    scenario: Scenario | str,
    *,
    vehicle: VehicleLike | None = None,
    aero: str | None = None,
    gains: str | Path | np.ndarray | None = None,
    sensing: SensingLike | None = None,
    where: tuple[str, ...] = ("vehicle", "aero", "gains", "sensing"),
) -> Scenario:
    """``scenario`` (a name, a path or a :class:`~swarm_mj.scenario.Scenario`) with the vehicle, the
    physics preset, the gains and the sensing asked for (None: the scenario's). What ``--vehicle``,
    ``--aero``, ``--gains`` and ``--sensing`` do in every command, and ``vehicle=``/``aero=`` in the
    environments. ``gains``: a gains file or an array; ``sensing``: a preset's name or a record, the whole
    ``[sensing]`` table (:func:`sensing_overrides`); ``where``: the names the errors give them."""
    sc = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
    if vehicle is not None:
        sc = replace(sc, **vehicle_overrides(sc, vehicle, where[0]))
    if sensing is not None:
        sc = replace(sc, **sensing_overrides(sc, sensing, where[3] if len(where) > 3 else "sensing"))
    if aero is not None:
        if not isinstance(aero, str):
            raise UserError(f"must be a physics preset's name ('paper' or 'realistic'), got {aero!r}", where=where[1])
        preset(aero, where=where[1])
        sc = with_aero(sc, aero)
    if gains is not None:
        if isinstance(gains, (str, Path)):
            g, source = load_gains(gains), str(gains)
        else:
            g, source = np.asarray(gains, dtype=float), "given"
        g = check_gains(g, sc.n_drones, where=f"{where[2]} {source}" if source != "given" else where[2])
        c = choose_gains(option=(g, source))
        sc = sc.with_overrides(gains=c.gains, gains_source=c.source, gains_origin=c.origin)
    return sc


def trajectory_args(sc: Scenario) -> dict[str, Any]:
    """Every parameter of the leader's trajectory: the scenario's, and the trajectory's defaults for the
    rest (lists as tuples), e.g. to tell the paper's experiment or the tune's step by their data."""
    sig = inspect.signature(TRAJECTORIES[sc.trajectory]).parameters
    return {k: _as_tuples(sc.trajectory_params.get(k, p.default)) for k, p in sig.items()}


def _as_tuples(v: Any) -> Any:
    """``v`` with every list or tuple in it a tuple (a TOML list equals a default tuple)."""
    return tuple(_as_tuples(x) for x in v) if isinstance(v, (list, tuple)) else v
