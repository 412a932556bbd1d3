"""What an exported set must pass before anything is written (docs/export.md, "The checks").

Every check is computed on the pieces as the Crazyflie stores them (float32 coefficients and
durations), for every drone: the fit's tolerance against the sampled path (float32 arithmetic, as the
commander's ``polyval``), the memory, the thrust and tilt the pieces ask for (their acceleration and
speed through the vehicle's drag, from its :class:`~swarm_mj.physics.params.QuadParams` at run time),
the keep-out between every pair (the run summary's measure, on a grid four times finer than the control
period) and the vertical take-offs to the starts. :func:`failures` is the one line of a refusal.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..control.backstepping import MAX_TILT
from ..formation.barrier import keepout_radii
from ..metrics import AIRBORNE_M, keepout_per_sample, keepout_summary
from ..physics.params import QuadParams
from .poly import Pieces

#: Bytes of one piece in the commander's memory: 32 float32 coefficients and a float32 duration
#: (crazyflie-firmware ``pptraj.h`` ``struct poly4d``; cflib ``Poly4D.pack``).
BYTES_PER_PIECE = 4 * 33
#: Trajectory memory of one Crazyflie (crazyflie-firmware ``crtp_commander_high_level.c``
#: ``TRAJECTORY_MEMORY_SIZE``).
MEMORY_BYTES = 4096
#: Pieces that fit in it: 31 (the firmware's own comment: "4k allows us to store 31 poly4d pieces").
MAX_PIECES = MEMORY_BYTES // BYTES_PER_PIECE
#: The dense grid's step, as a share of the control period.
DENSE_SHARE = 0.25


@dataclass(frozen=True)
class Limits:
    """The limits an export is checked against (docs/export.md gives each one's reason)."""

    tolerance_m: float = 0.01  # position: the pieces within 1 cm of every sample of the path
    yaw_tolerance_rad: float = float(np.deg2rad(1.0))  # yaw: within 1 degree
    thrust_margin: float = 0.8  # the thrust asked at most this share of the rotors' total 4·f_max
    max_tilt_rad: float = float(MAX_TILT)  # the controller's attitude limit (backstepping's clip)
    max_pieces: int = MAX_PIECES
    memory_bytes: int = MEMORY_BYTES


@dataclass(frozen=True)
class Check:
    """One check's outcome: its worst figure against its limit, where it was (drone and plan time, s) and
    one phrase saying so."""

    name: str
    passed: bool
    value: float
    limit: float
    unit: str
    text: str
    drone: str | None = None
    t: float | None = None
    figures: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        return {
            "passed": self.passed,
            "value": self.value,
            "limit": self.limit,
            "unit": self.unit,
            "drone": self.drone,
            "t_s": self.t,
            "text": self.text,
            **self.figures,
        }


def failures(checks: list[Check]) -> str | None:
    """The refusal's one line: every failed check by name and phrase (None when all passed)."""
    bad = [f"{c.name}: {c.text}" for c in checks if not c.passed]
    return "; ".join(bad) if bad else None


def _argmax2(a: np.ndarray) -> tuple[int, int]:
    """The (row, column) of the largest value of a 2D array."""
    r, c = np.unravel_index(int(np.argmax(a)), a.shape)
    return int(r), int(c)


def dense_times(duration: float, period: float) -> np.ndarray:
    """The grid (k,) the limits and the keep-out are checked on: :data:`DENSE_SHARE` of the control
    period from 0 to the end, the end included."""
    step = period * DENSE_SHARE
    return np.unique(np.r_[np.arange(0.0, duration, step), duration])


def _at_most(name: str, value: float, limit: float, unit: str, text: str, *, drone: str | None = None,
             t: float | None = None, figures: dict | None = None) -> Check:  # fmt: skip
    """A check that passes when ``value`` is at most ``limit``."""
    return Check(name=name, passed=bool(value <= limit), value=float(value), limit=float(limit), unit=unit, text=text,
                 drone=drone, t=t, figures=figures or {})  # fmt: skip


def fit_checks(pieces: list[Pieces], names: list[str], t: np.ndarray, pos: np.ndarray, yaw: np.ndarray,
               limits: Limits) -> list[Check]:  # fmt: skip
    """Tolerance (position, yaw; float32 arithmetic at the path's samples t (k,), pos (k, n, 3), yaw (k, n)),
    pieces and memory."""
    err, yerr = np.zeros((len(t), len(names))), np.zeros((len(t), len(names)))
    for i, p in enumerate(pieces):
        ev = p.evaluate(t, float32=True)
        err[:, i] = np.linalg.norm(ev[:, :3] - pos[:, i], axis=1)
        yerr[:, i] = np.abs(ev[:, 3] - yaw[:, i])
    k, i = _argmax2(err)
    ky, iy = _argmax2(yerr)
    n_p = np.array([p.n_pieces for p in pieces])
    j = int(np.argmax(n_p))
    mem = int(n_p.max()) * BYTES_PER_PIECE
    yaw_deg, yaw_lim = np.rad2deg(yerr.max()), np.rad2deg(limits.yaw_tolerance_rad)
    return [
        _at_most("tolerance", err.max(), limits.tolerance_m, "m",
                 f"{names[i]}'s pieces lie {err.max() * 100:.2f} cm from its path at t = {t[k]:.2f} s "
                 f"(limit {limits.tolerance_m * 100:g} cm)", drone=names[i], t=float(t[k])),
        _at_most("yaw tolerance", yerr.max(), limits.yaw_tolerance_rad, "rad",
                 f"{names[iy]}'s yaw {yaw_deg:.2f} deg from its path at t = {t[ky]:.2f} s (limit {yaw_lim:g} deg)",
                 drone=names[iy], t=float(t[ky])),
        _at_most("pieces", n_p.max(), limits.max_pieces, "",
                 f"{names[j]} has {n_p.max()} pieces (limit {limits.max_pieces})", drone=names[j]),
        _at_most("memory", mem, limits.memory_bytes, "bytes",
                 f"{names[j]}'s pieces take {mem} bytes (limit {limits.memory_bytes})", drone=names[j]),
    ]  # fmt: skip


def thrust_checks(pieces: list[Pieces], names: list[str], td: np.ndarray, params: QuadParams,
                  limits: Limits) -> list[Check]:  # fmt: skip
    """The rotors' force the pieces ask for on the dense grid td (k,): F = m·(a + g·ẑ) + K∘v (the vehicle's
    mass, gravity and linear drag K), its size against ``thrust_margin`` · 4·f_max and its tilt from the
    vertical against ``max_tilt_rad``; the speed and acceleration asked are reported with them."""
    m, g, K = float(params.m), float(params.g), np.asarray(params.drag, dtype=float)
    frac = np.zeros((len(td), len(names)))
    tilt = np.zeros_like(frac)
    speed, acc = np.zeros(len(names)), np.zeros(len(names))
    for i, p in enumerate(pieces):
        v, a = p.evaluate(td, 1)[:, :3], p.evaluate(td, 2)[:, :3]
        F = m * (a + np.array([0.0, 0.0, g])) + K * v
        Fn = np.linalg.norm(F, axis=1)
        frac[:, i] = Fn / (4.0 * params.f_max)
        tilt[:, i] = np.arccos(np.clip(F[:, 2] / np.maximum(Fn, 1e-12), -1.0, 1.0))
        speed[i], acc[i] = np.linalg.norm(v, axis=1).max(), np.linalg.norm(a, axis=1).max()
    k, i = _argmax2(frac)
    kt, it = _argmax2(tilt)
    figures = {"max_speed_m_s": float(speed.max()), "max_acceleration_m_s2": float(acc.max()),
               "rotors_total_n": 4.0 * float(params.f_max)}  # fmt: skip
    return [
        _at_most("thrust", frac.max(), limits.thrust_margin, "of 4 f_max",
                 f"{names[i]} asks {frac.max():.0%} of its rotors' {4 * params.f_max:.3g} N at t = {td[k]:.2f} s "
                 f"(limit {limits.thrust_margin:.0%})", drone=names[i], t=float(td[k]), figures=figures),
        _at_most("tilt", tilt.max(), limits.max_tilt_rad, "rad",
                 f"{names[it]} asks a tilt of {np.rad2deg(tilt.max()):.0f} deg at t = {td[kt]:.2f} s "
                 f"(limit {np.rad2deg(limits.max_tilt_rad):.0f} deg)", drone=names[it], t=float(td[kt])),
    ]  # fmt: skip


def _no_pair(name: str, why: str) -> Check:
    return Check(name=name, passed=True, value=float("inf"), limit=1.0, unit="", text=why)


def keepout_checks(pieces: list[Pieces], names: list[str], td: np.ndarray, params: QuadParams) -> list[Check]:
    """The keep-out (the run summary's ellipsoid, :func:`~swarm_mj.formation.barrier.keepout_radii`, between
    airborne drones) on the pieces evaluated on the dense grid td (k,), and the vertical take-offs to the
    starts: every two airborne starts at least the keep-out's width apart across (then the take-offs,
    straight up at once, keep out of it whatever their heights)."""
    radii = keepout_radii(params, rotor_radius=params.rotor_radius)
    pos = np.stack([p.evaluate(td)[:, :3] for p in pieces], axis=1)  # (k, n, 3)
    if len(names) < 2:
        return [_no_pair("keepout", "one drone: no pair"), _no_pair("takeoff", "one drone: no pair")]
    summ = keepout_summary(td, pos, radii)
    rho = keepout_per_sample(pos, radii)
    k = int(np.argmin(rho))
    d = (pos[k, :, None, :] - pos[k, None, :, :]) / radii  # (n, n, 3)
    i, j = sorted(_argmax2(-(np.linalg.norm(d, axis=-1) + np.where(np.eye(len(names)) > 0, np.inf, 0.0))))
    inside = float(summ["keepout_time_s"])
    keep = Check(
        name="keepout", passed=inside == 0.0, value=float(summ["keepout_min_distance"]), limit=1.0,
        unit="keep-out radii", drone=f"{names[i]}, {names[j]}", t=float(td[k]),
        text=f"closest: {names[i]} and {names[j]} at {rho[k]:.2f} x the keep-out's radii ({radii[0]:.3g}, "
        f"{radii[2]:.3g} m) at t = {td[k]:.2f} s; {inside:.2f} s inside it",
        figures={"time_inside_s": inside, "radii_m": radii.tolist()},
    )  # fmt: skip
    starts = pos[0]
    up = np.flatnonzero(starts[:, 2] > AIRBORNE_M)
    if len(up) < 2:
        return [keep, _no_pair("takeoff", "at most one start in the air: no take-off pair")]
    h = np.linalg.norm(starts[up, None, :2] - starts[None, up, :2], axis=-1) / radii[0]
    h[np.diag_indices(len(up))] = np.inf
    a, b = sorted(_argmax2(-h))
    ok = bool(h.min() >= 1.0)
    take = Check(
        name="takeoff", passed=ok, value=float(h.min()), limit=1.0, unit="keep-out widths",
        drone=f"{names[up[a]]}, {names[up[b]]}",
        text=f"{names[up[a]]} and {names[up[b]]} start {h.min() * radii[0]:.3f} m apart across, "
        + (f"at least the keep-out's width {radii[0]:.3g} m" if ok else
           f"less than the keep-out's width {radii[0]:.3g} m: their take-offs would cross it"),
    )  # fmt: skip
    return [keep, take]


def run_checks(pieces: list[Pieces], names: list[str], t: np.ndarray, pos: np.ndarray, yaw: np.ndarray,
               params: QuadParams, period: float, limits: Limits) -> list[Check]:  # fmt: skip
    """Every check of an export, in the order of docs/export.md."""
    td = dense_times(min(p.duration for p in pieces), period)
    return (
        fit_checks(pieces, names, t, pos, yaw, limits)
        + thrust_checks(pieces, names, td, params, limits)
        + keepout_checks(pieces, names, td, params)
    )
