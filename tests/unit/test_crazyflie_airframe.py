"""The Crazyflie 2.1 airframe (docs/vehicles.md, "The Crazyflie 2.1"): its values against their published
ranges, the "x" layout's mixing and rotor torques against hand-written ones and the firmware's formulas,
the aero stages on the true rotor positions, the colliding body's height, the simulator's downwash
equal to the validation's prediction, and the validation's motor delay and free-air offset.

Expected values are computed here from the rigid-body equations, the rotor positions typed in, and
the sources' numbers typed in (crazyflie-firmware, Neural-Swarm's defaultcf.txt); swarm_mj is what is
under test."""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

from swarm_mj.physics.aero.downwash import DownwashStage
from swarm_mj.physics.aero.ground import REST_HEIGHT
from swarm_mj.physics.aero.ground_effect import GroundEffectStage, ground_effect_factor
from swarm_mj.physics.aero.presets import PRESETS, vehicle_lag
from swarm_mj.physics.mixing import MIX_T, UNMIX_T, attitude_priority
from swarm_mj.physics.params import DEFAULT_PARAMS, QuadParams
from swarm_mj.physics.sim import Sim
from swarm_mj.physics.world import build_world
from swarm_mj.pipeline.records import Kinematics
from swarm_mj.validation.analysis import MIN_FREE_AIR, DroneSetup, measured
from swarm_mj.validation.flight import DT, DroneLog, Flight
from swarm_mj.validation.params import DATASET_MASS_G, ValidationParams, delay_alpha
from swarm_mj.validation.predict import jet_force
from swarm_mj.validation.sysid import G, ThrustModel
from swarm_mj.vehicles import load_vehicle

CF = load_vehicle("crazyflie21")
CFP = CF.params()
D = 0.046 / math.sqrt(2)  # per-axis moment arm of the "x" (the firmware's 0.707·ARM_LENGTH)
#: rotor centres (x, y) of the Crazyflie, numbered as crazyflie-firmware's power_distribution_quadrotor.c
#: (M1 front right, M2 back right, M3 back left, M4 front left)
XY = np.array([[D, -D], [-D, -D], [-D, D], [D, D]])
KAPPA = 0.0069928948992470565  # firmware THRUST2TORQUE, 2.1+ propellers


# --------------------------------------------------------------------------- the values
def test_crazyflie_values_lie_in_their_published_ranges() -> None:
    """Issue 47's ranges: inertia (Förster), drag-torque ratio (firmware), τ (the data's), f_max (a rotor)."""
    assert 1.60e-5 <= CFP.Ix <= 1.70e-5 and 1.60e-5 <= CFP.Iy <= 1.70e-5 and 2.85e-5 <= CFP.Iz <= 3.00e-5
    assert [CFP.Ix, CFP.Iy, CFP.Iz] == [16.571710e-6, 16.655602e-6, 29.261652e-6]  # controller_lee.c's J
    assert 6.9e-3 <= CFP.yaw_coefficient <= 7.4e-3 and CFP.yaw_coefficient == KAPPA
    assert 0.055 <= CFP.motor_tau <= 0.065
    assert 0.12 <= CFP.f_max <= 0.15
    assert CFP.m == DATASET_MASS_G["defaultcf.txt"] / 1000.0  # the configuration: the data's 32-g drones
    assert CFP.layout == "x" and CFP.height == 0.029 and CFP.L == 0.046


def test_max_thrust_is_the_datas_full_thrust_at_the_stated_voltage() -> None:
    """f_max: defaultcf.txt's max-thrust fit (e-block, g per rotor at full PWM, from the PWM and battery
    voltage before the step) at a 32-g hover's PWM (its thrust fit, C-block) and 3.54 V (typed in)."""
    c = (11.093358483549203, -39.08104165843915, -9.525647087583181, 20.573302305476638, 38.42885066644033)
    e = (-9.855774395877377, 3.0164756915292554, 26.716368783384496)
    v = 3.54 / 4.2
    lo, hi = 0.0, 1.0  # hover PWM p: 4 f(p, v) = 32 g, by bisection
    for _ in range(60):
        p = (lo + hi) / 2
        f = c[0] + c[1] * p + c[2] * v + c[3] * p * p + c[4] * v * p
        lo, hi = (p, hi) if 4 * f < 32.0 else (lo, p)
    assert CFP.f_max == pytest.approx((e[0] + e[1] * lo + e[2] * v) * 9.81e-3, abs=5e-4)


def test_the_simulator_and_the_validation_use_one_rotor_time_constant() -> None:
    """The validation's motor delay per 10-ms sample is DT/τ of the vehicle: the dataset's own 0.16
    (learning/utils.py, typed in) for τ = 1/16 s; the simulator's lag under --aero realistic is τ."""
    assert DT == 0.01
    assert delay_alpha(ValidationParams(), CF.motor_tau, DT, "here") == pytest.approx(0.16, rel=1e-15)
    assert vehicle_lag(PRESETS["realistic"], None, CFP).motor_tau == CF.motor_tau == 1 / 16


# --------------------------------------------------------------------------- the "x" mixing
def _hand_u(F: np.ndarray, L: float = 0.046, kappa: float = KAPPA) -> np.ndarray:
    """U1..U4 of rotor thrusts F (4,) at the rotor centres XY: U1 = ΣF, L·U2, L·U3 = the roll, pitch
    torques Σ r_k × (0, 0, F_k), L·U4 = the yaw torque κ·(−F1 + F2 − F3 + F4) (the firmware's yaw signs)."""
    tau = sum(np.cross([x, y, 0.0], [0.0, 0.0, f]) for (x, y), f in zip(XY, F, strict=True))
    return np.array([F.sum(), tau[0] / L, tau[1] / L, kappa * (-F[0] + F[1] - F[2] + F[3]) / L])


def _alpha(params: QuadParams, U: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Body angular acceleration (3,) at rest under command U, and the rotor thrusts (4,) of one Sim step
    with it (the rates the step gave are zeroed first: no gyroscopic term)."""
    sim = Sim(build_world(1, positions=[[0.0, 0.0, 2.0]], params=params))
    sim.step(U[None, :])
    sim.data.qvel[:] = 0.0
    mujoco.mj_forward(sim.model, sim.data)
    return sim.data.qacc[3:6].copy(), sim.rotor_thrust[0].copy()


def test_x_mixing_is_the_rotor_torques_written_out() -> None:
    rng = np.random.default_rng(0)
    F = rng.uniform(0.0, CFP.f_max, (50, 4))
    U = np.array([_hand_u(f) for f in F])
    np.testing.assert_allclose(F @ CFP.mix_t, U, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(U @ CFP.unmix_t, F, rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("dF", [[0.02, 0.0, 0.0, 0.0], [0.0, 0.015, -0.01, 0.0], [0.01, -0.01, 0.01, -0.01]])
def test_x_rotor_torques_accelerate_the_body(dF) -> None:  # noqa: ANN001
    """MuJoCo: α_x = d·(−F1 − F2 + F3 + F4)/Ix, α_y = d·(−F1 + F2 + F3 − F4)/Iy with d = L/√2, and
    α_z = κ·(−F1 + F2 − F3 + F4)/Iz; the rotors produce F."""
    F = CFP.m * 9.81 / 4 + np.array(dF)
    alpha, rotors = _alpha(CFP, _hand_u(F))
    np.testing.assert_allclose(rotors, F, rtol=1e-12)
    s = np.array([-1, -1, 1, 1]) @ F, np.array([-1, 1, 1, -1]) @ F, np.array([-1, 1, -1, 1]) @ F
    want = [D * s[0] / 16.571710e-6, D * s[1] / 16.655602e-6, KAPPA * s[2] / 29.261652e-6]
    np.testing.assert_allclose(alpha, want, rtol=1e-9, atol=1e-9)


def test_x_unmixing_is_the_firmwares_power_distribution() -> None:
    """crazyflie-firmware powerDistributionForceTorque (typed in): m1 = T/4 − r − p − y, m2 = T/4 − r + p + y,
    m3 = T/4 + r + p − y, m4 = T/4 + r − p + y, r = τx/(4·0.707106781·L), p = τy/(4·…), y = τz/(4κ)."""
    rng = np.random.default_rng(1)
    for _ in range(20):
        T, tx, ty, tz = rng.uniform(0.2, 0.5), *rng.uniform(-1e-3, 1e-3, 3)
        arm = 0.707106781 * 0.046
        r, p, y = 0.25 / arm * tx, 0.25 / arm * ty, 0.25 * tz / KAPPA
        fw = T / 4 + np.array([-r - p - y, -r + p + y, r + p - y, r - p + y])
        U = np.array([T, tx / 0.046, ty / 0.046, tz / 0.046])
        np.testing.assert_allclose(U @ CFP.unmix_t, fw, rtol=1e-8, atol=1e-12)


def test_the_paper_drone_keeps_its_plus_arrays() -> None:
    """The paper's drone: layout "+", the very MIX_T/UNMIX_T arrays, rotors on the body axes (typed in)."""
    for p in (DEFAULT_PARAMS, load_vehicle("paper").params()):
        assert p.layout == "+" and p.mix_t is MIX_T and p.unmix_t is UNMIX_T
        np.testing.assert_array_equal(p.rotor_dirs, [[0, -1], [1, 0], [0, 1], [-1, 0]])
        assert p.body_area == 0.12 * 0.12 and p.height is None
    k = QuadParams(yaw_coefficient=0.01)  # a "+" with a drag-torque ratio: its yaw row only is κ/L
    F = np.array([1.0, 2.0, 3.5, 0.5])
    F1, F2, F3, F4 = F
    want = [F.sum(), F3 - F1, F4 - F2, 0.01 * (F1 - F2 + F3 - F4) / 0.25]
    np.testing.assert_allclose(F @ k.mix_t, want, rtol=1e-14)


def test_attitude_priority_at_the_top_is_the_firmwares_cap() -> None:
    """powerDistributionCap: with a rotor above f_max, all four are lowered by the excess of the highest
    (computed here from the firmware's distribution); attitude_priority does the same where nothing
    reaches the bottom."""
    rng = np.random.default_rng(2)
    for _ in range(20):
        F = rng.uniform(0.06, 0.14, 4)
        F[rng.integers(4)] = rng.uniform(CFP.f_max + 0.001, CFP.f_max + 0.03)  # one above the top
        U = _hand_u(F)
        out = attitude_priority(U[None], CFP.f_min, CFP.f_max, CFP.unmix_t, CFP.mix_t)
        np.testing.assert_allclose(out[0] @ CFP.unmix_t, F - (F.max() - CFP.f_max), rtol=1e-12, atol=1e-15)


# --------------------------------------------------------------------------- geometry
def test_the_x_drone_is_built_on_its_true_rotor_positions() -> None:
    w = build_world(1, params=CFP)
    m = w.model
    for k, (x, y) in enumerate(XY, start=1):
        sid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, f"leader/rotor{k}")
        np.testing.assert_allclose(m.site_pos[sid][:2], [x, y], atol=1e-15)
    arm = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "leader/arm_x")  # along the diagonal, rotor to rotor
    c = math.cos(math.pi / 8)
    np.testing.assert_allclose(np.abs(m.geom_quat[arm]), [c, 0, 0, math.sin(math.pi / 8)], atol=1e-12)


def test_the_colliding_body_is_as_tall_as_the_drone() -> None:
    """29 mm from the foot of the landing gear (REST_HEIGHT × L/0.25 below the centre of mass) up."""
    w = build_world(1, params=CFP)
    g = mujoco.mj_name2id(w.model, mujoco.mjtObj.mjOBJ_GEOM, "leader/rotor_plane")
    half, zc = w.model.geom_size[g][1], w.model.geom_pos[g][2]
    assert 2 * half == pytest.approx(0.029, rel=1e-12)
    assert zc - half == pytest.approx(-REST_HEIGHT * 0.046 / 0.25, abs=1e-12)


@pytest.mark.parametrize(("gap", "touch"), [(-0.003, True), (0.003, False)])
def test_two_crazyflies_one_over_the_other_touch_within_its_height(gap: float, touch: bool) -> None:
    sim = Sim(build_world(2, positions=[[0.0, 0.0, 1.0], [0.01, 0.0, 1.0 + 0.029 + gap]], params=CFP))
    sim.step(np.tile([CFP.m * 9.81, 0.0, 0.0, 0.0], (2, 1)))
    assert (sim.data.ncon > 0) == touch


def test_ground_effect_acts_at_the_x_rotors() -> None:
    """One rotor producing thrust near the floor: the stage's torque is r_1 × ΔF with r_1 = (d, −d, h)."""
    st = GroundEffectStage(rotor_radius=CFP.rotor_radius, rotor_z=0.02 * CFP.size_scale)
    pos, quat = np.array([[0.0, 0.0, 0.03]]), np.array([[1.0, 0.0, 0.0, 0.0]])
    thrust = np.array([[0.08, 0.0, 0.0, 0.0]])

    class FakeSim:
        params = CFP
        kinematics = Kinematics(pos, quat, np.zeros((1, 3)), thrust)

    FakeSim.pos = pos
    st.reset(FakeSim)
    f, tq = np.zeros((1, 3)), np.zeros((1, 3))
    st.apply(FakeSim, f, tq)
    dF = (ground_effect_factor(0.03 + 0.02 * CFP.size_scale, CFP.rotor_radius) - 1.0) * 0.08
    np.testing.assert_allclose(f[0], [0, 0, dF], rtol=1e-12, atol=1e-18)
    np.testing.assert_allclose(tq[0], np.cross([D, -D, 0.02 * CFP.size_scale], [0, 0, dF]), rtol=1e-12, atol=1e-18)


# --------------------------------------------------------------------------- one downwash
@pytest.mark.parametrize("name", ["paper", "crazyflie21"])
def test_the_simulated_force_on_a_drone_below_is_the_validations_prediction(name: str) -> None:
    """For the same states, the simulator's downwash stage (DownwashStage.for_vehicle of the vehicle) pushes
    the lower drone with the force `swarm-mj validate downwash` predicts (predict.jet_force)."""
    v = load_vehicle(name)
    p = v.params()
    st = DownwashStage.for_vehicle(p)
    rng = np.random.default_rng(3)
    span = 12 * p.L
    for _ in range(8):
        pos = np.array([[0.0, 0.0, 3.0], [*rng.uniform(-p.L, p.L, 2), 3.0 - rng.uniform(0.3, 1.0) * span]])
        quat = np.array([[1.0, *rng.uniform(-0.1, 0.1, 3)], [1.0, *rng.uniform(-0.1, 0.1, 3)]])
        quat /= np.linalg.norm(quat, axis=1, keepdims=True)
        rotors = rng.uniform(0.8, 1.2, (2, 4)) * p.m * p.g / 4

        class FakeSim:
            n = 2
            params = p
            kinematics = Kinematics(pos, quat, np.zeros((2, 3)), rotors)

        FakeSim.pos = pos
        st.reset(FakeSim)
        st.apply(FakeSim, np.zeros((2, 3)), np.zeros((2, 3)))
        w, x, y, z = quat[0]
        axis = np.array([[2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)]])  # upper's body z
        want = jet_force(pos[:1], axis, rotors[:1].sum(axis=1), v, pos[1:], quat[1:, [1, 2, 3, 0]], v)
        assert want[0, 2] < 0
        np.testing.assert_allclose(st.force[1], want[0], rtol=1e-12, atol=1e-15)


# --------------------------------------------------------------------------- the free-air offset
def _log(name: str, x: np.ndarray, y: float, z: float, fa: np.ndarray) -> DroneLog:
    """A level drone's log at (x (k,), y, z) whose Fa_z (g) is fa (k,): thrust 32 g, mass 32 g."""
    k = len(x)
    acc = np.zeros((k, 3))
    acc[:, 2] = (fa + 32.0) * G / 32.0  # Fa_z = m a_z / G − T (sysid.residual_force_g, level)
    pos = np.column_stack([x, np.full(k, y), np.full(k, z)])
    q = np.tile([0.0, 0.0, 0.0, 1.0], (k, 1))
    return DroneLog(name, Path(name), DT * np.arange(k), pos, np.zeros((k, 3)), acc, q, np.zeros((k, 4)),
                    np.full(k, 3.7), 0)  # fmt: skip


def test_each_logs_free_air_median_is_removed() -> None:
    """Drone a flies highest (all free air, Fa −0.8 g); b passes under a (−6 g within 0.3 m, −0.8 g
    elsewhere with every tenth sample an outlier of +5 g: the median ignores it); c stays under a the
    whole flight and takes the median of the others' free-air samples (−0.8 g)."""
    k = 600
    xb = np.linspace(-3.0, 3.0, k)
    fb = np.where(np.abs(xb) < 0.3, -6.0, -0.8)
    out = (np.arange(k) % 10 == 0) & (np.abs(xb) >= 0.3)
    fb[out] = 5.0
    logs = {
        "a": _log("a", np.zeros(k), 0.0, 1.0, np.full(k, -0.8)),
        "b": _log("b", xb, 0.0, 0.5, fb),
        "c": _log("c", np.full(k, 0.05), 0.0, 0.4, np.full(k, -3.0)),
    }
    flight = Flight(Path("s"), "e", "00", logs)
    tm = ThrustModel("t", 8.0, 0.0, 0.0, 0.0, 0.0)
    setups = [DroneSetup(CF, tm, 32.0)] * 3
    offsets: dict = {}
    m = measured(flight, setups, [0.16] * 3, ValidationParams(smooth_window=1), offsets)
    np.testing.assert_allclose(m[0], 0.0, atol=1e-9)
    np.testing.assert_allclose(m[1][~out], np.where(np.abs(xb) < 0.3, -5.2, 0.0)[~out], atol=1e-9)
    np.testing.assert_allclose(m[2], -2.2, atol=1e-9)
    assert offsets["s/e/00/c"]["from"] == "flight" and offsets["s/e/00/c"]["free_air_samples"] < MIN_FREE_AIR
    assert offsets["s/e/00/b"]["from"] == "own" and offsets["s/e/00/b"]["offset_g"] == pytest.approx(-0.8)
    raw = measured(flight, setups, [0.16] * 3, ValidationParams(smooth_window=1, free_air_offset=False))
    np.testing.assert_allclose(raw[2], -3.0, atol=1e-9)
