"""Aerodynamics beyond the paper (swarm_mj.physics.aero, docs/aero.md), each checked against an independent calculation:
the jet formula of Bauersfeld et al. and momentum theory, Cheeseman–Bennett, the first-order lag
1 − exp(−t/τ), free fall onto a solid floor; and the paper preset left without lag, landing gear or
solid floor. Whole runs under either preset are in tests/integration/test_aero_runs.py."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from swarm_mj.errors import UserError
from swarm_mj.physics.aero import PAPER, parse_aero, preset, with_aero
from swarm_mj.physics.aero.downwash import (
    BD,
    BODY_AREA,
    S0,
    SPREAD,
    DownwashStage,
    centreline_velocity,
    half_width,
    hover_induced_velocity,
    jet_speed,
    plate_force,
)
from swarm_mj.physics.aero.ground import REST_HEIGHT, GroundContacts, rest_positions
from swarm_mj.physics.aero.ground_effect import GroundEffectStage, ground_effect_factor
from swarm_mj.physics.aero.presets import (
    AIR_DENSITY,
    DISC_DRAG_COEFFICIENT,
    ROTOR_PLANE_Z,
    ROTOR_RADIUS,
    install,
)
from swarm_mj.physics.params import DEFAULT_PARAMS as P
from swarm_mj.physics.sim import FLOOR_GATE_M, Sim, floor_gate
from swarm_mj.physics.world import build_world
from swarm_mj.pipeline.records import Kinematics
from swarm_mj.scenario import load_scenario, parse_scenario

R = ROTOR_RADIUS
L = P.L


def _sim(positions, *, cfg=None, quats=None, vel=None, dt=0.005, T=None):
    """A Sim of len(positions) drones with the stages of ``cfg`` (default: downwash only, no ground)."""
    cfg = cfg or parse_aero({"downwash": True})
    pos = np.asarray(positions, float)
    w = build_world(len(pos), positions=pos, timestep=dt, ground=cfg.ground, motor_tau=cfg.motor_tau)
    sim = Sim(w, T or dt)
    install(sim, cfg)
    if quats is not None or vel is not None:
        sim.reset(velocities=vel)
        if quats is not None:
            sim.quat[:] = quats
        mujoco.mj_forward(sim.model, sim.data)
        install(sim, cfg)
    return sim


def _rot(q):
    m = np.zeros(9)
    mujoco.mju_quat2Mat(m, np.asarray(q, float))
    return m.reshape(3, 3)  # columns: body axes in the world frame


def _expected_downwash(pos, quats, thrust_total):
    """Independent sum of the plate forces of every drone's jet on every other drone (docstring model)."""
    n = len(pos)
    F, Tq = np.zeros((n, 3)), np.zeros((n, 3))
    offsets = np.array([[0, -L, 0], [L, 0, 0], [0, L, 0], [-L, 0, 0], [0, 0, 0]], float)
    areas = [np.pi * R**2] * 4 + [BODY_AREA]
    for i in range(n):
        u_h = np.sqrt(thrust_total[i] / (2 * AIR_DENSITY * 4 * np.pi * R**2))
        d = -_rot(quats[i])[:, 2]
        for j in range(n):
            if j == i:
                continue
            for off, area in zip(offsets, areas):
                o = _rot(quats[j]) @ off
                rel = pos[j] + o - pos[i]
                s = rel @ d
                if s <= 0:
                    continue
                r = np.linalg.norm(rel - s * d)
                a = s / (2 * L) - S0
                u = u_h * BD / a / (1 + (np.sqrt(2) - 1) * (r / (2 * L * SPREAD * a)) ** 2) ** 2
                x = min(s / R, 1.0)
                u *= x * x * (3 - 2 * x)
                f = 0.5 * AIR_DENSITY * DISC_DRAG_COEFFICIENT * area * u**2 * d
                F[j] += f
                Tq[j] += np.cross(o, f)
    return F, Tq


# ------------------------------------------------------------------ the jet model


def test_hover_induced_velocity_is_momentum_theory():
    """U_H of the jet model at hover thrust = momentum theory's v_h = sqrt(m g / (2 ρ A)), A = 4 π R²
    (≈ 4.4 m/s for Table 1's drone); the centreline speed at the rotor plane lies between v_h (at the
    disc) and 2·v_h (the fully contracted wake), falls with depth, and the jet widens linearly."""
    v_h = np.sqrt(P.m * P.g / (2 * 1.225 * 4 * np.pi * 0.09**2))
    assert 4.3 < v_h < 4.45
    assert hover_induced_velocity(P.m * P.g) == pytest.approx(v_h, rel=1e-12)
    l = 2 * L
    u0 = centreline_velocity(0.0, v_h, l)
    assert v_h < u0 < 2 * v_h
    assert u0 == pytest.approx(v_h * 10.11 / 5.817, rel=1e-12)
    s = np.array([0.4, 0.8, 1.2, 2.0])
    uc = centreline_velocity(s, v_h, l)
    assert np.all(np.diff(uc) < 0)
    # half-width: where the profile is half the centreline speed; linear in depth
    hw = half_width(s, l)
    np.testing.assert_allclose(jet_speed(s, hw, v_h, l), 0.5 * uc, rtol=1e-12)
    np.testing.assert_allclose(np.diff(hw) / np.diff(s), 0.07668, rtol=1e-12)
    # thrust scaling: the jet speed goes with sqrt(T)
    assert hover_induced_velocity(4 * P.m * P.g) == pytest.approx(2 * v_h, rel=1e-12)
    # nothing above the source; nothing at r -> inf
    assert jet_speed(-0.1, 0.0, v_h, l) == 0.0
    assert jet_speed(0.5, 50.0, v_h, l) < 1e-6


@pytest.mark.parametrize(
    "offset",
    [(0.0, 0.0, -0.4), (0.2, 0.0, -0.4), (0.0, 0.35, -0.8), (0.5, -0.3, -1.2), (0.1, 0.1, -0.05), (0.0, 0.0, 0.4)],
)
def test_downwash_force_matches_formula_at_offsets(offset):
    """The stage's force and torque on a yawed, tilted lower drone below a tilted, thrusting upper drone
    equal the jet formula summed over the four rotor discs and the hub, computed independently."""
    upper = np.array([0.0, 0.0, 2.0])
    pos = np.array([upper, upper + offset])
    q_up = np.array([np.cos(0.1), np.sin(0.1), 0.0, 0.0])  # 11.5° roll: the jet leans
    q_lo = np.array([np.cos(0.3), 0.05, -0.03, np.sin(0.3)])
    q_lo /= np.linalg.norm(q_lo)
    sim = _sim(pos, quats=np.array([q_up, q_lo]))
    sim.rotor_thrust[:] = [[1.3, 1.1, 1.2, 1.25], [1.2, 1.2, 1.2, 1.2]]
    f, tq = np.zeros((2, 3)), np.zeros((2, 3))
    st = sim.force_stages[0]
    st.apply(sim, f, tq)
    F, Tq = _expected_downwash(sim.pos.copy(), sim.quat.copy(), sim.rotor_thrust.sum(axis=1))
    np.testing.assert_allclose(f, F, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(tq, Tq, rtol=1e-10, atol=1e-12)
    if offset[2] < -0.1 and np.hypot(*offset[:2]) < 0.4:
        assert f[1, 2] < -0.1  # pushed down by a tenth of a newton or more
    upper_one = 1 if offset[2] > 0 else 0
    assert np.all(f[upper_one] == 0.0)  # the upper one of two feels nothing


def test_downwash_on_axis_at_0_4_m_by_hand():
    """A level drone 0.4 m right below a hovering one: the rotors sit at r = L, the hub on the axis."""
    sim = _sim([[0, 0, 2.0], [0, 0, 1.6]])
    sim.rotor_thrust[:] = P.m * P.g / 4
    f, tq = np.zeros((2, 3)), np.zeros((2, 3))
    sim.force_stages[0].apply(sim, f, tq)
    v_h = np.sqrt(P.m * P.g / (2 * 1.225 * 4 * np.pi * 0.09**2))
    a = 0.4 / 0.5 + 5.817
    uc = v_h * 10.11 / a
    u_rotor = uc / (1 + (np.sqrt(2) - 1) * (0.25 / (0.5 * 0.07668 * a)) ** 2) ** 2
    expected = 0.5 * 1.225 * 1.17 * (4 * np.pi * 0.09**2 * u_rotor**2 + 0.0144 * uc**2)
    assert f[1, 2] == pytest.approx(-expected, rel=1e-12)
    assert plate_force(uc, BODY_AREA) + 4 * plate_force(u_rotor) == pytest.approx(expected, rel=1e-12)
    np.testing.assert_allclose(tq[1], 0.0, atol=1e-12)  # symmetric: no torque
    assert 0.1 * P.m * P.g < expected < 0.5 * P.m * P.g


def test_downwash_copies_do_not_interact():
    """Only drones of the same copy (copy-major order, n per copy) feel each other's jets: the stage reads
    only the documented attributes of the simulator."""

    class FakeSim:
        n = 2
        params = P
        pos = np.array([[0, 0, 2.0], [0, 0, 1.6], [0, 0, 1.6], [0, 0, 2.0]])
        quat = np.tile([1.0, 0, 0, 0], (4, 1))
        rotor_thrust = np.full((4, 4), 1.2)
        kinematics = Kinematics(
            pos, quat, np.zeros((4, 3)), rotor_thrust
        )  # what a stage reads (swarm_mj.pipeline.records)

    st = DownwashStage()
    sim = FakeSim()
    st.reset(sim)
    f, tq = np.zeros((4, 3)), np.zeros((4, 3))
    st.apply(sim, f, tq)
    assert f[1, 2] < 0 and f[2, 2] < 0  # each copy's lower drone
    assert f[0, 2] == 0 and f[3, 2] == 0
    assert f[1, 2] == pytest.approx(f[2, 2], rel=1e-14)


def test_crossing_drone_pushes_lower_one_down_by_the_modelled_amount():
    """MuJoCo, both drones under the backstepping controller: the upper one crosses at 1 m/s 0.4 m above
    the lower one, which holds its position. At every physics step the lower drone's vertical acceleration
    is (U1·cos(tilt) − m g + F_dw − Kz·ż)/m with F_dw the jet formula evaluated independently at the
    logged states: its vertical velocity and altitude follow that integral, and it dips by centimetres
    (by nothing without downwash)."""
    from swarm_mj.control.backstepping import TABLE4_GAINS, Backstepping
    from swarm_mj.physics.observation import observe_kernel

    dt = 0.005

    def fly(downwash: bool):
        cfg = parse_aero({"downwash": downwash})
        sim = _sim(np.array([[-1.5, 0.0, 2.4], [0.0, 0.0, 2.0]]), cfg=cfg, dt=dt)
        ctl = Backstepping(2, TABLE4_GAINS, params=P, control_period=dt)
        z3 = np.zeros((2, 3))
        vz_pred, z_pred, dips = sim.vel[1, 2], sim.pos[1, 2], []
        err_v = err_z = push = 0.0
        for k in range(int(3.0 / dt)):
            t = k * dt
            pos, vel, _quat, omega, rpy, rpy_rate, *_ = observe_kernel(sim.qpos, sim.qvel, 10.0)
            pos_d = np.array([[min(-1.5 + 1.0 * t, 1.5), 0.0, 2.4], [0.0, 0.0, 2.0]])
            vel_d = z3.copy()
            vel_d[0, 0] = 1.0 if pos_d[0, 0] < 1.5 else 0.0
            U = ctl.compute(rpy, rpy_rate, pos, vel, pos_d, vel_d, z3, np.zeros(2), wind_force=z3, omega_body=omega)
            vz0, q0 = sim.vel[1, 2], sim.quat.copy()
            sim.step(U)
            thrust = sim.rotor_thrust.sum(axis=1)  # saturated U1 held over the step
            F, _ = _expected_downwash(pos, q0, thrust) if downwash else (np.zeros((2, 3)), None)
            cos_tilt = 0.5 * (_rot(q0[1])[2, 2] + _rot(sim.quat[1])[2, 2])  # over the step (trapezoid)
            a = (thrust[1] * cos_tilt - P.m * P.g + F[1, 2] - P.Kz * vz0) / P.m
            z_pred += vz_pred * dt + 0.5 * a * dt * dt
            vz_pred += a * dt
            dips.append(2.0 - sim.pos[1, 2])
            err_v = max(err_v, abs(sim.vel[1, 2] - vz_pred))
            err_z = max(err_z, abs(sim.pos[1, 2] - z_pred))
            push = min(push, F[1, 2])
        assert sim.contact_events == 0
        print(
            f"downwash={downwash}: dip {max(dips):.4f} m, strongest push {push:.3f} N, "
            f"max |vz error| {err_v:.2e} m/s, max |z error| {err_z:.2e} m"
        )
        # the lower drone moves as the formula's force says, to 0.2 mm/s and 0.05 mm over 3 s
        assert err_v < 2e-4 and err_z < 5e-5
        return max(dips), push

    dip, push = fly(True)
    assert push < -0.5  # the jet's push at its strongest, N
    assert 0.03 < dip < 0.3
    dip0, push0 = fly(False)
    assert push0 == 0.0 and dip0 < 0.002


# ------------------------------------------------------------------ ground effect


def test_ground_effect_factor_is_cheeseman_bennett():
    z = np.array([0.05, 0.1, 0.2, 0.5, 1.0])
    np.testing.assert_allclose(ground_effect_factor(z), 1.0 / (1.0 - (0.09 / (4 * z)) ** 2), rtol=1e-14)
    # clipped at z = R/2: the gain stops at 4/3
    assert ground_effect_factor(0.0) == pytest.approx(4 / 3, rel=1e-14)
    assert ground_effect_factor(0.01) == pytest.approx(4 / 3, rel=1e-14)
    assert ground_effect_factor(5.0) < 1.0001


def test_ground_effect_stage_and_mujoco_acceleration():
    """A level drone with its rotors at height h gets (T_IGE/T_OGE − 1)·T extra upward force; in MuJoCo,
    with hover thrust, it accelerates upward by that over m."""
    h = 0.15
    cfg = parse_aero({"ground_effect": True})
    sim = _sim([[0, 0, h - ROTOR_PLANE_Z]], cfg=cfg)
    U = np.array([[P.m * P.g, 0, 0, 0]])
    expected = (1.0 / (1.0 - (R / (4 * h)) ** 2) - 1.0) * P.m * P.g
    sim.step(U)
    st = sim.force_stages[0]
    f0 = st.force.copy()
    assert sim.force_stages[0].name == "ground_effect"
    # first physics step: exactly the formula at the start height
    sim2 = _sim([[0, 0, h - ROTOR_PLANE_Z]], cfg=cfg)
    sim2.rotor_thrust[:] = P.m * P.g / 4
    f, tq = np.zeros((1, 3)), np.zeros((1, 3))
    sim2.force_stages[0].apply(sim2, f, tq)
    np.testing.assert_allclose(f[0], [0, 0, expected], rtol=1e-12)
    np.testing.assert_allclose(tq, 0.0, atol=1e-14)
    # MuJoCo: the gained velocity after one 5 ms step is that force's impulse (it barely moves)
    assert sim.vel[0, 2] == pytest.approx(expected / P.m * sim.control_period, rel=0.02)
    assert f0[0, 2] == pytest.approx(expected, rel=0.01)


# ------------------------------------------------------------------ rotor lag


@pytest.mark.parametrize("tau", [0.015, 0.05])
def test_motor_lag_step_response(tau):
    """Each rotor's produced thrust follows a step of its command as 1 − exp(−t/τ) (MuJoCo's filter
    actuator, integrated by RK4), and rotor_thrust reports the produced thrust."""
    cfg = parse_aero({"motor_tau": tau})
    dt = 0.005
    sim = _sim([[0, 0, 5.0]], cfg=cfg, dt=dt)
    assert sim.motor_lag
    F = np.array([1.0, 1.5, 2.0, 0.5])  # per-rotor commands: U = MIX F
    from swarm_mj.physics.mixing import rotor_to_u

    U = rotor_to_u(F[None])
    t, got = [], []
    for k in range(1, 60):
        sim.step(U)
        t.append(k * dt)
        got.append(sim.rotor_thrust[0].copy())
    t, got = np.array(t), np.array(got)
    want = F[None] * (1 - np.exp(-t[:, None] / tau))
    np.testing.assert_allclose(got, want, rtol=2e-4, atol=1e-6)
    np.testing.assert_allclose(sim.rotor_command[0], F, rtol=1e-12)


def test_paper_preset_has_no_lag_landing_gear_or_solid_floor():
    w = build_world(2)
    assert w.model.na == 0
    floor = mujoco.mj_name2id(w.model, mujoco.mjtObj.mjOBJ_GEOM, "floor")
    assert w.model.geom_contype[floor] == 0 and w.model.geom_conaffinity[floor] == 0
    assert w.xml == build_world(2, ground=False, motor_tau=0.0).xml
    wr = build_world(2, ground=True, motor_tau=0.02)
    assert wr.model.na == 8
    assert wr.model.ngeom == w.model.ngeom + 2  # a skid per drone (the strut is a site: drawn, never tested)
    assert wr.model.nsite == w.model.nsite + 2

    # drone-drone geometry is the paper's: the same pairs of geoms of two drones can collide, and the
    # landing gear touches only the floor
    def collide(m, g, h):
        return bool(m.geom_contype[g] & m.geom_conaffinity[h] or m.geom_contype[h] & m.geom_conaffinity[g])

    def pairs(m):
        gd = np.full(m.ngeom, -1)
        for k, name in enumerate(("leader", "follower1")):
            gd[m.geom_bodyid == mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, f"{name}/body")] = k
        return {
            (mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g), mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, h))
            for g in np.flatnonzero(gd == 0)
            for h in np.flatnonzero(gd == 1)
            if collide(m, g, h)
        }

    assert pairs(wr.model) == pairs(w.model) and len(pairs(w.model)) == 9
    floor_r = mujoco.mj_name2id(wr.model, mujoco.mjtObj.mjOBJ_GEOM, "floor")
    touching = {
        mujoco.mj_id2name(wr.model, mujoco.mjtObj.mjOBJ_GEOM, g)
        for g in range(wr.model.ngeom)
        if collide(wr.model, floor_r, g)
    }
    assert touching == {f"{d}/{g}" for d in ("leader", "follower1") for g in ("rotor_plane", "skid")}


# ------------------------------------------------------------------ the solid ground


def test_ground_holds_a_drone_at_rest_with_zero_thrust():
    cfg = preset("realistic")
    sim = _sim(rest_positions(np.array([[0.0, 0.0, 0.0]])), cfg=cfg, T=0.01)
    assert sim.pos[0, 2] == pytest.approx(REST_HEIGHT)
    U = np.zeros((1, 4))
    for _ in range(300):  # 3 s
        sim.step(U)
        sim.check()
    assert abs(sim.pos[0, 2] - REST_HEIGHT) < 2e-3  # resting on its skid (contact compliance: mm)
    assert np.abs(sim.vel).max() < 1e-3
    assert 1 - 2 * (sim.quat[0, 1] ** 2 + sim.quat[0, 2] ** 2) > np.cos(np.deg2rad(0.5))
    mon = sim.monitors[0]
    assert mon.ground_contacts == 0 and mon.crashes == 0
    assert mon.in_contact[0]


def test_fall_is_a_crash_and_a_soft_touchdown_is_not():
    """Zero thrust from 1 m: touchdown at sqrt(2 g h) > 1 m/s, a crash. 90 % of hover thrust from just
    above the take-off clearance: a touchdown of ~0.3 m/s, a ground contact but no crash."""
    cfg = parse_aero({"ground": True})
    sim = _sim([[0, 0, 1.0], [3.0, 0, REST_HEIGHT + 0.055]], cfg=cfg)
    U = np.zeros((2, 4))
    U[1, 0] = 0.9 * P.m * P.g
    for _ in range(int(1.0 / sim.control_period)):
        sim.step(U)
    mon = sim.monitors[0]
    assert mon.ground_contacts == 2
    assert mon.crashes == 1
    by_drone = {e[1]: e for e in mon.log}
    v_fall = np.sqrt(2 * P.g * (1.0 - REST_HEIGHT))
    assert by_drone[0][2] == pytest.approx(v_fall, rel=0.03) and by_drone[0][4]
    assert by_drone[1][2] < 0.5 and not by_drone[1][4]


def _farthest_floor_point(m, sim_world) -> float:
    """Independent of MuJoCo's bounding spheres: the largest distance from a drone's centre of any
    point of its geoms that can touch the floor (the rotor disc, a cylinder; the skid, a box)."""
    out = 0.0
    for g in range(m.ngeom):
        if sim_world.geom_drone[g] != 0 or not m.geom_conaffinity[g] & 4:
            continue
        pos, size = m.geom_pos[g], m.geom_size[g]
        if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_CYLINDER:  # rim point farthest from the centre
            far = np.hypot(np.hypot(pos[0], pos[1]) + size[0], abs(pos[2]) + size[1])
        else:
            assert m.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX
            corners = np.array(np.meshgrid(*[[-s, s] for s in size[:3]])).reshape(3, -1).T
            far = np.linalg.norm(pos + corners @ _rot(m.geom_quat[g]).T, axis=1).max()
        out = max(out, far)
    return out


def test_floor_gate_reach_bounds_every_orientation():
    """The floor gate (``swarm_mj.physics.sim.floor_gate``) tests the floor only when a drone's centre could
    come within its reach + FLOOR_GATE_M of it: the reach bounds every point of the geoms that touch
    the floor, and not loosely; at its reach no orientation touches the floor, just inside the
    farthest point a drone tilted onto its disc's rim does (the check can fail)."""
    w = build_world(1, ground=True)
    fid, solid, z_near = floor_gate(w)
    assert (fid, solid) == (mujoco.mj_name2id(w.model, mujoco.mjtObj.mjOBJ_GEOM, "floor"), 4)
    reach = z_near - FLOOR_GATE_M
    far = _farthest_floor_point(w.model, w)
    assert far <= reach <= far + 0.02
    m, d = w.model, mujoco.MjData(w.model)
    rng = np.random.default_rng(3)
    for q in [*rng.normal(size=(200, 4)), [np.cos(np.pi / 4), np.sin(np.pi / 4), 0, 0]]:
        d.qpos[:] = 0.0
        d.qpos[2] = reach
        d.qpos[3:7] = np.asarray(q) / np.linalg.norm(q)
        mujoco.mj_forward(m, d)
        assert d.ncon == 0
    d.qpos[2] = far - 0.003  # on its side (90° roll): the disc's rim points down
    mujoco.mj_forward(m, d)
    assert d.ncon > 0


def test_floor_gate_switches_the_floor_by_height_and_fall_speed():
    sim = _sim([[0.0, 0.0, 0.0]], cfg=preset("realistic"), T=0.01)
    fid, solid, z_near = floor_gate(sim.world)
    contype = sim.model.geom_contype
    U = np.zeros((1, 4))
    sim.step(U)
    assert contype[fid] == solid  # resting on the floor
    sim.reset(positions=np.array([[0.0, 0.0, 2.0]]))
    sim.step(U)
    assert contype[fid] == 0  # 2 m up: no floor test
    # 0.25 m above z_near, falling at 30 m/s: it could fall 0.3 m within the period
    sim.reset(positions=np.array([[0.0, 0.0, z_near + 0.25]]), velocities=np.array([[0.0, 0.0, -30.0]]))
    sim.step(U)
    assert contype[fid] == solid
    sim.reset(positions=np.array([[0.0, 0.0, 2.0]]))
    sim.floor_gate = False
    sim.step(U)
    assert contype[fid] == solid  # off: tested at every step
    assert floor_gate(build_world(1)) is None  # the paper's floor is never touched: nothing to gate


# ------------------------------------------------------------------ presets and bad input


def test_aero_table_and_overrides():
    assert parse_aero(None) is PAPER and PAPER.is_paper
    r = parse_aero({"model": "realistic", "downwash": False, "motor_tau": 0.02})
    assert r.ground and r.ground_effect and not r.downwash and r.motor_tau == 0.02
    for bad in ({"model": "wind"}, {"ground": 1}, {"motor_tau": -0.1}, {"tau": 0.1}):
        with pytest.raises(UserError):
            parse_aero(bad)
    sc = load_scenario("circle")
    assert sc.aero.is_paper
    with pytest.raises(UserError, match="aero.motor_tau"):  # shorter than the physics step
        parse_scenario(dict(sc.raw, aero={"motor_tau": 0.001}), "<t>")
    data = dict(sc.raw, aero={"model": "realistic", "ground_effect": False})
    sc2 = parse_scenario(data, "<t>")
    sc3 = with_aero(sc2, "paper")  # --aero keeps the scenario's own overrides
    assert sc3.aero.model == "paper" and not sc3.aero.ground_effect and not sc3.aero.ground


def test_ground_contacts_monitor_ignores_resting_start():
    """Drones resting at the start are not touchdowns; the monitor reads contacts from MuJoCo."""
    cfg = preset("realistic")
    sim = _sim(rest_positions(np.array([[0.0, 0, 0], [2.0, 0, 0]])), cfg=cfg, T=0.01)
    mon = next(m for m in sim.monitors if isinstance(m, GroundContacts))
    sim.step(np.zeros((2, 4)))
    assert mon.in_contact.all() and not mon.airborne.any() and mon.ground_contacts == 0
    assert isinstance(sim.force_stages[1], GroundEffectStage)


def test_tilted_touchdown_is_a_crash_even_when_slow():
    """A drone tilted 40° dropped 3 cm onto its rotor disc's edge: touchdown at ~0.7 m/s (below the
    1 m/s bar) but tilted more than 30°, so a crash."""
    cfg = parse_aero({"ground": True})
    a = np.deg2rad(40.0)
    sim = _sim([[0, 0, 0.2]], cfg=cfg, quats=np.array([[np.cos(a / 2), np.sin(a / 2), 0.0, 0.0]]))
    lowest = 0.25 * np.sin(a) + 0.015 * np.cos(a) - 0.01 * np.cos(a)  # disc edge below the CoM
    for _ in range(50):
        sim.step(np.zeros((1, 4)))
    mon = sim.monitors[0]
    assert mon.ground_contacts == 1 and mon.crashes == 1
    _t, _i, speed, tilt, crash = mon.log[0]
    assert speed == pytest.approx(np.sqrt(2 * P.g * (0.2 - lowest)), rel=0.1) and speed < 1.0
    assert tilt == pytest.approx(40.0, abs=1.0) and crash


def test_compiled_kernels_equal_their_numpy_source():
    """The Numba-compiled stages compute what their plain-Python source computes (SWARM_MJ_NO_JIT=1)."""
    from swarm_mj.physics.aero.downwash import downwash_kernel
    from swarm_mj.physics.aero.ground_effect import ground_effect_kernel
    from swarm_mj.physics.mixing import ROTOR_DIRS

    if not hasattr(downwash_kernel, "py_func"):
        pytest.skip("numba not in use")
    rng = np.random.default_rng(3)
    N = 8
    pos = rng.uniform(-1, 1, (N, 3)) + [0, 0, 1.0]
    quat = rng.normal(size=(N, 4)) * [1, 0.2, 0.2, 1]
    quat /= np.linalg.norm(quat, axis=1, keepdims=True)
    thrust = rng.uniform(0, 2, (N, 4))
    for fn, args in (
        (downwash_kernel, (pos, quat, thrust, 4, 0.25, ROTOR_DIRS["x"], 1.225, 0.09, 0.018, 0.01, 0.09)),
        (ground_effect_kernel, (pos, quat, thrust, 0.25, ROTOR_DIRS["x"], 0.02, 0.09, 0.045)),
    ):
        a = [np.zeros((N, 3)) for _ in range(4)]
        b = [np.zeros((N, 3)) for _ in range(4)]
        fn(*args, *a)
        fn.py_func(*args, *b)
        for x, y in zip(a, b):
            np.testing.assert_allclose(x, y, rtol=1e-12, atol=1e-15)
        assert np.abs(a[0]).max() > 0
