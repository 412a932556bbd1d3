"""Regular-polygon formation slots around the leader (paper §4, Fig. 4b; SPEC §4).

Follower k (1-based) of n_f sits at angle π/2 + 2π(k−1)/n_f, at distance D from the
leader's CURRENT position, at the leader's altitude. D is the leader-to-follower
distance (circumradius): SPEC §4 explains why the paper's "diameter" cannot be a
true diameter.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..errors import UserError


def polygon_offsets(n_followers: int, D: float = 1.0) -> np.ndarray:
    """Horizontal offsets (n_followers, 3) of the slots from the leader, for circumradius D."""
    k = np.arange(n_followers)
    ang = np.pi / 2 + 2 * np.pi * k / max(n_followers, 1)
    return np.column_stack([D * np.cos(ang), D * np.sin(ang), np.zeros(n_followers)])


def slot_positions(leader_pos: np.ndarray, D: float, unit_offsets: np.ndarray) -> np.ndarray:
    """Slots (n_followers, 3) = leader position (3,) + D · unit offsets (n_followers, 3)."""
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
