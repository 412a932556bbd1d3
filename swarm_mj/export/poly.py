"""Piecewise polynomials of degree 7 joined up to the third derivative (docs/export.md, "The fit").

A :class:`Pieces` holds ``N`` pieces of ``d`` columns (x, y, z, yaw for the Crazyflie): each a
polynomial of degree :data:`DEGREE` in its own local time τ ∈ [0, duration], coefficients in
ascending powers, as crazyflie-firmware's ``struct poly4d`` stores them (``pptraj.h``).

:func:`fit_pieces` fits samples y(t) on given knots by least squares with equality constraints: the
value and the first :data:`CONTINUITY` derivatives equal on both sides of every inner knot (C0..C3),
and the value and slope at both ends pinned to given ones. :func:`fit_adaptive` chooses the knots:
it splits the piece worst fitted until every sample lies within the tolerance, then removes the
knots it can without leaving it.
"""

from __future__ import annotations

from dataclasses import dataclass
from math import factorial

import numpy as np

#: Degree of every piece (crazyflie-firmware ``pptraj.h``: ``PP_DEGREE``).
DEGREE = 7
#: Coefficients per column of a piece.
N_COEF = DEGREE + 1
#: Derivatives equal on both sides of an inner knot (C0..C3: position, velocity, acceleration, jerk).
CONTINUITY = 3
#: Fewest samples a piece may hold: with C0..C3 fixed by its neighbour a piece has 4 free coefficients
#: per column, and twice that many samples keep the least-squares problem well posed.
MIN_SAMPLES = 8

# d^r/ds^r s^j at s = 1: j!/(j−r)! (0 for j < r), (CONTINUITY + 1, N_COEF)
_FALL = np.array([[factorial(j) / factorial(j - r) if j >= r else 0.0 for j in range(N_COEF)] for r in range(4)])


@dataclass(frozen=True)
class Pieces:
    """Piecewise polynomials: ``durations`` (N,) s and ``coeffs`` (N, d, 8) in ascending powers of each
    piece's local time."""

    durations: np.ndarray  # (N,)
    coeffs: np.ndarray  # (N, d, 8)

    @property
    def n_pieces(self) -> int:
        return int(len(self.durations))

    @property
    def knots(self) -> np.ndarray:
        """(N + 1,) the pieces' start times from 0, and the end (float64 sums of the durations)."""
        return np.concatenate([[0.0], np.cumsum(np.asarray(self.durations, dtype=np.float64))])

    @property
    def duration(self) -> float:
        return float(self.knots[-1])

    def as_float32(self) -> Pieces:
        """The pieces as the commander stores them: durations and coefficients rounded to float32."""
        return Pieces(
            durations=np.asarray(self.durations, dtype=np.float32),
            coeffs=np.asarray(self.coeffs, dtype=np.float32),
        )

    def locate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The piece index (k,) and local time (k,) of times t (k,): the first piece whose end is at or
        after t, as crazyflie-firmware's ``piecewise_eval`` walks them (``t <= duration``); t before 0 is
        clamped to 0 and t after the end to the end."""
        knots = self.knots
        t = np.clip(np.asarray(t, dtype=np.float64), 0.0, knots[-1])
        i = np.minimum(np.searchsorted(knots[1:], t, side="left"), self.n_pieces - 1)
        return i, t - knots[i]

    def evaluate(self, t: np.ndarray, derivative: int = 0, float32: bool = False) -> np.ndarray:
        """The ``derivative``-th derivative (k, d) at times t (k,) by Horner's rule on the stored coefficients:
        in float64 arithmetic, or with ``float32`` in float32 arithmetic as the Crazyflie's ``polyval`` does
        (every product and sum rounded to float32; the local time too)."""
        i, tau = self.locate(t)
        c = derivative_coeffs(np.asarray(self.coeffs, dtype=np.float64), derivative)[i]  # (k, d, m)
        if float32:
            return horner(c.astype(np.float32), tau.astype(np.float32)).astype(np.float64)
        return horner(c, tau)


def derivative_coeffs(coeffs: np.ndarray, r: int) -> np.ndarray:
    """Coefficients (..., m − r) of the r-th derivative of polynomials (..., m) in ascending powers."""
    m = coeffs.shape[-1]
    if r == 0:
        return coeffs
    if r >= m:
        return np.zeros(coeffs.shape[:-1] + (1,))
    j = np.arange(r, m)
    fall = np.array([factorial(k) / factorial(k - r) for k in j])
    return coeffs[..., r:] * fall


def horner(c: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """Σ_j c[..., j]·τ^j by Horner's rule: c (k, d, m) ascending, τ (k,) → (k, d), in c's arithmetic."""
    out = np.zeros(c.shape[:-1], dtype=c.dtype)
    for j in range(c.shape[-1] - 1, -1, -1):
        out = out * tau[:, None] + c[..., j]
    return out


def _design(t: np.ndarray, knots: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The piece (k,), the normalised local time s ∈ [0, 1] (k,) of each sample and the durations (N,)."""
    h = np.diff(knots)
    i = np.minimum(np.searchsorted(knots[1:], t, side="left"), len(h) - 1)
    return i, (t - knots[i]) / h[i], h


def _constraints(h: np.ndarray, ends: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]) -> tuple:
    """The equality constraints C a = e (rows, 8N) of the normalised coefficients a (piece i's
    p(s) = Σ a_ij s^j, s = τ / h_i): C0..C3 at every inner knot (each side scaled by the shorter
    duration, for conditioning), the value and slope at both ends. ``ends``: (y0, v0, y1, v1), each (d,)."""
    n = len(h)
    rows, rhs = [], []
    d = len(ends[0])
    zero = np.zeros(d)
    for i in range(n - 1):
        hm = min(h[i], h[i + 1])
        for r in range(CONTINUITY + 1):
            row = np.zeros(N_COEF * n)
            row[N_COEF * i : N_COEF * (i + 1)] = _FALL[r] * (hm / h[i]) ** r
            row[N_COEF * (i + 1) + r] -= factorial(r) * (hm / h[i + 1]) ** r
            rows.append(row)
            rhs.append(zero)
    y0, v0, y1, v1 = ends
    for row_part, piece, value in (
        (_FALL[0] * (np.arange(N_COEF) == 0), 0, y0),  # p(0) = y0
        (_FALL[1] * (np.arange(N_COEF) == 1), 0, v0 * h[0]),  # p'(0) = v0
        (_FALL[0], n - 1, y1),  # p(end) = y1
        (_FALL[1], n - 1, v1 * h[-1]),  # p'(end) = v1
    ):
        row = np.zeros(N_COEF * n)
        row[N_COEF * piece : N_COEF * (piece + 1)] = row_part
        rows.append(row)
        rhs.append(np.asarray(value, dtype=np.float64))
    return np.array(rows), np.array(rhs)


def fit_pieces(t: np.ndarray, y: np.ndarray, knots: np.ndarray, v0: np.ndarray, v1: np.ndarray) -> Pieces:
    """Least-squares fit of samples y (k, d) at times t (k,) (from knots[0] = 0 to knots[-1]) by pieces of
    degree 7 on ``knots`` (N + 1,), C0..C3 at the inner knots, through the first and last samples with
    slopes v0 and v1 (d,) there: the KKT system of the constrained problem, solved by least squares."""
    t = np.asarray(t, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    i, s, h = _design(t, knots)
    n = len(h)
    V = s[:, None] ** np.arange(N_COEF)  # (k, 8)
    # A^T A is block diagonal (one 8 x 8 block per piece), A^T y one 8-row block per piece; t rises, so
    # each piece's samples are one run of rows
    AtA = np.zeros((N_COEF * n, N_COEF * n))
    Aty = np.zeros((N_COEF * n, y.shape[1]))
    bounds = np.searchsorted(i, np.arange(n + 1), side="left")
    for p in range(n):
        rows = slice(bounds[p], bounds[p + 1])
        blk = slice(N_COEF * p, N_COEF * (p + 1))
        AtA[blk, blk] = V[rows].T @ V[rows]
        Aty[blk] = V[rows].T @ y[rows]
    C, e = _constraints(h, (y[0], np.asarray(v0, float), y[-1], np.asarray(v1, float)))
    nc = len(C)
    K = np.block([[AtA, C.T], [C, np.zeros((nc, nc))]])
    rhs = np.vstack([Aty, e])
    try:
        sol = np.linalg.solve(K, rhs)[: N_COEF * n]  # (8N, d)
    except np.linalg.LinAlgError:  # singular (a piece the constraints leave free): the least-squares solution
        sol = np.linalg.lstsq(K, rhs, rcond=None)[0][: N_COEF * n]
    a = sol.reshape(n, N_COEF, -1).transpose(0, 2, 1)  # (N, d, 8) normalised
    coeffs = a / h[:, None, None] ** np.arange(N_COEF)  # c_j = a_j / h^j
    return Pieces(durations=h, coeffs=coeffs)


def sample_errors(
    pieces: Pieces, t: np.ndarray, y: np.ndarray, tol: np.ndarray, groups: list[slice], float32: bool = False
) -> np.ndarray:
    """Each sample's error as a share of its tolerance (k,): for each group of columns (e.g. x, y, z
    together and yaw alone) the Euclidean norm of its error over its tolerance, the largest of the
    groups, the pieces evaluated as stored (in float32 arithmetic with ``float32``)."""
    e = pieces.evaluate(t, float32=float32) - y
    return np.max([np.linalg.norm(e[:, g], axis=1) / tol[k] for k, g in enumerate(groups)], axis=0)


def fit_adaptive(
    t: np.ndarray,
    y: np.ndarray,
    v0: np.ndarray,
    v1: np.ndarray,
    tol: np.ndarray,
    groups: list[slice],
    max_pieces: int,
    target: float = 0.9,
) -> Pieces | None:
    """Pieces within ``target`` × the tolerance of every sample (:func:`sample_errors`), their float32
    rounding included, in as few pieces as the greedy search finds; None when more than ``max_pieces``
    would be needed. Knots fall on sample times; a piece keeps at least :data:`MIN_SAMPLES` samples.

    Split: the piece with the worst sample is cut at its middle sample, and all are fitted again.
    Then one sweep from first to last removes each inner knot whose removal keeps every sample within
    the target."""
    t = np.asarray(t, dtype=np.float64)
    k = len(t)
    idx = [0, k - 1]  # knots as sample indices

    def fit(ix: list[int]) -> tuple[Pieces, np.ndarray]:
        p = fit_pieces(t - t[0], y, t[ix] - t[0], v0, v1).as_float32()
        return p, sample_errors(p, t - t[0], y, tol, groups, float32=True)

    pieces, err = fit(idx)
    while err.max() > target:
        if len(idx) - 1 >= max_pieces:
            return None
        worst = int(np.argmax(err))
        p = int(np.searchsorted(idx, worst, side="left")) - 1 if worst > 0 else 0
        p = min(max(p, 0), len(idx) - 2)
        if idx[p + 1] - idx[p] < 2 * MIN_SAMPLES:  # too short to split: split the worst of the splittable
            errs = [err[idx[q] : idx[q + 1] + 1].max() if idx[q + 1] - idx[q] >= 2 * MIN_SAMPLES else -1.0
                    for q in range(len(idx) - 1)]  # fmt: skip
            p = int(np.argmax(errs))
            if errs[p] < 0:
                return None
        idx.insert(p + 1, (idx[p] + idx[p + 1]) // 2)
        pieces, err = fit(idx)
    j = 1
    while j < len(idx) - 1:  # one sweep: remove each knot not needed, first to last
        trial, trial_err = fit(idx[:j] + idx[j + 1 :])
        if trial_err.max() <= target:
            idx.pop(j)
            pieces = trial
        else:
            j += 1
    return pieces
