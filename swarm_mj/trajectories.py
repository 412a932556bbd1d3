"""Reference trajectories with analytic position, velocity and acceleration (docs/interpretations.md §3).

Every trajectory is a callable ``traj(t)`` taking a scalar or an array of times (k,) and
returning a :class:`Reference` whose arrays have the time axis first: ``pos (k, 3)``,
``vel (k, 3)``, ``acc (k, 3)``, ``yaw (k,)``, ``yaw_rate (k,)``, ``yaw_acc (k,)``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .errors import UserError


@dataclass(frozen=True)
class Reference:
    pos: np.ndarray  # (k, 3)
    vel: np.ndarray  # (k, 3)
    acc: np.ndarray  # (k, 3)
    yaw: np.ndarray  # (k,)
    yaw_rate: np.ndarray  # (k,)
    yaw_acc: np.ndarray  # (k,)


def _t(t) -> np.ndarray:
    return np.atleast_1d(np.asarray(t, dtype=float))


def _constant(t, pos, yaw) -> Reference:
    t = _t(t)
    k = len(t)
    z = np.zeros((k, 3))
    return Reference(
        pos=np.tile(np.asarray(pos, float), (k, 1)),
        vel=z,
        acc=z.copy(),
        yaw=np.full(k, float(yaw)),
        yaw_rate=np.zeros(k),
        yaw_acc=np.zeros(k),
    )


def step(target=(1.0, 1.0, 1.0), yaw_deg: float = 25.0) -> Callable[[np.ndarray], Reference]:
    """Step of docs/interpretations.md §3: x_d = y_d = z_d = 1 m, ψ_d = 25° from t = 0 (derivatives zero)."""
    return lambda t: _constant(t, target, np.deg2rad(yaw_deg))


def hover(position=(0.0, 0.0, 2.0), yaw_deg: float = 0.0) -> Callable[[np.ndarray], Reference]:
    """Hold a fixed point."""
    return lambda t: _constant(t, position, np.deg2rad(yaw_deg))


def _harmonic(t, amp, omega, phase_cos: bool):
    """a·sin(ωt) (or a·cos(ωt)) with its first two derivatives."""
    if phase_cos:
        return amp * np.cos(omega * t), -amp * omega * np.sin(omega * t), -amp * omega**2 * np.cos(omega * t)
    return amp * np.sin(omega * t), amp * omega * np.cos(omega * t), -amp * omega**2 * np.sin(omega * t)


def lemniscate(
    amplitude: float = 2.5, omega: float = 0.08, altitude: float = 2.0, center=(0.0, 0.0)
) -> Callable[[np.ndarray], Reference]:
    """Paper eq. (30): x = 2.5 sin(0.08t), y = 2.5 sin(0.04t), z = 2."""

    def f(t):
        t = _t(t)
        k = len(t)
        x = _harmonic(t, amplitude, omega, False)
        y = _harmonic(t, amplitude, omega / 2, False)
        pos = np.column_stack([x[0] + center[0], y[0] + center[1], np.full(k, altitude)])
        vel = np.column_stack([x[1], y[1], np.zeros(k)])
        acc = np.column_stack([x[2], y[2], np.zeros(k)])
        return Reference(pos=pos, vel=vel, acc=acc, yaw=np.zeros(k), yaw_rate=np.zeros(k), yaw_acc=np.zeros(k))

    return f


def circle(
    radius: float = 2.5, omega: float = 0.08, altitude: float = 2.0, climb_rate: float = 0.0, center=(0.0, 0.0)
) -> Callable[[np.ndarray], Reference]:
    """docs/interpretations.md §3 circle: x = 2.5 sin(0.08t), y = 2.5 cos(0.08t), z = altitude + climb_rate·t."""

    def f(t):
        t = _t(t)
        k = len(t)
        x = _harmonic(t, radius, omega, False)
        y = _harmonic(t, radius, omega, True)
        pos = np.column_stack([x[0] + center[0], y[0] + center[1], altitude + climb_rate * t])
        vel = np.column_stack([x[1], y[1], np.full(k, climb_rate)])
        acc = np.column_stack([x[2], y[2], np.zeros(k)])
        return Reference(pos=pos, vel=vel, acc=acc, yaw=np.zeros(k), yaw_rate=np.zeros(k), yaw_acc=np.zeros(k))

    return f


def ascending_orbit(
    radius: float = 2.5, omega: float = 0.08, altitude: float = 1.0, climb_rate: float = 0.02, center=(0.0, 0.0)
) -> Callable[[np.ndarray], Reference]:
    """docs/interpretations.md §3 ascending orbit: the circle with z = 1 + 0.02t."""
    return circle(radius, omega, altitude, climb_rate, center)


def _quintic_from_rest(p0: np.ndarray, p1: np.ndarray, v1: np.ndarray, a1: np.ndarray, T: float, t: np.ndarray):
    """The quintic from rest at p0 (zero velocity and acceleration) at time 0 to the state (p1, v1, a1)
    at time T, per axis, at the times t (k,) in [0, T]: (pos, vel, acc), each (k, d)."""
    s = (t / T)[:, None]
    d, V, A = p1 - p0, v1 * T, a1 * T * T  # the end state in units of T
    c3 = 10.0 * d - 4.0 * V + 0.5 * A
    c4 = -15.0 * d + 7.0 * V - A
    c5 = 6.0 * d - 3.0 * V + 0.5 * A
    pos = p0 + c3 * s**3 + c4 * s**4 + c5 * s**5
    vel = (3.0 * c3 * s**2 + 4.0 * c4 * s**3 + 5.0 * c5 * s**4) / T
    acc = (6.0 * c3 * s + 12.0 * c4 * s**2 + 20.0 * c5 * s**3) / T**2
    return pos, vel, acc


def joined_from_rest(
    f: Callable[[np.ndarray], Reference], start: np.ndarray, horizontal_s: float, vertical_s: float
) -> Callable[[np.ndarray], Reference]:
    """The trajectory ``f`` joined from rest at ``start`` (3,): the leader's take-off plan
    (docs/barrier.md, "the leader's start"). Its horizontal position follows the quintic from rest at
    ``start`` to f's state at ``horizontal_s``, its altitude the one to f's at ``vertical_s``; from each
    time on, f's own. Position, velocity and acceleration are continuous (the quintic meets f's state);
    a duration of 0 leaves that axis f's from the first instant (a step from ``start``, as the paper's
    trajectories start)."""
    start = np.asarray(start, dtype=float)

    def g(t):
        t = _t(t)
        r = f(t)
        pos, vel, acc = r.pos.copy(), r.vel.copy(), r.acc.copy()
        for axes, T in ((slice(0, 2), horizontal_s), (slice(2, 3), vertical_s)):
            early = t < T
            if T > 0.0 and early.any():
                end = f(np.array([T]))
                pos[early, axes], vel[early, axes], acc[early, axes] = _quintic_from_rest(
                    start[axes], end.pos[0, axes], end.vel[0, axes], end.acc[0, axes], T, t[early]
                )
        return Reference(pos=pos, vel=vel, acc=acc, yaw=r.yaw, yaw_rate=r.yaw_rate, yaw_acc=r.yaw_acc)

    return g


TRAJECTORIES: dict[str, Callable[..., Callable[[np.ndarray], Reference]]] = {
    "step": step,
    "hover": hover,
    "lemniscate": lemniscate,
    "circle": circle,
    "ascending_orbit": ascending_orbit,
}


def _floats(v):
    """An integer (not a bool) as a float, and those of a list; anything else as it is."""
    if isinstance(v, list):
        return [_floats(x) for x in v]
    return float(v) if isinstance(v, int) and not isinstance(v, bool) else v


def make_trajectory(name: str, params: dict | None = None, where: str = "trajectory"):
    """Build a trajectory by name with keyword parameters from a scenario file (its integers as floats:
    TOML reads integers of any size, and numpy keeps one beyond int64 as an object, which its
    functions refuse)."""
    if name not in TRAJECTORIES:
        raise UserError(f"unknown trajectory {name!r}; choose one of {', '.join(sorted(TRAJECTORIES))}", where=where)
    try:
        return TRAJECTORIES[name](**{k: _floats(v) for k, v in (params or {}).items()})
    except (TypeError, OverflowError) as exc:
        raise UserError(f"bad parameters for trajectory {name!r}: {exc}", where=where) from None
