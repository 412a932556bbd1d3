"""Predicted downwash force on a lower drone from the logged states (docs/validation.md, "Models").

* ``jet``: swarm_mj.physics.aero.downwash's turbulent round jet (Bauersfeld et al. 2024) with its five-plate
  drag force (docs/aero.md), evaluated with the module's pure functions from the upper drone's
  position, thrust axis and produced thrust, on the lower drone's four rotor discs and hub;
* ``gym``: gym-pybullet-drones' empirical downwash (BaseAviary._downwash):
  F_z = −α exp(−½ (Δxy / β)²), α = c1 (R / (4 Δz))², β = c2 Δz + c3, for Δz > 0 (and Δxy < 10 m);
* ``none``: Fa = 0.

Each returns the world-frame force in newtons, (k, 3) for k samples.
"""

from __future__ import annotations

import numpy as np

from ..physics.aero.constants import AIR_DENSITY, DISC_DRAG_COEFFICIENT
from ..physics.aero.downwash import hover_induced_velocity, jet_speed, plate_force
from ..vehicles import Vehicle
from .flight import rotation_z_axis


def body_axes(q: np.ndarray) -> np.ndarray:
    """(k, 3, 3) rows = body x, y, z axes in the world frame, for quaternions q (k, 4) = (x, y, z, w)."""
    x, y, z, w = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    ex = np.stack([1 - 2 * (y * y + z * z), 2 * (x * y + w * z), 2 * (x * z - w * y)], axis=1)
    ey = np.stack([2 * (x * y - w * z), 1 - 2 * (x * x + z * z), 2 * (y * z + w * x)], axis=1)
    return np.stack([ex, ey, rotation_z_axis(q)], axis=1)


def rotor_offsets(q: np.ndarray, arm: float, layout: str) -> np.ndarray:
    """(k, 4, 3) world-frame offsets from the centre of mass to the four rotor centres: "+" puts them
    on the body axes (docs/aero.md's drone), "x" at 45° between them (the Crazyflie)."""
    ang = np.deg2rad([45.0, 135.0, 225.0, 315.0] if layout == "x" else [0.0, 90.0, 180.0, 270.0])
    ax = body_axes(q)
    dirs = np.cos(ang)[None, :, None] * ax[:, None, 0, :] + np.sin(ang)[None, :, None] * ax[:, None, 1, :]
    return arm * dirs


def jet_force(
    src_pos: np.ndarray,
    src_axis: np.ndarray,
    src_thrust_n: np.ndarray,
    src: Vehicle,
    dst_pos: np.ndarray,
    dst_quat: np.ndarray,
    dst: Vehicle,
    hub_area: float,
    layout: str = "x",
) -> np.ndarray:
    """(k, 3) push (N) of the jet of a source drone on a lower drone (docs/aero.md, "Downwash"):
    Σ over the lower drone's plates (four rotor discs π R², the hub) of ½ ρ C_D A U(s, r)² along the
    jet's direction −src_axis, U the jet speed at the plate's depth s below the source and distance r
    from its axis, U_H from the source's thrust and rotors, l = 2 × its arm."""
    d = -src_axis / np.linalg.norm(src_axis, axis=1, keepdims=True)
    u_h = hover_induced_velocity(src_thrust_n, AIR_DENSITY, src.rotor_radius)
    l = 2.0 * src.arm_length
    offs = rotor_offsets(dst_quat, dst.arm_length, layout)
    plates = np.concatenate([offs, np.zeros((len(dst_pos), 1, 3))], axis=1)  # (k, 5, 3)
    areas = np.array([np.pi * dst.rotor_radius**2] * 4 + [hub_area])
    rel = dst_pos[:, None, :] + plates - src_pos[:, None, :]
    s = np.einsum("kpc,kc->kp", rel, d)
    perp = rel - s[..., None] * d[:, None, :]
    r = np.linalg.norm(perp, axis=2)
    u = jet_speed(s, r, u_h[:, None], l, ramp=src.rotor_radius)
    f = (plate_force(u, 1.0, AIR_DENSITY, DISC_DRAG_COEFFICIENT) * areas[None, :]).sum(axis=1)
    return f[:, None] * d


def gym_force(
    src_pos: np.ndarray, dst_pos: np.ndarray, prop_radius: float, coeffs: tuple[float, float, float]
) -> np.ndarray:
    """(k, 3) gym-pybullet-drones' downwash (N) of a drone at src_pos on one at dst_pos (module
    docstring); at β = 0 (Δz = −c3/c2) the Gaussian's limit: 1 right below, 0 elsewhere."""
    c1, c2, c3 = coeffs
    dz = src_pos[:, 2] - dst_pos[:, 2]
    dxy = np.linalg.norm(src_pos[:, :2] - dst_pos[:, :2], axis=1)
    on = (dz > 0) & (dxy < 10.0)
    safe_dz = np.where(on, dz, 1.0)
    alpha = c1 * (prop_radius / (4.0 * safe_dz)) ** 2
    beta = c2 * safe_dz + c3
    with np.errstate(divide="ignore", invalid="ignore"):
        g = np.where(
            beta != 0.0, np.exp(-0.5 * (dxy / np.where(beta != 0.0, beta, 1.0)) ** 2), (dxy == 0).astype(float)
        )
    out = np.zeros((len(dz), 3))
    out[:, 2] = np.where(on, -alpha * g, 0.0)
    return out
