"""Regular-polygon formation slots around the leader (paper §4, Fig. 4b; docs/interpretations.md §4).

Follower k (1-based) of n_f sits at angle π/2 + 2π(k−1)/n_f, at distance D from the
leader's CURRENT position, at the leader's altitude. D is the leader-to-follower
distance (circumradius): docs/interpretations.md §4 explains why the paper's "diameter"
cannot be a true diameter. :func:`setpoints_into` builds every drone's references of a
control step from them (the observation's ``setpoint*`` keys).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .._jit import jit
from ..errors import UserError


def polygon_offsets(n_followers: int, D: float = 1.0) -> np.ndarray:
    """Horizontal offsets (n_followers, 3) of the slots from the leader, for circumradius D."""
    k = np.arange(n_followers)
    ang = np.pi / 2 + 2 * np.pi * k / max(n_followers, 1)
    return np.column_stack([D * np.cos(ang), D * np.sin(ang), np.zeros(n_followers)])


def min_slot_spacing(n_followers: int, D: float) -> float:
    """The smallest horizontal distance (m) between two of the formation's positions, the leader's
    included, for ``n_followers`` slots on the regular polygon of circumradius D (:func:`polygon_offsets`):
    D from the leader, 2·D·sin(π/n) between neighbours (n ≥ 2)."""
    if n_followers < 1:
        return float("inf")
    return float(D if n_followers == 1 else min(D, 2.0 * D * np.sin(np.pi / n_followers)))


def check_formation_fits(n_followers: int, D: float, width: float, what: str, where: str = "") -> None:
    """Refuse a formation whose positions are closer than ``width`` (m), the horizontal width of the
    keep-out ``what`` holds (e.g. the barrier filter's, docs/barrier.md, "keep-out"): the filter would
    hold the drones off their slots for ever. One :class:`UserError` naming the smallest D that fits."""
    spacing = min_slot_spacing(n_followers, D)
    if spacing < width:
        need = np.ceil(100.0 * width / min_slot_spacing(n_followers, 1.0)) / 100.0  # rounded up: the D named fits
        raise UserError(
            f"{n_followers} followers at D = {D:g} m are {spacing:.2f} m apart, inside {what} "
            f"({width:.2f} m wide): the formation cannot be reached; use a diameter of at least {need:.2f} m",
            where=where or None,
        )


def capt_assignment(starts: np.ndarray, goals: np.ndarray) -> np.ndarray:
    """The goal of each start: a permutation σ (m,) such that every pair satisfies
    (x_i − x_j)·(g_σ(i) − g_σ(j)) ≥ 0, starts x (m, d), goals g (m, d) (docs/barrier.md, "slot
    assignment"). From the identity, any pair that violates it swaps goals; a swap changes
    Σ‖x_i − g_σ(i)‖² by 2·(x_i − x_j)·(g_σ(i) − g_σ(j)) < 0, so the sum of squared distances falls
    at every swap and the loop ends (finitely many permutations). The pairwise condition is the one
    the separation argument of CAPT (Turpin, Michael & Kumar, IJRR 2014) uses: straight paths flown
    in step from such an assignment do not cross; the assignment minimising the sum satisfies it too."""
    x = np.asarray(starts, dtype=float)
    g = np.asarray(goals, dtype=float)
    m = x.shape[0]
    sigma = np.arange(m)
    swapped = True
    while swapped:
        swapped = False
        for i in range(m - 1):
            dots = ((x[i] - x[i + 1 :]) * (g[sigma[i]] - g[sigma[i + 1 :]])).sum(axis=1)  # (m − i − 1,)
            worst = int(np.argmin(dots))
            if dots[worst] < -1e-12 * (1.0 + float(np.abs(dots).max())):
                j = i + 1 + worst
                sigma[i], sigma[j] = sigma[j], sigma[i]
                swapped = True
    return sigma


@jit
def setpoints_into(
    k: int,
    T: float,
    leader: np.ndarray,
    prev_leader: np.ndarray,
    leader_vel: np.ndarray,
    ref_pos: np.ndarray,
    ref_vel: np.ndarray,
    ref_acc: np.ndarray,
    ref_yaw: float,
    D: float,
    unit_offsets: np.ndarray,
    sp: np.ndarray,
    sp_vel: np.ndarray,
    sp_acc: np.ndarray,
    yaw: np.ndarray,
) -> None:
    """The references of the observation (paper §4), into sp, sp_vel, sp_acc (n, 3) and the yaw references
    yaw (n,): the leader's (n = 0) from its trajectory, each follower's slot leader + D·offset_k
    (unit_offsets (n−1, 3)) moving with the leader's velocity, estimated as (leader − prev_leader)/T
    (updated in place in leader_vel (3,), and prev_leader (3,) set to leader; at k = 0 the velocity is
    left as it is)."""
    n = unit_offsets.shape[0] + 1
    if k > 0:
        for j in range(3):
            leader_vel[j] = (leader[j] - prev_leader[j]) / T
    for j in range(3):
        prev_leader[j] = leader[j]
    sp_acc[:] = 0.0
    yaw[:] = 0.0
    for j in range(3):
        sp[0, j] = ref_pos[j]
        sp_vel[0, j] = ref_vel[j]
        sp_acc[0, j] = ref_acc[j]
    yaw[0] = ref_yaw
    for i in range(1, n):
        for j in range(3):
            sp[i, j] = leader[j] + D * unit_offsets[i - 1, j]
            sp_vel[i, j] = leader_vel[j]


def slot_positions(leader_pos: np.ndarray, D: float, unit_offsets: np.ndarray) -> np.ndarray:
    """Slots (n_followers, 3) = leader position (3,) + D · unit offsets (n_followers, 3)
    (what :func:`setpoints_into` computes for the followers' rows)."""
    return leader_pos + D * unit_offsets


class DiameterSchedule:
    """Piecewise-constant D(t) (paper eq. 34): ``[(t0, D0), (t1, D1), ...]`` with t0 = 0."""

    def __init__(self, schedule: float | Sequence[Sequence[float]], where: str = "formation.diameter") -> None:
        if isinstance(schedule, (int, float)):
            schedule = [(0.0, float(schedule))]
        try:
            arr = np.asarray(schedule, dtype=float).reshape(-1, 2)
        except (TypeError, ValueError):
            raise UserError("must be a number or a list of [time, D] pairs", where=where) from None
        if len(arr) == 0:
            raise UserError("is empty", where=where)
        if not np.isfinite(arr).all():
            raise UserError("must be finite numbers", where=where)
        if (arr[:, 1] <= 0).any():
            raise UserError(f"D must be positive, got {arr[:, 1].min():g} m", where=where)
        if arr[0, 0] != 0.0 or (np.diff(arr[:, 0]) <= 0).any():
            raise UserError("times must start at 0 and increase", where=where)
        self.times = arr[:, 0]
        self.values = arr[:, 1]

    def __call__(self, t: float | np.ndarray) -> np.ndarray:
        idx = np.searchsorted(self.times, np.asarray(t, dtype=float) + 1e-12, side="right") - 1
        return self.values[np.clip(idx, 0, len(self.values) - 1)]

    @property
    def change_times(self) -> np.ndarray:
        """Times at which D is set (the first is t = 0)."""
        return self.times.copy()
