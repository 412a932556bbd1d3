"""What a drone senses, from MuJoCo's free-joint state (the observation of :class:`~swarm_mj.env.SwarmEnv`).

Compiled kernels on (n, ...) arrays (see :mod:`swarm_mj._jit`); the angle conversions are
:mod:`swarm_mj.physics.state`'s.
"""

from __future__ import annotations

import numpy as np

from .._jit import jit
from .state import euler_rates_kernel, quat_to_euler_kernel


def _rest_state(n: int = 2) -> tuple[np.ndarray, np.ndarray]:
    qpos = np.zeros((n, 7))
    qpos[:, 3] = 1.0
    return qpos, np.zeros((n, 6))


def observe_kernel(qpos: np.ndarray, qvel: np.ndarray, sensing_range: float):
    """From the free-joint state qpos (n, 7), qvel (n, 6): pos, vel, quat, body rates (copies),
    Euler angles and rates (n, 3), neighbours (n, n, 3) = p_j − p_i within ``sensing_range``
    (zero elsewhere), the mask (n, n) and the 3D distances (n, n) (+inf on the diagonal)."""
    n = qpos.shape[0]
    pos, vel, quat, omega = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 4)), np.empty((n, 3))
    rpy, rpy_rate, rel, mask, dist = (
        np.empty((n, 3)),
        np.empty((n, 3)),
        np.empty((n, n, 3)),
        np.empty((n, n)),
        np.empty((n, n)),
    )
    observe_kernel_into(qpos, qvel, sensing_range, pos, vel, quat, omega, rpy, rpy_rate, rel, mask, dist)
    return pos, vel, quat, omega, rpy, rpy_rate, rel, mask, dist


@jit
def observe_kernel_into(
    qpos: np.ndarray,
    qvel: np.ndarray,
    sensing_range: float,
    pos: np.ndarray,
    vel: np.ndarray,
    quat: np.ndarray,
    omega: np.ndarray,
    rpy: np.ndarray,
    rpy_rate: np.ndarray,
    rel: np.ndarray,
    mask: np.ndarray,
    dist: np.ndarray,
) -> None:
    """:func:`observe_kernel` into the buffers pos .. dist (the chunk driver's observation; the Euler angles
    and rates come from the compiled kernels' two fresh arrays, copied in)."""
    n = qpos.shape[0]
    for i in range(n):  # loops: a slice copy costs Numba's shape checks to compile
        for j in range(3):
            pos[i, j] = qpos[i, j]
            vel[i, j] = qvel[i, j]
            omega[i, j] = qvel[i, 3 + j]
        for j in range(4):
            quat[i, j] = qpos[i, 3 + j]
    angles = quat_to_euler_kernel(quat)
    rates = euler_rates_kernel(angles, omega)
    for i in range(n):
        for j in range(3):
            rpy[i, j] = angles[i, j]
            rpy_rate[i, j] = rates[i, j]
    rel[:] = 0.0
    mask[:] = 0.0
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


@jit(samples=lambda: [_rest_state()])
def attitude_kernel(qpos: np.ndarray, qvel: np.ndarray):
    """Euler angles rpy (m, 3) and their rates (m, 3) of free-joint states qpos (m, 7), qvel (m, 6)
    (one drone per row, e.g. the tuner's copies)."""
    rpy = quat_to_euler_kernel(qpos[:, 3:7])
    return rpy, euler_rates_kernel(rpy, qvel[:, 3:6])
