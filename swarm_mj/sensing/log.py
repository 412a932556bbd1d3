"""What each drone believed, period by period: a run's record of its sensing stage (docs/sensing.md,
"What a run records"), and the summary of it measured against the true states."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .stage import UNSEEN_M, SensingStage


@dataclass
class ViewLog:
    """Per control period k (k samples, n drones): row [k, i, j] is drone i's about drone j."""

    pos: np.ndarray  # (k, n, n, 3) where i believed j was (its track; the diagonal: its own estimate) (m)
    mask: np.ndarray  # (k, n, n) bool: i held a message from j, sent within range
    age: np.ndarray  # (k, n, n) s since j sent what i held (inf: nothing)
    held_pos: np.ndarray  # (k, n, n, 3) the position in that message, as it came (m)
    held_tick: np.ndarray  # (k, n, n) int64: the period in which j sent it (−1: nothing held)

    @classmethod
    def allocate(cls, k: int, n: int) -> ViewLog:
        return cls(
            pos=np.full((k, n, n, 3), np.nan),
            mask=np.zeros((k, n, n), dtype=bool),
            age=np.full((k, n, n), np.inf),
            held_pos=np.full((k, n, n, 3), np.nan),
            held_tick=np.full((k, n, n), -1, dtype=np.int64),
        )

    def record(self, k: int, stage: SensingStage) -> None:
        """Sample k from the stage's last view and the channel's held messages."""
        v, held = stage.last, stage.channel.state
        assert v is not None and held is not None
        self.pos[k] = v.pos
        self.mask[k] = v.mask
        self.age[k] = v.age
        self.held_pos[k] = held.held_pos
        self.held_tick[k] = held.held_tick

    def truncated(self, k: int) -> ViewLog:
        return ViewLog(
            pos=self.pos[:k], mask=self.mask[:k], age=self.age[:k], held_pos=self.held_pos[:k],
            held_tick=self.held_tick[:k],
        )  # fmt: skip


def belief_errors(views: ViewLog, true_pos: np.ndarray) -> np.ndarray:
    """‖believed − true‖ (m) of every pair i ≠ j and period where i held a message from j, from the
    log's beliefs and the true positions (k, n, 3); a flat array."""
    k, n = views.mask.shape[:2]
    err = np.linalg.norm(views.pos[:k] - true_pos[:k, None, :, :], axis=-1)  # (k, n, n)
    use = views.mask[:k] & (views.pos[:k, :, :, 0] < 0.5 * UNSEEN_M)
    return err[use]


def view_summary(views: ViewLog, true_pos: np.ndarray) -> dict[str, Any]:
    """The summary's numbers of what the drones believed: the belief error's median, 99th percentile
    and largest (m) over the pairs held, the share of pair-periods with a message held, the oldest entry
    held (s)."""
    e = belief_errors(views, true_pos)
    n = views.mask.shape[1]
    off = ~np.eye(n, dtype=bool)
    held = views.mask[:, off]
    ages = views.age[:, off][held]
    return {
        "belief_error_m": {
            "median": float(np.median(e)) if e.size else None,
            "p99": float(np.quantile(e, 0.99)) if e.size else None,
            "max": float(e.max()) if e.size else None,
        },
        "held_share": float(held.mean()) if held.size else 0.0,
        "oldest_held_s": float(ages.max()) if ages.size else None,
    }
