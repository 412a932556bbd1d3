"""Physics of the MuJoCo swarm model (docs/interpretations.md §1, paper eq. (1), Table 1, eqs. (26)–(29)).

Every expected value below is computed in this file with numpy from the physics
(rigid-body equations, rotations, mixing written out here). swarm_mj.physics.state and the
expected-value side of swarm_mj.physics.mixing are deliberately NOT used: the package is
the thing under test.

Conventions checked here (and relied on by the rest of the package):
MuJoCo quaternions are (w, x, y, z), body -> world; a free joint's qvel/qacc are
(linear velocity of the body origin in the WORLD frame, angular velocity in the
BODY frame).
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from swarm_mj.errors import UserError
from swarm_mj.physics import mixing
from swarm_mj.physics.params import QuadParams
from swarm_mj.physics.sim import Sim
from swarm_mj.physics.world import build_world

# Paper Table 1, typed in again here (not read from QuadParams) so that a wrong default fails.
M = 0.486
IX, IY, IZ = 0.0038, 0.0038, 0.0071
INERTIA = np.array([IX, IY, IZ])
L = 0.25
K = np.array([0.0056, 0.0056, 0.0064])
G = 9.81
GRAV = np.array([0.0, 0.0, -G])
F_MAX = 4.5
HOVER = M * G


# ----------------------------------------------------------------------------- independent math
def qmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product of quaternions (..., 4), (w, x, y, z)."""
    aw, ax, ay, az = np.moveaxis(a, -1, 0)
    bw, bx, by, bz = np.moveaxis(b, -1, 0)
    return np.stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ],
        axis=-1,
    )


def qconj(q: np.ndarray) -> np.ndarray:
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def q_axis_angle(axis, angle) -> np.ndarray:
    axis = np.asarray(axis, float)
    return np.concatenate([[np.cos(angle / 2)], np.sin(angle / 2) * axis / np.linalg.norm(axis)])


def q_from_zyx(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """R = Rz(yaw)·Ry(pitch)·Rx(roll) as a product of elementary rotations."""
    return qmul(qmul(q_axis_angle([0, 0, 1], yaw), q_axis_angle([0, 1, 0], pitch)), q_axis_angle([1, 0, 0], roll))


def rot_x(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def rot_y(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def rot_z(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """q ⊗ (0, v) ⊗ q*: the body-frame vector v expressed in the world frame (..., 3)."""
    qv = np.concatenate([np.zeros(v.shape[:-1] + (1,)), v], axis=-1)
    return qmul(qmul(q, qv), qconj(q))[..., 1:]


def rotmat(q: np.ndarray) -> np.ndarray:
    """Body -> world rotation matrices (..., 3, 3), columns = images of the body axes."""
    eye = np.eye(3)
    return np.stack([rotate(q, np.broadcast_to(eye[k], q.shape[:-1] + (3,))) for k in range(3)], axis=-1)


def rotvec(q: np.ndarray) -> np.ndarray:
    """Rotation vector (axis·angle) of a unit quaternion (..., 4)."""
    q = np.where(q[..., :1] < 0, -q, q)
    s = np.linalg.norm(q[..., 1:], axis=-1, keepdims=True)
    ang = 2.0 * np.arctan2(s, q[..., :1])
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(s > 1e-300, q[..., 1:] * ang / s, 2.0 * q[..., 1:])


def angle_between(q1: np.ndarray, q2: np.ndarray) -> np.ndarray:
    """Angle (rad) of the rotation taking q1 to q2 (..., 4)."""
    return np.linalg.norm(rotvec(qmul(qconj(q1), q2)), axis=-1)


def zyx_from_R(R: np.ndarray) -> np.ndarray:
    """(roll, pitch, yaw) (..., 3) of R = Rz·Ry·Rx, read off the matrix entries."""
    return np.stack(
        [
            np.arctan2(R[..., 2, 1], R[..., 2, 2]),
            -np.arcsin(np.clip(R[..., 2, 0], -1, 1)),
            np.arctan2(R[..., 1, 0], R[..., 0, 0]),
        ],
        axis=-1,
    )


def newton_euler(y: np.ndarray, U: np.ndarray, F_ext: np.ndarray) -> np.ndarray:
    """d/dt of y = [p(3), v(3), q(4), ω_body(3)] (n, 13) for a rigid body with body-z thrust U1,
    body torques L·(U2, U3, U4), world drag −K·v and an external world force F_ext (n, 3):

        ṗ = v,   m·v̇ = U1·R(q)·e_z − K·v + F_ext + m·g,   q̇ = ½ q ⊗ (0, ω),   I·ω̇ = τ − ω × I·ω

    (written out component-wise: this runs 80 000 times per test)."""
    w, x, yq, z = y[:, 6], y[:, 7], y[:, 8], y[:, 9]
    p, q, r = y[:, 10], y[:, 11], y[:, 12]
    U1 = U[:, 0]
    out = np.empty_like(y)
    out[:, 0:3] = y[:, 3:6]
    # R(q)·e_z = third column of the rotation matrix = q ⊗ (0, 0, 0, 1) ⊗ q* (checked in test_rotation_convention)
    out[:, 3] = U1 * 2.0 * (x * z + w * yq)
    out[:, 4] = U1 * 2.0 * (yq * z - w * x)
    out[:, 5] = U1 * (1.0 - 2.0 * (x * x + yq * yq))
    out[:, 3:6] += F_ext - K * y[:, 3:6]
    out[:, 3:6] /= M
    out[:, 5] -= G
    out[:, 6] = 0.5 * (-x * p - yq * q - z * r)
    out[:, 7] = 0.5 * (w * p + yq * r - z * q)
    out[:, 8] = 0.5 * (w * q + z * p - x * r)
    out[:, 9] = 0.5 * (w * r + x * q - yq * p)
    out[:, 10] = (L * U[:, 1] - (IZ - IY) * q * r) / IX
    out[:, 11] = (L * U[:, 2] - (IX - IZ) * r * p) / IY
    out[:, 12] = (L * U[:, 3] - (IY - IX) * p * q) / IZ
    return out


def eq1(x: np.ndarray, U: np.ndarray, Ix=IX, Iy=IY, Iz=IZ) -> np.ndarray:
    """Paper eq. (1), state (n, 12) = [φ φ̇ θ θ̇ ψ ψ̇ x ẋ y ẏ z ż], no wind."""
    phi, dphi, th, dth, psi, dpsi = (x[:, k] for k in range(6))
    vx, vy, vz = x[:, 7], x[:, 9], x[:, 11]
    U1, U2, U3, U4 = U.T
    out = np.empty_like(x)
    out[:, 0] = dphi
    out[:, 1] = (Iy - Iz) / Ix * dth * dpsi + L / Ix * U2
    out[:, 2] = dth
    out[:, 3] = (Iz - Ix) / Iy * dphi * dpsi + L / Iy * U3
    out[:, 4] = dpsi
    out[:, 5] = (Ix - Iy) / Iz * dphi * dth + L / Iz * U4
    out[:, 6] = vx
    out[:, 7] = (np.cos(phi) * np.sin(th) * np.cos(psi) + np.sin(phi) * np.sin(psi)) / M * U1 - K[0] * vx / M
    out[:, 8] = vy
    out[:, 9] = (np.cos(phi) * np.sin(th) * np.sin(psi) - np.sin(phi) * np.cos(psi)) / M * U1 - K[1] * vy / M
    out[:, 10] = vz
    out[:, 11] = np.cos(phi) * np.cos(th) / M * U1 - K[2] * vz / M - G
    return out


def rk4(f, y, h, *args):
    k1 = f(y, *args)
    k2 = f(y + 0.5 * h * k1, *args)
    k3 = f(y + 0.5 * h * k2, *args)
    k4 = f(y + h * k3, *args)
    return y + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)


def free_body_ids(world) -> np.ndarray:
    m = world.model
    return m.jnt_bodyid[m.jnt_type == mujoco.mjtJoint.mjJNT_FREE]


def single(pos=(0.0, 0.0, 1.0), **kw):
    """A one-drone world (no contacts) and a raw MjData on it."""
    world = build_world(1, positions=[pos], collisions=False, **kw)
    return world, mujoco.MjData(world.model)


# ----------------------------------------------------------------------------- 1. mass and inertia
@pytest.mark.parametrize("n", [1, 6])
def test_mass_and_inertia_match_table1(n):
    world = build_world(n, positions=np.column_stack([np.arange(n) * 2.0, np.zeros(n), np.ones(n)]))
    m = world.model
    assert len(world.body_ids) == n
    np.testing.assert_allclose(m.body_mass[world.body_ids], M, rtol=0, atol=1e-12)
    np.testing.assert_allclose(m.body_inertia[world.body_ids], np.tile(INERTIA, (n, 1)), rtol=0, atol=1e-12)
    # principal axes = body axes, centre of mass at the body origin (the com site, where the motors act)
    np.testing.assert_allclose(m.body_iquat[world.body_ids], np.tile([1.0, 0, 0, 0], (n, 1)), atol=1e-12)
    np.testing.assert_allclose(m.body_ipos[world.body_ids], 0.0, atol=1e-12)
    free = free_body_ids(world)
    assert len(free) == n
    np.testing.assert_allclose(m.body_subtreemass[free], M, rtol=0, atol=1e-12)
    np.testing.assert_allclose(m.body_subtreemass[0], n * M, rtol=1e-12)  # nothing else has mass
    # The joint-space mass matrix is what the dynamics use: for a free body with its centre of
    # mass at the joint origin it is diag(m, m, m, Ix, Iy, Iz) in any orientation.
    d = mujoco.MjData(m)
    rng = np.random.default_rng(1)
    q = rng.normal(size=(n, 4))
    d.qpos.reshape(n, 7)[:, 3:7] = q / np.linalg.norm(q, axis=1, keepdims=True)
    mujoco.mj_forward(m, d)
    Mfull = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, Mfull)
    expected = np.kron(np.eye(n), np.diag([M, M, M, IX, IY, IZ]))
    np.testing.assert_allclose(Mfull, expected, rtol=0, atol=1e-12)


# ----------------------------------------------------------------------------- 2. hover
def test_hover_holds_altitude():
    p0 = np.array([[0.3, -0.2, 1.0]])
    sim = Sim(build_world(1, positions=p0))
    U = np.array([[HOVER, 0.0, 0.0, 0.0]])
    for _ in range(1000):  # 10 s
        sim.step(U)
    assert sim.time == pytest.approx(10.0)
    drift = np.abs(sim.pos - p0).max()
    assert drift < 1e-6, f"hover drift {drift:.3e} m"
    assert np.abs(sim.vel).max() < 1e-6
    assert np.abs(sim.omega).max() < 1e-9
    assert angle_between(sim.quat[0], np.array([1.0, 0, 0, 0])) < 1e-9


# ----------------------------------------------------------------------------- 3. body-frame actuation
RPY_TILT = np.deg2rad([30.0, -20.0, 40.0])


def _tilted_single():
    world, d = single()
    q0 = q_from_zyx(*RPY_TILT)
    d.qpos[3:7] = q0
    return world, d, q0


def test_rotation_convention():
    """MuJoCo's body orientation is the test's R = Rz(ψ)·Ry(θ)·Rx(φ) (matrix products)."""
    world, d, q0 = _tilted_single()
    mujoco.mj_forward(world.model, d)
    R = rot_z(RPY_TILT[2]) @ rot_y(RPY_TILT[1]) @ rot_x(RPY_TILT[0])
    np.testing.assert_allclose(d.xmat[world.body_ids[0]].reshape(3, 3), R, atol=1e-12)
    np.testing.assert_allclose(rotmat(q0), R, atol=1e-12)
    np.testing.assert_allclose(zyx_from_R(R), RPY_TILT, atol=1e-12)


def test_thrust_acts_along_body_z():
    world, d, q0 = _tilted_single()
    R = rot_z(RPY_TILT[2]) @ rot_y(RPY_TILT[1]) @ rot_x(RPY_TILT[0])
    U1 = 7.0
    d.ctrl[:] = [U1, 0.0, 0.0, 0.0]
    mujoco.mj_forward(world.model, d)
    a_expected = R @ np.array([0.0, 0.0, U1]) / M + GRAV
    np.testing.assert_allclose(d.qacc[0:3], a_expected, rtol=0, atol=1e-12)
    np.testing.assert_allclose(d.qacc[3:6], 0.0, atol=1e-12)
    thrust_dir = (d.qacc[0:3] - GRAV) / np.linalg.norm(d.qacc[0:3] - GRAV)
    np.testing.assert_allclose(thrust_dir, R[:, 2], atol=1e-12)  # the drone's own z axis
    assert np.degrees(np.arccos(thrust_dir[2])) == pytest.approx(np.degrees(np.arccos(R[2, 2])), abs=1e-9)
    assert thrust_dir[2] < 0.9  # not world z
    # finite difference: 10 ms of motion (2 RK4 steps) is exactly p0 + a t²/2 (constant acceleration)
    p0 = d.qpos[0:3].copy()
    for _ in range(2):
        mujoco.mj_step(world.model, d)
    t = d.time
    np.testing.assert_allclose(d.qpos[0:3], p0 + 0.5 * a_expected * t**2, rtol=0, atol=1e-12)
    np.testing.assert_allclose(d.qvel[0:3], a_expected * t, rtol=0, atol=1e-12)
    assert angle_between(d.qpos[3:7], q0) < 1e-12


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_torque_acts_about_own_body_axis(axis):
    world, d, q0 = _tilted_single()
    U = 0.8 * (-1) ** axis
    ctrl = np.zeros(4)
    ctrl[0] = HOVER
    ctrl[1 + axis] = U
    d.ctrl[:] = ctrl
    mujoco.mj_forward(world.model, d)
    alpha = L * U / INERTIA[axis]
    e = np.eye(3)[axis]
    np.testing.assert_allclose(d.qacc[3:6], alpha * e, rtol=0, atol=1e-9 * abs(alpha))
    # Independent check of the frame: from rest, a constant torque about a principal axis turns the
    # drone about that axis only, by alpha·t²/2. The relative rotation q0* ⊗ q(t) is then that
    # rotation about the BODY axis e, and q(t) ⊗ q0* the same angle about R0·e in the world frame.
    for _ in range(4):
        mujoco.mj_step(world.model, d)
    t = d.time
    q = d.qpos[3:7].copy()
    ang = 0.5 * alpha * t**2
    np.testing.assert_allclose(rotvec(qmul(qconj(q0), q)), ang * e, rtol=0, atol=1e-9)
    np.testing.assert_allclose(rotvec(qmul(q, qconj(q0))), ang * rotmat(q0) @ e, rtol=0, atol=1e-9)
    np.testing.assert_allclose(d.qvel[3:6], alpha * t * e, rtol=0, atol=1e-9)
    # a rotation about the WORLD axis e would be a different one (the test can tell them apart)
    assert np.linalg.norm(rotvec(qmul(q, qconj(q0))) - ang * e) > 0.1 * abs(ang)


def test_torque_motors_on_the_free_joint_give_the_site_wrench():
    """build_world puts U2..U4 on the free joint (O(1) transmission); the wrench must be the one
    of the asset's site motors: same generalised forces and accelerations at a random state, and
    the same flight to rounding."""
    worlds = {tm: build_world(2, positions=[[0, 0, 1], [2, 0, 1]], torque_motors=tm) for tm in ("site", "joint")}
    m_site, m_joint = worlds["site"].model, worlds["joint"].model
    trn = m_joint.actuator_trntype.reshape(2, 4)
    assert (trn[:, 0] == mujoco.mjtTrn.mjTRN_SITE).all() and (trn[:, 1:] == mujoco.mjtTrn.mjTRN_JOINT).all()
    assert (m_site.actuator_trntype == mujoco.mjtTrn.mjTRN_SITE).all()
    rng = np.random.default_rng(0)
    datas = {k: mujoco.MjData(w.model) for k, w in worlds.items()}
    q = rng.normal(size=(2, 4))
    qpos = datas["site"].qpos.copy()
    qpos.reshape(2, 7)[:, 3:7] = q / np.linalg.norm(q, axis=1, keepdims=True)
    qvel, ctrl = rng.normal(size=12), np.abs(rng.normal(size=8))
    for d in datas.values():
        d.qpos[:], d.qvel[:], d.ctrl[:] = qpos, qvel, ctrl
    for k, w in worlds.items():
        mujoco.mj_forward(w.model, datas[k])
    np.testing.assert_allclose(datas["joint"].qfrc_actuator, datas["site"].qfrc_actuator, rtol=0, atol=1e-12)
    np.testing.assert_allclose(datas["joint"].qacc, datas["site"].qacc, rtol=1e-12, atol=1e-10)
    for _ in range(200):  # 1 s of tumbling flight under the same inputs
        for k, w in worlds.items():
            mujoco.mj_step(w.model, datas[k])
    np.testing.assert_allclose(datas["joint"].qpos, datas["site"].qpos, rtol=0, atol=1e-9)
    with pytest.raises(UserError):
        build_world(1, torque_motors="tendon")


# ----------------------------------------------------------------------------- 4. gyroscopic coupling
@pytest.mark.parametrize("torque", [(0.0, 0.0, 0.0), (0.3, -0.2, 0.1)])
def test_euler_equations(torque):
    world, d, q0 = _tilted_single()
    w = np.array([3.0, -2.0, 5.0])
    d.qvel[3:6] = w
    d.ctrl[:] = [HOVER, *torque]
    mujoco.mj_forward(world.model, d)
    tau = L * np.asarray(torque)
    Iw = INERTIA * w
    gyro = np.array(
        [
            w[1] * Iw[2] - w[2] * Iw[1],  # ω × Iω written out
            w[2] * Iw[0] - w[0] * Iw[2],
            w[0] * Iw[1] - w[1] * Iw[0],
        ]
    )
    wdot = (tau - gyro) / INERTIA
    np.testing.assert_allclose(d.qacc[3:6], wdot, rtol=1e-10, atol=1e-10)
    assert np.abs(gyro).max() > 0.01  # the coupling is really exercised
    # translation is not affected by the spin (centre of mass at the joint origin)
    a = rotmat(q0) @ np.array([0.0, 0.0, HOVER]) / M + GRAV
    np.testing.assert_allclose(d.qacc[0:3], a, atol=1e-12)


# ----------------------------------------------------------------------------- 5. drag
@pytest.mark.parametrize("v0", [(2.0, -1.0, 0.0), (0.0, 0.0, 1.5)])
def test_drag_decay(v0):
    v0 = np.array(v0)
    p0 = np.array([0.0, 0.0, 5.0])
    sim = Sim(build_world(1, positions=[p0]))
    sim.reset(velocities=v0[None])
    U = np.array([[HOVER, 0.0, 0.0, 0.0]])
    for _ in range(500):  # 5 s
        sim.step(U)
    t = sim.time
    decay = np.exp(-K * t / M)
    v_exp = v0 * decay
    p_exp = p0 + v0 * M / K * (1.0 - decay)
    # Sim refreshes the drag at the start of each 5-ms physics step and holds it over the step, so
    # v_N = v0·(1 − x)^N with x = K·h/m instead of v0·exp(−N·x): relative difference ≈ N·x²/2,
    # with x ≤ 0.0064·0.005/0.486 = 6.6e-5 and N = 1000 steps (5 s): ≤ 2.2e-6. rtol 1e-5 leaves
    # margin, while a wrong coefficient (Kz for Kx: 14 % of the loss), drag applied twice or not at
    # all (the loss is 5.6-6.4 % of v0 here) fails by orders of magnitude.
    np.testing.assert_allclose(sim.vel[0], v_exp, rtol=1e-5, atol=1e-12)
    np.testing.assert_allclose(sim.pos[0] - p0, p_exp - p0, rtol=1e-5, atol=1e-12)  # measured 8e-7
    moving = v0 != 0
    lost = 1.0 - sim.vel[0][moving] / v0[moving]
    assert np.all(lost > 0.05)  # the decay itself is measurable


# ----------------------------------------------------------------------------- 6. external force
def test_external_force_acceleration():
    F = np.array([[0.3, -0.2, 0.1], [-0.1, 0.4, -0.25], [0.0, 0.0, 0.0]])
    p0 = np.array([[0.0, 0.0, 3.0], [5.0, 0.0, 3.0], [10.0, 0.0, 3.0]])
    sim = Sim(build_world(3, positions=p0))
    U = np.tile([HOVER, 0.0, 0.0, 0.0], (3, 1))
    sim.step(U, F)
    for _ in range(99):  # 1 s in all
        sim.step(U, F)
    t = sim.time
    decay = np.exp(-K * t / M)
    # exact solution from rest with linear drag: v = F/K·(1 − e^{−Kt/m}), x = F/K·(t − m/K·(1 − e^{−Kt/m}))
    v_exp = F / K * (1.0 - decay)
    p_exp = p0 + F / K * (t - M / K * (1.0 - decay))
    # Sim holds the drag of the start of each 5-ms physics step (docs/interpretations.md §1): it lags by h/2, which
    # makes v and x small by the relative amount h·K/(2m) ≈ 3e-5. The drag itself is 0.6 % of v
    # after 1 s, so rtol 1e-4 sees it (and F/Ix, the paper's typo, is 128× off).
    np.testing.assert_allclose(sim.vel, v_exp, rtol=1e-4, atol=1e-12)
    np.testing.assert_allclose(sim.pos - p0, p_exp - p0, rtol=1e-4, atol=1e-12)
    # a (3,) force is applied to every drone
    sim.reset()
    sim.step(U, F[0])
    np.testing.assert_allclose(sim.vel, np.tile(sim.vel[0], (3, 1)), atol=1e-15)
    assert sim.vel[0] @ F[0] > 0


# ----------------------------------------------------------------------------- 7. MuJoCo vs Newton–Euler
def _geometric_controller(p, v, q, w, target, yaw_t):
    """A test-only SO(3) controller, just to keep random flights in a sane envelope (n drones)."""
    a = -2.0 * (p - target) - 2.5 * v
    a_xy = np.linalg.norm(a[:, :2], axis=1, keepdims=True)
    lim = G * np.tan(np.radians(35.0))
    a[:, :2] *= np.minimum(1.0, lim / np.maximum(a_xy, 1e-9))
    f = M * (a - GRAV)
    R = rotmat(q)
    U1 = np.einsum("ij,ij->i", f, R[:, :, 2])
    b3 = f / np.linalg.norm(f, axis=1, keepdims=True)
    c1 = np.stack([np.cos(yaw_t), np.sin(yaw_t), np.zeros_like(yaw_t)], axis=1)
    b2 = np.cross(b3, c1)
    b2 /= np.linalg.norm(b2, axis=1, keepdims=True)
    Rd = np.stack([np.cross(b2, b3), b2, b3], axis=2)
    E = np.einsum("nji,njk->nik", Rd, R) - np.einsum("nji,njk->nik", R, Rd)
    eR = 0.5 * np.stack([E[:, 2, 1], E[:, 0, 2], E[:, 1, 0]], axis=1)
    tau = INERTIA * (-60.0 * eR - 12.0 * w)
    return np.column_stack([U1, tau / L])


def test_mujoco_matches_newton_euler_reference():
    """10 s of random flight (three drones, seeded): MuJoCo at the product defaults against an
    independent quaternion Newton–Euler integration (RK4 at 0.5 ms, continuous drag −K·v).

    The inputs are zero-order held for 10 ms: a test controller keeps the drones in an envelope
    (waypoints within ±3 m, random headings, tilts up to ~45°), random thrust/torque noise and a
    random wind force are added; the reference replays exactly the U that MuJoCo received (after
    rotor saturation). What remains is the product's drag, held over each 5-ms physics step
    (docs/interpretations.md §1): it lags by h/2, a relative error ≈ h·K/(2m) ≈ 3e-5 of the distance flown
    (measured 0.17 mm here; with the drag held the same way in the reference the two agree to
    2 µm and 1e-6°). Tolerances as asked: 1 mm, 0.1°.
    """
    n = 3
    home = np.array([[0.0, 0.0, 5.0], [30.0, 0.0, 5.0], [0.0, 30.0, 5.0]])
    sim = Sim(build_world(n, positions=home))  # product defaults: RK4, 5 ms, drag via xfrc
    assert sim.model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4 and sim.model.opt.timestep == 0.005
    rng = np.random.default_rng(20240607)
    y = np.zeros((n, 13))
    y[:, 0:3] = home
    y[:, 6] = 1.0
    h_ref, sub = 0.0005, 20  # reference: RK4 at 0.5 ms
    max_dp = max_dang = 0.0
    max_tilt = flown = 0.0
    target, yaw_t, wind = home.copy(), np.zeros(n), np.zeros((n, 3))
    prev = home.copy()
    for k in range(1000):  # 10 s, zero-order hold at 10 ms
        if k % 100 == 0:  # new random waypoint, heading, wind each second
            target = home + rng.uniform(-3, 3, size=(n, 3))
            yaw_t = rng.uniform(-np.pi, np.pi, size=n)
            wind = rng.normal(0.0, 0.15, size=(n, 3))
        U = _geometric_controller(sim.pos, sim.vel, sim.quat, sim.omega, target, yaw_t)
        U += np.column_stack([rng.normal(0, 0.5, n), rng.normal(0, 0.2, (n, 3))])  # random inputs
        sim.step(U, wind)
        U_app = sim.ctrl.copy()  # after rotor saturation: what MuJoCo got
        for _ in range(sub):
            y = rk4(newton_euler, y, h_ref, U_app, wind)
        y[:, 6:10] /= np.linalg.norm(y[:, 6:10], axis=1, keepdims=True)
        max_dp = max(max_dp, np.abs(sim.pos - y[:, 0:3]).max())
        max_dang = max(max_dang, angle_between(sim.quat, y[:, 6:10]).max())
        max_tilt = max(max_tilt, np.degrees(np.arccos(np.clip(rotmat(y[:, 6:10])[:, 2, 2], -1, 1))).max())
        flown += np.linalg.norm(sim.pos - prev, axis=1).max()
        prev = sim.pos.copy()
    sim.check()
    print(
        f"\nNewton-Euler reference: max |dp| {max_dp * 1e3:.4f} mm, max attitude error "
        f"{np.degrees(max_dang):.2e} deg, max tilt {max_tilt:.1f} deg, path {flown:.1f} m"
    )
    assert max_tilt > 15.0 and flown > 10.0  # the flight is not trivial
    assert max_dp < 1e-3, f"position error {max_dp:.3e} m"
    assert np.degrees(max_dang) < 0.1, f"attitude error {np.degrees(max_dang):.3e} deg"


# ----------------------------------------------------------------------------- 8. MuJoCo vs eq. (1)
def _small_angle_controller(pos, vel, ang, dang, target, noise):
    """Test-only cascaded PD near hover on (x, y, z, ψ) and Euler angles/angle rates (n drones)."""
    a = -1.5 * (pos - target) - 2.0 * vel
    phi, th, psi = ang.T
    U1 = M * (G + a[:, 2]) / (np.cos(phi) * np.cos(th))
    lim = np.radians(5.0)
    th_d = np.clip((a[:, 0] * np.cos(psi) + a[:, 1] * np.sin(psi)) / G, -lim, lim)
    phi_d = np.clip((a[:, 0] * np.sin(psi) - a[:, 1] * np.cos(psi)) / G, -lim, lim)
    err = ang - np.column_stack([phi_d, th_d, np.zeros_like(psi)])
    tau = INERTIA * (-40.0 * err - 12.0 * dang)
    return np.column_stack([U1, tau / L]) + noise


def _mujoco_to_eq1_state(sim):
    """(angles, Euler-angle rates) from MuJoCo's quaternion and body rates, written out here."""
    ang = zyx_from_R(rotmat(sim.quat))
    phi, th = ang[:, 0], ang[:, 1]
    p, q, r = sim.omega.T
    dang = np.column_stack(
        [
            p + (q * np.sin(phi) + r * np.cos(phi)) * np.tan(th),
            q * np.cos(phi) - r * np.sin(phi),
            (q * np.sin(phi) + r * np.cos(phi)) / np.cos(th),
        ]
    )
    return ang, dang


def test_mujoco_matches_eq1_near_hover():
    """MuJoCo and eq. (1), each in closed loop with the same test controller and the same random
    setpoints and random input perturbations, near hover (commanded |roll|, |pitch| <= 5°).

    Why closed loop: eq. (1) is the Newton–Euler model with Euler-angle rates in place of body
    rates. Open loop the attitude is a double integrator, so any difference between the two grows
    without bound; the paper uses eq. (1) under feedback, and so does this test.

    Why these tolerances: the kinematic difference is (rate × angle): ψ̇ − r ≈ q·φ, φ̇ − p ≈ r·θ,
    θ̇ − q ≈ −r·φ. Roll and pitch are held by the feedback, so their difference stays small
    (measured 0.03°; tolerance 0.1°). Yaw integrates q·φ ≈ θ̇·φ, an area in the (φ, θ) plane:
    second order, of the size tilt² (measured 0.14° at 5.5° tilt, where tilt² = 0.53°; tolerance
    tilt²). A roll/pitch difference δ tilts the thrust: a horizontal acceleration g·δ that the
    position loop (ω ≈ 1 rad/s) turns into ≈ g·δ/ω² ≈ 5 mm at δ = 0.03° worst case (measured
    1.7 mm; tolerance 3 mm). The same run against eq. (1) with Ix, Iy 10 % too large gives
    6–10 mm and 0.16–0.25°, outside these tolerances: the comparison can see a wrong model.
    """
    n = 2
    home = np.array([[0.0, 0.0, 3.0], [5.0, 0.0, 3.0]])
    sim = Sim(build_world(n, positions=home))
    rng = np.random.default_rng(7)
    # eq. (1) states: nominal for both drones, then the same two with Ix, Iy +10 % (control case)
    x = np.zeros((2 * n, 12))
    x[:, 6], x[:, 8], x[:, 10] = np.tile(home[:, 0], 2), np.tile(home[:, 1], 2), np.tile(home[:, 2], 2)
    Ix = np.array([IX] * n + [1.1 * IX] * n)
    Iy = np.array([IY] * n + [1.1 * IY] * n)
    h_ref, sub = 0.0005, 20  # eq. (1) by RK4 at 0.5 ms
    err_p = np.zeros(2 * n)  # max |Δposition| (m), nominal then 10 % off
    err_a = np.zeros((2 * n, 3))  # max |Δ(φ, θ, ψ)| (rad)
    tilt = 0.0
    target = home.copy()
    for k in range(1000):  # 10 s, zero-order hold at 10 ms
        if k % 100 == 0:
            target = home + rng.uniform(-1.0, 1.0, size=(n, 3))
        noise = np.column_stack([rng.normal(0, 0.2, n), rng.normal(0, 0.02, (n, 3))])
        ang, dang = _mujoco_to_eq1_state(sim)
        sim.step(_small_angle_controller(sim.pos, sim.vel, ang, dang, target, noise))
        Ue = _small_angle_controller(
            x[:, 6:12:2], x[:, 7:12:2], x[:, 0:6:2], x[:, 1:6:2], np.tile(target, (2, 1)), np.tile(noise, (2, 1))
        )
        Ue = mixing_saturate_independent(Ue)  # the same rotor limits as the product
        for _ in range(sub):
            x = rk4(eq1, x, h_ref, Ue, Ix, Iy, IZ)
        ang, _ = _mujoco_to_eq1_state(sim)
        ang2 = np.tile(ang, (2, 1))
        err_p = np.maximum(err_p, np.abs(np.tile(sim.pos, (2, 1)) - x[:, 6:12:2]).max(axis=1))
        err_a = np.maximum(err_a, np.abs((ang2 - x[:, 0:6:2] + np.pi) % (2 * np.pi) - np.pi))
        tilt = max(tilt, np.abs(ang[:, :2]).max())
    sim.check()
    ep, ea = err_p[:n].max(), np.degrees(err_a[:n].max(axis=0))
    ep_off, ea_off = err_p[n:].max(), np.degrees(err_a[n:, :2].max())
    print(
        f"\neq. (1): max |dp| {ep * 1e3:.3f} mm, max |d roll|, |d pitch|, |d yaw| "
        f"{ea[0]:.4f}, {ea[1]:.4f}, {ea[2]:.4f} deg at max tilt {np.degrees(tilt):.2f} deg; "
        f"eq. (1) with Ix, Iy +10 %: {ep_off * 1e3:.2f} mm, {ea_off:.3f} deg"
    )
    assert np.degrees(tilt) > 3.0  # the flight is not trivial
    assert ep < 3e-3, f"position error {ep:.3e} m"
    assert max(ea[0], ea[1]) < 0.1, f"roll/pitch error {ea[:2]} deg"
    assert ea[2] < np.degrees(tilt**2), f"yaw error {ea[2]:.3e} deg > tilt² {np.degrees(tilt**2):.3f} deg"
    assert ep_off > 3e-3 and ea_off > 0.1  # ... and a 10 % inertia error is caught


def mixing_saturate_independent(U: np.ndarray) -> np.ndarray:
    """Eqs. (26)–(29) inverted by hand, rotors clipped to [0, 4.5] N, mapped back."""
    F = rotor_from_u(U)
    return u_from_rotor(np.clip(F, 0.0, F_MAX))


def rotor_from_u(U: np.ndarray) -> np.ndarray:
    U1, U2, U3, U4 = np.moveaxis(U, -1, 0)
    return np.stack(
        [U1 / 4 - U2 / 2 + U4 / 4, U1 / 4 - U3 / 2 - U4 / 4, U1 / 4 + U2 / 2 + U4 / 4, U1 / 4 + U3 / 2 - U4 / 4],
        axis=-1,
    )


def u_from_rotor(F: np.ndarray) -> np.ndarray:
    F1, F2, F3, F4 = np.moveaxis(F, -1, 0)
    return np.stack([F1 + F2 + F3 + F4, F3 - F1, F4 - F2, F1 - F2 + F3 - F4], axis=-1)


# ----------------------------------------------------------------------------- 9. contacts
def _fly(p, v, steps, collisions=True):
    sim = Sim(build_world(2, positions=p, collisions=collisions))
    sim.reset(velocities=v)
    U = np.tile([HOVER, 0.0, 0.0, 0.0], (2, 1))  # gravity compensated
    seen = set()
    for _ in range(steps):
        sim.step(U)
        seen.update(sim.drone_contacts())
    return sim, seen


def test_drones_flown_into_each_other_collide():
    p = np.array([[0.0, 0.0, 2.0], [1.2, 0.0, 2.0]])
    v = np.array([[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]])
    sim, seen = _fly(p, v, 50)  # 0.5 s; rotor planes meet after ~0.35 s
    assert sim.contact_events >= 1
    assert seen == {(0, 1)}
    assert sim.contact_log and sim.contact_log[0][1:] == (0, 1)
    t_hit = sim.contact_log[0][0]
    # the collision reach is L = 0.25 m (paper §4: contact when two drones are ≤ 0.5 m apart),
    # so the 1.2 m gap closing at 2 m/s (drag is negligible) is closed to 0.5 m at t = 0.35 s
    assert 0.33 < t_hit < 0.37, t_hit
    # the contact is physical: the drones do not pass through each other
    assert sim.pos[1, 0] - sim.pos[0, 0] > 0.3


def test_drones_flown_apart_do_not_collide():
    p = np.array([[0.0, 0.0, 2.0], [1.2, 0.0, 2.0]])
    v = np.array([[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    sim, seen = _fly(p, v, 100)
    assert sim.contact_events == 0 and sim.contact_log == [] and seen == set()
    assert sim.pos[1, 0] - sim.pos[0, 0] > 3.0


def test_no_contacts_when_collisions_disabled():
    p = np.array([[0.0, 0.0, 2.0], [1.2, 0.0, 2.0]])
    v = np.array([[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]])
    sim, seen = _fly(p, v, 100, collisions=False)
    assert sim.contact_events == 0 and seen == set()
    assert sim.pos[1, 0] < sim.pos[0, 0]  # they passed through each other


@pytest.mark.parametrize("ground", [False, True])
def test_every_drone_geom_collides_and_the_drawn_parts_are_sites(ground):
    """A geom costs MuJoCo bounding-volume and collision work at every RK4 stage even when it never
    collides, so each drone's geoms are its colliders only; the parts that are only drawn (hub, rotor
    discs, nose, landing strut) are sites (assets/quadrotor.xml; docs/design.md, "Start-up and the step's own
    cost")."""
    w = build_world(2, positions=[[0, 0, 2], [2, 0, 2]], ground=ground, params=QuadParams(L=0.3))  # not the asset's L
    m = w.model
    for i, b in enumerate(w.body_ids):
        geoms = np.flatnonzero(m.geom_bodyid == b)
        assert (m.geom_contype[geoms] | m.geom_conaffinity[geoms] > 0).all(), [m.geom(g).name for g in geoms]
        sites = {m.site(s).name.split("/", 1)[1] for s in np.flatnonzero(m.site_bodyid == b)}
        drawn = {"hub", "rotor1", "rotor2", "rotor3", "rotor4", "nose"} | ({"strut"} if ground else set())
        assert drawn <= sites, sites
        # the rotor discs sit at the motors (0, -L), (L, 0), (0, L), (-L, 0), drawn in the drone's colour
        L = w.params.L
        rotors = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, f"{w.names[i]}/rotor{k}") for k in range(1, 5)]
        np.testing.assert_allclose(m.site_pos[rotors, :2], [[0, -L], [L, 0], [0, L], [-L, 0]])
        hub = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, f"{w.names[i]}/hub")
        assert m.site_rgba[hub, 0] > 0.8 if i == 0 else m.site_rgba[hub, 2] > 0.8  # leader red, followers blue


# ----------------------------------------------------------------------------- 10. mixing
def test_mixing_round_trip_and_saturation():
    rng = np.random.default_rng(3)
    U = np.column_stack([rng.uniform(2, 12, 200), rng.uniform(-1.5, 1.5, (200, 3))])
    F = mixing.u_to_rotor(U)
    np.testing.assert_allclose(F, rotor_from_u(U), atol=1e-12)
    np.testing.assert_allclose(mixing.rotor_to_u(F), U, atol=1e-12)
    np.testing.assert_allclose(u_from_rotor(rotor_from_u(U)), U, atol=1e-12)  # the test's own pair
    # hover: four equal rotors
    np.testing.assert_allclose(mixing.u_to_rotor(np.array([HOVER, 0, 0, 0])), HOVER / 4, atol=1e-12)
    # saturation: wild commands, each rotor clipped to [0, 4.5] N, the wrench is the clipped rotors'
    Uw = np.column_stack([rng.uniform(-5, 25, 500), rng.uniform(-8, 8, (500, 3))])
    U_app, F_app = mixing.saturate(Uw, 0.0, F_MAX)
    F_exp = np.clip(rotor_from_u(Uw), 0.0, F_MAX)
    assert (rotor_from_u(Uw) > F_MAX).any() and (rotor_from_u(Uw) < 0).any()
    np.testing.assert_allclose(F_app, F_exp, atol=1e-12)
    np.testing.assert_allclose(U_app, u_from_rotor(F_exp), atol=1e-12)
    assert F_app.min() >= 0.0 and F_app.max() <= F_MAX
    # commands inside the envelope pass unchanged
    Uin = np.column_stack([rng.uniform(4, 8, 50), rng.uniform(-0.3, 0.3, (50, 3))])
    np.testing.assert_allclose(mixing.saturate(Uin, 0.0, F_MAX)[0], Uin, atol=1e-12)
    # the simulator applies the saturated wrench and logs the rotor thrusts
    sim = Sim(build_world(2, positions=[[0, 0, 5], [3, 0, 5]]))
    Us = np.array([[30.0, 2.0, -1.0, 0.5], [HOVER, 0.0, 0.0, 0.0]])
    sim.step(Us)
    F_s = np.clip(rotor_from_u(Us), 0.0, F_MAX)
    np.testing.assert_allclose(sim.rotor_thrust, F_s, atol=1e-12)
    np.testing.assert_allclose(sim.ctrl, u_from_rotor(F_s), atol=1e-12)
    assert sim.ctrl[0, 0] <= 4 * F_MAX + 1e-12


# ----------------------------------------------------------------------------- 11. bad input
@pytest.mark.parametrize(
    "call, needle",
    [
        (lambda: build_world(0), "0"),
        (lambda: QuadParams(m=-1), "-1"),
        (lambda: build_world(1, params=QuadParams(Iz=0.0)), "Iz"),
        (lambda: build_world(2, asset="/nonexistent.xml"), "/nonexistent.xml"),
        (lambda: build_world(3, positions=np.zeros((2, 3))), "(2, 3)"),
        (lambda: build_world(2, positions=np.zeros((2, 2))), "(2, 2)"),
        (lambda: build_world(1, positions=[[0.0, np.nan, 1.0]]), "positions"),
    ],
)
def test_bad_input_raises_user_error(call, needle):
    with pytest.raises(UserError) as info:
        call()
    assert needle in str(info.value), str(info.value)


# ----------------------------------------------------------------------------- 12. n = 50
def test_fifty_drones_build_and_step():
    n = 50
    p0 = np.column_stack([np.arange(n) % 10 * 1.0, np.arange(n) // 10 * 1.0, np.full(n, 2.0)])
    world = build_world(n, positions=p0)
    assert world.n_drones == n and len(set(world.names)) == n
    assert world.model.nq == 7 * n and world.model.nu == 4 * n
    np.testing.assert_allclose(world.model.body_mass[world.body_ids], M)
    sim = Sim(world)
    U = np.tile([HOVER, 0.0, 0.0, 0.0], (n, 1))
    wind = np.array([0.05, 0.0, 0.0])
    for _ in range(20):
        sim.step(U, wind)
    sim.check()
    assert sim.contact_events == 0
    t = sim.time
    decay = np.exp(-K[0] * t / M)
    dx = wind[0] / K[0] * (t - M / K[0] * (1.0 - decay))
    np.testing.assert_allclose(sim.pos - p0, np.tile([dx, 0.0, 0.0], (n, 1)), atol=1e-4 * dx)


# ----------------------------------------------------------------------------- MuJoCo's profiling clock
def test_sim_steps_with_mujocos_profiling_clock_off_and_puts_it_back():
    """The Python bindings set MuJoCo's ``mjcb_time`` whenever an MjData is made, and MuJoCo then reads a
    clock around every stage of every step (``mjData.timer``). ``Sim.step`` switches it off while it steps
    (swarm_mj/physics/_mjstep.py) and puts it back: the timers measure nothing inside, do outside, and the physics
    is the same as raw ``mj_step`` with the clock on, bit for bit."""
    from swarm_mj.physics import _mjstep

    w = build_world(2, positions=[[0, 0, 2], [2, 0, 2]])
    sim = Sim(w)
    cb = _mjstep._time_callback()
    assert cb is not None and cb.value  # the bindings' clock, installed with the MjData
    before = cb.value
    U = np.tile([w.params.hover_thrust + 0.3, 0.01, -0.02, 0.003], (2, 1))
    step_timer = int(mujoco.mjtTimer.mjTIMER_STEP)
    for _ in range(20):
        sim.step(U)
    assert (
        sim.data.timer[step_timer].number == 20 * sim.n_substeps and sim.data.timer[step_timer].duration == 0.0
    )  # no clock read
    assert cb.value == before  # and it is back afterwards

    raw = mujoco.MjData(w.model)  # the same 40 physics steps from Python, clock on
    raw.ctrl[:] = sim.ctrl.ravel()
    for _ in range(20 * sim.n_substeps):
        raw.xfrc_applied[w.body_ids, :3] = (
            -np.array([w.params.Kx, w.params.Ky, w.params.Kz]) * raw.qvel.reshape(2, 6)[:, :3]
        )
        mujoco.mj_step(w.model, raw)
    assert raw.timer[step_timer].number == 20 * sim.n_substeps and raw.timer[step_timer].duration > 0.0  # the clock on
    np.testing.assert_array_equal(raw.qpos, sim.data.qpos)
    np.testing.assert_array_equal(raw.qvel, sim.data.qvel)

    with _mjstep.profiler_paused():
        assert not cb.value
        with _mjstep.profiler_paused():  # nested: the outer one restores
            pass
        assert not cb.value
    assert cb.value == before
