"""Wind model of the paper, eqs. (35)–(37), as fixed by docs/interpretations.md §5.

Wind speed (world frame, m/s), paper eq. (35)::

    V_x(t) = 5.2 + 2 sin(0.05 t) + 0.5 sin(0.5 t) + X_x(t)
    V_y(t) = 3 + 1.5 sin(0.04 t + pi/3)           + X_y(t)
    V_z(t) = 0

Turbulence X, paper eq. (36): an Ornstein–Uhlenbeck process sampled *exactly* at
the sample period ``dt`` (the control period, 0.01 s by default)::

    X_k = a X_{k-1} + sigma sqrt(1 - a^2) eta_k,   a = exp(-dt / tau),   eta_k ~ N(0, 1)

This is the exact transition of the continuous OU process over ``dt``, so the
statistics do not depend on ``dt``: mean 0, variance sigma^2, autocorrelation
exp(-|lag| / tau). **Initial value**: X_0 is drawn from the stationary law
N(0, sigma^2), so the series is stationary from its first sample (no start-up
transient towards the stationary variance, as X_0 = 0 would give).

Force per axis, paper eq. (37) with its sign fixed (the paper writes V^2, which
would always push towards +x/+y, and sigma for rho)::

    F_i = 0.5 rho C_d A |V_i| V_i        i in {x, y, z}, world frame

``|V_i|`` is the magnitude of the *component*, not of the vector (the paper and
docs/interpretations.md §5 give the force "per axis").

Schedule (paper §5.3): the force of an axis is applied only inside its windows.
A schedule is data: a tuple of windows ``(t_start, t_end, axes)``, each the
half-open interval ``[t_start, t_end)`` with ``axes`` a non-empty subset of
``"xy"``. The default is the paper's ``((20, 50, "x"), (50, inf, "xy"))``.
**An empty schedule means the force is never applied** (the speed is still
reported); for a wind that is always on give ``[(-inf, inf, "xy")]``
(:data:`ALWAYS_ON`). Windows may overlap; an axis is on if any window turns it
on. The z force is never scheduled (V_z = 0; the drone's own linear drag Kz is
handled by the simulator).

Design for speed: the whole run's wind is computed once,
``WindField(cfg, dt, seed).sample(times) -> WindSeries`` with arrays of shape
(k, 3); the simulator indexes them at each control step. The module is pure:
no global state, ``sample`` draws from a fresh ``np.random.default_rng`` built
from the field's seed each time, so the same seed gives the same series.

Optional, off by default: ``relative_airspeed = true`` makes the force on each
drone come from the air speed seen by that drone, ``V_wind - v_drone``, instead
of ``V_wind`` alone (:func:`relative_force`, :meth:`WindSeries.drone_forces`).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np

from ..errors import UserError

__all__ = [
    "ALWAYS_ON",
    "PAPER_SCHEDULE",
    "WindConfig",
    "WindField",
    "WindSeries",
    "deterministic_speed",
    "force_from_speed",
    "ou_filter",
    "ou_series",
    "relative_force",
    "schedule_mask",
]

INF = math.inf

Window = tuple[float, float, str]  # (t_start, t_end, axes): [t_start, t_end), axes in "xy"
Sinusoid = tuple[float, float, float]  # (amplitude m/s, omega rad/s, phase rad)

#: Paper §5.3: F_x during [20, 50) s, F_x and F_y from 50 s to the end of the run.
PAPER_SCHEDULE: tuple[Window, ...] = ((20.0, 50.0, "x"), (50.0, INF, "xy"))
#: A schedule with the force on at every time, both horizontal axes.
ALWAYS_ON: tuple[Window, ...] = ((-INF, INF, "xy"),)

_AXIS_INDEX = {"x": 0, "y": 1}


class _FieldError(Exception):
    """Internal: a bad value in one field of the wind config."""

    def __init__(self, field_name: str, message: str) -> None:
        super().__init__(message)
        self.field_name = field_name
        self.message = message


# --------------------------------------------------------------------------- config


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, (bool, np.bool_))


def _number(name: str, v: Any, *, allow_inf: bool = False) -> float:
    if not _is_number(v):
        raise _FieldError(name, f"must be a number, got {v!r}")
    x = float(v)
    if math.isnan(x) or (math.isinf(x) and not allow_inf):
        raise _FieldError(name, f"must be a finite number, got {v!r}")
    return x


def _seq(name: str, v: Any) -> Sequence[Any]:
    if isinstance(v, (str, bytes)) or not isinstance(v, (Sequence, np.ndarray)):
        raise _FieldError(name, f"must be a list, got {v!r}")
    return list(v)


def _pair(name: str, v: Any) -> tuple[float, float]:
    """A pair (x, y); a single number is used for both axes."""
    if _is_number(v):
        x = _number(name, v)
        return (x, x)
    items = _seq(name, v)
    if len(items) != 2:
        raise _FieldError(name, f"must be a list of 2 numbers [x, y], got {v!r}")
    return (_number(name, items[0]), _number(name, items[1]))


def _sinusoids(name: str, v: Any) -> tuple[Sinusoid, ...]:
    out: list[Sinusoid] = []
    for i, item in enumerate(_seq(name, v)):
        where = f"{name}[{i}]"
        if _is_number(item):
            raise _FieldError(where, f"must be [amplitude, omega, phase], got {item!r}")
        triple = _seq(where, item)
        if len(triple) != 3:
            raise _FieldError(where, f"must be [amplitude, omega, phase], got {item!r}")
        amplitude, omega, phase = (_number(where, t) for t in triple)
        out.append((amplitude, omega, phase))
    return tuple(out)


def _schedule(name: str, v: Any) -> tuple[Window, ...]:
    out = []
    for i, item in enumerate(_seq(name, v)):
        where = f"{name}[{i}]"
        if _is_number(item) or isinstance(item, str):
            raise _FieldError(where, f"must be [t_start, t_end, axes], got {item!r}")
        w = _seq(where, item)
        if len(w) != 3:
            raise _FieldError(where, f"must be [t_start, t_end, axes], got {item!r}")
        t0 = _number(where, w[0], allow_inf=True)
        t1 = _number(where, w[1], allow_inf=True)
        axes = w[2]
        if not t0 < t1:
            raise _FieldError(where, f"window is empty or inverted: t_start {t0} must be < t_end {t1}")
        if (
            not isinstance(axes, str)
            or not axes
            or any(c not in _AXIS_INDEX for c in axes)
            or len(set(axes)) != len(axes)
        ):
            raise _FieldError(where, f'axes must be a non-empty string of distinct letters from "xy", got {axes!r}')
        out.append((t0, t1, axes))
    return tuple(out)


def _flag(name: str, v: Any) -> bool:
    if not isinstance(v, (bool, np.bool_)):
        raise _FieldError(name, f"must be true or false, got {v!r}")
    return bool(v)


@dataclass(frozen=True)
class WindConfig:
    """Every parameter of the wind model; defaults are docs/interpretations.md §5 / paper eqs. (35)–(37).

    Attributes
    ----------
    enabled : False gives zero speed and zero force everywhere.
    mean : (V_x mean, V_y mean) in m/s, eq. (35).  # (2,)
    sinusoids_x, sinusoids_y : terms ``amplitude * sin(omega * t + phase)`` of eq. (35),
        each (amplitude m/s, omega rad/s, phase rad).
    tau : OU correlation times (tau_x, tau_y) in s, eq. (36), > 0.  # (2,)
    sigma : OU stationary standard deviations (sigma_x, sigma_y) in m/s, eq. (36), >= 0.  # (2,)
    rho, cd, area : air density kg/m^3, drag coefficient, frontal area m^2, eq. (37), >= 0.
    schedule : windows ``(t_start, t_end, axes)``, half-open ``[t_start, t_end)``; empty
        means the force is never on (see the module docstring and :data:`ALWAYS_ON`).
    relative_airspeed : compute each drone's force from ``V_wind - v_drone`` (off by default).

    Sequences given as lists are stored as tuples; a bad value raises
    :class:`~swarm_mj.errors.UserError` with ``where="wind.<field>"``.
    """

    enabled: bool = True
    mean: tuple[float, float] = (5.2, 3.0)
    sinusoids_x: tuple[Sinusoid, ...] = ((2.0, 0.05, 0.0), (0.5, 0.5, 0.0))
    sinusoids_y: tuple[Sinusoid, ...] = ((1.5, 0.04, math.pi / 3),)
    tau: tuple[float, float] = (2.0, 2.0)
    sigma: tuple[float, float] = (0.8, 0.5)
    rho: float = 1.225
    cd: float = 1.0
    area: float = 0.025
    schedule: tuple[Window, ...] = PAPER_SCHEDULE
    relative_airspeed: bool = False

    def __post_init__(self) -> None:
        try:
            normalised = _normalise(self)
        except _FieldError as e:
            raise UserError(e.message, where=f"wind.{e.field_name}") from None
        for k, v in normalised.items():
            object.__setattr__(self, k, v)

    @classmethod
    def none(cls) -> WindConfig:
        """No wind: zero speed and zero force."""
        return cls(enabled=False)

    @classmethod
    def from_dict(cls, d: Mapping[str, Any] | None, where: str) -> WindConfig:
        """Build from a TOML ``[wind]`` table, validated; missing keys take the defaults of docs/interpretations.md §5.

        Keys: enabled, mean, sinusoids_x, sinusoids_y, tau, sigma, rho, cd, area,
        schedule, relative_airspeed (see :class:`WindConfig`). ``tau``/``sigma`` may be
        one number for both axes. A schedule end may be TOML ``inf`` or a large number.
        Errors raise ``UserError(message, where=f"{where}: wind.<field>")``.
        """
        d = {} if d is None else d
        if not isinstance(d, Mapping):
            raise UserError(f"must be a table, got {d!r}", where=f"{where}: wind")
        known = {f.name for f in fields(cls)}
        for key in d:
            if key not in known:
                hint = " (wind feedforward belongs in the controller section)" if key == "feedforward" else ""
                raise UserError(
                    f"unknown key {key!r}{hint}; known keys: {', '.join(sorted(known))}",
                    where=f"{where}: wind.{key}",
                )
        try:
            values = _normalise(_Raw({**{f.name: getattr(_DEFAULTS, f.name) for f in fields(cls)}, **d}))
        except _FieldError as e:
            raise UserError(e.message, where=f"{where}: wind.{e.field_name}") from None
        return cls(**values)

    def to_dict(self) -> dict[str, Any]:
        """The TOML-table form (inverse of :meth:`from_dict`)."""
        return {
            "enabled": self.enabled,
            "mean": list(self.mean),
            "sinusoids_x": [list(s) for s in self.sinusoids_x],
            "sinusoids_y": [list(s) for s in self.sinusoids_y],
            "tau": list(self.tau),
            "sigma": list(self.sigma),
            "rho": self.rho,
            "cd": self.cd,
            "area": self.area,
            "schedule": [list(w) for w in self.schedule],
            "relative_airspeed": self.relative_airspeed,
        }


class _Raw:
    """Attribute view of a dict, so that :func:`_normalise` reads configs and tables alike."""

    def __init__(self, d: Mapping[str, Any]) -> None:
        self.__dict__.update(d)


def _normalise(c: Any) -> dict[str, Any]:
    """Validate every field of ``c`` and return them in canonical (tuple, float) form."""
    out: dict[str, Any] = {
        "enabled": _flag("enabled", c.enabled),
        "mean": _pair("mean", c.mean),
        "sinusoids_x": _sinusoids("sinusoids_x", c.sinusoids_x),
        "sinusoids_y": _sinusoids("sinusoids_y", c.sinusoids_y),
        "tau": _pair("tau", c.tau),
        "sigma": _pair("sigma", c.sigma),
        "schedule": _schedule("schedule", c.schedule),
        "relative_airspeed": _flag("relative_airspeed", c.relative_airspeed),
    }
    if min(out["tau"]) <= 0:
        raise _FieldError("tau", f"correlation times must be > 0 s, got {list(out['tau'])}")
    if min(out["sigma"]) < 0:
        raise _FieldError("sigma", f"turbulence intensities must be >= 0 m/s, got {list(out['sigma'])}")
    for name in ("rho", "cd", "area"):
        x = _number(name, getattr(c, name))
        if x < 0:
            raise _FieldError(name, f"must be >= 0, got {x}")
        out[name] = x
    return out


# The defaults, built without running validation twice on import-time constants.
_DEFAULTS = WindConfig()


# --------------------------------------------------------------------------- pure functions


def force_from_speed(speed: np.ndarray, rho: float = 1.225, cd: float = 1.0, area: float = 0.025) -> np.ndarray:
    """Paper eq. (37), sign fixed: F = 0.5 rho C_d A |V| V, component by component.

    ``speed`` (..., 3) in m/s -> force (..., 3) in N, same frame (world).
    """
    v = np.asarray(speed, dtype=float)
    return (0.5 * rho * cd * area) * np.abs(v) * v


def relative_force(
    wind_speed: np.ndarray,
    drone_vel: np.ndarray,
    mask: np.ndarray,
    rho: float = 1.225,
    cd: float = 1.0,
    area: float = 0.025,
) -> np.ndarray:
    """Paper eq. (37) on the relative air speed of each drone: F = 0.5 rho C_d A |V_r| V_r.

    ``wind_speed`` (3,) m/s, ``drone_vel`` (n, 3) m/s (world frame), ``mask`` (3,) bool
    (the schedule at that time) -> force (n, 3) N, zero on the masked-off axes.
    """
    v_rel = np.asarray(wind_speed, dtype=float)[None, :] - np.asarray(drone_vel, dtype=float).reshape(-1, 3)  # (n, 3)
    return np.where(np.asarray(mask, dtype=bool)[None, :], force_from_speed(v_rel, rho, cd, area), 0.0)


def deterministic_speed(times: np.ndarray, cfg: WindConfig) -> np.ndarray:
    """Paper eq. (35) without the turbulence X: mean + sum of sinusoids, V_z = 0.

    ``times`` (k,) s -> speed (k, 3) m/s. Zero when ``cfg.enabled`` is False.
    """
    t = np.asarray(times, dtype=float).reshape(-1)  # (k,)
    v = np.zeros((t.size, 3))  # (k, 3)
    if not cfg.enabled:
        return v
    for axis, terms in ((0, cfg.sinusoids_x), (1, cfg.sinusoids_y)):
        v[:, axis] = cfg.mean[axis]
        for amp, omega, phase in terms:
            v[:, axis] += amp * np.sin(omega * t + phase)
    return v


def schedule_mask(times: np.ndarray, schedule: Iterable[Window]) -> np.ndarray:
    """Paper §5.3 as data: which force axes are on at each time.

    ``times`` (k,) s -> bool (k, 3); window ``(t0, t1, axes)`` turns ``axes`` on for
    t0 <= t < t1; column z is always False. An empty schedule gives all False.
    """
    t = np.asarray(times, dtype=float).reshape(-1)  # (k,)
    mask = np.zeros((t.size, 3), dtype=bool)  # (k, 3)
    for t0, t1, axes in schedule:
        inside = (t >= t0) & (t < t1)  # (k,)
        for c in axes:
            mask[:, _AXIS_INDEX[c]] |= inside
    return mask


def ou_filter(x0: np.ndarray, w: np.ndarray, a: np.ndarray) -> np.ndarray:
    """The AR(1) recursion of paper eq. (36): X_0 = x0, X_i = a X_{i-1} + w_i, vectorised.

    ``x0`` (m,), ``w`` (k-1, m) innovations, ``a`` (m,) in [0, 1) -> X (k, m).

    Computed block by block: inside a block starting at X_b,
    X_{b+i} = a^i (X_b + sum_{j<=i} a^{-j} w_{b+j}), a cumulative sum. The block length
    is chosen so that a^{-len} <= e (no loss of precision), so the Python loop runs
    about k (1 - a) times per axis (k dt / tau blocks), not k times.
    """
    x0 = np.asarray(x0, dtype=float).reshape(-1)  # (m,)
    w = np.asarray(w, dtype=float).reshape(-1, x0.size)  # (k-1, m)
    a = np.broadcast_to(np.asarray(a, dtype=float), x0.shape)  # (m,)
    k = w.shape[0] + 1
    out = np.empty((k, x0.size))  # (k, m)
    out[0] = x0
    for j in range(x0.size):
        aj = float(a[j])
        if not 0.0 <= aj < 1.0:
            raise ValueError(f"AR(1) coefficient must be in [0, 1), got {aj}")
        if aj == 0.0:
            out[1:, j] = w[:, j]
            continue
        # Largest block with a^-B <= e, i.e. B * (-ln a) <= 1.
        block = int(max(1, min(k - 1, math.floor(1.0 / -math.log(aj))))) if k > 1 else 1
        powers = aj ** np.arange(1, block + 1)  # (B,) a^1 .. a^B
        prev = out[0, j]
        for s in range(1, k, block):
            e = min(s + block, k)
            p = powers[: e - s]
            out[s:e, j] = p * (prev + np.cumsum(w[s - 1 : e - 1, j] / p))
            prev = out[e - 1, j]
    return out


def ou_series(k: int, dt: float, tau: np.ndarray, sigma: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Paper eq. (36), exact OU discretisation at ``dt``: k samples of m independent processes.

    X_0 ~ N(0, sigma^2) (stationary start), X_i = a X_{i-1} + sigma sqrt(1 - a^2) eta_i,
    a = exp(-dt / tau). ``tau``, ``sigma`` (m,) -> X (k, m).

    Draw order (part of the reproducibility contract): ``rng.standard_normal(m)`` for
    X_0, then ``rng.standard_normal((k - 1, m))`` for eta, row by row, so the first
    samples of a longer series equal a shorter one drawn with the same seed.
    """
    tau = np.atleast_1d(np.asarray(tau, dtype=float))  # (m,)
    sigma = np.broadcast_to(np.asarray(sigma, dtype=float), tau.shape)  # (m,)
    if k <= 0:
        return np.zeros((0, tau.size))
    a = np.exp(-dt / tau)  # (m,)
    x0 = sigma * rng.standard_normal(tau.size)  # (m,)
    eta = rng.standard_normal((k - 1, tau.size))  # (k-1, m)
    return ou_filter(x0, eta * (sigma * np.sqrt(1.0 - a * a)), a)


# --------------------------------------------------------------------------- field and series


@dataclass(frozen=True)
class WindSeries:
    """The wind of a whole run, sampled at the control times.

    ``times`` (k,) s; ``speed`` (k, 3) m/s, eq. (35), reported even where the force is
    off; ``force`` (k, 3) N, eq. (37) from ``speed``, already masked by the schedule;
    ``on_mask`` (k, 3) bool, the schedule. With ``relative_airspeed`` the force a drone
    feels comes from :meth:`drone_forces`, not ``force``.
    """

    times: np.ndarray  # (k,)
    speed: np.ndarray  # (k, 3)
    force: np.ndarray  # (k, 3)
    on_mask: np.ndarray  # (k, 3)
    rho: float = 1.225
    cd: float = 1.0
    area: float = 0.025
    relative_airspeed: bool = False

    def __len__(self) -> int:
        return int(self.times.shape[0])

    def drone_forces(self, i: int, drone_vel: np.ndarray) -> np.ndarray:
        """World-frame wind force on each drone at sample ``i``: (n, 3) N, a fresh array.

        ``drone_vel`` (n, 3) m/s. Without relative airspeed every drone gets ``force[i]``
        (the same field for all, docs/interpretations.md §5); with it, :func:`relative_force`.
        The one place that chooses between the two: the simulator's wind, the controller's
        feedforward and the log all call it.
        """
        if not self.relative_airspeed:
            n = (
                drone_vel.shape[0]
                if isinstance(drone_vel, np.ndarray) and drone_vel.ndim == 2
                else np.asarray(drone_vel, dtype=float).reshape(-1, 3).shape[0]
            )
            out = np.empty((n, 3))
            out[:] = self.force[i]
            return out
        vel = np.asarray(drone_vel, dtype=float).reshape(-1, 3)  # (n, 3)
        return relative_force(self.speed[i], vel, self.on_mask[i], self.rho, self.cd, self.area)


@dataclass(frozen=True)
class WindField:
    """A seeded wind field: ``sample(times)`` gives the whole run's :class:`WindSeries`.

    ``dt`` is the sample period (the control period, docs/interpretations.md §2: 0.01 s); the OU turbulence
    is discretised exactly at this step. ``seed`` is passed to ``np.random.default_rng``
    (via a ``SeedSequence``; ``None`` draws fresh entropy once, at construction). ``sample``
    is a pure function of (config, dt, seed, times): calling it twice gives the same series.
    """

    config: WindConfig = field(default_factory=WindConfig)
    dt: float = 0.01
    seed: int | None = 0
    _seed_seq: np.random.SeedSequence = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if not (isinstance(self.dt, (int, float)) and math.isfinite(self.dt) and self.dt > 0):
            raise ValueError(f"dt must be a positive finite number, got {self.dt!r}")
        object.__setattr__(self, "_seed_seq", np.random.SeedSequence(self.seed))

    def turbulence(self, k: int) -> np.ndarray:
        """X (k, 2): the OU turbulence of eq. (36) at k consecutive samples, for (x, y)."""
        rng = np.random.default_rng(self._seed_seq)
        return ou_series(k, self.dt, np.array(self.config.tau), np.array(self.config.sigma), rng)

    def sample(self, times: np.ndarray) -> WindSeries:
        """The wind at ``times`` (k,): uniformly spaced with step ``dt`` (validated), any start.

        Returns speed (eq. 35–36), force (eq. 37, masked by the schedule) and the mask.
        """
        t = np.asarray(times, dtype=float)
        if t.ndim != 1:
            raise ValueError(f"times must be a 1-D array, got shape {t.shape}")
        if not np.all(np.isfinite(t)):
            raise ValueError("times must be finite")
        if t.size >= 2:
            steps = np.diff(t)  # (k-1,)
            err = float(np.max(np.abs(steps - self.dt)))
            if err > 1e-6 * self.dt:
                raise ValueError(
                    f"times must be uniformly spaced with step dt = {self.dt}; steps deviate by up to {err:.3g} s"
                )
        cfg = self.config
        k = t.size
        if not cfg.enabled:
            zeros = np.zeros((k, 3))
            return WindSeries(
                times=t,
                speed=zeros,
                force=zeros.copy(),
                on_mask=np.zeros((k, 3), dtype=bool),
                rho=cfg.rho,
                cd=cfg.cd,
                area=cfg.area,
                relative_airspeed=cfg.relative_airspeed,
            )
        speed = deterministic_speed(t, cfg)  # (k, 3)
        speed[:, :2] += self.turbulence(k)
        on = schedule_mask(t, cfg.schedule)  # (k, 3)
        force = np.where(on, force_from_speed(speed, cfg.rho, cfg.cd, cfg.area), 0.0)  # (k, 3)
        return WindSeries(
            times=t,
            speed=speed,
            force=force,
            on_mask=on,
            rho=cfg.rho,
            cd=cfg.cd,
            area=cfg.area,
            relative_airspeed=cfg.relative_airspeed,
        )
