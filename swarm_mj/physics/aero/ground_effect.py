"""Ground effect: Cheeseman–Bennett thrust gain of each rotor near the floor (docs/aero.md).

Cheeseman & Bennett, "The effect of the ground on a helicopter rotor in forward flight",
ARC R&M 3021 (1955), hover case (method of images):

    T_IGE / T_OGE = 1 / (1 − (R / (4 z))²)

with R the rotor radius and z the height of the rotor's centre above the floor (z = 0).
The formula diverges at z = R/4; like peer simulators we clip the height, here at
z ≥ R/2 (:data:`Z_CLIP_FRACTION`·R), which caps the gain at 4/3 (the largest gain measured
for small propellers close to the ground is of that order). Each rotor k of each drone
adds ΔF_k = (T_IGE/T_OGE − 1)·F_k along the drone's body z axis at the rotor's centre
(force and torque at the centre of mass, world frame), F_k the produced rotor thrust.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..._jit import jit
from ...pipeline.records import Kinematics
from ._frames import body_axes, rotor_offset
from .constants import ROTOR_PLANE_Z, ROTOR_RADIUS

#: Heights below Z_CLIP_FRACTION · R are clipped to it (gain cap 1 / (1 − 1/4) = 4/3).
Z_CLIP_FRACTION = 0.5


def ground_effect_factor(z, rotor_radius: float = ROTOR_RADIUS, clip_fraction: float = Z_CLIP_FRACTION):
    """T_IGE / T_OGE at rotor height z (m) above the floor: Cheeseman–Bennett with the height clipped."""
    zc = np.maximum(np.asarray(z, float), clip_fraction * rotor_radius)
    return 1.0 / (1.0 - (rotor_radius / (4.0 * zc)) ** 2)


@jit
def ground_effect_kernel(
    pos: np.ndarray,
    quat: np.ndarray,
    rotor_thrust: np.ndarray,
    arm: float,
    dirs: np.ndarray,
    rotor_z: float,
    rotor_r: float,
    z_clip: float,
    force: np.ndarray,
    torque: np.ndarray,
    add_force: np.ndarray,
    add_torque: np.ndarray,
) -> None:
    """Set force, torque (N, 3) to the ground-effect gain of every rotor of every drone, and add the
    same to add_force, add_torque (N, 3) (the simulator's buffers of this physics step).

    pos (N, 3), quat (N, 4) (w, x, y, z), rotor_thrust (N, 4) produced rotor thrusts F1..F4, at
    dirs (4, 2) × arm in the body frame (the vehicle's layout, ``QuadParams.rotor_dirs``).
    """
    N = pos.shape[0]
    axes = np.empty((3, 3))
    off = np.empty(3)
    for j in range(N):
        body_axes(quat, j, axes)
        fx = fy = fz = tx = ty = tz = 0.0
        for k in range(4):
            rotor_offset(axes, k, dirs, arm, rotor_z, off)
            z = pos[j, 2] + off[2]
            z = max(z, z_clip)
            ratio = rotor_r / (4.0 * z)
            dF = (1.0 / (1.0 - ratio * ratio) - 1.0) * rotor_thrust[j, k]
            ax, ay, az = dF * axes[2, 0], dF * axes[2, 1], dF * axes[2, 2]
            fx += ax
            fy += ay
            fz += az
            tx += off[1] * az - off[2] * ay
            ty += off[2] * ax - off[0] * az
            tz += off[0] * ay - off[1] * ax
        force[j, 0] = fx
        force[j, 1] = fy
        force[j, 2] = fz
        torque[j, 0] = tx
        torque[j, 1] = ty
        torque[j, 2] = tz
        add_force[j, 0] += fx
        add_force[j, 1] += fy
        add_force[j, 2] += fz
        add_torque[j, 0] += tx
        add_torque[j, 1] += ty
        add_torque[j, 2] += tz


class GroundEffectRecord(NamedTuple):
    """:class:`GroundEffectStage` for a compiled driver (swarm_mj.pipeline.records)."""

    arm: float  # L (m)
    dirs: np.ndarray  # (4, 2) rotor centres / L in the body frame (the vehicle's layout)
    rotor_z: float  # rotor plane above the centre of mass (m)
    rotor_radius: float  # m
    z_clip: float  # smallest rotor height the factor is evaluated at (m)
    force: np.ndarray  # (N, 3) this stage's force over the last physics step (N)
    torque: np.ndarray  # (N, 3)


@jit
def ground_effect_apply(rec: GroundEffectRecord, kin: Kinematics, force: np.ndarray, torque: np.ndarray) -> None:
    """The ground-effect stage's step: :func:`ground_effect_kernel` at the drones' state, added to force, torque."""
    ground_effect_kernel(
        kin.pos, kin.quat, kin.rotor_thrust, rec.arm, rec.dirs, rec.rotor_z, rec.rotor_radius, rec.z_clip, rec.force,
        rec.torque, force, torque,
    )  # fmt: skip


class GroundEffectStage:
    """Force stage: Cheeseman–Bennett ground effect on every rotor (module docstring).

    After each :meth:`apply`, ``force`` and ``torque`` (N, 3) hold what this stage added.
    """

    name = "ground_effect"

    def __init__(
        self, rotor_radius: float = ROTOR_RADIUS, rotor_z: float = ROTOR_PLANE_Z, clip_fraction: float = Z_CLIP_FRACTION
    ) -> None:
        self.rotor_radius = float(rotor_radius)
        self.rotor_z = float(rotor_z)
        self.z_clip = float(clip_fraction) * self.rotor_radius
        self.force = np.zeros((0, 3))
        self.torque = np.zeros((0, 3))

    def reset(self, sim) -> None:
        N = sim.pos.shape[0]
        self.arm = float(sim.params.L)
        self.dirs = sim.params.rotor_dirs
        self.force = np.zeros((N, 3))
        self.torque = np.zeros((N, 3))
        self._record = GroundEffectRecord(
            arm=self.arm,
            dirs=self.dirs,
            rotor_z=self.rotor_z,
            rotor_radius=self.rotor_radius,
            z_clip=self.z_clip,
            force=self.force,
            torque=self.torque,
        )

    def reset_rows(self, sim, rows: np.ndarray) -> None:  # noqa: ANN001 - swarm_mj.physics.sim.Sim
        """As :meth:`reset` for the drones of ``rows`` (N,) bool (:meth:`~swarm_mj.physics.sim.Sim.reset_copies`)."""
        self.force[rows] = 0.0
        self.torque[rows] = 0.0

    def record(self) -> GroundEffectRecord:
        """This stage for a compiled driver (valid until the next :meth:`reset`)."""
        return self._record

    def apply(self, sim, force: np.ndarray, torque: np.ndarray) -> None:
        ground_effect_apply(self._record, sim.kinematics, force, torque)
