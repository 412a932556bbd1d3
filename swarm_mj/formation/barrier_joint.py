"""The barrier filter's joint fallback (docs/barrier.md, "the joint fallback"): where a drone's share
of its pairs' constraints has no input within its limits (it is *boxed*: a climbing follower between
the leader and a follower closing from the other side), the drones round it solve their constraints
together, so that a neighbour with room takes more than its share.

The decentralised split fixes each pair's shares in advance (the higher index takes a burden); two rows
each within a drone's limits can then be contradictory (normals opposed) where the pair's other drone
could take it all. A *cluster* is a connected set of the graph joining each boxed drone to every
filtering drone within its sensing range; its QP (:func:`joint_command`) is each member's rows at once:
its accelerations as close as possible to their nominals (each drone's metric), each pair inside the
cluster on its full constraint A·(u_k − u_l) ≥ b (on the member's reference state and on its sensed one,
as the split's rows), each pair with a filtering drone outside it on the split's share (which that drone
keeps), each pair with a drone that does not filter on all of it; within the members' limits, else the
reserve's. Where nothing meets the rows the members keep the split's commands (relaxed where they were).

Guarantee and its assumption: the rows are (B) for every pair, so where the cluster's QP has a solution
and every member flies its part of the same solution, (B) holds for every pair of the cluster (and with
the drones outside it, by the split). Every member computes the same solution where it holds the same
data: the rule's every row (each drone's reference, nominal and limits, as the filter of every drone
has them); under a sensing model each drone's copy computes every row on its own view (its prediction
of the others, docs/sensing.md), so the members' solutions differ by their views' differences and (B)
holds to that. The solver is Goldfarb and Idnani's dual active set (Math. Programming 27, 1983) for the
identity Hessian: exact, and it says where the rows have no common point."""

from __future__ import annotations

import numpy as np

from .._jit import jit
from .barrier_qp import limit_rows, solve_small
from .keepout import pair_row, split_rhs

_TOL = 1e-9  # feasibility tolerance of a row, relative to (1 + |b|)


@jit
def _dot(G, k, w, d):
    s = 0.0
    for c in range(d):
        s += G[k, c] * w[c]
    return s


@jit
def gi_project(x0: np.ndarray, G: np.ndarray, h: np.ndarray, m: int, x: np.ndarray) -> bool:
    """argmin ‖x − x0‖² subject to G[:m]·x ≥ h[:m] (G (≥ m, d)), written into x (d,): Goldfarb and
    Idnani's dual method (the unconstrained optimum x0 first, then the most violated row added, a row
    whose multiplier would turn negative dropped), exact to _TOL. Returns False where the rows have no
    common point (then x is not a solution)."""
    d = x0.shape[0]
    for c in range(d):
        x[c] = x0[c]
    act = np.empty(d, dtype=np.int64)
    lam = np.zeros(d + 1)
    NN = np.empty((d, d))
    M = np.empty((d, d + 1))
    rhs = np.empty(d)
    r = np.zeros(d)
    z = np.empty(d)
    q = 0
    for _ in range(4 * (m + d) + 50):
        p, worst = -1, 0.0
        for k in range(m):
            s = h[k] - _dot(G, k, x, d)
            if s > _TOL * (1.0 + abs(h[k])):
                nk = np.sqrt(_dot(G, k, G[k], d))
                if nk <= 0.0:
                    return False  # 0 ≥ h_k > 0: no point
                if s / nk > worst:
                    worst, p = s / nk, k
        if p < 0:
            return True  # every row holds: the optimum (KKT with the multipliers kept ≥ 0)
        lam_p = 0.0
        for _inner in range(d + 2):
            for a in range(q):
                rhs[a] = _dot(G, act[a], G[p], d)
                for b2 in range(q):
                    NN[a, b2] = _dot(G, act[a], G[act[b2]], d)
            if q > 0 and not solve_small(NN, rhs, q, r, M):
                return False
            for c in range(d):
                z[c] = G[p, c]
                for a in range(q):
                    z[c] -= r[a] * G[act[a], c]
            zz = 0.0
            for c in range(d):
                zz += z[c] * z[c]
            t1, drop = np.inf, -1
            for a in range(q):
                if r[a] > 1e-12 and lam[a] / r[a] < t1:
                    t1, drop = lam[a] / r[a], a
            t2 = (h[p] - _dot(G, p, x, d)) / zz if zz > 1e-12 * _dot(G, p, G[p], d) else np.inf
            t = min(t1, t2)
            if t == np.inf:
                return False  # p is a combination of the active rows with no room: the set is empty
            if t2 < np.inf:
                for c in range(d):
                    x[c] += t * z[c]
            for a in range(q):
                lam[a] -= t * r[a]
            lam_p += t
            if t2 <= t1:  # the full step: p joins the active set
                act[q] = p
                lam[q] = lam_p
                q += 1
                break
            for a in range(drop, q - 1):  # the partial step: the blocking row leaves
                act[a] = act[a + 1]
                lam[a] = lam[a + 1]
            q -= 1
    return False  # not converged within the iteration bound: treated as empty (the split's commands kept)


@jit
def _limit_block(G, h, m, col, a_h, up, down, sh, tmp, tb):
    """A drone's limits as 10 rows from row m, on its columns col .. col + 2 (its metric's √c ``sh``)."""
    limit_rows(tmp, tb, a_h, up, down)
    for k in range(10):
        for c in range(G.shape[1]):
            G[m + k, c] = 0.0
        G[m + k, col] = tmp[k, 0] / sh
        G[m + k, col + 1] = tmp[k, 1] / sh
        G[m + k, col + 2] = tmp[k, 2]
        h[m + k] = tb[k]
    return m + 10


@jit
def _pair_rows(rec, pos, vel, sensed_pos, sensed_vel, sensed_acc, filters, member, slot, sh, G, h):
    """The cluster's pair rows (module docstring) as rows 0 .. m − 1 of G·x ≥ h in the members' metric
    (x = (√c·u_x, √c·u_y, u_z) per member, √c = ``sh``): each member's rows on its reference state (pos,
    vel) and, with ``both_states``, on its sensed one, against each drone's sensed state. Returns m."""
    n = pos.shape[0]
    r2 = rec.sensing_range * rec.sensing_range
    p, v, a = np.empty(3), np.empty(3), np.empty(3)
    m = 0
    for k in range(n):
        if not member[k]:
            continue
        for l2 in range(n):
            if l2 == k:
                continue
            for src in range(2 if rec.both_states else 1):
                if src == 1 and member[l2] and l2 < k:
                    continue  # the two sensed states: that pair's row once
                for c in range(3):
                    p[c] = (pos[k, c] if src == 0 else sensed_pos[k, c]) - sensed_pos[l2, c]
                    v[c] = (vel[k, c] if src == 0 else sensed_vel[k, c]) - sensed_vel[l2, c]
                if p[0] ** 2 + p[1] ** 2 + p[2] ** 2 > r2 or (
                    sensed_pos[k, 2] < rec.floor_m and sensed_pos[l2, 2] < rec.floor_m
                ):
                    continue
                bs, _, _ = pair_row(p, v, rec.radii, rec.gain, a)
                for c in range(G.shape[1]):
                    G[m, c] = 0.0
                if filters[l2] and member[l2]:  # inside the cluster: the full constraint on the two commands
                    for c in range(3):
                        G[m, 3 * slot[l2] + c] = -a[c] / (sh[l2] if c < 2 else 1.0)
                else:  # the split's share, which a drone outside keeps (all of it against the leader)
                    bs = split_rhs(bs, k, l2, filters, rec.priority_share, a, sensed_acc)
                for c in range(3):
                    G[m, 3 * slot[k] + c] = a[c] / (sh[k] if c < 2 else 1.0)
                h[m] = bs
                m += 1
    return m


@jit
def joint_command(rec, pos, vel, sensed_pos, sensed_vel, sensed_acc, u_nom, filters, limits, hcost, member):
    """The cluster's QP (module docstring; the cluster ``member`` (n,) bool; the arguments as
    :func:`~.barrier_kernels.filter_accelerations`'): the members' accelerations (n, 3) (their rows) as
    close as possible to their nominals in their metrics, within their limits, else within the reserve's.
    Returns (u, ok, reserve): ok False where no input within them meets every row (the members then keep
    the split's commands, relaxed where it was)."""
    n = pos.shape[0]
    slot = np.full(n, -1, dtype=np.int64)
    sh = np.sqrt(hcost)
    nc = 0
    for k in range(n):
        if member[k]:
            slot[k] = nc
            nc += 1
    nv = 3 * nc
    G = np.zeros((nc * (2 * n + 10), nv))
    h = np.zeros(G.shape[0])
    x0 = np.zeros(nv)
    for k in range(n):
        if member[k]:
            for c in range(3):
                x0[3 * slot[k] + c] = u_nom[k, c] * (sh[k] if c < 2 else 1.0)
    mp = _pair_rows(rec, pos, vel, sensed_pos, sensed_vel, sensed_acc, filters, member, slot, sh, G, h)
    tmp, tb = np.empty((10, 3)), np.empty(10)
    x = np.zeros(nv)
    u = np.zeros((n, 3))
    m = mp
    for attempt in range(2):
        wide = attempt == 1
        if wide and not rec.reserve_a_h > rec.a_h:
            break
        m = mp
        for k in range(n):
            if member[k]:
                a_h = max(limits[k, 0], rec.reserve_a_h) if wide else limits[k, 0]
                m = _limit_block(G, h, m, 3 * slot[k], a_h, limits[k, 1], limits[k, 2], sh[k], tmp, tb)
        if gi_project(x0, G, h, m, x):
            _unpack(x, slot, sh, u)
            return u, True, wide
    return u, False, False


@jit
def _unpack(x, slot, sh, u):
    for k in range(slot.shape[0]):
        if slot[k] >= 0:
            u[k, 0] = x[3 * slot[k]] / sh[k]
            u[k, 1] = x[3 * slot[k] + 1] / sh[k]
            u[k, 2] = x[3 * slot[k] + 2]
