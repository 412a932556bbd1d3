"""Backstepping controller (paper §3.1, eqs. 4–24; docs/interpretations.md §2): equilibria, the closed-loop
characteristic polynomial s² + (α_a + α_b)s + (1 + α_a·α_b) of every axis (from the paper's Lyapunov design:
ė1 = e2 − α_a e1, ė2 = −e1 − α_b e2), found by linearising eq. (1) under the controller, gain shapes,
vectorisation, validation and the wind feedforward of eqs. (23)–(24) with F^w/m (docs/interpretations.md §2
typo fix). Its single-drone results in MuJoCo (issue 3 "Done when") are in
tests/integration/test_controller_runs.py.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from swarm_mj.control.backstepping import TABLE4_GAINS, Backstepping, check_gains, load_gains
from swarm_mj.errors import UserError
from swarm_mj.physics.params import DEFAULT_PARAMS as P
from swarm_mj.physics.state import body_rates_to_euler_rates

Z3 = np.zeros((1, 3))
RNG_GAINS = np.random.default_rng(7).uniform(0.5, 9.0, 12)  # distinct per axis: catches swapped pairs


def _poly_roots(a: float, b: float) -> np.ndarray:
    return np.roots([1.0, a + b, 1.0 + a * b])


def _sorted(z: np.ndarray) -> np.ndarray:
    z = np.asarray(z, dtype=complex)
    return z[np.lexsort((np.round(z.imag, 6), np.round(z.real, 6)))]


def _jacobian(f, x0: np.ndarray, h: float = 1e-6) -> np.ndarray:
    n = len(x0)
    J = np.empty((n, n))
    for j in range(n):
        d = np.zeros(n)
        d[j] = h
        J[:, j] = (f(x0 + d) - f(x0 - d)) / (2 * h)
    return J


def _call(ctl, rpy, rate, pos, vel, pos_d, vel_d=None, acc_d=None, yaw_d=0.0, **kw):
    a = lambda v: np.atleast_2d(np.asarray(v, dtype=float))  # noqa: E731
    vel_d = Z3 if vel_d is None else a(vel_d)
    acc_d = Z3 if acc_d is None else a(acc_d)
    return ctl.compute(a(rpy), a(rate), a(pos), a(vel), a(pos_d), vel_d, acc_d, np.atleast_1d(yaw_d), **kw)


# --------------------------------------------------------------------------- equilibria


@pytest.mark.parametrize("amap", ["exact", "paper"])
@pytest.mark.parametrize("yaw", [0.0, 0.7, -2.5])
def test_hover_with_zero_error_gives_weight_and_no_torque(amap, yaw):
    ctl = Backstepping(1, attitude_map=amap)
    for _ in range(3):  # the finite-difference history must not disturb the equilibrium
        U = _call(ctl, [0, 0, yaw], [0, 0, 0], [0.3, -1.0, 2.0], [0, 0, 0], [0.3, -1.0, 2.0], yaw_d=yaw, omega_body=Z3)
        assert U[0, 0] == pytest.approx(P.m * P.g, rel=1e-12)
        np.testing.assert_allclose(U[0, 1:], 0.0, atol=1e-12)


@pytest.mark.parametrize("amap", ["exact", "paper"])
@pytest.mark.parametrize("phi,theta,psi", [(0.3, -0.2, 0.0), (-0.5, 0.4, 1.1), (0.1, 0.6, -2.0)])
def test_tilted_state_with_zero_error(amap, phi, theta, psi):
    """Zero position/velocity error at a tilt: U1 = m·g/(cos φ cos θ) (eq. 18).

    With the reference acceleration that this tilt and thrust produce in eq. (1), the commanded
    attitude of eqs. (21)–(22) is the tilt itself, so every error is zero and the torques vanish.
    """
    ctl = Backstepping(1, attitude_map=amap)
    # zero error, zero reference acceleration: U1 still compensates the tilt
    U = _call(ctl, [phi, theta, psi], [0, 0, 0], [1, 2, 3], [0, 0, 0], [1, 2, 3], yaw_d=psi, omega_body=Z3)
    assert U[0, 0] == pytest.approx(P.m * P.g / (math.cos(phi) * math.cos(theta)), rel=1e-12)
    # consistent reference acceleration: fully zero error
    U1 = P.m * P.g / (math.cos(phi) * math.cos(theta))
    ax = (math.cos(phi) * math.sin(theta) * math.cos(psi) + math.sin(phi) * math.sin(psi)) * U1 / P.m
    ay = (math.cos(phi) * math.sin(theta) * math.sin(psi) - math.sin(phi) * math.cos(psi)) * U1 / P.m
    ctl = Backstepping(1, attitude_map=amap)
    for _ in range(3):
        U = _call(
            ctl,
            [phi, theta, psi],
            [0, 0, 0],
            [1, 2, 3],
            [0, 0, 0],
            [1, 2, 3],
            acc_d=[ax, ay, 0.0],
            yaw_d=psi,
            omega_body=Z3,
        )
        assert U[0, 0] == pytest.approx(U1, rel=1e-12)
        np.testing.assert_allclose(ctl.att_d[0], [phi, theta, psi], atol=1e-12)
        np.testing.assert_allclose(U[0, 1:], 0.0, atol=1e-10)


# --------------------------------------------------------------------------- closed-loop polynomials


def _attitude_rhs(gains, yaw_d):
    """Eq. (1) attitude part under the controller (attitude_map="paper"), position at its setpoint.

    State s = (φ, φ̇, θ, θ̇, ψ, ψ̇). With zero position error Ux = Uy = 0, so φ_d = θ_d = 0 and
    ψ_d = yaw_d are constant (a fresh controller: no finite-difference history).
    """
    p = P

    def f(s):
        ctl = Backstepping(1, gains, attitude_map="paper")
        U = _call(ctl, [s[0], s[2], s[4]], [s[1], s[3], s[5]], [0, 0, 1], [0, 0, 0], [0, 0, 1], yaw_d=yaw_d)[0]
        pd, td, yd = s[1], s[3], s[5]
        return np.array(
            [
                pd,
                (p.Iy - p.Iz) / p.Ix * td * yd + p.L / p.Ix * U[1],
                td,
                (p.Iz - p.Ix) / p.Iy * pd * yd + p.L / p.Iy * U[2],
                yd,
                (p.Ix - p.Iy) / p.Iz * pd * td + p.L / p.Iz * U[3],
            ]
        )

    return f


def _position_rhs(gains, pos_d, yaw_d):
    """Eq. (1) translational part, the attitude following its command (φ, θ, ψ) = (φ_d, θ_d, ψ_d).

    This is the position loop of the paper on its double integrator: the controller's U1 and the
    attitude of eqs. (21)–(22) give the acceleration of eq. (1), drag included. The attitude is
    found as the fixed point att = att_d(att) (U1 depends on cos φ cos θ).
    """
    p = P

    def f(s):
        pos, vel = np.array([s[0], s[2], s[4]]), np.array([s[1], s[3], s[5]])
        rpy = np.array([0.0, 0.0, yaw_d])
        for _ in range(30):
            ctl = Backstepping(1, gains, attitude_map="paper")
            U = _call(ctl, rpy, [0, 0, 0], pos, vel, pos_d, yaw_d=yaw_d)[0]
            new = ctl.att_d[0].copy()
            if np.array_equal(new, rpy):
                break
            rpy = new
        phi, th, psi = rpy
        U1 = U[0]
        acc = (
            np.array(
                [
                    (math.cos(phi) * math.sin(th) * math.cos(psi) + math.sin(phi) * math.sin(psi)) * U1 / p.m,
                    (math.cos(phi) * math.sin(th) * math.sin(psi) - math.sin(phi) * math.cos(psi)) * U1 / p.m,
                    math.cos(phi) * math.cos(th) * U1 / p.m - p.g,
                ]
            )
            - p.drag * vel / p.m
        )
        return np.array([vel[0], acc[0], vel[1], acc[1], vel[2], acc[2]])

    return f


@pytest.mark.parametrize("gains", [TABLE4_GAINS, RNG_GAINS], ids=["table4", "random"])
@pytest.mark.parametrize("yaw_d", [0.0, np.deg2rad(25.0)])
def test_attitude_error_dynamics_have_the_backstepping_polynomial(gains, yaw_d):
    s0 = np.array([0.0, 0.0, 0.0, 0.0, yaw_d, 0.0])
    f = _attitude_rhs(gains, yaw_d)
    np.testing.assert_allclose(f(s0), 0.0, atol=1e-12)  # hover is an equilibrium
    eig = np.linalg.eigvals(_jacobian(f, s0))
    expected = np.concatenate(
        [_poly_roots(gains[0], gains[1]), _poly_roots(gains[2], gains[3]), _poly_roots(gains[4], gains[5])]
    )
    np.testing.assert_allclose(_sorted(eig), _sorted(expected), rtol=1e-5, atol=1e-5)
    # and axis by axis: each 2×2 diagonal block is the roll / pitch / yaw loop
    J = _jacobian(f, s0)
    for ax in range(3):
        blk = J[2 * ax : 2 * ax + 2, 2 * ax : 2 * ax + 2]
        a, b = gains[2 * ax], gains[2 * ax + 1]
        # s² − tr·s + det  ≡  s² + (a + b)s + (1 + ab)
        assert -np.trace(blk) == pytest.approx(a + b, rel=1e-6)
        assert np.linalg.det(blk) == pytest.approx(1 + a * b, rel=1e-6)


@pytest.mark.parametrize("gains", [TABLE4_GAINS, RNG_GAINS], ids=["table4", "random"])
@pytest.mark.parametrize("yaw_d", [0.0, np.deg2rad(25.0), -2.0])
def test_position_error_dynamics_have_the_backstepping_polynomial(gains, yaw_d):
    pos_d = np.array([1.0, -0.5, 2.0])
    s0 = np.array([pos_d[0], 0.0, pos_d[1], 0.0, pos_d[2], 0.0])
    f = _position_rhs(gains, pos_d, yaw_d)
    np.testing.assert_allclose(f(s0), 0.0, atol=1e-12)
    J = _jacobian(f, s0)
    eig = np.linalg.eigvals(J)
    expected = np.concatenate(
        [_poly_roots(gains[6], gains[7]), _poly_roots(gains[8], gains[9]), _poly_roots(gains[10], gains[11])]
    )
    np.testing.assert_allclose(_sorted(eig), _sorted(expected), rtol=1e-5, atol=1e-5)
    for ax in range(3):  # decoupled: x, y, z each with their own pair of gains
        blk = J[2 * ax : 2 * ax + 2, 2 * ax : 2 * ax + 2]
        a, b = gains[6 + 2 * ax], gains[7 + 2 * ax]
        assert -np.trace(blk) == pytest.approx(a + b, rel=1e-6)
        assert np.linalg.det(blk) == pytest.approx(1 + a * b, rel=1e-6)
    off = J.copy()
    for ax in range(3):
        off[2 * ax : 2 * ax + 2, 2 * ax : 2 * ax + 2] = 0.0
    np.testing.assert_allclose(off, 0.0, atol=1e-5)


def test_exact_attitude_map_realises_the_papers_euler_accelerations():
    """attitude_map="exact": on the rigid body (Newton–Euler, body rates) the torques give the same
    Euler-angle accelerations that eq. (1) gives under attitude_map="paper" at the same state."""
    rng = np.random.default_rng(3)
    I = P.inertia
    for _ in range(5):
        rpy = rng.uniform([-0.6, -0.6, -3.0], [0.6, 0.6, 3.0])
        eta_dot = rng.uniform(-2.0, 2.0, 3)
        # ω from η̇: body_rates_to_euler_rates is linear in ω, invert it numerically
        E = np.column_stack([body_rates_to_euler_rates(rpy, e) for e in np.eye(3)])
        omega = np.linalg.solve(E, eta_dot)
        args = (
            rpy,
            eta_dot,
            rng.uniform(-1, 1, 3),
            rng.uniform(-1, 1, 3),
            rng.uniform(-1, 1, 3),
            rng.uniform(-1, 1, 3),
            rng.uniform(-1, 1, 3),
        )
        kw = {"yaw_d": rng.uniform(-3, 3)}
        Up = _call(Backstepping(1, attitude_map="paper"), *args, **kw)[0]
        Ue = _call(Backstepping(1, attitude_map="exact"), *args, omega_body=omega[None], **kw)[0]
        assert Ue[0] == pytest.approx(Up[0], rel=1e-12)
        # eq. (1): η̈ = Coriolis + (L/I)·U
        pd, td, yd = eta_dot
        eta_dd_paper = (
            np.array([(P.Iy - P.Iz) / P.Ix * td * yd, (P.Iz - P.Ix) / P.Iy * pd * yd, (P.Ix - P.Iy) / P.Iz * pd * td])
            + P.L / I * Up[1:]
        )
        # rigid body: ω̇ = I⁻¹(τ − ω × Iω), η̈ = d/dt E(η)ω = (∂(Eω)/∂η)·η̇ + E·ω̇
        tau = P.L * Ue[1:]
        omega_dot = (tau - np.cross(omega, I * omega)) / I
        h = 1e-6
        dE = np.column_stack(
            [
                (body_rates_to_euler_rates(rpy + h * e, omega) - body_rates_to_euler_rates(rpy - h * e, omega))
                / (2 * h)
                for e in np.eye(3)
            ]
        )
        eta_dd_rigid = dE @ eta_dot + E @ omega_dot
        np.testing.assert_allclose(eta_dd_rigid, eta_dd_paper, rtol=1e-6, atol=1e-6)


# --------------------------------------------------------------------------- shapes and vectorisation


def _random_states(rng, n):
    return dict(
        rpy=rng.uniform(-0.4, 0.4, (n, 3)),
        rate=rng.uniform(-1, 1, (n, 3)),
        pos=rng.uniform(-2, 2, (n, 3)),
        vel=rng.uniform(-1, 1, (n, 3)),
        pos_d=rng.uniform(-2, 2, (n, 3)),
        vel_d=rng.uniform(-1, 1, (n, 3)),
        acc_d=rng.uniform(-1, 1, (n, 3)),
        yaw=rng.uniform(-3, 3, n),
        yaw_rate=rng.uniform(-0.5, 0.5, n),
        yaw_acc=rng.uniform(-0.5, 0.5, n),
        wind=rng.uniform(-0.3, 0.3, (n, 3)) * [1, 1, 0],
        omega=rng.uniform(-1, 1, (n, 3)),
    )


def _compute(ctl, s, sl=slice(None)):
    return ctl.compute(
        s["rpy"][sl],
        s["rate"][sl],
        s["pos"][sl],
        s["vel"][sl],
        s["pos_d"][sl],
        s["vel_d"][sl],
        s["acc_d"][sl],
        s["yaw"][sl],
        s["yaw_rate"][sl],
        s["yaw_acc"][sl],
        wind_force=s["wind"][sl],
        omega_body=s["omega"][sl],
    )


@pytest.mark.parametrize("amap", ["exact", "paper"])
def test_shared_gains_as_12_or_n_by_12_are_identical(amap):
    n = 4
    rng = np.random.default_rng(11)
    a = Backstepping(n, RNG_GAINS, attitude_map=amap)
    b = Backstepping(n, np.tile(RNG_GAINS, (n, 1)), attitude_map=amap)
    for _ in range(3):
        s = _random_states(rng, n)
        np.testing.assert_array_equal(_compute(a, s), _compute(b, s))


@pytest.mark.parametrize("amap", ["exact", "paper"])
def test_vectorised_call_equals_single_drone_calls(amap):
    n = 5
    rng = np.random.default_rng(12)
    gains = rng.uniform(0.5, 9.0, (n, 12))
    vec = Backstepping(n, gains, attitude_map=amap)
    singles = [Backstepping(1, gains[i], attitude_map=amap) for i in range(n)]
    for _ in range(4):  # several calls: the finite-difference history is per drone
        s = _random_states(rng, n)
        U = _compute(vec, s)
        for i in range(n):
            Ui = _compute(singles[i], s, slice(i, i + 1))
            np.testing.assert_allclose(U[i], Ui[0], rtol=1e-12, atol=1e-12)
            np.testing.assert_allclose(vec.att_d[i], singles[i].att_d[0], rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize(
    "bad",
    [
        np.ones(11),
        np.ones((3, 12)),
        np.ones((2, 13)),
        np.ones((2, 2, 12)),
        np.r_[np.ones(11), 0.0],
        np.r_[np.ones(11), -1.0],
        np.r_[np.ones(11), np.nan],
        np.r_[np.ones(11), np.inf],
        ["a"] * 12,
        "table4",
        [[1.0] * 12, [1.0] * 11],
    ],
    ids=["11", "n_mismatch", "13", "3d", "zero", "negative", "nan", "inf", "strings", "string", "ragged"],
)
def test_invalid_gains_raise_user_error(bad):
    with pytest.raises(UserError):
        Backstepping(2, bad)
    with pytest.raises(UserError):
        check_gains(bad, 2)


def test_gains_file_errors_are_user_errors(tmp_path):
    with pytest.raises(UserError, match="not found"):
        load_gains(tmp_path / "missing.toml")
    p = tmp_path / "g.toml"
    p.write_text("gains = [1, 2,\n")
    with pytest.raises(UserError, match="g.toml"):
        load_gains(p)
    p.write_text("gain = [1.0]\n")
    with pytest.raises(UserError, match="gains"):
        load_gains(p)
    p.write_text("gains = [" + ", ".join(["1.5"] * 12) + "]\n")
    np.testing.assert_array_equal(load_gains(p), np.full(12, 1.5))


def test_invalid_attitude_map_is_a_user_error():
    with pytest.raises(UserError):
        Backstepping(1, attitude_map="euler")


# --------------------------------------------------------------------------- wind feedforward


def _ux_uy(att_d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Invert eqs. (21)–(22): sin φ_d = Ux sψ − Uy cψ, sin θ_d cos φ_d = Ux cψ + Uy sψ."""
    phi, th, psi = att_d[:, 0], att_d[:, 1], att_d[:, 2]
    a, b = np.sin(phi), np.sin(th) * np.cos(phi)
    s, c = np.sin(psi), np.cos(psi)
    return a * s + b * c, -a * c + b * s


@pytest.mark.parametrize("amap", ["exact", "paper"])
def test_wind_feedforward_shifts_ux_uy_by_minus_f_over_u1(amap):
    """Eqs. (23)–(24) with F^w/m (docs/interpretations.md §2): Ux_on − Ux_off = −(m/U1)·F_x/m = −F_x/U1, same for y."""
    n = 6
    rng = np.random.default_rng(5)
    s = _random_states(rng, n)
    s["rpy"] *= 0.3
    s["pos_d"] = s["pos"] + rng.uniform(-0.05, 0.05, (n, 3))  # small errors: no clipping of φ_d, θ_d
    s["vel_d"] = s["vel"] + rng.uniform(-0.05, 0.05, (n, 3))
    s["acc_d"] = rng.uniform(-0.5, 0.5, (n, 3))
    s["wind"] = rng.uniform(-0.4, 0.4, (n, 3)) * [1, 1, 0]  # horizontal wind force (N), as in eq. (37)
    on = Backstepping(n, attitude_map=amap, wind_feedforward=True)
    off = Backstepping(n, attitude_map=amap, wind_feedforward=False)
    U_on, U_off = _compute(on, s), _compute(off, s)
    np.testing.assert_allclose(U_on[:, 0], U_off[:, 0], rtol=1e-14)  # U1 does not see a horizontal wind
    assert (np.abs(on.att_d[:, :2]) < np.deg2rad(44)).all()  # no clipping in this check
    ux_on, uy_on = _ux_uy(on.att_d)
    ux_off, uy_off = _ux_uy(off.att_d)
    U1 = U_on[:, 0]
    np.testing.assert_allclose(ux_on - ux_off, -s["wind"][:, 0] / U1, rtol=1e-9, atol=1e-13)
    np.testing.assert_allclose(uy_on - uy_off, -s["wind"][:, 1] / U1, rtol=1e-9, atol=1e-13)
    # with the switch off, the wind force given to the controller is ignored altogether
    off2 = Backstepping(n, attitude_map=amap, wind_feedforward=False)
    s0 = dict(s, wind=np.zeros((n, 3)))
    np.testing.assert_array_equal(_compute(off2, s0), U_off)
    # and feedforward on with zero wind equals off
    on0 = Backstepping(n, attitude_map=amap, wind_feedforward=True)
    np.testing.assert_array_equal(_compute(on0, s0), U_off)


def test_wind_feedforward_cancels_the_wind_on_eq_1():
    """At hover with a wind force F, the commanded tilt makes eq. (1)'s horizontal acceleration zero."""
    F = np.array([[0.35, -0.2, 0.0]])
    ctl = Backstepping(1, attitude_map="paper")
    rpy = np.zeros(3)
    for _ in range(40):  # attitude at its command (fixed point)
        c = Backstepping(1, attitude_map="paper")
        U = _call(c, rpy, [0, 0, 0], [0, 0, 2], [0, 0, 0], [0, 0, 2], wind_force=F)[0]
        rpy = c.att_d[0].copy()
    phi, th, psi = rpy
    U1 = U[0]
    ax = (math.cos(phi) * math.sin(th) * math.cos(psi) + math.sin(phi) * math.sin(psi)) * U1 / P.m + F[0, 0] / P.m
    ay = (math.cos(phi) * math.sin(th) * math.sin(psi) - math.sin(phi) * math.cos(psi)) * U1 / P.m + F[0, 1] / P.m
    az = math.cos(phi) * math.cos(th) * U1 / P.m - P.g
    np.testing.assert_allclose([ax, ay, az], 0.0, atol=1e-9)
    del ctl
