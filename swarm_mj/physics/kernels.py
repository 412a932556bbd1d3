"""The simulator's kernels (:class:`swarm_mj.physics.sim.Sim`): the health codes and checks of a state, the
force sums of a physics step (drag, wind, the extra stages' sums, the produced rotor thrusts) and the floor
gate. Each is compiled on its own (:func:`swarm_mj._jit.jit`) and called from Python or from the compiled
period (:mod:`swarm_mj.physics.compiled`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import mujoco
import numpy as np

from .._jit import jit

if TYPE_CHECKING:
    from .world import World

#: Health codes of :meth:`Sim.health` (per copy; 0 = healthy).
HEALTHY, NON_FINITE, BELOW_FLOOR, TOO_FAR, TILTED, MUJOCO_WARNING = 0, 1, 2, 3, 4, 5
HEALTH_NAMES = {
    HEALTHY: "healthy",
    NON_FINITE: "non-finite state",
    BELOW_FLOOR: "below the floor",
    TOO_FAR: "too far",
    TILTED: "tilted too far",
    MUJOCO_WARNING: "MuJoCo divergence warning",
}
#: MuJoCo warnings that mean the simulation diverged (MuJoCo resets MjData on the first three).
DIVERGENCE_WARNINGS = (
    mujoco.mjtWarning.mjWARN_BADQACC,
    mujoco.mjtWarning.mjWARN_BADQPOS,
    mujoco.mjtWarning.mjWARN_BADQVEL,
    mujoco.mjtWarning.mjWARN_BADCTRL,
)
#: Their indices in ``MjData.warning`` (what a compiled kernel reads).
DIVERGENCE_WARNING_IDS = tuple(int(w) for w in DIVERGENCE_WARNINGS)


def _state_samples():
    qpos = np.zeros((2, 7))
    qpos[:, 3] = 1.0
    return qpos, np.zeros((2, 6))


@jit
def drone_state(qpos: np.ndarray, qvel: np.ndarray, i: int, floor_z: float, max_distance: float) -> int:
    """Drone i of qpos (N, 7), qvel (N, 6): 0 if sane, 1 if non-finite, 2 if below ``floor_z``,
    3 if beyond ``max_distance`` on an axis."""
    for c in range(7):
        if not np.isfinite(qpos[i, c]):
            return NON_FINITE
    for c in range(6):
        if not np.isfinite(qvel[i, c]):
            return NON_FINITE
    if qpos[i, 2] < floor_z:
        return BELOW_FLOOR
    for c in range(3):
        if abs(qpos[i, c]) > max_distance:
            return TOO_FAR
    return HEALTHY


@jit
def copy_state(
    qpos: np.ndarray, qvel: np.ndarray, c: int, n: int, floor_z: float, max_distance: float, max_tilt: float
) -> int:
    """The code of the first unhealthy drone of copy c (rows c·n .. c·n + n − 1 of qpos (N, 7),
    qvel (N, 6)): :func:`drone_state`'s, or TILTED where |roll| or |pitch| > ``max_tilt``; 0 if none."""
    for i in range(c * n, c * n + n):
        code = drone_state(qpos, qvel, i, floor_z, max_distance)
        if code != HEALTHY:
            return code
        if max_tilt < np.inf:
            # roll and pitch of the quaternion (w, x, y, z): the formulas of swarm_mj.physics.state
            w, x, y, z = qpos[i, 3], qpos[i, 4], qpos[i, 5], qpos[i, 6]
            roll = np.arctan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
            pitch = np.arcsin(min(max(2.0 * (w * y - z * x), -1.0), 1.0))
            if not (abs(roll) <= max_tilt and abs(pitch) <= max_tilt):
                return TILTED
    return HEALTHY


@jit(samples=lambda: [(*_state_samples(), 2, -0.5, 1e3, np.inf, np.zeros(1, dtype=np.int8))])
def health_kernel(
    qpos: np.ndarray, qvel: np.ndarray, n: int, floor_z: float, max_distance: float, max_tilt: float, out: np.ndarray
) -> None:
    """The state part of the health mask: out (m,) = :func:`copy_state` of each copy of n drones."""
    for c in range(out.shape[0]):
        out[c] = copy_state(qpos, qvel, c, n, floor_z, max_distance, max_tilt)


@jit(samples=lambda: [(*_state_samples(), 2, 1, -0.5, 1e3, np.inf)])
def first_unhealthy(
    qpos: np.ndarray, qvel: np.ndarray, n: int, m: int, floor_z: float, max_distance: float, max_tilt: float
) -> int:
    """The first nonzero :func:`copy_state` code of the m copies (0: all healthy)."""
    for c in range(m):
        code = copy_state(qpos, qvel, c, n, floor_z, max_distance, max_tilt)
        if code != HEALTHY:
            return code
    return HEALTHY


@jit(samples=lambda: [(np.zeros((2, 3)), np.ones(3), np.zeros((2, 3)), np.zeros((5, 6))[1::2, 0:3])])
def drag_kernel(vel: np.ndarray, neg_drag: np.ndarray, ext: np.ndarray, out: np.ndarray) -> None:
    """out (N, 3) = −K·v (N, 3) + F_ext (N, 3): linear drag of eq. (1) plus the wind force
    (the drag and wind stages fused, when they are the only ones)."""
    n = vel.shape[0]
    for i in range(n):
        for c in range(3):
            out[i, c] = neg_drag[c] * vel[i, c] + ext[i, c]


@jit(samples=lambda: [(np.zeros((5, 6))[1::2, 0:3], np.zeros((5, 6))[1::2, 3:6], np.zeros((2, 3)), np.zeros((2, 3)))])
def flush_stage_forces(xf: np.ndarray, xtorque: np.ndarray, force: np.ndarray, torque: np.ndarray) -> None:
    """xf (N, 3) += force, xtorque (N, 3) = torque (the extra stages' sum of one physics step), then
    force and torque back to zero for the next step."""
    for i in range(force.shape[0]):
        for c in range(3):
            xf[i, c] += force[i, c]
            xtorque[i, c] = torque[i, c]
            force[i, c] = 0.0
            torque[i, c] = 0.0


@jit(samples=lambda: [(np.zeros((2, 4)), np.eye(4), np.zeros((2, 4)))])
def unmix_kernel(U: np.ndarray, unmix_t: np.ndarray, F_out: np.ndarray) -> None:
    """F_out (N, 4) = U (N, 4) · UNMIXᵀ: rotor thrusts F1..F4 of the wrench U1..U4 (eqs. 26–29)."""
    for i in range(U.shape[0]):
        for r in range(4):
            f = 0.0
            for c in range(4):
                f += U[i, c] * unmix_t[c, r]
            F_out[i, r] = f


@jit(samples=lambda: [(np.zeros((2, 3)), np.ones(3), np.zeros((2, 3)))])
def add_drag_kernel(vel: np.ndarray, neg_drag: np.ndarray, force: np.ndarray) -> None:
    """force (N, 3) += −K·v (N, 3): the linear drag of paper eq. (1)."""
    n = vel.shape[0]
    for i in range(n):
        for c in range(3):
            force[i, c] += neg_drag[c] * vel[i, c]


#: The floor gate's clearance (m): the floor is tested for contacts in a control period only when a
#: drone's bounding sphere could come within this of it, falling at its present speed (docs/aero.md,
#: "Cost"). 0.1 m covers an acceleration of 2000 m/s² over a 10-ms period, far beyond any drone's.
FLOOR_GATE_M = 0.1


@jit(samples=lambda: [(*_state_samples(), 0.3, 0.01, np.zeros(3, dtype=np.int32), 0, 4)])
def floor_gate_kernel(
    qpos: np.ndarray, qvel: np.ndarray, z_near: float, horizon: float, contype: np.ndarray, floor_id: int, solid: int
) -> None:
    """The floor gate: ``contype[floor_id]`` (the model's ``geom_contype``) = ``solid`` when a drone of
    qpos (N, 7), qvel (N, 6) could reach the floor within ``horizon`` s, else 0 (no floor pair is
    tested). A drone can reach it when z − |v_z,down|·horizon < ``z_near`` (the floor's top + the
    drones' floor reach + :data:`FLOOR_GATE_M`). With the floor off, MuJoCo finds no floor contact,
    as it would have found none with it on: the contacts, hence the run, are the same bit for bit."""
    near = False
    for i in range(qpos.shape[0]):
        fall = -qvel[i, 2] if qvel[i, 2] < 0.0 else 0.0
        if not qpos[i, 2] - fall * horizon >= z_near:  # NaN: near (the health check reports it)
            near = True
            break
    contype[floor_id] = solid if near else 0


def floor_gate(world: World) -> tuple[int, int, float] | None:
    """(floor geom id, its contype, z_near of :func:`floor_gate_kernel`) for a world whose floor is
    solid, else None. The reach is the largest |geom position| + bounding radius + margin over the
    drones' geoms that can touch the floor (MuJoCo's contype/conaffinity test)."""
    m = world.model
    fid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "floor")
    if fid < 0:
        return None
    ct = int(m.geom_contype[fid])
    if ct == 0 or m.geom_conaffinity[fid] != 0:  # not solid, or solid through what the gate leaves alone
        return None
    level = np.allclose(np.abs(m.geom_quat[fid]), (1.0, 0.0, 0.0, 0.0))
    if m.geom_type[fid] != mujoco.mjtGeom.mjGEOM_PLANE or m.geom_bodyid[fid] != 0 or not level:
        return None
    touch = (world.geom_drone >= 0) & ((m.geom_conaffinity & ct) != 0)
    if not np.isin(m.geom_bodyid[touch], world.body_ids).all():
        return None  # floor-touching geoms on a body other than the drones' free ones
    reach = np.linalg.norm(m.geom_pos[touch], axis=1) + m.geom_rbound[touch] + m.geom_margin[touch]
    if reach.size == 0:
        return None
    return fid, ct, float(m.geom_pos[fid, 2] + reach.max() + FLOOR_GATE_M)
