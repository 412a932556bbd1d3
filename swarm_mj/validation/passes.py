"""Pass detection: the intervals where one drone flies over another (docs/validation.md, "Passes").

For a lower drone d, at each sample, the drones *over* it are those at least ``dz_min`` higher and
within ``r_window`` horizontally. An *event* is a maximal run of samples with at least one drone
over d; it is a *pass* when some drone over it comes within ``r_pass`` horizontally, and it does not
touch either end of the log (a pass cut by the log's start or end is left out). A pass is a
*single* pass when at most one drone is over d at every sample of it (the pairing "upper over
lower"), a *stack* when two or more are over d at once (d is the bottom of a stack).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Pass:
    """A pass over drone ``lower``: samples ``start:stop`` of the flight; ``uppers`` the drones over
    it during the pass (one for a single pass); ``i_min`` the sample where the nearest comes closest
    horizontally, ``r_min`` (m) that distance, ``dz`` (m) its height above ``lower`` then."""

    lower: int
    uppers: tuple[int, ...]
    start: int
    stop: int
    i_min: int
    r_min: float
    dz: float

    @property
    def stack(self) -> bool:
        return len(self.uppers) > 1


def runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """Maximal runs [start, stop) of True in a boolean array."""
    m = np.concatenate([[False], np.asarray(mask, bool), [False]])
    edges = np.flatnonzero(m[1:] != m[:-1])
    return [(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2], strict=True)]


def find_passes(
    pos: np.ndarray, lower: int, r_pass: float, r_window: float, dz_min: float, cut: list[tuple[int, int]] | None = None
) -> list[Pass]:
    """The passes over drone ``lower`` (module docstring); pos (n_drones, k, 3) positions (m). The
    events left out because the log's start or end cuts them are appended to ``cut`` (start, stop)."""
    n, k, _ = pos.shape
    others = [j for j in range(n) if j != lower]
    if not others:
        return []
    rxy = np.stack([np.linalg.norm(pos[j, :, :2] - pos[lower, :, :2], axis=1) for j in others])  # (n-1, k)
    dz = np.stack([pos[j, :, 2] - pos[lower, :, 2] for j in others])
    over = (dz >= dz_min) & (rxy < r_window)
    out: list[Pass] = []
    for a, b in runs(np.asarray(over.any(axis=0))):
        r = np.where(over[:, a:b], rxy[:, a:b], np.inf)
        if a == 0 or b == k:
            if cut is not None and r.min() < r_pass:
                cut.append((a, b))
            continue
        jj, ii = np.unravel_index(int(np.argmin(r)), r.shape)
        if r[jj, ii] >= r_pass:
            continue
        uppers = tuple(others[j] for j in range(len(others)) if over[j, a:b].any())
        out.append(
            Pass(
                lower=lower,
                uppers=uppers if over[:, a:b].sum(axis=0).max() > 1 else (others[jj],),
                start=a,
                stop=b,
                i_min=a + int(ii),
                r_min=float(r[jj, ii]),
                dz=float(dz[jj, a + ii]),
            )
        )
    return out
