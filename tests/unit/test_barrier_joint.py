"""The barrier's joint fallback (swarm_mj/formation/barrier_joint.py, docs/barrier.md "the joint fallback"):
the dual active-set solver against SciPy, and the fallback's contract over random crowded swarms: a cluster
only round a drone whose split has no input within its limits, every pair's constraint on the two commands
it solved for, the limits, the least change in the members' metrics, the split's commands kept only where
nothing meets the cluster's rows, and every other drone's command the split's, bit for bit."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import optimize as scipy_optimize
from test_barrier import _constraint, _reference_projection, _share

from swarm_mj.formation.barrier import apply_filter
from swarm_mj.formation.barrier_joint import gi_project
from swarm_mj.formation.barrier_params import BarrierParams


def _margin(A: np.ndarray, b: np.ndarray) -> float:
    """The largest t with A·x ≥ b + t·‖A_k‖ on every row k (HiGHS; t ≤ 100): ≥ 0 where the rows meet."""
    norms = np.linalg.norm(A, axis=1)
    pair = norms > 0
    res = scipy_optimize.linprog(
        np.r_[np.zeros(A.shape[1]), -1.0],
        A_ub=np.c_[-A, np.where(pair, norms, 0.0)],
        b_ub=-b,
        bounds=[(None, None)] * A.shape[1] + [(None, 100.0)],
    )
    assert res.success
    return float(-res.fun)


@settings(max_examples=200, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), d=st.integers(1, 12), m=st.integers(1, 30))
def test_the_solver_is_the_projection_or_says_the_rows_do_not_meet(seed, d, m):
    rng = np.random.default_rng(seed)
    G = rng.normal(size=(m, d))
    if m > 2:
        G[-1] = G[0] * rng.uniform(0.5, 2.0)  # a parallel row, and a repeated one: degenerate active sets
        G[-2] = G[1]
    h = rng.normal(scale=2.0, size=m)
    x0 = rng.normal(scale=2.0, size=d)
    x = np.empty(d)
    ok = gi_project(x0, G, h, m, x)
    margin = _margin(G, h)
    if not ok:
        assert margin < 1e-7
        return
    assert np.all(G @ x >= h - 1e-8 * (1 + np.abs(h)))
    if margin > 1e-6:  # SLSQP wants an interior; the KKT point is checked below in every case
        ref = _reference_projection(x0, G, h)
        assert np.sum((x - x0) ** 2) <= np.sum((ref - x0) ** 2) * (1 + 1e-7) + 1e-6
    # KKT: x − x0 a non-negative combination of the rows active at x
    act = np.abs(G @ x - h) <= 1e-7 * (1 + np.abs(h))
    if act.any():
        lam, *_ = np.linalg.lstsq(G[act].T, x - x0, rcond=None)
        nnls, res = scipy_optimize.nnls(G[act].T, x - x0)
        assert res <= 1e-6 * (1 + np.linalg.norm(x - x0))
    else:
        np.testing.assert_allclose(x, x0, atol=1e-9)


def _clusters(boxed: np.ndarray, filters: np.ndarray) -> list[np.ndarray]:
    """The connected sets of the graph joining each boxed drone to every filtering drone (range unbounded)."""
    n = len(boxed)
    label = -np.ones(n, dtype=int)
    for k in np.flatnonzero(boxed):
        if label[k] >= 0:
            continue
        label[k], todo = k, [k]
        while todo:
            x = todo.pop()
            for j in range(n):
                if filters[j] and label[j] < 0 and (boxed[x] or boxed[j]):
                    label[j] = k
                    todo.append(j)
    return [label == c for c in np.unique(label[label >= 0])]


def _limit_rows(a_h: float, up: float, down: float) -> tuple[np.ndarray, np.ndarray]:
    ang = np.arange(8) * np.pi / 4
    A = np.vstack([np.stack([-np.cos(ang), -np.sin(ang), 0 * ang], 1), [[0, 0, -1.0], [0, 0, 1.0]]])
    return A, np.concatenate([np.full(8, -a_h * np.cos(np.pi / 8)), [-up, -down]])


def _cluster_rows(member, n, pos, vel, sp, sv, sa, filters, radii, gain, prio):
    """The cluster's rows over the stacked members' accelerations, written again from the module docstring."""
    idx = np.flatnonzero(member)
    col = {k: 3 * c for c, k in enumerate(idx)}
    rows, rhs = [], []
    for k in idx:
        for j in range(n):
            if j == k:
                continue
            for own_p, own_v in ((pos[k], vel[k]), (sp[k], sv[k])):
                share = _share(k, j, filters, prio) if not member[j] else (lambda b: 1.0)
                A, b = _constraint(own_p, own_v, sp[j], sv[j], radii, gain, share)
                row = np.zeros(3 * len(idx))
                row[col[k] : col[k] + 3] = A
                if not filters[j]:
                    b += A @ sa[j]
                elif member[j]:
                    row[col[j] : col[j] + 3] = -A
                rows.append(row)
                rhs.append(b)
    return np.array(rows), np.array(rhs), idx


@settings(max_examples=150, deadline=None)
@given(
    n=st.integers(3, 6),
    seed=st.integers(0, 2**31 - 1),
    tilt=st.floats(8.0, 30.0),
    spread=st.floats(0.4, 1.2),
    prio=st.sampled_from([0.0, 0.5]),
    cost=st.sampled_from([1.0, 16.0]),
)
def test_the_joint_fallback_keeps_its_contract(n, seed, tilt, spread, prio, cost):
    rng = np.random.default_rng(seed)
    pos = rng.normal(scale=spread, size=(n, 3)) + np.array([0, 0, 3.0])
    vel = rng.normal(scale=1.0, size=(n, 3))
    u_nom = rng.normal(scale=2.0, size=(n, 3))
    filters = np.ones(n, dtype=bool)
    filters[0] = rng.random() < 0.5  # the leader: filtering or not
    sp, sv = pos + rng.normal(scale=0.05, size=(n, 3)), vel + rng.normal(scale=0.05, size=(n, 3))
    sa = rng.normal(scale=1.0, size=(n, 3))
    hcost = np.where(rng.random(n) < 0.5, cost, 1.0)
    kw = dict(max_tilt_deg=tilt, tiebreak=0.0, sensing_range=1e9, floor_m=-1e6, priority_share=prio)
    split = apply_filter(BarrierParams(joint_fallback=False, **kw), pos, vel, u_nom, filters, (sp, sv, sa), hcost=hcost)
    bp = BarrierParams(**kw)
    u, active, relaxed, _, reserve, _, joint = apply_filter(bp, pos, vel, u_nom, filters, (sp, sv, sa), hcost=hcost)
    boxed = split[2] | split[4]  # the split's: relaxed or on the reserve (none here): no input within the limits
    clusters = _clusters(boxed & filters, filters)
    in_any = np.zeros(n, dtype=bool)
    for member in clusters:
        in_any |= member
    assert not (joint & ~in_any).any()  # a joint QP only round a boxed drone
    np.testing.assert_array_equal(u[~joint], split[0][~joint])  # every other command the split's
    radii, a_h, up, down = bp.radii(), bp.horizontal_limit(), bp.accel_up, bp.accel_down
    for member in clusters:
        G, h, idx = _cluster_rows(member, n, pos, vel, sp, sv, sa, filters, radii, bp.gain, prio)
        L, lb = _limit_rows(a_h, up, down)
        G_all = np.vstack([G, *[np.c_[np.zeros((10, 3 * c)), L, np.zeros((10, 3 * (len(idx) - c - 1)))]
                                for c in range(len(idx))]])  # fmt: skip
        h_all = np.concatenate([h, np.tile(lb, len(idx))])
        if not joint[member].any():  # the split's commands kept (above) only where nothing meets the rows
            assert _margin(G_all, h_all) < 1e-7
            continue
        assert joint[member].all() and not relaxed[member].any()
        x = u[idx].ravel()
        assert np.all(G_all @ x >= h_all - 1e-7 * (1 + np.abs(h_all)))  # every pair's rows, every limit
        W = np.repeat(np.sqrt(hcost[idx]), 3)
        W[2::3] = 1.0
        ref = _reference_projection(W * u_nom[idx].ravel(), G_all / W, h_all) / W
        assert np.sum((W * (x - u_nom[idx].ravel())) ** 2) <= np.sum((W * (ref - u_nom[idx].ravel())) ** 2) + 1e-6


def test_a_follower_between_the_leader_and_a_follower_is_no_longer_relaxed():
    """The sandwich of docs/barrier.md: the leader (it does not give way) closes on follower 1 from −x at
    0.5 m/s, follower 2 from +x; the split gives follower 2 the burden of its pair, so follower 1 must flee
    the leader (u_x ≥ 0.34 m/s²) and not close on follower 2 (u_x ≤ 0): no input. Jointly, follower 2
    takes more than its pair's burden and both rows hold."""
    pos = np.array([[-1.0, 0.0, 3.0], [0.0, 0.0, 3.0], [1.0, 0.0, 3.0]])
    vel = np.array([[0.5, 0.0, 0.0], [0.0, 0.0, 0.0], [-0.5, 0.0, 0.0]])
    filters = np.array([False, True, True])
    kw = dict(tiebreak=0.0, floor_m=-1e6)
    zero = np.zeros((3, 3))
    split = apply_filter(BarrierParams(joint_fallback=False, **kw), pos, vel, zero, filters, (pos, vel, zero))
    assert split[2][1]  # the split relaxed follower 1
    bp = BarrierParams(**kw)
    u, _, relaxed, _, _, _, joint = apply_filter(bp, pos, vel, zero, filters, (pos, vel, zero))
    assert not relaxed.any() and joint[1:].all() and not joint[0]
    radii = bp.radii()
    A, b = _constraint(pos[1], vel[1], pos[0], vel[0], radii, bp.gain, lambda b: 1.0)
    assert A @ u[1] >= b - 1e-9  # against the leader, all of it
    A, b = _constraint(pos[2], vel[2], pos[1], vel[1], radii, bp.gain, lambda b: 1.0)
    assert A @ (u[2] - u[1]) >= b - 1e-9  # the followers' pair, on the two commands
    assert u[2, 0] > u[1, 0] > 0.0


def test_the_contract_above_meets_both_outcomes():
    """Over such swarms the fallback solves some clusters and finds nothing for others: the property test
    compares joint solutions, not only untouched splits."""
    solved = failed = 0
    for seed in range(100):
        rng = np.random.default_rng(seed)
        n = int(rng.integers(3, 7))
        pos = rng.normal(scale=0.6, size=(n, 3)) + np.array([0, 0, 3.0])
        vel, u_nom = rng.normal(size=(n, 3)), rng.normal(scale=2.0, size=(n, 3))
        filters = np.arange(n) > 0
        kw = dict(max_tilt_deg=15.0, tiebreak=0.0, sensing_range=1e9, floor_m=-1e6)
        split = apply_filter(BarrierParams(joint_fallback=False, **kw), pos, vel, u_nom, filters)
        joint = apply_filter(BarrierParams(**kw), pos, vel, u_nom, filters)[6]
        solved += joint.any()
        failed += (split[2] | split[4]).any() and not joint.any()
    assert solved >= 10 and failed >= 10
