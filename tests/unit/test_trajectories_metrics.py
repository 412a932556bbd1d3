"""Trajectories (docs/interpretations.md §3) and metrics (§7 there, paper eqs. 25 and 38) on known signals.

Every expected value here comes from the formula in docs/interpretations.md / the paper or from a closed-form
signal (first-order and second-order step responses, sinusoids), never from the code
under test.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from swarm_mj.errors import UserError
from swarm_mj.metrics import (
    ISE_WEIGHTS,
    follower_distances,
    formation_settling,
    ise,
    leader_distances,
    min_separation,
    rmse,
    step_metrics,
)
from swarm_mj.trajectories import TRAJECTORIES, make_trajectory

# --------------------------------------------------------------------------- trajectories

# Every bundled trajectory with its defaults, plus non-default parameters that move every knob.
TRAJ_CASES = [(name, {}) for name in sorted(TRAJECTORIES)] + [
    ("lemniscate", {"amplitude": 1.3, "omega": 0.3, "altitude": 1.5, "center": (0.4, -0.7)}),
    ("circle", {"radius": 1.7, "omega": 0.25, "altitude": 3.0, "climb_rate": -0.05, "center": (1.0, 2.0)}),
    ("ascending_orbit", {"radius": 2.0, "omega": 0.5, "altitude": 0.5, "climb_rate": 0.1}),
    ("step", {"target": (-2.0, 0.5, 3.0), "yaw_deg": -40.0}),
    ("hover", {"position": (1.0, 2.0, 3.0), "yaw_deg": 10.0}),
]


@pytest.mark.parametrize("name,params", TRAJ_CASES, ids=[f"{n}-{i}" for i, (n, _) in enumerate(TRAJ_CASES)])
def test_analytic_derivatives_equal_finite_differences(name, params):
    """vel and acc (and the yaw rates) are the time derivatives of pos (and yaw)."""
    traj = make_trajectory(name, params)
    t = np.linspace(0.0, 200.0, 4001)
    h = 1e-4
    r0, rp, rm = traj(t), traj(t + h), traj(t - h)
    k = len(t)
    for f in ("pos", "vel", "acc"):
        assert getattr(r0, f).shape == (k, 3)
    for f in ("yaw", "yaw_rate", "yaw_acc"):
        assert getattr(r0, f).shape == (k,)
    # central differences: truncation error h²/6·|x'''| ≤ 1e-8·A·ω³ (tiny here), rounding ~1e-12/h
    np.testing.assert_allclose((rp.pos - rm.pos) / (2 * h), r0.vel, atol=1e-7)
    np.testing.assert_allclose((rp.vel - rm.vel) / (2 * h), r0.acc, atol=1e-7)
    np.testing.assert_allclose((rp.yaw - rm.yaw) / (2 * h), r0.yaw_rate, atol=1e-7)
    np.testing.assert_allclose((rp.yaw_rate - rm.yaw_rate) / (2 * h), r0.yaw_acc, atol=1e-7)
    # second difference of position as an independent check of acc
    np.testing.assert_allclose((rp.pos - 2 * r0.pos + rm.pos) / h**2, r0.acc, atol=2e-4)


def test_trajectory_formulas_of_spec_section_3():
    t = np.linspace(0.0, 180.0, 1801)
    lem = make_trajectory("lemniscate")(t)
    np.testing.assert_allclose(lem.pos[:, 0], 2.5 * np.sin(0.08 * t), atol=1e-12)
    np.testing.assert_allclose(lem.pos[:, 1], 2.5 * np.sin(0.04 * t), atol=1e-12)
    np.testing.assert_allclose(lem.pos[:, 2], 2.0, atol=0)
    circ = make_trajectory("circle")(t)
    np.testing.assert_allclose(circ.pos[:, 0], 2.5 * np.sin(0.08 * t), atol=1e-12)
    np.testing.assert_allclose(circ.pos[:, 1], 2.5 * np.cos(0.08 * t), atol=1e-12)
    np.testing.assert_allclose(circ.pos[:, 2], 2.0, atol=0)
    orb = make_trajectory("ascending_orbit")(t)
    np.testing.assert_allclose(orb.pos[:, :2], circ.pos[:, :2], atol=1e-12)
    np.testing.assert_allclose(orb.pos[:, 2], 1.0 + 0.02 * t, atol=1e-12)
    st = make_trajectory("step")(t)
    np.testing.assert_allclose(st.pos, np.tile([1.0, 1.0, 1.0], (len(t), 1)))
    np.testing.assert_allclose(st.yaw, np.deg2rad(25.0))
    for r in (lem, circ, orb):
        np.testing.assert_allclose(r.yaw, 0.0)


def test_trajectory_accepts_scalar_time():
    r = make_trajectory("circle")(3.0)
    assert r.pos.shape == (1, 3)
    np.testing.assert_allclose(r.pos[0], [2.5 * math.sin(0.24), 2.5 * math.cos(0.24), 2.0])


def test_unknown_trajectory_and_bad_parameters_are_user_errors():
    with pytest.raises(UserError, match="spiral"):
        make_trajectory("spiral")
    with pytest.raises(UserError, match="lemniscate"):
        make_trajectory("lemniscate", {"wobble": 3})


# --------------------------------------------------------------------------- step_metrics


@pytest.mark.parametrize("t0,y0,target", [(0.0, 0.0, 1.0), (2.5, 1.0, -1.0), (0.0, 0.3, 0.7)])
def test_step_metrics_first_order_response(t0, y0, target):
    """y = target + (y0 − target)·exp(−(t − t0)/τ): no overshoot, 2 % settling = −τ·ln(0.02)."""
    tau, dt = 0.4, 0.001
    t = t0 + np.arange(0.0, 6.0 + dt / 2, dt)
    y = target + (y0 - target) * np.exp(-(t - t0) / tau)
    m = step_metrics(t, y, target, y0)
    assert m["overshoot_pct"] == pytest.approx(0.0, abs=1e-12)
    assert abs(m["settling_s"] - (-tau * math.log(0.02))) <= dt + 1e-12
    assert m["steady_state_error"] == pytest.approx(abs(y0 - target) * math.exp(-6.0 / tau), rel=1e-9)
    # y0 defaults to the first sample
    assert step_metrics(t, y, target) == m


@pytest.mark.parametrize("zeta", [0.2, 0.45, 0.7])
def test_step_metrics_damped_oscillation(zeta):
    """Second-order step response: overshoot exp(−πζ/√(1−ζ²)), settling where |y − 1| last leaves 2 %."""
    wn, dt = 4.0, 1e-4
    wd = wn * math.sqrt(1 - zeta**2)
    t = np.arange(0.0, 20.0, dt)

    def y_of(tt):
        return 1.0 - np.exp(-zeta * wn * tt) * (np.cos(wd * tt) + zeta / math.sqrt(1 - zeta**2) * np.sin(wd * tt))

    y = 2.0 * y_of(t)  # a step of size 2 from 0
    m = step_metrics(t, y, 2.0, 0.0)
    expected_os = 100.0 * math.exp(-math.pi * zeta / math.sqrt(1 - zeta**2))
    assert m["overshoot_pct"] == pytest.approx(expected_os, rel=1e-5)
    # e(t) = y/2 − 1 is monotone between its peaks t_k = kπ/ωd, where |e| = exp(−ζωn t_k). The last
    # peak outside the 2 % band is k* = floor(ln 50 / (ζωn π/ωd)); e then runs monotonically to the
    # next peak (inside the band), so the settling time is the root of s·e(t) = 0.02 on
    # [t_k*, t_k*+1] with s = sign e(t_k*): bisection on the closed form.
    k_star = math.floor(math.log(50.0) / (zeta * wn * math.pi / wd))
    a, b = k_star * math.pi / wd, (k_star + 1) * math.pi / wd
    s = math.copysign(1.0, float(y_of(a)) - 1.0)
    g = lambda tt: s * (float(y_of(tt)) - 1.0) - 0.02  # noqa: E731
    assert g(a) > 0 > g(b)
    for _ in range(80):
        mid = 0.5 * (a + b)
        if g(mid) > 0:
            a = mid
        else:
            b = mid
    assert abs(m["settling_s"] - b) <= 2 * dt
    assert m["steady_state_error"] < 1e-12 + 2.0 * math.exp(-zeta * wn * 20.0) / math.sqrt(1 - zeta**2)


def test_step_metrics_never_settled_and_zero_step():
    t = np.linspace(0, 1, 101)
    m = step_metrics(t, np.sin(20 * t), 1.0, 0.0)
    assert m["settling_s"] == float("inf")
    z = step_metrics(t, np.full_like(t, 2.0), 2.0, 2.0)
    assert z["overshoot_pct"] == 0.0 and z["steady_state_error"] == 0.0


# --------------------------------------------------------------------------- rmse, ise


def test_rmse_of_known_signals():
    t = np.arange(0.0, 10.0, 0.001)  # 10 whole periods of sin(2πt)
    e = np.column_stack([0.3 * np.sin(2 * np.pi * t), np.full_like(t, -0.2), np.zeros_like(t)])
    np.testing.assert_allclose(rmse(e), [0.3 / math.sqrt(2), 0.2, 0.0], rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(rmse(e.T, axis=1), rmse(e), rtol=1e-15)


def test_ise_weights_are_those_of_eq_25():
    np.testing.assert_array_equal(ISE_WEIGHTS, [3, 3, 1, 2, 2, 1])


def test_ise_of_known_signals():
    dt = 0.001
    t = np.arange(0.0, 10.0, dt)  # 10 s, 10 000 samples
    # constant errors c_j: ISE = T·Σ w_j c_j²
    c = np.array([0.1, -0.2, 0.3, 0.05, -0.01, 0.4])
    e = np.tile(c, (len(t), 1))
    assert ise(e, dt) == pytest.approx(10.0 * float(np.sum(np.array([3, 3, 1, 2, 2, 1]) * c**2)), rel=1e-12)
    # one axis at a time: unit error on axis j alone gives w_j·T
    for j, w in enumerate([3, 3, 1, 2, 2, 1]):
        ej = np.zeros((len(t), 6))
        ej[:, j] = 1.0
        assert ise(ej, dt) == pytest.approx(w * 10.0, rel=1e-12)
    # sinusoid A·sin(2πt) over whole periods: ∫A² sin² = A²·T/2
    es = np.zeros((len(t), 6))
    es[:, 0] = 0.5 * np.sin(2 * np.pi * t)
    es[:, 4] = 0.2 * np.sin(2 * np.pi * t)
    assert ise(es, dt) == pytest.approx(3 * 0.25 * 5.0 + 2 * 0.04 * 5.0, rel=1e-9)
    # batched: (k, m, 6) → (m,)
    batch = np.stack([e, es], axis=1)
    np.testing.assert_allclose(ise(batch, dt), [ise(e, dt), ise(es, dt)], rtol=1e-12)


# --------------------------------------------------------------------------- formation metrics


def test_formation_settling_on_synthetic_data():
    """Leader distances converging exponentially to D after each change: settling τ·ln(e0/tol)."""
    dt = 0.01
    t = np.arange(0.0, 30.0 + dt / 2, dt)
    change = np.array([0.0, 6.0, 11.0, 16.0])
    values = np.array([1.0, 1.7, 1.2, 2.0])  # eq. (34)
    idx = np.searchsorted(change, t + 1e-9, side="right") - 1
    D = values[idx]
    tau = np.array([0.5, 0.3, 0.8, 0.4, 0.6])  # one per follower
    e0 = np.array([0.6, -0.5, 0.7, -0.4, 0.3])  # error right after a change (per follower)
    dist = np.empty((len(t), 5))
    for seg in range(4):
        m = idx == seg
        dist[m] = D[m, None] + e0 * np.exp(-(t[m, None] - change[seg]) / tau)
    settling, max_err = formation_settling(t, dist, D, change, tol=0.05)
    expected = float(np.max(tau * np.log(np.abs(e0) / 0.05)))  # the slowest follower decides
    assert len(settling) == 4
    for s in settling:
        assert abs(s - expected) <= dt + 1e-9
    # once settled, the largest error is just under the tolerance (the first settled sample)
    assert 0.05 - 0.01 < max_err <= 0.05


def test_formation_settling_never_and_immediately():
    t = np.arange(0.0, 10.0, 0.01)
    D = np.ones_like(t)
    dist = np.column_stack([np.ones_like(t) + 0.2, np.ones_like(t)])
    s, _ = formation_settling(t, dist, D, np.array([0.0]))
    assert s == [float("inf")]
    s, err = formation_settling(t, np.ones((len(t), 2)) + 0.01, D, np.array([0.0]))
    assert s == [0.0] and err == pytest.approx(0.01)


def test_min_separation_and_distances_on_synthetic_data():
    t = np.linspace(-2.0, 2.0, 401)  # t = 0 at index 200
    pos = np.zeros((len(t), 3, 3))
    pos[:, 1] = np.column_stack([t, np.full_like(t, 0.3), np.full_like(t, 0.4)])  # passes at 0.5 m
    pos[:, 2] = [5.0, 5.0, 0.0]
    d, k, pair = min_separation(pos)
    assert d == pytest.approx(0.5, abs=1e-12) and k == 200 and pair == (0, 1)
    ld = leader_distances(pos)
    np.testing.assert_allclose(ld[:, 0], np.hypot(t, 0.3))  # horizontal only
    np.testing.assert_allclose(ld[:, 1], math.hypot(5, 5))
    fd, pairs = follower_distances(pos)
    assert pairs == [(1, 2)]
    np.testing.assert_allclose(fd[:, 0], np.hypot(5 - t, 4.7))
    assert min_separation(pos[:, :1])[0] == float("inf")


def test_path_per_follower_is_the_arc_length_of_each_followers_log() -> None:
    """swarm_mj.experiments.stress.path_per_follower: a follower on a unit circle sampled finely flies
    ≈ 2π, one standing still 0, the leader (row 0) is left out; the mean of the followers."""
    from swarm_mj.experiments.stress import path_per_follower

    th = np.linspace(0.0, 2.0 * np.pi, 20001)
    pos = np.zeros((th.size, 3, 3))
    pos[:, 0, 0] = 50.0 * th  # the leader: far, not counted
    pos[:, 1, 0], pos[:, 1, 1] = np.cos(th), np.sin(th)
    pos[:, 2] = (3.0, 0.0, 1.0)
    assert path_per_follower(pos) == pytest.approx(np.pi, rel=1e-6)  # (2π + 0) / 2
    assert path_per_follower(pos[:1]) == 0.0
