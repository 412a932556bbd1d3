"""The barrier filter's quadratic programme (docs/barrier.md; the mathematics: swarm_mj/formation/barrier.py,
"Filter"): the exact projection onto a polyhedron (:func:`project_polyhedron`, KKT with Carathéodory) and the
input limits as rows of it (an octagon inscribed in the tilt-limit disc, the vertical bounds)."""

from __future__ import annotations

import numpy as np

from .._jit import jit

_TOL = 1e-9  # feasibility tolerance of a constraint, relative to (1 + |b|)
_LAM_TOL = 1e-9  # a multiplier counts as non-negative above −this·(1 + max |λ|)


@jit
def solve_small(G: np.ndarray, r: np.ndarray, s: int, x: np.ndarray, M: np.ndarray) -> bool:
    """Solve G[:s, :s]·x = r[:s] by Gaussian elimination with partial pivoting (M (≥ s, ≥ s + 1) the
    caller's work buffer); False if singular."""
    scale = 0.0
    for i in range(s):
        for j in range(s):
            M[i, j] = G[i, j]
            scale = max(scale, abs(G[i, j]))
        M[i, s] = r[i]
    if scale == 0.0:
        return False
    for c in range(s):
        p = c
        for i in range(c + 1, s):
            if abs(M[i, c]) > abs(M[p, c]):
                p = i
        if abs(M[p, c]) <= 1e-10 * scale:
            return False
        if p != c:
            for j in range(s + 1):
                tmp = M[c, j]
                M[c, j] = M[p, j]
                M[p, j] = tmp
        for i in range(c + 1, s):
            f = M[i, c] / M[c, c]
            for j in range(c, s + 1):
                M[i, j] -= f * M[c, j]
    for i in range(s - 1, -1, -1):
        acc = M[i, s]
        for j in range(i + 1, s):
            acc -= M[i, j] * x[j]
        x[i] = acc / M[i, i]
    return True


@jit
def _kkt_point(w0, A, b, m, idx, s, w, lam, G, r, M) -> bool:
    """Whether the projection w of w0 onto {w: A[idx[k]]·w = b[idx[k]], k < s} is the optimum of
    argmin ‖w − w0‖² s.t. A[:m]·w ≥ b[:m]: w − w0 = A_Sᵀλ with every λ ≥ 0 (within _LAM_TOL) and
    every constraint satisfied (within _TOL): the KKT conditions, sufficient for this convex QP.
    G (4, 4), r (4,), M (4, 5): work buffers."""
    d = w0.shape[0]
    for k in range(s):
        rk = b[idx[k]]
        for c in range(d):
            rk -= A[idx[k], c] * w0[c]
        r[k] = rk
        for l2 in range(s):
            g = 0.0
            for c in range(d):
                g += A[idx[k], c] * A[idx[l2], c]
            G[k, l2] = g
    if s > 0 and not solve_small(G, r, s, lam, M):
        return False
    big = 0.0
    for k in range(s):
        big = max(big, abs(lam[k]))
    for k in range(s):
        if lam[k] < -_LAM_TOL * (1.0 + big):
            return False  # a constraint pulls the wrong way: not the optimum's active set
    for c in range(d):
        v = w0[c]
        for k in range(s):
            v += A[idx[k], c] * lam[k]
        w[c] = v
    for k in range(m):
        v = 0.0
        for c in range(d):
            v += A[k, c] * w[c]
        if v < b[k] - _TOL * (1.0 + abs(b[k])):
            return False
    return True


@jit(on_demand=True, samples=lambda: [(np.zeros(3), np.array([[1.0, 0.0, 0.0]]), np.array([1.0]))])
def project_polyhedron(w0: np.ndarray, A: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, bool]:
    """argmin ‖w − w0‖² subject to A·w ≥ b (A (m, d), d ≤ 4), exactly, and whether it is feasible.

    The optimum w* satisfies w* − w0 = A_Sᵀλ, λ ≥ 0, over its active set S; by Carathéodory a
    linearly independent subset S' ⊆ S (|S'| ≤ d) with λ ≥ 0 carries the same combination, so w*
    is the projection of w0 onto the affine set A_S'·w = b_S'. Conversely, a projection onto such
    an affine set whose multipliers are all ≥ 0 and which satisfies every constraint satisfies the
    KKT conditions, sufficient for this strictly convex QP: it is w* (unique). The subsets are
    tried by size (w0 itself first, then single rows, pairs, …), and the first that passes is
    returned. Returns (w0, False) when none passes (then the set is empty)."""
    m, d = A.shape
    w0c = w0.copy()
    cand = np.empty(d)
    lam = np.empty(4)
    idx = np.empty(4, dtype=np.int64)
    G = np.empty((4, 4))
    r = np.empty(4)
    M = np.empty((4, 5))
    if _kkt_point(w0c, A, b, m, idx, 0, cand, lam, G, r, M):
        return w0c, True
    for s in range(1, min(d, m) + 1):
        for k in range(s):  # the first subset of s rows, then the next in lexicographic order
            idx[k] = k
        while True:
            if _kkt_point(w0c, A, b, m, idx, s, cand, lam, G, r, M):
                return cand.copy(), True
            k = s - 1
            while k >= 0 and idx[k] == m - s + k:
                k -= 1
            if k < 0:
                break
            idx[k] += 1
            for j in range(k + 1, s):
                idx[j] = idx[j - 1] + 1
    return w0c, False


@jit
def limit_rows(A: np.ndarray, b: np.ndarray, a_h: float, a_up: float, a_down: float) -> int:
    """Write the input limits as 10 rows of A·u ≥ b (A (m, d), columns ≥ 3 zero): an octagon inscribed
    in the disc ‖u_xy‖ ≤ a_h, and −a_down ≤ u_z ≤ a_up. Returns the number of rows (10)."""
    face = a_h * np.cos(np.pi / 8.0)
    for k in range(8):
        ang = k * np.pi / 4.0
        for c in range(A.shape[1]):
            A[k, c] = 0.0
        A[k, 0] = -np.cos(ang)
        A[k, 1] = -np.sin(ang)
        b[k] = -face
    for k in range(8, 10):
        for c in range(A.shape[1]):
            A[k, c] = 0.0
    A[8, 2] = -1.0
    b[8] = -a_up
    A[9, 2] = 1.0
    b[9] = -a_down
    return 10


#: cos, sin of the octagon's vertex angles (k + ½)·π/4 (constants of the compiled code)
_VERTEX_COS = np.cos((np.arange(8) + 0.5) * np.pi / 4.0)
_VERTEX_SIN = np.sin((np.arange(8) + 0.5) * np.pi / 4.0)


@jit
def min_over_limits(a: np.ndarray, a_h: float, a_up: float, a_down: float) -> float:
    """min of a·u (a (3,)) over the limit polytope of :func:`limit_rows` (its 16 vertices)."""
    best = np.inf
    for k in range(8):
        v = a_h * (a[0] * _VERTEX_COS[k] + a[1] * _VERTEX_SIN[k])
        best = min(best, v)
    return best + min(a[2] * a_up, -a[2] * a_down)
