"""Metrics of docs/interpretations.md §7, as pure functions on logged arrays (time axis first)."""

from __future__ import annotations

from typing import cast

import numpy as np

from ._jit import jit
from .physics.aero.downwash import S0, SPREAD
from .physics.params import DEFAULT_PARAMS, QuadParams

#: Weights of eq. (25) on e_x, e_y, e_z, e_φ, e_θ, e_ψ.
ISE_WEIGHTS = np.array([3.0, 3.0, 1.0, 2.0, 2.0, 1.0])


def step_metrics(
    t: np.ndarray, y: np.ndarray, target: float, y0: float | None = None, band: float = 0.02
) -> dict[str, float]:
    """Overshoot (%), 2 % settling time (s) and steady-state error of a step response.

    t: (k,), y: (k,). Overshoot is the largest excursion past the target, as a percentage
    of the step size |target − y0|; settling is the first time after which y stays within
    ``band``·|target − y0| of the target (``inf`` if y is outside at the end); the
    steady-state error is |y(end) − target|. One response of :func:`step_metrics_batch`.
    """
    y = np.asarray(y, dtype=float)
    y0 = float(y[0]) if y0 is None else float(y0)
    m = step_metrics_batch(t, y[:, None], np.array([float(target)]), np.array([y0]), band)
    return {key: float(v[0]) for key, v in m.items()}


def step_metrics_batch(
    t: np.ndarray, y: np.ndarray, target: np.ndarray | float, y0: np.ndarray | float, band: float = 0.02
) -> dict[str, np.ndarray]:
    """:func:`step_metrics` of m responses at once: t (k,), y (k, m), target and y0 (m,) or scalars.

    Returns ``overshoot_pct``, ``settling_s``, ``steady_state_error``, each (m,). A response
    whose step size is zero has no overshoot and settles at once.
    """
    t = np.asarray(t, dtype=float)  # (k,)
    y = np.asarray(y, dtype=float)  # (k, m)
    m = y.shape[1]
    target = np.broadcast_to(np.asarray(target, dtype=float), (m,))  # (m,)
    y0 = np.broadcast_to(np.asarray(y0, dtype=float), (m,))  # (m,)
    size = np.abs(target - y0)  # (m,)
    sign = np.sign(target - y0)
    dev = y - target  # (k, m)
    over = np.maximum(0.0, np.max(sign * dev, axis=0))
    outside = np.abs(dev) > band * size  # (k, m)
    last = len(t) - 1 - np.argmax(outside[::-1], axis=0)  # last sample outside
    settle = np.where(outside.any(axis=0), t[np.minimum(last + 1, len(t) - 1)], t[0]) - t[0]
    settle = np.where(outside[-1], np.inf, settle)
    zero = size == 0
    with np.errstate(divide="ignore", invalid="ignore"):
        over_pct = np.where(zero, 0.0, 100.0 * over / np.where(zero, 1.0, size))
    return {
        "overshoot_pct": over_pct,
        "settling_s": np.where(zero, 0.0, settle),
        "steady_state_error": np.abs(y[-1] - target),
    }


def norm(x: np.ndarray) -> np.ndarray:
    """Euclidean norm along the last axis of x (..., c), c ≤ 3 (a 2- or 3-vector): sqrt((x_0² + x_1²) + x_2²),
    summed in order as ``np.linalg.norm(x, axis=-1)`` sums so few terms (the same bits), at a third of its
    cost on a run's log (one pass per component rather than a 3-term reduction per element)."""
    x = np.asarray(x, dtype=float)
    if not 0 < x.shape[-1] <= 3:
        return np.linalg.norm(x, axis=-1)
    s = x[..., 0] * x[..., 0]
    for c in range(1, x.shape[-1]):
        s += x[..., c] * x[..., c]
    return np.sqrt(s)


def rmse(err: np.ndarray, axis: int = 0) -> np.ndarray:
    """Root mean square error, eq. (38): sqrt(1/k Σ e²) along ``axis`` (the time axis)."""
    err = np.asarray(err, dtype=float)
    return np.sqrt(np.mean(err * err, axis=axis))


def ise(errors: np.ndarray, dt: float, weights: np.ndarray = ISE_WEIGHTS) -> np.ndarray:
    """Integral squared error, eq. (25), by the rectangle rule at the sample period dt.

    errors: (k, ..., 6) errors e_x, e_y, e_z (m), e_φ, e_θ, e_ψ (rad) → (...,) ISE.
    """
    return dt * np.einsum("k...j,j->...", errors * errors, weights)


def min_separation(pos: np.ndarray, dist: np.ndarray | None = None) -> tuple[float, float, tuple[int, int]]:
    """Smallest 3D centre distance over time and pairs; pos: (k, n, 3) → (distance, time index, pair).
    ``dist``: the pairs' distances (k, pairs) ‖p_i − p_j‖, i < j in ``np.triu_indices`` order, if already
    known (:func:`pair_measures`)."""
    n = pos.shape[1]
    if n < 2:
        return float("inf"), -1, (-1, -1)
    i, j = np.triu_indices(n, 1)
    d = norm(pos[:, i, :] - pos[:, j, :]) if dist is None else dist  # (k, pairs)
    flat = int(np.argmin(d))
    kk, pp = divmod(flat, d.shape[1])
    return float(d[kk, pp]), kk, (int(i[pp]), int(j[pp]))


def leader_distances(pos: np.ndarray) -> np.ndarray:
    """Horizontal leader–follower distances (k, n−1) from pos (k, n, 3) (paper Fig. 14, left)."""
    return norm(pos[:, 1:, :2] - pos[:, :1, :2])


def follower_distances(pos: np.ndarray) -> tuple[np.ndarray, list[tuple[int, int]]]:
    """Horizontal follower–follower distances (k, pairs) and the pairs (paper Fig. 14, right)."""
    n = pos.shape[1]
    i, j = np.triu_indices(n - 1, 1)
    i, j = i + 1, j + 1
    x, y = pos[:, :, 0], pos[:, :, 1]  # per axis: the pairs gathered from (k, n) planes, not (k, n, 3)
    dx, dy = x[:, i] - x[:, j], y[:, i] - y[:, j]  # (k, pairs)
    return np.sqrt(dx * dx + dy * dy), list(zip(i.tolist(), j.tolist()))  # norm()'s sum, the same bits


def formation_settling(
    t: np.ndarray, dist: np.ndarray, D: np.ndarray, change_times: np.ndarray, tol: float = 0.05
) -> tuple[list[float], float]:
    """Settling time after each change of D and the largest distance error once settled.

    dist: (k, n_f) leader–follower distances; D: (k,) desired. For the segment starting at
    each change time, the settling time is the first instant after which every |dist − D|
    stays within ``tol`` until the segment ends (inf if never). Returns (settling per change,
    max |dist − D| over the settled parts).
    """
    err = np.abs(dist - D[:, None]).max(axis=1)  # (k,)
    bounds = list(change_times) + [np.inf]
    settling, settled_err = [], [0.0]
    for a, b in zip(bounds[:-1], bounds[1:]):
        seg = (t >= a - 1e-9) & (t < b - 1e-9)
        if not seg.any():
            continue
        ts, es = t[seg], err[seg]
        bad = es > tol
        if not bad.any():
            s = 0.0
            first = 0
        elif bad[-1]:
            settling.append(float("inf"))
            continue
        else:
            first = np.flatnonzero(bad)[-1] + 1
            s = float(ts[first] - a)
        settling.append(s)
        settled_err.append(float(es[first:].max()))
    return settling, max(settled_err)


# ---------------------------------------------------------------------------- downwash dip
#: Jet geometry of the downwash dip (docs/interpretations.md, "downwash dip"). The jet below a
#: drone is the turbulent round jet of Bauersfeld et al. (RA-L 2024, arXiv:2403.13321, their
#: eqs. 6 and 9, the model swarm_mj.physics.aero.downwash applies): half-width r_½(s) = l·S·(s/l − s0*)
#: at a depth s along the drone's thrust axis, l = 2L the upper drone's motor distance,
#: S = 0.07668, s0* = −5.817. Its edge is taken at 2·r_½ (there the jet speed is
#: 1/(1 + 4(√2 − 1))² = 14 % of the centreline's and its push on a rotor disc 2 %):
#: ``r0 + spread·s`` with r0 = 2·l·S·(−s0*). A drone whose rotor span (``radius`` from its centre)
#: reaches inside that edge, at a depth between 0 and ``reach`` = ``JET_REACH_MOTOR_DISTANCES``·l,
#: is in the jet. All but ``spread`` are the vehicle's sizes (:func:`jet_geometry`); the module
#: constants are the paper drone's.
JET_SPREAD = 2.0 * SPREAD  # 0.153 m per m of depth, whatever the vehicle
#: The centreline push on a hovering drone, relative to its weight, is C_D·B_d²/4/(s/l − s0*)²
#: (the same for any vehicle at the same s/l): still a tenth of its weight 12 motor distances down.
JET_REACH_MOTOR_DISTANCES = 12.0


def jet_geometry(vehicle: QuadParams) -> dict[str, float]:
    """The keyword arguments of :func:`in_jet` (and ``downwash_dip``'s ``jet``) for drones of
    parameters ``vehicle`` (module comment above): r0 = 2·l·S·(−s0*), spread = 2·S,
    reach = 12·l with l = 2L, and the rotor span L + r of the drone below as ``radius``."""
    l = 2.0 * vehicle.L
    return {
        "r0": 2.0 * l * SPREAD * (-S0),
        "spread": JET_SPREAD,
        "reach": JET_REACH_MOTOR_DISTANCES * l,
        "radius": float(vehicle.rotor_span),
    }


_PAPER_JET = jet_geometry(DEFAULT_PARAMS)
JET_R0_M = _PAPER_JET["r0"]  # 0.446 m: 2·r_½ at the rotor plane of the paper's drone
JET_REACH_M = _PAPER_JET["reach"]  # 6 m for the paper's drone
DRONE_RADIUS_M = _PAPER_JET["radius"]  # rotor span of the paper's drone: L + rotor radius (0.25 + 0.09 m)


def in_jet(
    pos: np.ndarray,
    quat: np.ndarray,
    *,
    r0: float = JET_R0_M,
    spread: float = JET_SPREAD,
    reach: float = JET_REACH_M,
    radius: float = DRONE_RADIUS_M,
) -> np.ndarray:
    """Which drone is in which drone's jet, (k, n, n) bool: ``[t, i, j]`` = drone j is in drone i's jet.

    pos (k, n, 3), quat (k, n, 4) (w, x, y, z). The jet of drone i leaves along −(body z of i)
    (it follows the drone's thrust direction); drone j, at depth s = (p_j − p_i)·(−z_i) along
    that axis and radial offset r from it, is in the jet when 0 < s ≤ ``reach`` and
    r < ``r0`` + ``spread``·s + ``radius`` (its rotor span reaches into the jet's edge).
    """
    pos = np.ascontiguousarray(pos, dtype=float)
    out = np.empty(pos.shape[:2] + pos.shape[1:2], dtype=np.bool_)  # (k, n, n)
    in_jet_kernel(
        pos, np.ascontiguousarray(quat, dtype=float), float(r0), float(spread), float(reach), float(radius), out
    )
    return out


def _in_jet_samples():
    pos = np.array([[[0.0, 0.0, 2.0], [0.1, 0.0, 1.0]]])
    quat = np.tile([1.0, 0.0, 0.0, 0.0], (1, 2, 1))
    return [(pos, quat, 0.4, 0.15, 6.0, 0.34, np.empty((1, 2, 2), dtype=np.bool_))]


@jit(samples=_in_jet_samples)
def in_jet_kernel(
    pos: np.ndarray, quat: np.ndarray, r0: float, spread: float, reach: float, radius: float, out: np.ndarray
) -> None:
    """:func:`in_jet` into out (k, n, n) bool, from pos (k, n, 3) and quat (k, n, 4) (w, x, y, z), in one
    pass: drone i's jet direction a_i = −(body z of i) = −(2(xz + wy), 2(yz − wx), 1 − 2(x² + y²));
    rel = p_j − p_i, s = rel·a_i, r² = |rel|² − s², j in i's jet when 0 < s ≤ reach and
    r² < (r0 + spread·s + radius)², never its own. The sums are taken in the order NumPy's ``einsum``
    took them here before (x + z, then + y: the same bits)."""
    k, n = pos.shape[0], pos.shape[1]
    for t in range(k):
        for i in range(n):
            w, x, y, z = quat[t, i, 0], quat[t, i, 1], quat[t, i, 2], quat[t, i, 3]
            ax = -(2.0 * (x * z + w * y))
            ay = -(2.0 * (y * z - w * x))
            az = -(1.0 - 2.0 * (x * x + y * y))
            for j in range(n):
                rx = pos[t, j, 0] - pos[t, i, 0]
                ry = pos[t, j, 1] - pos[t, i, 1]
                rz = pos[t, j, 2] - pos[t, i, 2]
                s = rx * ax + rz * az + ry * ay
                r2 = rx * rx + rz * rz + ry * ry - s * s
                edge = r0 + spread * s + radius
                out[t, i, j] = i != j and s > 0.0 and s <= reach and r2 < edge * edge


def downwash_dip(
    t: np.ndarray, pos: np.ndarray, pos_d: np.ndarray, quat: np.ndarray, *, airborne: float = 0.1, **jet: float
) -> dict:
    """The worst altitude dip of a drone in another drone's jet (docs/interpretations.md).

    t (k,), pos (k, n, 3) positions, pos_d (k, n, 3) commanded positions (after the
    anti-collision rule), quat (k, n, 4) attitudes (w, x, y, z). Drone j is *in a jet* at a
    sample where it is in the jet of an airborne drone i (:func:`in_jet`; ``jet`` passes its
    geometry) and j has taken off (its altitude has once exceeded ``airborne`` m). Its altitude
    error below the reference is e = max(0, z_d − z). Over each stretch of consecutive samples
    in a jet, its *dip* is how much e has grown since the stretch began, e(t) − e(start): the
    sinking the jet caused, not the lag the drone already had (a drone entering a jet while it
    still climbs towards its reference, such as the leader after its take-off step, is already
    below it, jet or not). Returns ``worst_m`` (the largest dip, 0 if none), ``drone`` and
    ``above`` (the indices, −1 if none), ``t_s`` (when), ``time_in_jet_s`` (samples with any
    drone in a jet × the sample period), ``per_drone_m`` (n,) the worst dip of each drone, and
    ``below_ref_worst_m``, the largest e itself at a sample in a jet (lag included).
    """
    t = np.asarray(t, dtype=float)
    pos = np.asarray(pos, dtype=float)
    k, n = pos.shape[:2]
    empty = {
        "worst_m": 0.0,
        "drone": -1,
        "above": -1,
        "t_s": None,
        "time_in_jet_s": 0.0,
        "per_drone_m": [0.0] * n,
        "below_ref_worst_m": 0.0,
    }
    if n < 2 or k == 0:
        return empty
    z = pos[:, :, 2]  # (k, n)
    up = np.maximum.accumulate(z > airborne, axis=0)  # (k, n) taken off by then
    in_jets = in_jet(pos, quat, **jet) & (z > airborne)[:, :, None] & up[:, None, :]  # (k, i, j)
    below = cast(np.ndarray, in_jets.any(axis=1))  # (k, n) j in some jet (numpy's stubs allow a scalar)
    e = np.maximum(0.0, np.asarray(pos_d, dtype=float)[:, :, 2] - z)  # (k, n)
    start = below & ~np.vstack([np.zeros((1, n), dtype=bool), below[:-1]])  # (k, n) a stretch begins
    stretch = np.cumsum(start, axis=0)  # (k, n) stretch number (per drone)
    base = np.zeros((k, n))
    for j in range(n):
        first = np.flatnonzero(start[:, j])  # sample where each stretch begins
        if len(first):
            base[:, j] = np.concatenate([[0.0], e[first, j]])[stretch[:, j]]
    dips = np.where(below, np.maximum(e - base, 0.0), 0.0)  # (k, n)
    dt = float(np.median(np.diff(t))) if k > 1 else 0.0
    out = dict(empty)
    out["time_in_jet_s"] = float(below.any(axis=1).sum() * dt)
    out["per_drone_m"] = [float(v) for v in dips.max(axis=0)]
    out["below_ref_worst_m"] = float(np.where(below, e, 0.0).max())
    if not (dips > 0.0).any():
        return out
    kk, j = map(int, np.unravel_index(int(np.argmax(dips)), dips.shape))
    i = int(np.argmax(in_jets[kk, :, j]))
    out.update(worst_m=float(dips[kk, j]), drone=int(j), above=i if in_jets[kk, i, j] else -1, t_s=float(t[kk]))
    return out


# ---------------------------------------------------------------------------- keep-out invariant
#: A drone is airborne at a sample when its centre is above this altitude (m), the bar of
#: ``min_separation_airborne_m`` (docs/barrier.md, "the invariant measured").
AIRBORNE_M = 0.1


def keepout_distance(offset: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """Normalised ellipsoidal distance ρ = ‖S·p‖ (...,) of centre offsets p (..., 3), S = diag(1/radii)
    (docs/barrier.md, "keep-out"): ρ = 1 on the keep-out ellipsoid of radii (a, a, c), < 1 inside."""
    return norm(np.asarray(offset, dtype=float) / np.asarray(radii, dtype=float))


def keepout_per_sample(pos: np.ndarray, radii: np.ndarray, airborne: float = AIRBORNE_M) -> np.ndarray:
    """Smallest normalised ellipsoidal distance (k,) over the pairs of drones both airborne (centre
    above ``airborne`` m) at each sample of pos (k, n, 3); +inf where no pair is (NaN where a pair's
    is: :func:`pair_measures`)."""
    return pair_measures(pos, radii, airborne)[1]


def pair_measures(pos: np.ndarray, radii: np.ndarray, airborne: float = AIRBORNE_M) -> tuple[np.ndarray, np.ndarray]:
    """One pass over every pair i < j of pos (k, n, 3) (``np.triu_indices`` order): their centre distances
    ‖p_i − p_j‖ (k, pairs) (what :func:`min_separation` takes) and :func:`keepout_per_sample` (k,)."""
    pos = np.ascontiguousarray(pos, dtype=float)
    k, n = pos.shape[:2]
    dist, rho = np.empty((k, n * (n - 1) // 2)), np.full(k, np.inf)
    if n >= 2:
        pair_kernel(pos, np.ascontiguousarray(radii, dtype=float).reshape(3), float(airborne), dist, rho)
    return dist, rho


def _pair_samples():
    pos = np.array([[[0.0, 0.0, 1.0], [0.5, 0.0, 1.0], [0.0, 0.5, 0.0]]])
    return [(pos, np.array([0.6, 0.6, 0.9]), 0.1, np.empty((1, 3)), np.empty(1))]


@jit(samples=_pair_samples)
def pair_kernel(pos: np.ndarray, radii: np.ndarray, airborne: float, dist: np.ndarray, rho: np.ndarray) -> None:
    """:func:`pair_measures` into dist (k, pairs) and rho (k,): for each pair i < j at each sample, d = p_i − p_j,
    dist = sqrt((d_x² + d_y²) + d_z²) (:func:`norm`'s order), and, where both centres are above
    ``airborne``, ρ = ‖d / radii‖ (:func:`keepout_distance`), rho the smallest (NaN if any is NaN, as
    NumPy's ``min``; +inf where no pair is airborne)."""
    k, n = pos.shape[0], pos.shape[1]
    for t in range(k):
        best = np.inf
        p = 0
        for i in range(n):
            for j in range(i + 1, n):
                dx = pos[t, i, 0] - pos[t, j, 0]
                dy = pos[t, i, 1] - pos[t, j, 1]
                dz = pos[t, i, 2] - pos[t, j, 2]
                dist[t, p] = np.sqrt(dx * dx + dy * dy + dz * dz)
                p += 1
                if pos[t, i, 2] > airborne and pos[t, j, 2] > airborne:
                    ex, ey, ez = dx / radii[0], dy / radii[1], dz / radii[2]
                    r = np.sqrt(ex * ex + ey * ey + ez * ez)
                    if r < best or r != r:
                        best = r if best == best else best
        rho[t] = best


def keepout_min_distance(pos: np.ndarray, radii: np.ndarray, airborne: float = AIRBORNE_M) -> float:
    """``keepout_min_distance``: the smallest normalised ellipsoidal distance between two airborne
    drones over a run (pos (k, n, 3)); 1 = on the keep-out, < 1 = inside; +inf if never two airborne."""
    return float(np.min(keepout_per_sample(pos, radii, airborne), initial=np.inf))


def keepout_time_s(t: np.ndarray, pos: np.ndarray, radii: np.ndarray, airborne: float = AIRBORNE_M) -> float:
    """``keepout_time_s``: the time (s) during which some pair of airborne drones is inside the
    keep-out (ρ < 1): the samples of t (k,) where that holds × the median sample period."""
    return _time_inside(t, keepout_per_sample(pos, radii, airborne))


def _time_inside(t: np.ndarray, rho: np.ndarray) -> float:
    """The samples of t (k,) where rho (k,) < 1, × the median sample period (s)."""
    t = np.asarray(t, dtype=float)
    if len(t) < 2:
        return 0.0
    return float((rho < 1.0).sum() * np.median(np.diff(t)))


def keepout_summary(t: np.ndarray, pos: np.ndarray, radii: np.ndarray, rho: np.ndarray | None = None) -> dict:
    """The run summary's keep-out keys: ``keepout_min_distance`` (None for one drone, +inf when
    never two are airborne) and ``keepout_time_s`` (docs/barrier.md, "the invariant measured"),
    from one pass over the log (:func:`keepout_per_sample`; ``rho``: its result, if already known)."""
    if np.asarray(pos).shape[1] < 2:
        return {"keepout_min_distance": None, "keepout_time_s": 0.0}
    rho = keepout_per_sample(pos, radii) if rho is None else rho
    return {"keepout_min_distance": float(np.min(rho, initial=np.inf)), "keepout_time_s": _time_inside(t, rho)}
