"""Predicted downwash force on a lower drone from the logged states (docs/validation.md, "Models").

* ``jet``: the simulator's own downwash, :func:`swarm_mj.physics.aero.downwash.jet_on_drone` (the
  arithmetic :class:`~swarm_mj.physics.aero.downwash.DownwashStage` applies), called through
  :func:`~swarm_mj.physics.aero.downwash.jet_on_samples`: the turbulent round jet (Bauersfeld et al.
  2024) of the upper drone from its position, thrust axis and produced thrust, on the lower drone's
  plates as the simulator builds them from its vehicle file (four rotor discs at its layout's rotor
  centres, its hub ``QuadParams.body_area``), × the upper vehicle's ``downwash_gain``;
* ``gym``: gym-pybullet-drones' empirical downwash (BaseAviary._downwash):
  F_z = −α exp(−½ (Δxy / β)²), α = c1 (R / (4 Δz))², β = c2 Δz + c3, for Δz > 0 (and Δxy < 10 m);
* ``none``: Fa = 0.

Each returns the world-frame force in newtons, (k, 3) for k samples.
"""

from __future__ import annotations

import numpy as np

from ..physics.aero.constants import AIR_DENSITY, DISC_DRAG_COEFFICIENT
from ..physics.aero.downwash import jet_on_samples, plate_coefficients
from ..physics.params import QuadParams
from ..vehicles import Vehicle


def plates(vehicle: Vehicle) -> QuadParams:
    """The parameters of the plates the simulator gives a drone of ``vehicle`` (its arm, rotor radius,
    ``layout``, ``hub_area`` and ``downwash_gain``; ``QuadParams.rotor_dirs`` and ``body_area`` read them
    as the simulator does). Only these fields are the vehicle's: a vehicle file of the validation needs no
    inertia, drag or thrust (the other fields are left at the paper drone's)."""
    return QuadParams(
        L=vehicle.arm_length,
        rotor_radius=vehicle.rotor_radius,
        layout=vehicle.layout,
        hub_area=vehicle.hub_area,
        downwash_gain=vehicle.downwash_gain,
    )


def jet_force(
    src_pos: np.ndarray,
    src_axis: np.ndarray,
    src_thrust_n: np.ndarray,
    src: Vehicle,
    dst_pos: np.ndarray,
    dst_quat: np.ndarray,
    dst: Vehicle,
) -> np.ndarray:
    """(k, 3) push (N) of the jet of a source drone (vehicle ``src``) on a lower drone (vehicle ``dst``) at
    k samples: src_pos (k, 3), src_axis (k, 3) its thrust axis, src_thrust_n (k,) its produced thrust (N);
    dst_pos (k, 3), dst_quat (k, 4) (x, y, z, w, the logs' order). The simulator's force (module
    docstring): the lower drone's plates of :func:`plates`, ½ ρ C_D A each, × the source's ``downwash_gain``."""
    up, lo = plates(src), plates(dst)
    half_cda, half_cda_body = plate_coefficients(
        AIR_DENSITY, DISC_DRAG_COEFFICIENT, lo.rotor_radius, lo.body_area, up.downwash_gain
    )
    c = np.ascontiguousarray
    out = np.empty((len(dst_pos), 3))
    jet_on_samples(
        c(src_pos, dtype=float), c(src_axis, dtype=float), c(src_thrust_n, dtype=float), up.L, up.rotor_radius,
        AIR_DENSITY, c(dst_pos, dtype=float), c(np.asarray(dst_quat, float)[:, [3, 0, 1, 2]]), lo.rotor_dirs, lo.L,
        half_cda, half_cda_body, out,
    )  # fmt: skip
    return out


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
