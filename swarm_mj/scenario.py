"""Scenario files: TOML data in ``scenarios/``, validated into dataclasses (DESIGN "Scenario").

A scenario names the drones and their starts, the leader's trajectory, the D schedule,
the anti-collision rule, the controller gains, the wind, the duration, the control
period, the physics timestep and the seed. Code never branches on a scenario's name.
Every mistake is reported as one :class:`~swarm_mj.errors.UserError` naming the file and
the field, e.g. ``scenarios/x.toml: formation.diameter: D must be positive, got -1 m``.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from .aero.presets import PAPER, AeroConfig, parse_aero
from .control.backstepping import TABLE4_GAINS, check_gains, load_gains
from .errors import UserError
from .formation.anticollision import ANTI_COLLISION_RULES
from .formation.slots import DiameterSchedule
from .resources import SCENARIOS_DIR
from .trajectories import TRAJECTORIES, make_trajectory
from .wind import WindConfig

_TOP_KEYS = {"name", "description", "duration", "control_period", "timestep", "integrator", "seed",
             "steady_after", "leader", "followers", "formation", "controller", "wind", "aero"}
_LEADER_KEYS = {"trajectory", "params", "start", "yaw_deg"}
_FOLLOWER_KEYS = {"count", "start", "random_start"}
_RANDOM_KEYS = {"radius", "min_spacing", "seed", "max_tries"}
_FORMATION_KEYS = {"diameter", "anti_collision", "safety_distance", "hop", "hysteresis", "arrive",
                   "sensing_range"}
_CONTROLLER_KEYS = {"gains", "wind_feedforward", "attitude_map"}


@dataclass(frozen=True)
class RandomStart:
    """Seeded random follower starts on the ground around the leader (issue: random crossing starts)."""

    radius: float = 3.0
    min_spacing: float = 0.6
    seed: int = 0
    max_tries: int = 20000


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
    leader_start: np.ndarray          # (3,)
    leader_yaw_deg: float
    n_followers: int
    follower_starts: np.ndarray | None  # (n_f, 3) or None when random
    random_start: RandomStart | None
    diameter: Any                     # float or [[t, D], ...]
    anti_collision: str
    anti_collision_params: dict[str, float]
    sensing_range: float
    gains: np.ndarray                 # (12,) or (n, 12)
    gains_source: str
    wind_feedforward: bool
    attitude_map: str
    wind: WindConfig
    path: str = ""
    raw: dict = field(default_factory=dict, repr=False, compare=False)
    aero: AeroConfig = PAPER          # physics preset (docs/aero.md); the paper's model by default

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

    def initial_positions(self) -> np.ndarray:
        """(n, 3) start positions: leader first, then followers (random ones drawn with their seed)."""
        if self.n_followers == 0:
            return self.leader_start[None, :].copy()
        if self.follower_starts is not None:
            return np.vstack([self.leader_start, self.follower_starts])
        return np.vstack([self.leader_start, random_follower_starts(self.leader_start, self.n_followers,
                                                                    self.random_start, where=self.path)])

    def with_overrides(self, **kw) -> "Scenario":
        """A copy with some fields replaced (e.g. ``gains=...``, ``anti_collision="paper"``)."""
        return replace(self, **kw)


#: Centre distance below which two level drones may already touch on the ground: rotor tip
#: to rotor tip is 2·(L + rotor radius) = 2·(0.25 + 0.09) = 0.68 m along a body axis (SPEC §1
#: geometry), plus 2 cm. Measured in MuJoCo: two followers 0.60 m or 0.65 m apart along x
#: are in contact from the first physics step; 0.70 m apart they are not.
START_CLEARANCE_M = 0.70


def random_follower_starts(leader: np.ndarray, n: int, rs: RandomStart, where: str = "") -> np.ndarray:
    """n follower starts (n, 3) on the ground within ``rs.radius`` of the leader (SPEC §4's
    "seeded random crossing starts"), every two drones (leader included) at least
    max(``rs.min_spacing``, :data:`START_CLEARANCE_M`) apart; rejection sampling, seeded.

    The floor of 0.70 m keeps a start from being a contact before anything flies: with a
    smaller spacing two drones lined up along x or y would overlap their rotors at t = 0,
    and MuJoCo would count that against whatever rule is flown.
    """
    check_random_start_feasible(n, rs, where)
    spacing = max(rs.min_spacing, START_CLEARANCE_M)
    rng = np.random.default_rng(rs.seed)
    pts = np.empty((n + 1, 2))                  # (n + 1, 2) leader first
    pts[0] = np.asarray(leader[:2], float)
    placed, tries = 1, 0
    while placed < n + 1:
        tries += 1
        if tries > rs.max_tries:
            raise UserError(f"could not place {n} followers at least {spacing:g} m apart within "
                            f"{rs.radius:g} m of the leader after {rs.max_tries} tries; lower min_spacing "
                            f"or raise radius", where=f"{where}: followers.random_start")
        r = rs.radius * np.sqrt(rng.uniform())
        a = rng.uniform(0, 2 * np.pi)
        p = pts[0] + r * np.array([np.cos(a), np.sin(a)])
        if np.hypot(*(pts[:placed] - p).T).min() >= spacing:
            pts[placed] = p
            placed += 1
    return np.column_stack([pts[1:], np.full(n, float(leader[2]))])


def check_random_start_feasible(n: int, rs: RandomStart, where: str = "") -> None:
    """Refuse, before anything is simulated, a request no placement can meet.

    Disks of radius s/2 around n + 1 points (the leader and n followers, s the effective
    spacing max(min_spacing, :data:`START_CLEARANCE_M`)) that lie within r of the leader
    fit in a disk of radius r + s/2 without overlapping, so (n + 1)·(s/2)² ≤
    0.9069·(r + s/2)² is necessary (0.9069 = π/√12, the densest packing of equal disks in
    the plane). Requests that pass may still be too tight for rejection sampling; those
    are refused after ``max_tries`` draws, still before anything flies.
    """
    s, r = rs.min_spacing, rs.radius
    wr = f"{where}: followers.random_start"
    if not (np.isfinite(r) and np.isfinite(s)) or r <= 0 or s <= 0:
        raise UserError("radius and min_spacing must be positive", where=wr)
    if n < 0:
        raise UserError(f"follower count must be >= 0, got {n}", where=wr)
    se = max(s, START_CLEARANCE_M)
    if (n + 1) * (se / 2) ** 2 > 0.9069 * (r + se / 2) ** 2:
        raise UserError(f"cannot place {n} followers {se:g} m apart (and from the leader) within "
                        f"{r:g} m of the leader: not enough room (the packing bound allows at most "
                        f"{max(int(0.9069 * (r + se / 2) ** 2 / (se / 2) ** 2) - 1, 0)} followers); lower min_spacing "
                        f"or raise radius", where=wr)


def _check_keys(table: Any, allowed: set[str], where: str) -> dict:
    if not isinstance(table, dict):
        raise UserError("must be a table", where=where)
    unknown = set(table) - allowed
    if unknown:
        raise UserError(f"unknown key(s) {', '.join(sorted(unknown))}; allowed: {', '.join(sorted(allowed))}",
                        where=where)
    return table


def _number(table: dict, key: str, default, where: str, *, positive: bool = False, minimum=None,
            integer: bool = False):
    if key not in table:
        if default is None:
            raise UserError("missing field", where=f"{where}{key}")
        return default
    v = table[key]
    if isinstance(v, bool) or not isinstance(v, (int, float)) or (integer and not isinstance(v, int)):
        raise UserError(f"must be {'an integer' if integer else 'a number'}, got {v!r}", where=f"{where}{key}")
    if not np.isfinite(v):
        raise UserError(f"must be finite, got {v!r}", where=f"{where}{key}")
    if positive and v <= 0:
        raise UserError(f"must be positive, got {v!r}", where=f"{where}{key}")
    if minimum is not None and v < minimum:
        raise UserError(f"must be >= {minimum}, got {v!r}", where=f"{where}{key}")
    return v


def _vec(v, n: int | None, where: str) -> np.ndarray:
    try:
        a = np.asarray(v, dtype=float)
    except (TypeError, ValueError):
        raise UserError(f"must be numbers, got {v!r}", where=where) from None
    if not np.isfinite(a).all():
        raise UserError("must be finite numbers", where=where)
    if n is not None and a.shape != (n,):
        raise UserError(f"must be a list of {n} numbers, got {v!r}", where=where)
    return a


def parse_scenario(data: dict, path: str = "<scenario>", name: str | None = None) -> Scenario:
    """Validate a parsed TOML document into a :class:`Scenario`."""
    base = Path(path).parent if path and not path.startswith("<") else Path.cwd()
    _check_keys(data, _TOP_KEYS, path)
    w = f"{path}: "
    duration = float(_number(data, "duration", None, w, positive=True))
    T = float(_number(data, "control_period", 0.01, w, positive=True))
    dt = float(_number(data, "timestep", 0.005, w, positive=True))
    nsub = round(T / dt)
    if nsub < 1 or abs(nsub * dt - T) > 1e-9:
        raise UserError(f"must divide control_period = {T} s (got {dt} s)", where=f"{w}timestep")
    integrator = data.get("integrator", "RK4")
    if integrator not in ("RK4", "Euler", "implicitfast"):
        raise UserError(f"unknown integrator {integrator!r}; choose RK4, Euler or implicitfast",
                        where=f"{w}integrator")
    seed = int(_number(data, "seed", 0, w, integer=True, minimum=0))
    steady_after = float(_number(data, "steady_after", 10.0, w, minimum=0))

    leader = _check_keys(data.get("leader", None) if "leader" in data else _missing(w + "leader"),
                         _LEADER_KEYS, w + "leader")
    if "trajectory" not in leader:
        raise UserError("missing field", where=f"{w}leader.trajectory")
    traj = leader["trajectory"]
    if traj not in TRAJECTORIES:
        raise UserError(f"unknown trajectory {traj!r}; choose one of {', '.join(sorted(TRAJECTORIES))}",
                        where=f"{w}leader.trajectory")
    tparams = leader.get("params", {})
    if not isinstance(tparams, dict):
        raise UserError("must be a table", where=f"{w}leader.params")
    make_trajectory(traj, tparams, where=f"{w}leader.params")   # validates the parameters
    leader_start = _vec(leader.get("start", [0.0, 0.0, 0.0]), 3, f"{w}leader.start")
    yaw_deg = float(_number(leader, "yaw_deg", 0.0, f"{w}leader."))

    fol = _check_keys(data.get("followers", {"count": 0}), _FOLLOWER_KEYS, w + "followers")
    if "start" in fol and "random_start" in fol:
        raise UserError("give either start or random_start, not both", where=f"{w}followers")
    default_count = len(fol["start"]) if isinstance(fol.get("start"), list) else None
    n_f = int(_number(fol, "count", default_count if default_count is not None else None,
                      f"{w}followers.", integer=True, minimum=0))
    starts = None
    rstart = None
    if n_f > 0:
        if "start" in fol:
            starts = _vec(fol["start"], None, f"{w}followers.start")
            if starts.shape != (n_f, 3):
                raise UserError(f"must be {n_f} [x, y, z] positions, got shape {starts.shape}",
                                where=f"{w}followers.start")
        elif "random_start" in fol:
            r = _check_keys(fol["random_start"], _RANDOM_KEYS, f"{w}followers.random_start")
            wr = f"{w}followers.random_start."
            rstart = RandomStart(radius=float(_number(r, "radius", 3.0, wr, positive=True)),
                                 min_spacing=float(_number(r, "min_spacing", 0.6, wr, positive=True)),
                                 seed=int(_number(r, "seed", seed, wr, integer=True, minimum=0)),
                                 max_tries=int(_number(r, "max_tries", 20000, wr, integer=True, minimum=1)))
            check_random_start_feasible(n_f, rstart, path)
        else:
            raise UserError("followers need start positions or random_start", where=f"{w}followers")

    form = _check_keys(data.get("formation", {}), _FORMATION_KEYS, w + "formation")
    diameter = form.get("diameter", 1.0)
    DiameterSchedule(diameter, where=f"{w}formation.diameter")
    rule = form.get("anti_collision", "clearance")
    if rule not in ANTI_COLLISION_RULES:
        raise UserError(f"unknown rule {rule!r}; choose one of {', '.join(ANTI_COLLISION_RULES)}",
                        where=f"{w}formation.anti_collision")
    wf = f"{w}formation."
    ac_params = {k: float(_number(form, k, d, wf, positive=True)) for k, d in
                 (("safety_distance", 0.8), ("hop", 0.4), ("hysteresis", 0.05), ("arrive", 0.2))}
    sensing = float(_number(form, "sensing_range", 4.0, wf, positive=True))

    ctl = _check_keys(data.get("controller", {}), _CONTROLLER_KEYS, w + "controller")
    g = ctl.get("gains", "table4")
    if isinstance(g, str):
        if g == "table4":
            gains, source = TABLE4_GAINS.copy(), "table4"
        else:
            gpath = (base / g) if not Path(g).is_absolute() else Path(g)
            try:
                gains, source = load_gains(gpath), str(gpath)
            except UserError as exc:
                raise UserError(str(exc), where=f"{w}controller.gains") from None
    else:
        gains, source = check_gains(g, 1 + n_f, where=f"{w}controller.gains"), "inline"
    ff = ctl.get("wind_feedforward", True)
    if not isinstance(ff, bool):
        raise UserError(f"must be true or false, got {ff!r}", where=f"{w}controller.wind_feedforward")
    amap = ctl.get("attitude_map", "exact")
    if amap not in ("exact", "paper"):
        raise UserError(f"must be 'exact' or 'paper', got {amap!r}", where=f"{w}controller.attitude_map")

    wind_table = data.get("wind", {"enabled": False})
    if not isinstance(wind_table, dict):
        raise UserError("must be a table", where=f"{w}wind")
    wind = WindConfig.from_dict(wind_table, where=path)

    aero = parse_aero(data.get("aero"), where=f"{w}aero")
    if 0 < aero.motor_tau < dt:
        raise UserError(f"must be 0 (ideal rotors) or at least the physics timestep {dt:g} s, got {aero.motor_tau:g}",
                        where=f"{w}aero.motor_tau")
    _check_above_ground(leader_start, starts, traj, tparams, duration, T, w)

    nm = name or data.get("name") or (Path(path).stem if not path.startswith("<") else "scenario")
    return Scenario(name=str(nm), description=str(data.get("description", "")), duration=duration,
                    control_period=T, timestep=dt, integrator=integrator, seed=seed, steady_after=steady_after,
                    trajectory=traj, trajectory_params=dict(tparams), leader_start=leader_start,
                    leader_yaw_deg=yaw_deg, n_followers=n_f, follower_starts=starts, random_start=rstart,
                    diameter=diameter, anti_collision=rule, anti_collision_params=ac_params,
                    sensing_range=sensing, gains=gains, gains_source=source, wind_feedforward=ff,
                    attitude_map=amap, wind=wind, path=path, raw=data, aero=aero)


def _check_above_ground(leader_start: np.ndarray, starts: np.ndarray | None, traj: str, tparams: dict,
                        duration: float, T: float, w: str) -> None:
    """The floor is the plane z = 0 (docs/aero.md): a start or a leader reference below it is bad input."""
    if leader_start[2] < 0:
        raise UserError(f"z = {leader_start[2]:g} m is below the ground (z = 0)", where=f"{w}leader.start")
    if starts is not None and (starts[:, 2] < 0).any():
        k = int(np.argmax(starts[:, 2] < 0))
        raise UserError(f"follower {k + 1} starts at z = {starts[k, 2]:g} m, below the ground (z = 0)",
                        where=f"{w}followers.start")
    ref = make_trajectory(traj, tparams)(np.arange(round(duration / T) + 1) * T)
    zmin = float(ref.pos[:, 2].min())
    if zmin < 0:
        k = int(np.argmin(ref.pos[:, 2]))
        raise UserError(f"the leader's reference goes below the ground (z = {zmin:g} m at t = {k * T:g} s)",
                        where=f"{w}leader.params")


def _missing(where: str):
    raise UserError("missing table", where=where)


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
        raise UserError(f"unknown scenario {name_or_path!r}; bundled: {', '.join(found) or 'none'} "
                        f"(or give a path to a .toml file)")
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
