"""Per-step kernels of the environment loop, compiled by Numba when available (see ``_jit``).

Each is a pure function on (n_drones, ...) arrays, written so that the same source runs
as plain numpy.
"""

from __future__ import annotations

import numpy as np

from ._jit import jit
from .state import _body_rates_to_euler_rates, _quat_to_euler


@jit
def observe_kernel(qpos: np.ndarray, qvel: np.ndarray, sensing_range: float):
    """From the free-joint state qpos (n, 7), qvel (n, 6): pos, vel, quat, body rates (copies),
    Euler angles and rates (n, 3), neighbours (n, n, 3) = p_j − p_i within ``sensing_range``
    (zero elsewhere), the mask (n, n) and the 3D distances (n, n) (+inf on the diagonal)."""
    n = qpos.shape[0]
    pos = qpos[:, 0:3].copy()
    quat = qpos[:, 3:7].copy()
    vel = qvel[:, 0:3].copy()
    omega = qvel[:, 3:6].copy()
    rpy = _quat_to_euler(quat)
    rpy_rate = _body_rates_to_euler_rates(rpy, omega)
    rel = np.zeros((n, n, 3))
    mask = np.zeros((n, n))
    dist = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            dx = pos[j, 0] - pos[i, 0]
            dy = pos[j, 1] - pos[i, 1]
            dz = pos[j, 2] - pos[i, 2]
            d = np.sqrt(dx * dx + dy * dy + dz * dz)
            if i == j:
                dist[i, j] = np.inf
                continue
            dist[i, j] = d
            if d < sensing_range:
                mask[i, j] = 1.0
                rel[i, j, 0] = dx
                rel[i, j, 1] = dy
                rel[i, j, 2] = dz
    return pos, vel, quat, omega, rpy, rpy_rate, rel, mask, dist


@jit
def setpoints_kernel(k: int, T: float, leader: np.ndarray, prev_leader: np.ndarray, leader_vel: np.ndarray,
                     ref_pos: np.ndarray, ref_vel: np.ndarray, ref_acc: np.ndarray, ref_yaw: float, D: float,
                     unit_offsets: np.ndarray):
    """The references of the observation (paper §4): the leader's (n = 0) from its trajectory,
    each follower's slot leader + D·offset_k (unit_offsets (n−1, 3)) moving with the leader's
    velocity, estimated as (leader − prev_leader)/T (updated in place in leader_vel (3,), and
    prev_leader (3,) set to leader; at k = 0 the velocity is left as it is). Returns sp, sp_vel,
    sp_acc (n, 3) and the yaw references (n,)."""
    n = unit_offsets.shape[0] + 1
    if k > 0:
        for j in range(3):
            leader_vel[j] = (leader[j] - prev_leader[j]) / T
    for j in range(3):
        prev_leader[j] = leader[j]
    sp = np.empty((n, 3))
    sp_vel = np.empty((n, 3))
    sp_acc = np.zeros((n, 3))
    yaw = np.zeros(n)
    for j in range(3):
        sp[0, j] = ref_pos[j]
        sp_vel[0, j] = ref_vel[j]
        sp_acc[0, j] = ref_acc[j]
    yaw[0] = ref_yaw
    for i in range(1, n):
        for j in range(3):
            sp[i, j] = leader[j] + D * unit_offsets[i - 1, j]
            sp_vel[i, j] = leader_vel[j]
    return sp, sp_vel, sp_acc, yaw


@jit
def react_needed(offset: np.ndarray, h: np.ndarray, safety: float) -> bool:
    """Fig. 5 has work to do: a drone holds an altitude offset (n,), or two drones are closer
    than ``safety`` horizontally (h (n, n))."""
    for x in offset:
        if x != 0.0:
            return True
    for x in h.flat:
        if x < safety:
            return True
    return False


@jit
def merge_rows(steer: np.ndarray, rule_vel: np.ndarray, rule_acc: np.ndarray, vel: np.ndarray, acc: np.ndarray):
    """Copies of vel, acc (n, 3) whose rows where steer (n,) is set come from rule_vel, rule_acc."""
    v = vel.copy()
    a = acc.copy()
    for i in range(steer.shape[0]):
        if steer[i]:
            for j in range(3):
                v[i, j] = rule_vel[i, j]
                a[i, j] = rule_acc[i, j]
    return v, a


@jit
def all_finite(a: np.ndarray) -> bool:
    """True if every entry of a (any shape) is finite."""
    for x in a.flat:
        if not np.isfinite(x):
            return False
    return True


@jit
def horizontal_distances(pos: np.ndarray) -> np.ndarray:
    """Pairwise horizontal distances (n, n) of positions (n, 3), +inf on the diagonal."""
    n = pos.shape[0]
    h = np.empty((n, n))
    for i in range(n):
        h[i, i] = np.inf
        for j in range(i + 1, n):
            dx = pos[j, 0] - pos[i, 0]
            dy = pos[j, 1] - pos[i, 1]
            d = np.sqrt(dx * dx + dy * dy)
            h[i, j] = d
            h[j, i] = d
    return h


@jit
def formation_reward(pos: np.ndarray, setpoint: np.ndarray, dist: np.ndarray, close: float) -> tuple[float, int]:
    """Mean follower distance to its slot and the number of pairs closer than ``close`` (3D)."""
    n = pos.shape[0]
    err = 0.0
    for i in range(1, n):
        dx = pos[i, 0] - setpoint[i, 0]
        dy = pos[i, 1] - setpoint[i, 1]
        dz = pos[i, 2] - setpoint[i, 2]
        err += np.sqrt(dx * dx + dy * dy + dz * dz)
    pairs = 0
    for i in range(n):
        for j in range(i + 1, n):
            if dist[i, j] < close:
                pairs += 1
    return err / max(n - 1, 1), pairs


@jit
def saturate_kernel(U: np.ndarray, unmix_t: np.ndarray, mix_t: np.ndarray, f_min: float, f_max: float,
                    U_out: np.ndarray, F_out: np.ndarray) -> None:
    """Rotor mixing with per-rotor clipping (eqs. 26–29, SPEC §1): F = clip(U·UNMIXᵀ), U_out = F·MIXᵀ."""
    n = U.shape[0]
    for i in range(n):
        for r in range(4):
            f = 0.0
            for c in range(4):
                f += U[i, c] * unmix_t[c, r]
            F_out[i, r] = min(max(f, f_min), f_max)
        for r in range(4):
            u = 0.0
            for c in range(4):
                u += F_out[i, c] * mix_t[c, r]
            U_out[i, r] = u


@jit
def drone_state(qpos: np.ndarray, qvel: np.ndarray, i: int, floor_z: float, max_distance: float) -> int:
    """Drone i of qpos (n, 7), qvel (n, 6): 0 if sane, 1 if non-finite, 2 if below ``floor_z``,
    3 if beyond ``max_distance`` on an axis."""
    for c in range(7):
        if not np.isfinite(qpos[i, c]):
            return 1
    for c in range(6):
        if not np.isfinite(qvel[i, c]):
            return 1
    if qpos[i, 2] < floor_z:
        return 2
    for c in range(3):
        if abs(qpos[i, c]) > max_distance:
            return 3
    return 0


@jit
def state_ok(qpos: np.ndarray, qvel: np.ndarray, floor_z: float, max_distance: float) -> int:
    """0 if the state is sane, else :func:`drone_state`'s code of the first drone that is not."""
    for i in range(qpos.shape[0]):
        code = drone_state(qpos, qvel, i, floor_z, max_distance)
        if code != 0:
            return code
    return 0


@jit
def drag_kernel(vel: np.ndarray, neg_drag: np.ndarray, ext: np.ndarray, out: np.ndarray) -> None:
    """out (n, 3) = −K·v (n, 3) + F_ext (n, 3): linear drag of eq. (1) plus the wind force."""
    n = vel.shape[0]
    for i in range(n):
        for c in range(3):
            out[i, c] = neg_drag[c] * vel[i, c] + ext[i, c]


@jit
def unmix_kernel(U: np.ndarray, unmix_t: np.ndarray, F_out: np.ndarray) -> None:
    """F_out (n, 4) = U (n, 4) · UNMIXᵀ: rotor thrusts F1..F4 of the wrench U1..U4 (eqs. 26–29)."""
    for i in range(U.shape[0]):
        for r in range(4):
            f = 0.0
            for c in range(4):
                f += U[i, c] * unmix_t[c, r]
            F_out[i, r] = f


@jit
def flush_stage_forces(xf: np.ndarray, xtorque: np.ndarray, force: np.ndarray, torque: np.ndarray) -> None:
    """xf (n, 3) += force, xtorque (n, 3) = torque (the force stages' sum of one physics step), then
    force and torque back to zero for the next step."""
    for i in range(force.shape[0]):
        for c in range(3):
            xf[i, c] += force[i, c]
            xtorque[i, c] = torque[i, c]
            force[i, c] = 0.0
            torque[i, c] = 0.0


def warm_up() -> float:
    """Compile (or load from the on-disk cache) every per-step kernel; returns the seconds spent.

    Called before a run's clock starts so that the real-time factor measures simulation,
    not compilation (the first run on a machine compiles for several seconds).
    """
    import time

    from .control.backstepping import _backstepping_kernel
    from .mixing import _MIX_T, _UNMIX_T

    t0 = time.perf_counter()
    n = 2
    qpos = np.zeros((n, 7))
    qpos[:, 3] = 1.0
    qvel = np.zeros((n, 6))
    z3, z1 = np.zeros((n, 3)), np.zeros(n)
    pos, vel, quat, omega, rpy, rpy_rate, rel, mask, dist = observe_kernel(qpos, qvel, 2.0)
    formation_reward(pos, z3, dist, 0.5)
    setpoints_kernel(1, 0.01, pos[0], np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3), 0.0, 1.0,
                     np.zeros((n - 1, 3)))
    all_finite(qpos)
    react_needed(z1, dist, 0.8)
    merge_rows(np.ones(n, dtype=np.bool_), z3, z3, z3, z3)
    all_finite(np.zeros((n, 4)))
    horizontal_distances(pos)
    U = np.zeros((n, 4))
    saturate_kernel(U, _UNMIX_T, _MIX_T, 0.0, 4.5, np.zeros((n, 4)), np.zeros((n, 4)))
    state_ok(qpos, qvel, -0.5, 1e3)
    xfrc = np.zeros((2 * n + 1, 6))
    drag_kernel(vel, np.ones(3), z3, xfrc[1::2, 0:3])
    g = np.ones((n, 3))
    for exact in (True, False):
        for first in (True, False):
            _backstepping_kernel(rpy, rpy_rate, omega, pos, vel, z3, z3, z3, z1, z1, z1, z3, False, g, g, g, g, g,
                                 g, np.ones(3), 0.5, 9.81, np.ones(3), np.ones(3), np.ones(3), 0.25, 0.01,
                                 np.zeros((n, 2)), first, exact, np.zeros((n, 3)))
    z2, b = np.zeros((n, 2)), np.zeros(n, dtype=np.bool_)
    formed_step_kernel(0.01, z3, 1.0, z1, np.zeros(3), z2, z2.copy(), z2.copy(), b, z1.copy(), z1.copy(),
                       z1.copy(), 6.0, 120.0, 15.0, 4.0, 0.5, 9.81, 4.0, 8.0, 1.5, 5.0, z3.copy(), z3.copy(),
                       z3.copy())
    unmix_kernel(U, _UNMIX_T, np.zeros((n, 4)))
    from .aero.downwash import downwash_kernel
    from .aero.ground_effect import ground_effect_kernel

    quat = np.zeros((n, 4))
    quat[:, 0] = 1.0
    f4 = [np.zeros((n, 3)) for _ in range(4)]
    downwash_kernel(pos, quat, np.ones((n, 4)), n, 0.25, 1.225, 0.09, 0.01, 0.01, 0.09, *f4)
    ground_effect_kernel(pos, quat, np.ones((n, 4)), 0.25, 0.02, 0.09, 0.045, *f4)
    flush_stage_forces(xfrc[1::2, 0:3], xfrc[1::2, 3:6], f4[0], f4[1])
    return time.perf_counter() - t0


@jit
def advance_paths_kernel(dt: float, goal: np.ndarray, goal_vel: np.ndarray, p: np.ndarray, v: np.ndarray,
                         a: np.ndarray, blocked: np.ndarray, za: np.ndarray, a_max: float, jerk: float,
                         k_v: float, v_max: float, tan_tilt: float, g: float) -> None:
    """One step of the layered rule's horizontal paths (see LayeredRule._advance_paths), in place:
    p, v, a (n, 2) move towards goal (n, 2) moving at goal_vel (n, 2)."""
    n = p.shape[0]
    lag = 2.0 * a_max / jerk + 1.0 / k_v
    for i in range(n):
        ex = goal[i, 0] - p[i, 0]
        ey = goal[i, 1] - p[i, 1]
        dist = np.sqrt(ex * ex + ey * ey)
        rx = v[i, 0] - goal_vel[i, 0]
        ry = v[i, 1] - goal_vel[i, 1]
        e_eff = max(dist - np.sqrt(rx * rx + ry * ry) * lag, 0.0)
        speed = min(min(v_max, np.sqrt(1.6 * a_max * e_eff)), 3.0 * dist)
        k = speed / max(dist, 1e-9)
        vx = goal_vel[i, 0] + ex * k
        vy = goal_vel[i, 1] + ey * k
        s = min(1.0, v_max / max(np.sqrt(vx * vx + vy * vy), 1e-9))
        vx *= s
        vy *= s
        if blocked[i]:
            vx = 0.0
            vy = 0.0
        a_lim = min(a_max, max(g + za[i], 1.0) * tan_tilt)
        ax = k_v * (vx - v[i, 0])
        ay = k_v * (vy - v[i, 1])
        s = min(1.0, a_lim / max(np.sqrt(ax * ax + ay * ay), 1e-12))
        ax *= s
        ay *= s
        dx = ax - a[i, 0]
        dy = ay - a[i, 1]
        s = min(1.0, jerk * dt / max(np.sqrt(dx * dx + dy * dy), 1e-12))
        a[i, 0] += dx * s
        a[i, 1] += dy * s
        v[i, 0] += a[i, 0] * dt
        v[i, 1] += a[i, 1] * dt
        p[i, 0] += v[i, 0] * dt
        p[i, 1] += v[i, 1] * dt


@jit
def advance_altitude_kernel(dt: float, target: np.ndarray, target_vel: np.ndarray, zp: np.ndarray, zv: np.ndarray,
                            za: np.ndarray, vu: float, au: float, vd: float, ad: float, jerk: float,
                            k_v: float) -> None:
    """One step of the layered rule's altitude paths (see LayeredRule._advance_altitude), in place."""
    n = zp.shape[0]
    lag = (au + ad) / jerk + 1.0 / k_v
    for i in range(n):
        e = target[i] - zp[i]
        up = e >= 0.0
        e_eff = max(abs(e) - abs(zv[i]) * lag, 0.0)
        v_stop = np.sqrt(2.0 * 0.8 * ad * e_eff) if up else np.sqrt(2.0 * 0.8 * au * e_eff)
        speed = min(min(vu if up else vd, v_stop), 4.0 * abs(e))
        sgn = 1.0 if e > 0.0 else (-1.0 if e < 0.0 else 0.0)
        v_des = min(max(target_vel[i] + sgn * speed, -vd), vu)
        a_des = min(max(k_v * (v_des - zv[i]), -ad), au)
        za[i] += min(max(a_des - za[i], -jerk * dt), jerk * dt)
        zv[i] += za[i] * dt
        zp[i] += zv[i] * dt


@jit
def formed_step_kernel(dt: float, pos_d: np.ndarray, formation_alt: float, offset: np.ndarray,
                       lead_vel: np.ndarray, p: np.ndarray, v: np.ndarray, a: np.ndarray, blocked: np.ndarray,
                       zp: np.ndarray, zv: np.ndarray, za: np.ndarray, a_max: float, jerk: float, k_v: float,
                       v_max: float, tan_tilt: float, g: float, vu: float, au: float, vd: float, ad: float,
                       out_pos: np.ndarray, out_vel: np.ndarray, out_acc: np.ndarray) -> None:
    """The layered rule once every follower is formed (LayeredRule._update_formed), after the
    reactive rule has set the altitude offsets (n,): the horizontal paths p, v, a (n, 2) follow
    the slots pos_d[:, :2] moving at the leader's velocity lead_vel (3,), the altitude paths
    zp, zv, za (n,) follow formation_alt + offset; writes the followers' references into
    out_pos (from pos_d), out_vel, out_acc (n, 3) (the leader's row: pos_d, zero, zero)."""
    n = pos_d.shape[0]
    blocked[:] = False
    if dt > 0.0:
        goal = np.empty((n, 2))
        goal_vel = np.empty((n, 2))
        z_target = np.empty(n)
        z_target_vel = np.empty(n)
        for i in range(n):
            goal[i, 0] = pos_d[i, 0]
            goal[i, 1] = pos_d[i, 1]
            goal_vel[i, 0] = lead_vel[0]
            goal_vel[i, 1] = lead_vel[1]
            z_target[i] = formation_alt + offset[i]
            z_target_vel[i] = lead_vel[2]
        advance_paths_kernel(dt, goal, goal_vel, p, v, a, blocked, za, a_max, jerk, k_v, v_max, tan_tilt, g)
        advance_altitude_kernel(dt, z_target, z_target_vel, zp, zv, za, vu, au, vd, ad, jerk, k_v)
    else:
        a[:] = 0.0
        za[:] = 0.0
    for j in range(3):
        out_pos[0, j] = pos_d[0, j]
        out_vel[0, j] = 0.0
        out_acc[0, j] = 0.0
    for i in range(1, n):
        out_pos[i, 0] = p[i, 0]
        out_pos[i, 1] = p[i, 1]
        out_pos[i, 2] = zp[i]
        out_vel[i, 0] = v[i, 0]
        out_vel[i, 1] = v[i, 1]
        out_vel[i, 2] = zv[i]
        out_acc[i, 0] = a[i, 0]
        out_acc[i, 1] = a[i, 1]
        out_acc[i, 2] = za[i]
