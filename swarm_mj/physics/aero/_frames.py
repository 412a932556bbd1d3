"""Small compiled helpers shared by the aerodynamic stages: body axes and rotor positions."""

from __future__ import annotations

import numpy as np

from ..._jit import jit


@jit
def body_axes(q: np.ndarray, i: int, out: np.ndarray) -> None:
    """Rows 0, 1, 2 of out (3, 3) = the body x, y, z axes in the world frame of quaternion q[i] (w, x, y, z)."""
    w, x, y, z = q[i, 0], q[i, 1], q[i, 2], q[i, 3]
    nrm = w * w + x * x + y * y + z * z
    s = 2.0 / nrm if nrm > 0.0 else 0.0
    out[0, 0] = 1.0 - s * (y * y + z * z)
    out[0, 1] = s * (x * y + w * z)
    out[0, 2] = s * (x * z - w * y)
    out[1, 0] = s * (x * y - w * z)
    out[1, 1] = 1.0 - s * (x * x + z * z)
    out[1, 2] = s * (y * z + w * x)
    out[2, 0] = s * (x * z + w * y)
    out[2, 1] = s * (y * z - w * x)
    out[2, 2] = 1.0 - s * (x * x + y * y)


@jit
def rotor_offset(axes: np.ndarray, k: int, dirs: np.ndarray, arm: float, rotor_z: float, out: np.ndarray) -> None:
    """out (3,) = world-frame offset from the centre of mass to the centre of rotor k (0..3): dirs (4, 2)
    the rotor centres in the body frame divided by the arm (``QuadParams.rotor_dirs``: the layout,
    :data:`swarm_mj.physics.mixing.ROTOR_DIRS`), arm L (m), rotor_z the rotor plane's height (m)."""
    dx = dirs[k, 0] * arm
    dy = dirs[k, 1] * arm
    for c in range(3):
        out[c] = dx * axes[0, c] + dy * axes[1, c] + rotor_z * axes[2, c]
