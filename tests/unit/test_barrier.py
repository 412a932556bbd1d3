"""The barrier filter's core (docs/barrier.md): the exact QP against a reference solver, the barrier
constraint against finite differences, the filter's properties (hypothesis), the keep-out geometry
and metrics against independent calculations, and closed-loop checks on a double integrator written
here (a model of the filter's assumptions, not of the product's physics)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.optimize as scipy_optimize  # the reference QP solver (the test extra)
from hypothesis import given, settings
from hypothesis import strategies as st

from swarm_mj.formation.barrier import (
    BarrierFilter,
    BarrierParams,
    apply_filter,
    keepout_radii,
    pair_constraint,
    project_polyhedron,
)
from swarm_mj.formation.separation import Sensed
from swarm_mj.metrics import keepout_distance, keepout_min_distance, keepout_time_s
from swarm_mj.physics.params import QuadParams


def _reference_projection(w0: np.ndarray, A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """argmin ‖w − w0‖² s.t. A·w ≥ b with SciPy's SLSQP (the reference solver)."""
    res = scipy_optimize.minimize(
        lambda w: float(np.sum((w - w0) ** 2)),
        w0,
        jac=lambda w: 2.0 * (w - w0),
        constraints=[{"type": "ineq", "fun": lambda w: A @ w - b, "jac": lambda w: A}],
        method="SLSQP",
        options={"ftol": 1e-12, "maxiter": 500},
    )
    # SLSQP may stop on its line search at this tolerance after converging (status 8): its point is
    # the reference whenever it is feasible; else SciPy's interior-point trust-constr is asked
    if res.success or np.all(A @ res.x >= b - 1e-9):
        return res.x
    res = scipy_optimize.minimize(
        lambda w: float(np.sum((w - w0) ** 2)),
        w0,
        jac=lambda w: 2.0 * (w - w0),
        hess=lambda w: 2.0 * np.eye(len(w0)),
        constraints=[scipy_optimize.LinearConstraint(A, b, np.inf)],
        method="trust-constr",
        options={"gtol": 1e-12, "xtol": 1e-14, "maxiter": 5000},
    )
    assert np.all(A @ res.x >= b - 1e-8), res.message
    return res.x


def _random_feasible(rng: np.random.Generator, d: int, m: int):
    """m random half-spaces A·w ≥ b in R^d that contain a random point, and a random w0."""
    A = rng.normal(size=(m, d))
    x = rng.normal(size=d)
    b = A @ x - rng.exponential(0.5, size=m) * (rng.random(m) < 0.7)
    return rng.normal(scale=2.0, size=d), A, b


@pytest.mark.parametrize("d", [2, 3, 4])
def test_projection_matches_reference_qp(d):
    rng = np.random.default_rng(1234 + d)
    worst = 0.0
    for _ in range(150):
        w0, A, b = _random_feasible(rng, d, int(rng.integers(1, 9)))
        w, ok = project_polyhedron(w0, A, b)
        assert ok
        ref = _reference_projection(w0, A, b)
        assert np.all(A @ w >= b - 1e-8 * (1 + np.abs(b)))
        # the reference is feasible too, so our cost may not exceed it (ours is the exact optimum)
        assert np.sum((w - w0) ** 2) <= np.sum((ref - w0) ** 2) + 1e-7
        worst = max(worst, float(np.abs(w - ref).max()))
    assert worst < 1e-5


def test_projection_kkt_certificate():
    """Independent of any solver: w − w0 = Aₐᵀλ with λ ≥ 0 over the active rows (NNLS)."""
    rng = np.random.default_rng(7)
    for _ in range(200):
        w0, A, b = _random_feasible(rng, 3, int(rng.integers(1, 12)))
        w, ok = project_polyhedron(w0, A, b)
        assert ok
        act = np.abs(A @ w - b) <= 1e-7 * (1 + np.abs(b))
        if not act.any():
            np.testing.assert_allclose(w, w0, atol=1e-12)
            continue
        lam, resid = scipy_optimize.nnls(A[act].T, w - w0)
        assert resid < 1e-7 * (1 + np.linalg.norm(w - w0))


def test_projection_reports_infeasible():
    A = np.array([[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]])
    b = np.array([1.0, 0.0])  # x ≥ 1 and x ≤ 0
    _, ok = project_polyhedron(np.zeros(3), A, b)
    assert not ok


def test_pair_constraint_finite_differences():
    """h, ḣ and ḧ = 2‖q̇‖² + A·Δu of the module docstring against finite differences of h(p(t))."""
    rng = np.random.default_rng(3)
    radii = np.array([0.7, 0.7, 2.0])
    for _ in range(20):
        p, v, du = rng.normal(size=3), rng.normal(size=3), rng.normal(size=3)
        k = 2.5
        A, b_full, h, hd = pair_constraint(p, v, radii, k, 1.0)
        hf = lambda s, p=p, v=v, du=du: float(np.sum(((p + v * s + 0.5 * du * s * s) / radii) ** 2) - 1.0)  # noqa: E731
        e = 1e-4
        assert h == pytest.approx(hf(0.0), abs=1e-12)
        assert hd == pytest.approx((hf(1e-6) - hf(-1e-6)) / 2e-6, rel=1e-6, abs=1e-8)
        hdd = (hf(e) - 2 * hf(0.0) + hf(-e)) / (e * e)
        qd = v / radii
        assert hdd == pytest.approx(2 * qd @ qd + A @ du, rel=1e-4, abs=1e-5)
        # (B) as printed: b = −2‖q̇‖² − 2k·ḣ − k²·h
        assert b_full == pytest.approx(-2 * qd @ qd - 2 * k * hd - k * k * h, rel=1e-12, abs=1e-12)
        _, b_half, _, _ = pair_constraint(p, v, radii, k, 0.5)
        assert b_half == pytest.approx(0.5 * b_full, rel=1e-12, abs=1e-15)


def test_keepout_radii_from_the_vehicle():
    veh = QuadParams(L=0.3)
    r = keepout_radii(veh, rotor_radius=0.1, downwash_multiple=2.0, margin=0.05)
    np.testing.assert_allclose(r, [2 * 0.4 + 0.1, 2 * 0.4 + 0.1, 2.0 * 0.8 + 0.1])


def test_keepout_distance_on_the_ellipsoid():
    rng = np.random.default_rng(5)
    radii = np.array([0.68, 0.68, 2.04])
    th, ph = rng.uniform(0, np.pi, 50), rng.uniform(0, 2 * np.pi, 50)
    pts = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], -1) * radii
    np.testing.assert_allclose(keepout_distance(pts, radii), 1.0, rtol=1e-12)
    np.testing.assert_allclose(keepout_distance(0.5 * pts, radii), 0.5, rtol=1e-12)


def test_keepout_metrics_against_a_loop():
    rng = np.random.default_rng(11)
    radii = np.array([0.68, 0.68, 2.04])
    k, n = 60, 4
    pos = rng.uniform(-1.0, 1.0, size=(k, n, 3)) + np.array([0, 0, 1.0])
    pos[:10, 2, 2] = 0.05  # drone 2 on the ground for the first samples: its pairs do not count
    t = np.arange(k) * 0.01
    best, inside = np.inf, 0
    for s in range(k):
        any_in = False
        for i in range(n):
            for j in range(i + 1, n):
                if pos[s, i, 2] <= 0.1 or pos[s, j, 2] <= 0.1:
                    continue
                d = np.sqrt(sum(((pos[s, i, c] - pos[s, j, c]) / radii[c]) ** 2 for c in range(3)))
                best = min(best, d)
                any_in |= d < 1.0
        inside += any_in
    assert keepout_min_distance(pos, radii) == pytest.approx(best, rel=1e-12)
    assert keepout_time_s(t, pos, radii) == pytest.approx(inside * 0.01, rel=1e-9)


def test_keepout_time_of_a_pass():
    """Drone 1 passes drone 0 horizontally at 1 m/s, 0.2 m to the side: inside |x| < √(a² − 0.04)."""
    a = 0.68
    radii = np.array([a, a, 3 * a])
    t = np.arange(0.0, 4.0, 0.001)
    pos = np.zeros((len(t), 2, 3))
    pos[:, :, 2] = 1.0
    pos[:, 1, 0] = t - 2.0
    pos[:, 1, 1] = 0.2
    expect = 2 * np.sqrt(a * a - 0.04)  # s inside
    assert keepout_time_s(t, pos, radii) == pytest.approx(expect, abs=2e-3)
    assert keepout_min_distance(pos, radii) == pytest.approx(0.2 / a, rel=1e-9)


# ----------------------------------------------------------------------- the filter's properties
P = BarrierParams()


def _limits_ok(u: np.ndarray, a_h: float, a_up: float, a_down: float) -> bool:
    """u within the octagon inscribed in ‖u_xy‖ ≤ a_h and −a_down ≤ u_z ≤ a_up (independently)."""
    ang = np.arange(8) * np.pi / 4
    face = a_h * np.cos(np.pi / 8)
    tol = 1e-9 * (1 + a_h)
    return bool(np.all(np.cos(ang) * u[0] + np.sin(ang) * u[1] <= face + tol) and -a_down - tol <= u[2] <= a_up + tol)


def _feasibility_margin(rows, a_h, a_up, a_down) -> float:
    """The largest t with A·u ≥ b + t for every row (A, b) and u within the limits of :func:`_limits_ok` (a
    linear programme, SciPy's HiGHS): ≥ 0 where some input meets every row."""
    ang = np.arange(8) * np.pi / 4
    lim_A = np.vstack([np.stack([np.cos(ang), np.sin(ang), 0 * ang], 1), [[0, 0, 1.0], [0, 0, -1.0]]])
    lim_b = np.concatenate([np.full(8, a_h * np.cos(np.pi / 8)), [a_up, a_down]])
    A = np.array([r[0] for r in rows])
    b = np.array([r[1] for r in rows])
    # variables (u, t): −A·u + t ≤ −b; the limits lim_A·u ≤ lim_b; maximise t (t ≤ 100 keeps it bounded)
    A_ub = np.vstack([np.c_[-A, np.ones(len(rows))], np.c_[lim_A, np.zeros(10)]])
    b_ub = np.concatenate([-b, lim_b])
    res = scipy_optimize.linprog([0, 0, 0, -1.0], A_ub=A_ub, b_ub=b_ub, bounds=[(None, None)] * 3 + [(None, 100.0)])
    assert res.success
    return float(-res.fun)


def _constraint(pi, vi, pj, vj, radii, k, share):
    """(B) for drone i, written here again from docs/barrier.md: A·u_i ≥ share(b)·b."""
    S = 1.0 / radii
    q, qd = S * (pi - pj), S * (vi - vj)
    h, hd = q @ q - 1.0, 2 * q @ qd
    b = -2 * qd @ qd - 2 * k * hd - k * k * h
    return 2 * S * q, share(b) * b


def _share(i, j, filters, prio):
    """docs/barrier.md's split: all of it against a drone that does not filter; a burden (b > 0) by
    priority (the lower index takes prio); room (b ≤ 0) in halves."""
    if not filters[j]:
        return lambda b: 1.0
    return lambda b: (prio if i < j else 1 - prio) if b > 0 else 0.5


vec = st.tuples(*[st.floats(-2.0, 2.0)] * 3).map(np.array)


@settings(max_examples=300, deadline=None)
@given(
    n=st.integers(2, 5),
    seed=st.integers(0, 2**31 - 1),
    gain=st.floats(0.5, 6.0),
    tilt=st.floats(10.0, 45.0),
    up=st.floats(1.0, 8.0),
    down=st.floats(1.0, 6.0),
    spread=st.floats(0.3, 3.0),
    prio=st.floats(0.0, 1.0),
    track=st.sampled_from([0.0, 0.05, 0.2]),
    cost=st.sampled_from([1.0, 4.0, 16.0, 100.0]),
    reserve=st.sampled_from([0.0, 45.0, 70.0]),
)
def test_filter_properties(n, seed, gain, tilt, up, down, spread, prio, track, cost, reserve):
    """docs/barrier.md, "Tests": every constraint reported feasible holds, the limits hold (the reserve's
    where it was used, and it was used only where no input within the limits meets the constraints, by a
    linear programme), the nominal exactly when no constraint is active, and nothing within the
    constraints is closer to the nominal in the drone's metric (diag(√c, √c, 1) for the drones given a
    horizontal cost c, else I) than the filter's answer, by a reference QP solver."""
    rng = np.random.default_rng(seed)
    pos = rng.normal(scale=spread, size=(n, 3)) + np.array([0, 0, 3.0])
    vel = rng.normal(scale=1.5, size=(n, 3))
    u_nom = rng.normal(scale=2.0, size=(n, 3))
    filters = rng.random(n) < 0.8
    bp = BarrierParams(
        gain=gain,
        max_tilt_deg=tilt,
        accel_up=up,
        accel_down=down,
        tiebreak=0.0,
        sensing_range=1e9,
        floor_m=-1e6,  # below every sampled altitude: no pair is "both on the ground" (the filter skips those)
        priority_share=prio,
        reserve_tilt_deg=reserve,
        joint_fallback=False,  # the split alone (the joint fallback: tests/unit/test_barrier_joint.py)
    )
    radii, a_nominal = bp.radii(), bp.horizontal_limit()
    a_reserve = bp.reserve_horizontal_limit() or a_nominal
    # what the others sense: each drone off its own (reference) state by a tracking error
    sp, sv = pos + rng.normal(scale=track, size=(n, 3)), vel + rng.normal(scale=track, size=(n, 3))
    hcost = np.where(rng.random(n) < 0.5, cost, 1.0)  # the descent's metric on some of the drones
    sensed = (sp, sv, np.zeros((n, 3)))
    u, active, relaxed, _, used, _, _ = apply_filter(bp, pos, vel, u_nom, filters, sensed, hcost=hcost)
    for i in range(n):
        rows = [
            _constraint(own_p, own_v, sp[j], sv[j], radii, gain, _share(i, j, filters, prio))
            for j in range(n)
            if j != i
            for own_p, own_v in ((pos[i], vel[i]), (sp[i], sv[i]))  # reference and sensed state
        ]
        nominal_ok = all(A @ u_nom[i] >= b for A, b in rows)
        if not filters[i] or nominal_ok:
            # the nominal, exactly, when no constraint is active
            assert not active[i]
            np.testing.assert_array_equal(u[i], u_nom[i])
            continue
        assert active[i]
        assert not used[i] or a_reserve > a_nominal
        a_h = a_reserve if used[i] else a_nominal
        assert _limits_ok(u[i], a_h, up, down)
        if used[i]:  # the reserve only where the limits leave nothing
            assert _feasibility_margin(rows, a_nominal, up, down) < 1e-7
        if relaxed[i]:  # the relaxation only where the widest limits leave nothing
            assert _feasibility_margin(rows, a_h, up, down) < 1e-7
        if not relaxed[i]:
            for A, b in rows:
                assert A @ u[i] >= b - 1e-8 * (1 + abs(b))
            # and minimal: the reference QP finds nothing closer to the nominal
            ang = np.arange(8) * np.pi / 4
            lim_A = np.vstack([np.stack([-np.cos(ang), -np.sin(ang), 0 * ang], 1), [[0, 0, -1.0], [0, 0, 1.0]]])
            lim_b = np.concatenate([np.full(8, -a_h * np.cos(np.pi / 8)), [-up, -down]])
            A_all = np.vstack([np.array([r[0] for r in rows]), lim_A])
            b_all = np.concatenate([[r[1] for r in rows], lim_b])
            # in w = W·u the weighted QP is a projection: A·u ≥ b is (A·W⁻¹)·w ≥ b
            W = np.array([np.sqrt(hcost[i]), np.sqrt(hcost[i]), 1.0])
            ref = _reference_projection(W * u_nom[i], A_all / W, b_all) / W
            assert np.sum((W * (u[i] - u_nom[i])) ** 2) <= np.sum((W * (ref - u_nom[i])) ** 2) + 1e-6


def test_relaxation_is_used_and_flagged():
    """Two drones closing at 4 m/s, 0.9 m apart (ρ = 1.2), the tilt limited to 5°: braking within the
    limits cannot satisfy (B) (it asks for 2.5 m/s² each, the limits give 0.6). The burden split in
    halves (``priority_share`` 0.5), so that both drones have a share to relax."""
    pos = np.array([[0.0, 0.0, 2.0], [0.9, 0.0, 2.0]])
    vel = np.array([[2.0, 0.0, 0.0], [-2.0, 0.0, 0.0]])
    bp = BarrierParams(max_tilt_deg=5.0, priority_share=0.5, reserve_tilt_deg=0.0)
    u, active, relaxed, _, _, _, _ = apply_filter(bp, pos, vel, np.zeros((2, 3)), np.ones(2, dtype=np.bool_))
    assert active.all() and relaxed.all()
    for i in range(2):
        assert _limits_ok(u[i], bp.horizontal_limit(), bp.accel_up, bp.accel_down)
    # it still brakes as hard as it may along the line joining them
    assert u[0, 0] < -0.9 * bp.horizontal_limit() * np.cos(np.pi / 8) and u[1, 0] > -u[0, 0] * 0.99


# ---------------------------------------------------------- closed loop on a double integrator (test model)
def _fly(pos0, goal, bp, T=12.0, dt=0.01, kp=2.0, kd=2.5, leader=None):
    """p̈ = u, u = filter(kp·(goal − p) − kd·ṗ clipped to the limits), explicit Euler at dt; returns
    the positions (k, n, 3), the count of relaxed drone-periods."""
    pos, vel = pos0.astype(float).copy(), np.zeros_like(pos0, dtype=float)
    n = len(pos)
    filters = np.ones(n, dtype=np.bool_)
    if leader is not None:
        filters[leader] = False
    a_h = bp.horizontal_limit()
    out, n_relaxed = [pos.copy()], 0
    for _ in range(int(T / dt)):
        u_nom = kp * (goal - pos) - kd * vel
        nh = np.linalg.norm(u_nom[:, :2], axis=1, keepdims=True)
        u_nom[:, :2] *= np.minimum(1.0, 0.9 * a_h / np.maximum(nh, 1e-12))
        u_nom[:, 2] = np.clip(u_nom[:, 2], -bp.accel_down, bp.accel_up)
        u, _, relaxed, _, _, _, _ = apply_filter(bp, pos, vel, u_nom, filters)
        n_relaxed += int(relaxed.sum())
        vel += u * dt
        pos += vel * dt
        out.append(pos.copy())
    return np.array(out), n_relaxed


def test_head_on_swap_tiebreak():
    """Two drones swap places head-on, exactly symmetric: with the tie-break they pass each other
    and never enter the keep-out; without it they stop face to face (the deadlock)."""
    pos0 = np.array([[-2.0, 0.0, 2.0], [2.0, 0.0, 2.0]])
    goal = pos0[::-1].copy()
    bp = BarrierParams(priority_share=0.5)  # Wang et al.'s equal split: the symmetric case
    traj, relaxed = _fly(pos0, goal, bp)
    radii = bp.radii()
    rho = keepout_distance(traj[:, 0] - traj[:, 1], radii)
    assert rho.min() > 0.99, rho.min()  # the discrete-time filter at 10 ms: within 1 % of the ellipsoid
    np.testing.assert_allclose(traj[-1], goal, atol=0.05)
    assert relaxed == 0
    stuck, _ = _fly(pos0, goal, BarrierParams(priority_share=0.5, tiebreak=0.0))
    assert np.linalg.norm(stuck[-1] - goal, axis=1).min() > 1.0  # deadlock without the tie-break
    assert keepout_distance(stuck[:, 0] - stuck[:, 1], radii).min() > 0.99


def test_random_swaps_stay_out_of_the_keepout():
    """Seeded random exchanges of 5 drones (one a leader that does not filter, flying straight):
    the keep-out of the filter is never entered by more than the discretisation's 1 %."""
    rng = np.random.default_rng(2024)
    bp = BarrierParams()
    radii = bp.radii()
    for _ in range(4):
        ang = rng.permutation(5) * 2 * np.pi / 5 + rng.normal(scale=0.05, size=5)
        pos0 = np.stack([2.5 * np.cos(ang), 2.5 * np.sin(ang), 2.0 + rng.normal(scale=0.1, size=5)], 1)
        goal = -pos0 + np.array([0, 0, 4.0])
        traj, _ = _fly(pos0, goal, bp, T=15.0)
        assert keepout_min_distance(traj, radii) > 0.99


# --------------------------------------------------------------------------- the separation filter
def _sensed(t: float, pos: np.ndarray, vel: np.ndarray, dt: float, rng: float = 4.0) -> Sensed:
    d = np.linalg.norm(pos[:, None] - pos[None], axis=2)
    return Sensed(t, pos, vel, d <= rng, 0.4, dt)


def _by_hand_barrier(p_i, v_i, p_j, v_j, radii, k):
    """(A, b) of (B) for the pair, written out here: h = ρ² − 1, ḣ = 2 qᵀq̇, A = 2 S q,
    b = −2‖q̇‖² − 2k·ḣ − k²·h (docs/barrier.md)."""
    S = 1.0 / radii
    q, qd = S * (p_i - p_j), S * (v_i - v_j)
    h, hd = q @ q - 1.0, 2.0 * q @ qd
    return 2.0 * S * q, -2.0 * qd @ qd - 2.0 * k * hd - k * k * h


def test_filter_passes_the_planner_through_when_nothing_is_near():
    """Drones far apart: the output is the planner's references bit for bit, nobody guarded."""
    rng = np.random.default_rng(7)
    f = BarrierFilter()
    f.reset(4)
    pos = np.array([[0.0, 0.0, 2.0], [10.0, 0.0, 2.0], [0.0, 10.0, 2.0], [-10.0, 0.0, 2.0]])
    steer = np.array([False, True, True, True])
    for k in range(5):
        p_d, v_d, a_d = pos + rng.normal(scale=0.1, size=(4, 3)), rng.normal(size=(4, 3)), rng.normal(size=(4, 3))
        out = f(_sensed(0.01 * k, pos, np.zeros((4, 3)), 0.01 if k else 0.0), p_d, v_d, a_d, steer)
        for o, i in zip(out, (p_d, v_d, a_d)):
            np.testing.assert_array_equal(o, i)
            assert o is not i
    assert not f.guarded.any() and not f.active.any()


def test_filter_guards_a_violating_reference_and_satisfies_the_barrier():
    """Follower 1 asked to fly into follower 2 (both seen): its acceleration is changed so that (B)
    holds for its share of the pair (computed by hand), it is guarded, the leader's row (not steered)
    and a far, unseen drone's row are the planner's; moving the unseen drone changes nothing."""
    bp = BarrierParams(both_states=False, tiebreak=0.0)
    radii = bp.radii()
    pos = np.array([[0.0, 0.0, 2.0], [-0.5, 3.0, 2.0], [0.5, 3.0, 2.0], [30.0, 0.0, 2.0]])
    vel = np.zeros((4, 3))
    vel[1, 0], vel[2, 0] = 1.0, -1.0  # closing at 2 m/s
    p_d, v_d = pos.copy(), vel.copy()
    a_d = np.zeros((4, 3))
    a_d[1, 0], a_d[2, 0] = 2.0, -2.0  # and asked to speed up
    steer = np.array([False, True, True, True])
    outs = []
    for far in (30.0, 40.0):
        f = BarrierFilter(bp)
        f.reset(4)
        pp = pos.copy()
        pp[3, 0] = far
        pd = p_d.copy()
        pd[3, 0] = far
        outs.append(f(_sensed(0.0, pp, vel, 0.0), pd, v_d, a_d, steer))
        assert f.guarded[1] and f.guarded[2] and not f.guarded[0] and not f.guarded[3]
        np.testing.assert_array_equal(f.active, [False, True, True, False])  # where it acted this period
    (o_p, o_v, o_a), (o_p2, _, o_a2) = outs
    np.testing.assert_array_equal(o_a[:3], o_a2[:3])  # rows 0-2 do not depend on the unseen drone
    np.testing.assert_array_equal(o_a[0], a_d[0])
    np.testing.assert_array_equal(o_p[3], p_d[3])
    A, b = _by_hand_barrier(pos[1], vel[1], pos[2], vel[2], radii, bp.gain)
    assert b > 0.0  # a burden: drone 1 (the lower index) takes priority_share of it
    assert A @ o_a[1] >= bp.priority_share * b - 1e-9
    assert A @ a_d[1] < bp.priority_share * b  # the planner's did not


def test_filter_hands_a_drone_back_to_its_planner():
    """A follower guarded once (by a neighbour passing close) is handed back once its nominal is
    safe and its reference is back on the planner's: the output is then the planner's bit for bit
    (the burden split in halves, so that both are guarded)."""
    bp = BarrierParams(priority_share=0.5)
    f = BarrierFilter(bp)
    f.reset(3)
    dt = 0.01
    pos = np.array([[0.0, 0.0, 2.0], [0.0, 3.0, 2.0], [0.6, 3.0, 2.0]])
    steer = np.array([False, True, True])
    z = np.zeros((3, 3))
    f(_sensed(0.0, pos, z, 0.0), pos, z, z, steer)
    assert f.guarded[1] and f.guarded[2]  # inside each other's keep-out: (B) asks them apart
    pos[2, 0] = 5.0  # the neighbour is gone
    p_d = pos.copy()
    for k in range(1, 600):
        out = f(_sensed(dt * k, pos, z, dt), p_d, z, z, steer)
        pos = np.where(steer[:, None], out[0], pos)  # perfect tracking
        if not f.guarded.any():
            break
    assert not f.guarded.any(), f.guarded
    out = f(_sensed(dt * (k + 1), pos, z, dt), p_d, z, z, steer)
    for o, i in zip(out, (p_d, z, z)):
        np.testing.assert_array_equal(o, i)


def test_filter_keeps_straight_line_planners_apart():
    """Two followers whose planner flies them straight through each other (constant-speed lines,
    the leader far away): flown as double integrators tracking the filter's references exactly,
    the keep-out of the filter is never entered by more than the discretisation's 1 %, and both
    reach their goals."""
    bp = BarrierParams(priority_share=0.5)
    radii = bp.radii()
    f = BarrierFilter(bp)
    f.reset(3)
    dt, T, speed = 0.01, 14.0, 1.0
    start = np.array([[20.0, 0.0, 2.0], [-2.0, 0.05, 2.0], [2.0, 0.0, 2.0]])
    goal = np.array([[20.0, 0.0, 2.0], [2.0, 0.05, 2.0], [-2.0, 0.0, 2.0]])
    steer = np.array([False, True, True])
    pos, vel, traj = start.copy(), np.zeros((3, 3)), []
    for k in range(int(T / dt)):
        t = k * dt
        s = min(1.0, speed * t / 4.0)
        p_d = start + s * (goal - start)
        v_d = np.where(s < 1.0, speed / 4.0, 0.0) * (goal - start)
        out = f(_sensed(t, pos, vel, dt if k else 0.0), p_d, v_d, np.zeros((3, 3)), steer)
        pos, vel = out[0].copy(), out[1].copy()  # the drones on their references
        traj.append(pos.copy())
    traj = np.array(traj)
    assert keepout_distance(traj[:, 1] - traj[:, 2], radii).min() > 0.99
    np.testing.assert_allclose(traj[-1], goal, atol=0.05)


def test_filter_take_off_gate():
    """Follower 2 stands on the ground 0.3 m from follower 1 (a lower index): it holds where it
    stands (acceleration and velocity references 0) while follower 1 climbs on its planner's
    references; with follower 1 far above, follower 2 is free again."""
    f = BarrierFilter()
    f.reset(3)
    pos = np.array([[5.0, 0.0, 0.05], [0.0, 0.0, 0.05], [0.3, 0.0, 0.05]])
    p_d = pos + np.array([0.0, 0.0, 0.5])
    v_d = np.tile([0.0, 0.0, 1.0], (3, 1))
    a_d = np.tile([0.0, 0.0, 2.0], (3, 1))
    steer = np.array([False, True, True])
    z = np.zeros((3, 3))
    o_p, o_v, o_a = f(_sensed(0.0, pos, z, 0.0), p_d, v_d, a_d, steer)
    np.testing.assert_array_equal(o_p[2], pos[2])
    np.testing.assert_array_equal(o_v[2], 0.0)
    np.testing.assert_array_equal(o_a[2], 0.0)
    np.testing.assert_array_equal(o_a[1], a_d[1])
    far = pos.copy()
    far[1] = [0.0, 0.0, 5.0]
    o_p, o_v, o_a = f(_sensed(0.01, far, z, 0.01), p_d, v_d, a_d, steer)
    assert o_a[2, 2] > 0.0


@pytest.mark.parametrize("gap_rho", [0.9, 1.1])
def test_take_off_gate_against_a_grounded_neighbour_and_an_airborne_one(gap_rho):
    """Two followers on the ground ``gap_rho`` keep-out radii apart (level: ρ = gap_rho, computed here
    from the radii): the higher index waits at ρ < ``gate_rho_ground`` (1.0) only, so both lift off
    together at 1.1 (outside each other's keep-out, at rest: h ≥ 0 and ḣ = 0, the barrier's assumption
    (5)). The same neighbour airborne, straight above its pad at the same ρ, holds it (ρ < ``gate_rho``,
    1.2); with ``gate_rho_ground`` 1.2 the grounded one holds it too (the gate before this key)."""
    from swarm_mj.formation.barrier import takeoff_wait_kernel

    bp = BarrierParams()
    radii = bp.radii()
    filters = np.array([False, True, True])
    z = np.zeros((3, 3))

    def waits(pos: np.ndarray, ground: float) -> bool:
        wait = np.zeros(3, dtype=np.bool_)
        takeoff_wait_kernel(pos, radii, filters, z, z, True, bp.floor_m, bp.gate_rho, ground, bp.gate_horizon_s,
                            wait, pos[0], False, np.zeros(3, dtype=np.bool_))  # fmt: skip
        return bool(wait[2])

    grounded = np.array([[9.0, 0.0, 0.05], [0.0, 0.0, 0.05], [gap_rho * radii[0], 0.0, 0.05]])
    assert np.linalg.norm((grounded[2] - grounded[1]) / radii) == pytest.approx(gap_rho)
    assert waits(grounded, bp.gate_rho_ground) == (gap_rho < 1.0)
    assert waits(grounded, 1.2)  # both gaps are inside 1.2
    # airborne at the same ρ: straight up from a pad gap_rho·a·cos(30°) away, ρ unchanged
    up = grounded.copy()
    up[1] = [grounded[2, 0] - gap_rho * radii[0] * np.cos(np.pi / 6), 0.0, 0.05 + gap_rho * radii[2] * 0.5]
    assert np.linalg.norm((up[2] - up[1]) / radii) == pytest.approx(gap_rho)
    assert waits(up, bp.gate_rho_ground)


def _two_closing_followers(bp: BarrierParams):
    """Two followers closing head-on at 4 m/s, 0.9 m apart, the leader far: the filter of ``bp`` flown two
    periods on them. Returns (filter, positions, velocities, the last acceleration references)."""
    f = BarrierFilter(bp)
    f.reset(3)
    pos = np.array([[20.0, 0.0, 2.0], [0.0, 0.0, 2.0], [0.9, 0.0, 2.0]])
    vel = np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [-2.0, 0.0, 0.0]])
    steer = np.array([False, True, True])
    z = np.zeros((3, 3))
    for k in range(2):
        _, _, a = f(_sensed(0.01 * k, pos, vel, 0.01 if k else 0.0), pos, vel, z, steer)
    return f, pos, vel, a


def test_filter_counts_a_relaxation_once_per_stretch_as_an_event():
    """Two followers closing at 4 m/s, 0.9 m apart, the tilt limited to 5° (the case of
    test_relaxation_is_used_and_flagged): the filter relaxes both, and each gets one relax event
    at the first period of the stretch (t of that call), not one per period; the counters count
    drone-periods. The events go through the compiled step's buffer (barrier_step) to ``events``
    (the burden split in halves, so that both relax). No reserve: with it they would not relax
    (test_filter_uses_the_reserve_before_it_relaxes)."""
    f, _, _, _ = _two_closing_followers(BarrierParams(max_tilt_deg=5.0, priority_share=0.5, reserve_tilt_deg=0.0))
    assert f.relaxed_periods == 4 and f.active_periods == 4
    assert f.events == [{"t": 0.0, "drone": d, "other": 3 - d, "action": "relax"} for d in (1, 2)]  # each other
    assert f.record().ev_count[0] == 0  # the buffer was emptied into events


def _max_over_limits(a: np.ndarray, a_h: float, a_up: float, a_down: float) -> float:
    """max of a·u over the limits of :func:`_limits_ok`, by its 16 vertices written out here."""
    ang = (np.arange(8) + 0.5) * np.pi / 4  # the octagon's vertices, inscribed in the disc of radius a_h
    xy = a_h * np.stack([np.cos(ang), np.sin(ang)], 1)
    return max(float(a[:2] @ v + a[2] * z) for v in xy for z in (a_up, -a_down))


def test_a_relaxation_names_the_neighbour_that_asked_most():
    """A follower between the leader (which does not filter) accelerating straight at it at 8 m/s²
    and a follower above it closing slowly: no input within its limits meets both rows, the filter
    relaxes, and names as ``against`` the neighbour whose row asks most beyond its limits, (b −
    max_U A·u)/‖A‖, each written out here: the leader's."""
    pos = np.array([[-0.9, 0.0, 2.0], [0.0, 0.0, 2.0], [0.0, 0.0, 3.9]])
    vel = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, -0.2]])
    acc = np.array([[8.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    filters = np.array([False, True, True])
    bp = BarrierParams(tiebreak=0.0, priority_share=0.5)
    u, active, relaxed, _, _, against, _ = apply_filter(bp, pos, vel, np.zeros((3, 3)), filters, (pos, vel, acc))
    assert relaxed[1] and against[1] == 0 and against[0] == -1
    radii, a_h = bp.radii(), bp.horizontal_limit()
    excess = {}
    for j, share in ((0, lambda b: 1.0), (2, lambda b: 0.5)):  # all against the leader; halves (priority_share)
        A, b = _constraint(pos[1], vel[1], pos[j], vel[j], radii, bp.gain, share)
        b += A @ acc[j]  # a drone that does not filter: its acceleration too
        excess[j] = (b - _max_over_limits(A, a_h, bp.accel_up, bp.accel_down)) / np.linalg.norm(A)
    assert excess[0] > 0 and excess[0] > excess[2]  # the leader's row alone is beyond the limits


def test_filter_uses_the_reserve_before_it_relaxes():
    """The same two followers, the tilt limited to 5° and the reserve at 45° (docs/barrier.md, "the
    reserve"): braking within 5° cannot satisfy (B), within 45° it can, so no drone relaxes, both use the
    reserve (counted per drone-period), (B) written out here holds, and each command is within the
    reserve's limits and beyond the nominal's."""
    bp = BarrierParams(max_tilt_deg=5.0, priority_share=0.5, reserve_tilt_deg=45.0, tiebreak=0.0, both_states=False)
    f, pos, vel, a = _two_closing_followers(bp)
    assert f.relaxed_periods == 0 and f.reserve_periods == 4 and f.events == []
    radii = bp.radii()
    for i, j in ((1, 2), (2, 1)):
        A, b = _constraint(pos[i], vel[i], pos[j], vel[j], radii, bp.gain, lambda _: 0.5)
        assert A @ a[i] >= b - 1e-8 * (1 + abs(b))
        assert _limits_ok(a[i], bp.reserve_horizontal_limit(), bp.accel_up, bp.accel_down)
        assert not _limits_ok(a[i], bp.horizontal_limit(), bp.accel_up, bp.accel_down)


def test_filter_flies_the_leader_with_leader_filters():
    """The leader (not steered) and a follower closing head-on. Without ``leader_filters`` the
    leader's row is its trajectory's, bit for bit, and the follower takes the whole constraint
    (the leader's acceleration added). With it and ``leader_yields`` (the leader takes its share) the
    leader is filtered too: its row changes and (B), written out here, holds for its share of the
    pair (the lower index, ``priority_share`` of the burden). With it and without ``leader_yields``
    (the default) the leader's row is its nominal, bit for bit, and the follower's command holds (B)
    for the whole pair, as when the leader does not filter. A leader whose trajectory's reference is
    beyond ``leader_guard_m`` (its first) is guarded from where it is: its reference is its position, its
    velocity its sensed one (docs/barrier.md, "the leader")."""
    pos = np.array([[0.0, 0.0, 2.0], [0.9, 0.0, 2.0]])
    vel = np.array([[0.5, 0.0, 0.0], [-0.5, 0.0, 0.0]])  # a burden within the follower's limits
    a_d = np.array([[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]])
    steer = np.array([False, True])
    for on, yields in ((False, False), (True, True), (True, False)):
        bp = BarrierParams(leader_filters=on, leader_yields=yields, tiebreak=0.0, both_states=False)
        f = BarrierFilter(bp)
        f.reset(2)
        o_p, o_v, o_a = f(_sensed(0.0, pos, vel, 0.0), pos, vel, a_d, steer)
        A, b = _by_hand_barrier(pos[0], vel[0], pos[1], vel[1], bp.radii(), bp.gain)
        assert b > 0.0  # a burden
        if not yields:
            for o, i in zip((o_p, o_v, o_a), (pos, vel, a_d)):
                np.testing.assert_array_equal(o[0], i[0])
            assert not f.guarded[0]
            # the follower takes all of it: A·(u_0 − u_1) ≥ b with the leader's estimate 0 at the first call
            assert -A @ o_a[1] >= b - 1e-9
            assert -A @ a_d[1] < b
            assert f.relaxed_periods == 0
        else:
            assert f.guarded[0]
            assert A @ o_a[0] >= bp.priority_share * b - 1e-9
            assert A @ a_d[0] < bp.priority_share * b
    f = BarrierFilter(BarrierParams(leader_filters=True))
    f.reset(2)
    far = pos.copy()
    far[1] = [30.0, 0.0, 2.0]
    goal = far.copy()
    goal[0] = [2.0, 2.5, 2.0]  # the leader's trajectory starts 3.2 m away
    o_p, o_v, _ = f(_sensed(0.0, far, vel, 0.0), goal, np.zeros((2, 3)), np.zeros((2, 3)), steer)
    assert f.guarded[0]
    np.testing.assert_array_equal(o_p[0], far[0])  # where it is (dt = 0)
    np.testing.assert_array_equal(o_v[0], vel[0])


def test_take_off_gate_keeps_off_the_leaders_way():
    """A follower on the ground 1.2 m from the leader, under the leader's way to its reference
    (3 m past it at 2 m up), out of its present and predicted keep-out: ``gate_leader_way`` holds
    it; off, it is free; a follower beside the way, off it by more than the gate, is free either
    way (takeoff_wait_kernel's segment, docs/barrier.md, "take-off gate")."""
    from swarm_mj.formation.barrier import takeoff_wait_kernel

    bp = BarrierParams()
    radii = bp.radii()
    pos = np.array([[0.0, 0.0, 0.5], [0.0, 1.2, 0.05], [2.5, -0.5, 0.05]])
    filters = np.array([False, True, True])
    z = np.zeros((3, 3))
    goal = np.array([0.0, 3.0, 2.0])
    for use in (True, False):
        wait = np.zeros(3, dtype=np.bool_)
        takeoff_wait_kernel(pos, radii, filters, z, z, True, bp.floor_m, bp.gate_rho, bp.gate_rho_ground,
                            bp.gate_horizon_s, wait, goal, use, np.zeros(3, dtype=np.bool_))  # fmt: skip
        assert wait[1] == use
        assert not wait[2]


def test_vertical_jerk_limit_bounds_a_guarded_drones_command():
    """Two followers closing head-on, flown on their references, their planner's vertical
    acceleration chattering (±1.5 m/s² every period): with ``vertical_jerk_limit`` J, a guarded
    drone's vertical acceleration reference moves by at most J·dt from one period to the next, and
    the periods where the limit cut a command the barrier had changed are counted; without the limit
    (0) the same start passes the chatter on (so the bound is not vacuous) and nothing is counted
    (docs/barrier.md, "jerk limit")."""
    dt = 0.01
    jumps, counted = {}, {}
    for J in (10.0, 0.0):
        f = BarrierFilter(BarrierParams(vertical_jerk_limit=J, priority_share=0.5))
        f.reset(3)
        pos = np.array([[20.0, 0.0, 2.0], [-3.0, 0.0, 2.0], [3.0, 0.0, 2.0]])
        vel = np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [-2.0, 0.0, 0.0]])
        steer = np.array([False, True, True])
        prev, worst = None, 0.0
        for k in range(250):
            a_d = np.zeros((3, 3))
            a_d[1:, 2] = 1.5 * (-1.0) ** k
            out = f(_sensed(k * dt, pos, vel, dt if k else 0.0), pos + vel * dt, vel, a_d, steer)
            flown = f.guarded.copy()  # still guarded after this call: this period's row is the filter's
            flown[0] = False
            if prev is not None and flown.any():
                worst = max(worst, float(np.abs(out[2][flown, 2] - prev[flown, 2]).max()))
            prev = out[2].copy()
            pos, vel = out[0].copy(), out[1].copy()
        jumps[J], counted[J] = worst, f.rate_limited_periods
    assert jumps[10.0] <= 10.0 * dt + 1e-12
    assert jumps[0.0] > 10.0 * dt
    assert counted[10.0] > 0 and counted[0.0] == 0


def test_a_descending_follower_is_changed_vertically_first():
    """docs/barrier.md, "the descent's metric": follower 2, which its planner descends onto ring
    neighbour 1 (0.74 m beside it, 0.5 m above, sinking at 1.5 m/s and asked to sink faster),
    must take its pair's burden (by hand: b > 0, the nominal violates (B)). With the plain projection
    the change is mostly sideways (the tall keep-out's normal is horizontal there); with the descent's
    metric (``descent_horizontal_cost`` 16) it is mostly a slower descent. Each is the projection
    computed here in its metric (one active row), and (B) holds. A follower its planner does not
    descend (pushed sideways into its neighbour instead) is projected plainly, whatever the cost."""
    pos = np.array([[20.0, 0.0, 2.0], [0.0, 3.0, 2.4], [0.74, 3.0, 2.9]])
    steer = np.array([False, True, True])
    cases = {  # name: (descent_horizontal_cost, the planner's vertical velocity, acc_d of follower 2, the metric)
        "plain": (1.0, -1.5, (0.0, 0.0, -2.0), 1.0),
        "descent": (16.0, -1.5, (0.0, 0.0, -2.0), 16.0),
        "level": (16.0, 0.0, (-2.0, 0.0, 0.0), 1.0),
    }
    change = {}
    for name, (cost, sink, acc, metric) in cases.items():
        bp = BarrierParams(descent_horizontal_cost=cost, tiebreak=0.0, both_states=False)
        f = BarrierFilter(bp)
        f.reset(3)
        v_d = np.zeros((3, 3))
        v_d[2, 2] = sink
        a_d = np.zeros((3, 3))
        a_d[2] = acc
        A, b = _by_hand_barrier(pos[2], v_d[2], pos[1], v_d[1], bp.radii(), bp.gain)
        share = 1.0 if b > 0 else 0.5  # a burden all the higher index's (priority_share 0); room in halves
        assert A @ a_d[2] < share * b  # the nominal violates (B)
        _, _, o_a = f(_sensed(0.0, pos, v_d, 0.0), pos, v_d, a_d, steer)
        np.testing.assert_array_equal(f.active, [False, False, True])
        assert A @ o_a[2] >= share * b - 1e-9 * (1 + abs(b))
        Wi2 = np.array([1.0 / metric, 1.0 / metric, 1.0])  # Δu = λ·W⁻²·A, λ = (s·b − A·u_nom) / (A·W⁻²·A)
        expect = (share * b - A @ a_d[2]) / (A @ (Wi2 * A)) * Wi2 * A
        change[name] = o_a[2] - a_d[2]
        np.testing.assert_allclose(change[name], expect, rtol=1e-9, atol=1e-12)
    assert np.linalg.norm(change["plain"][:2]) > 5.0 * abs(change["plain"][2])  # sideways
    assert abs(change["descent"][2]) > np.linalg.norm(change["descent"][:2])  # mostly a slower descent


def test_deadlock_escape_takes_a_wedged_follower_out_of_the_corner():
    """A follower wedged in the corner of two keep-outs (the leader's and a ring neighbour's, neither
    of which moves), its planner's reference going straight through the leader to the far side: the
    two constraints leave it only the vertical line where their planes meet, which its nominal does
    not move along, and the horizontal keep-right tie-break cannot take it out. Flown as a double
    integrator on the filter's references: without the escape (``escape_after_s`` 0) it is still
    there after 20 s; with it, it climbs, passes over, and reaches its goal, never inside a keep-out
    by more than the discretisation's 1 %, with the escape counted (docs/barrier.md, "deadlock
    escape")."""
    radii = BarrierParams().radii()
    a = float(radii[0])
    # the follower's way to its goal runs into the leader's keep-out beside the neighbour's
    start = np.array([[0.0, 0.0, 2.0], [1.6, 0.0, 2.0], [a + 0.2, 0.75, 2.0]])
    goal = np.array([-1.0, 0.0, 2.0])
    steer = np.array([False, True, False])  # the leader and the neighbour keep their references
    dt, speed = 0.01, 0.5
    out_of_reach, escapes = {}, {}
    for after in (0.0, BarrierParams().escape_after_s):
        f = BarrierFilter(BarrierParams(leader_filters=False, escape_after_s=after))
        f.reset(3)
        pos, vel, rho = start.copy(), np.zeros((3, 3)), []
        way = goal - start[1]
        for k in range(int(20.0 / dt)):
            t = k * dt
            s = min(1.0, speed * t / float(np.linalg.norm(way)))
            p_d, v_d = start.copy(), np.zeros((3, 3))
            p_d[1] = start[1] + s * way
            v_d[1] = (speed / np.linalg.norm(way)) * way if s < 1.0 else 0.0
            out = f(_sensed(t, pos, vel, dt if k else 0.0), p_d, v_d, np.zeros((3, 3)), steer)
            pos, vel = out[0].copy(), out[1].copy()  # the drones on their references
            rho.append(min(keepout_distance(pos[1] - pos[j], radii) for j in (0, 2)))
        assert min(rho) > 0.99
        out_of_reach[after] = float(np.linalg.norm(pos[1, :2] - goal[:2]))
        escapes[after] = f.escapes
    assert out_of_reach[0.0] > 1.0 and escapes[0.0] == 0  # stuck without it: the test is not vacuous
    assert out_of_reach[BarrierParams().escape_after_s] < 0.05 and escapes[BarrierParams().escape_after_s] >= 1


def test_ground_envelope_stops_a_pushed_descent_above_the_band():
    """The leader descends at 1.5 m/s straight onto a hovering follower (tie-break off, the pair
    exactly aligned: the only way out is down). The filter pushes the follower down; with the
    ground envelope (``ground_brake_share``) its reference never sinks below ``ground_band_m``
    (within one period's step) and it is braking when it gets there, so the real drone can stop
    above the ground; without it (0) the same push carries the reference into the ground band at a
    speed it cannot brake from there, which is the crash the envelope is for (docs/barrier.md,
    "near the ground")."""
    dt = 0.01
    lowest, speed_at_band = {}, {}
    for share in (0.8, 0.0):
        bp = BarrierParams(ground_brake_share=share, tiebreak=0.0, leader_filters=False)
        f = BarrierFilter(bp)
        f.reset(2)
        pos = np.array([[0.0, 0.0, 4.6], [0.0, 0.0, 2.2]])
        vel = np.array([[0.0, 0.0, -1.5], [0.0, 0.0, 0.0]])
        steer = np.array([False, True])
        zs, vz_band = [], None
        for k in range(300):
            p_d = np.array([pos[0], [0.0, 0.0, 2.2]])
            v_d = np.array([vel[0], [0.0, 0.0, 0.0]])
            out = f(_sensed(k * dt, pos, vel, dt if k else 0.0), p_d, v_d, np.zeros((2, 3)), steer)
            pos, vel = out[0].copy(), out[1].copy()
            if pos[0, 2] > 0.6:
                pos[0, 2] -= 1.5 * dt  # the leader flies its trajectory down to 0.6 m
            else:
                vel[0, 2] = 0.0
            zs.append(pos[1, 2])
            if vz_band is None and pos[1, 2] < bp.ground_band_m + 0.05:
                vz_band = vel[1, 2]
        lowest[share], speed_at_band[share] = min(zs), vz_band
    band, a_b = BarrierParams().ground_band_m, 0.8 * BarrierParams().accel_up
    assert lowest[0.8] >= band - 0.05
    # without the envelope: into the band faster than a_b could stop it in the 0.5 m left
    assert speed_at_band[0.0] is not None and speed_at_band[0.0] ** 2 > 2.0 * a_b * band
    assert lowest[0.0] < lowest[0.8]


def test_the_chunk_drivers_relax_events_become_the_rules_events():
    # the chunk driver (swarm_mj/pipeline/fast.py) hands the compiled step's relax events to the
    # rule after each chunk, as the Python period does, so that the summary counts them
    from types import SimpleNamespace

    from swarm_mj.formation.anticollision import make_rule
    from swarm_mj.pipeline.fast import FastLoop

    rule = make_rule("barrier", 3)
    rule.reset(np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [-2.0, 0.0, 0.0]]))
    rec = rule.separation_filter.record()
    rec.ev_t[:2], rec.ev_drone[:2], rec.ev_other[:2], rec.ev_count[0] = (1.25, 1.5), (2, 1), (0, 2), 2
    FastLoop._take_filter_events(SimpleNamespace(policy=SimpleNamespace(rule=rule), _ruled=True))
    assert [e for e in rule.events if e["action"] == "relax"] == [
        {"t": 1.25, "drone": 2, "other": 0, "action": "relax"},
        {"t": 1.5, "drone": 1, "other": 2, "action": "relax"},
    ]
    assert rule.separation_filter.events == [] and rec.ev_count[0] == 0
