"""Downwash between drones: the induced flow below a quadrotor as a turbulent round jet (docs/aero.md).

Flow model: Bauersfeld, Muller, Ziegler, Coletti, Scaramuzza, "Robotics meets Fluid Dynamics:
a Characterization of the Induced Airflow below a Quadrotor as a Turbulent Jet", RA-L 2024
(arXiv:2403.13321). With T the upper drone's thrust, A = 4·π·R² its rotors' total disc area
and l its motor distance (opposite motors, 2L):

    U_H     = sqrt(T / (2 ρ A))                          hover-induced velocity (their eq. 1)
    s* = s/l,  r* = r/l                                   normalisation (their eq. 8)
    U_c(s)  = U_H · B_d / (s* − s0*)                      centreline velocity (their eq. 2)
    r_½(s)  = l · S · (s* − s0*)                          jet half-width (their eq. 6)
    U(s, r) = U_c / (1 + (√2 − 1)·(r / r_½)²)²           radial profile (their eq. 3)

with the far-field fit B_d = 10.11, S = 0.07668, s0* = −5.817 (their eq. 9). s is the depth
below the upper drone's centre of mass along its −z body axis (the jet follows its actual
thrust direction and magnitude), r the distance from that axis. The jet is switched on over
the first rotor radius below the source (a smoothstep of s/R on U), so that two drones at
the same height feel nothing and no force jumps.

Force (ours; the paper gives the flow, not its effect): the lower drone meets the jet with
five flat plates normal to it, drag coefficient C_D = 1.17 (Hoerner's flat disc): its four
rotor discs (area π·R² each, at the rotor centres p_k of its layout, ``QuadParams.rotor_dirs``) and its
hub (area ``QuadParams.body_area``: :data:`BODY_AREA` for the paper's drone, at the centre of mass p):

    F_k = ½ ρ C_D A_k · U(s_k, r_k)² · d        d = the upper drone's −z axis (jet direction)

added over every upper drone, applied where the plate is (so a drone half in a jet is also
tilted): force Σ F_k and torque Σ (p_k − p) × F_k at the centre of mass, world frame. The
lower drone's own motion through the air is the paper's linear drag, left as it is. One function,
:func:`jet_on_drone`, computes one jet's push on one drone: the stage and ``swarm-mj validate downwash``
(:func:`jet_on_samples`) both call it (docs/validation.md).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from ..._jit import jit
from ...pipeline.records import Kinematics
from ._frames import body_axes, rotor_offset
from .constants import AIR_DENSITY, BODY_AREA, DISC_DRAG_COEFFICIENT, ROTOR_RADIUS

if TYPE_CHECKING:
    from ..params import QuadParams

#: Far-field fit of Bauersfeld et al. (2024), their eq. (9).
BD = 10.11
SPREAD = 0.07668
S0 = -5.817
PROFILE_A = math.sqrt(2.0) - 1.0
N_ROTORS = 4


def hover_induced_velocity(
    thrust, rho: float = AIR_DENSITY, rotor_radius: float = ROTOR_RADIUS, n_rotors: int = N_ROTORS
):
    """U_H = sqrt(T / (2 ρ n π R²)) (m/s): momentum theory's induced velocity at thrust T (N)."""
    return np.sqrt(np.maximum(thrust, 0.0) / (2.0 * rho * n_rotors * np.pi * rotor_radius**2))


def centreline_velocity(s, u_h, l):
    """U_c (m/s) at depth s (m) below a drone with hover-induced velocity u_h and motor distance l."""
    return u_h * BD / (np.asarray(s, float) / l - S0)


def half_width(s, l):
    """r_½ (m): the radius at depth s (m) where the jet speed is half the centreline's."""
    return l * SPREAD * (np.asarray(s, float) / l - S0)


def jet_speed(s, r, u_h, l, ramp: float = ROTOR_RADIUS):
    """U(s, r) (m/s): jet speed at depth s (m) below the source and distance r (m) from its axis;
    zero above the source (s <= 0), switched on by a smoothstep over 0 < s < ``ramp``."""
    s = np.asarray(s, float)
    r = np.asarray(r, float)
    a = np.maximum(s / l - S0, 1e-9)
    u = u_h * BD / a / (1.0 + PROFILE_A * (r / (l * SPREAD * a)) ** 2) ** 2
    x = np.clip(s / ramp, 0.0, 1.0)
    return np.where(s > 0.0, u * x * x * (3.0 - 2.0 * x), 0.0)


def plate_force(u, area: float = np.pi * ROTOR_RADIUS**2, rho: float = AIR_DENSITY, cd: float = DISC_DRAG_COEFFICIENT):
    """Magnitude (N) of the jet's push on a plate of ``area`` (default: one rotor disc) in a flow of
    speed u (m/s): ½ ρ C_D A u²."""
    return 0.5 * rho * cd * area * np.asarray(u, float) ** 2


@jit
def induced_velocity(thrust: float, rho: float, rotor_r: float) -> float:
    """U_H (m/s) of a drone of total thrust T (N) > 0 and four rotors of radius rotor_r (m): √(T / (2 ρ A))."""
    area = N_ROTORS * math.pi * rotor_r * rotor_r
    return math.sqrt(thrust / (2.0 * rho * area))


@jit
def jet_on_drone(
    src: np.ndarray,
    dx: float,
    dy: float,
    dz: float,
    u_h: float,
    l: float,
    ramp: float,
    dst: np.ndarray,
    dst_axes: np.ndarray,
    dirs: np.ndarray,
    arm: float,
    half_cda: float,
    half_cda_body: float,
    off: np.ndarray,
    force: np.ndarray,
    torque: np.ndarray,
) -> None:
    """Add to force, torque (3,) the push of one jet on one drone (module docstring): the jet leaves a
    drone at src (3,) along the unit direction (dx, dy, dz), with hover-induced velocity u_h (m/s),
    motor distance l (m) and switch-on depth ramp (m); the drone below is at dst (3,), its body axes
    dst_axes (3, 3) (rows), its rotors at dirs (4, 2) × arm (its layout), its plates' ½ ρ C_D A
    half_cda (a rotor disc) and half_cda_body (the hub). off (3,) is scratch. The one implementation of
    the force: the simulator's stage (:func:`downwash_kernel`) and the validation
    (:func:`jet_on_samples`, ``swarm-mj validate downwash``) both call it."""
    for k in range(N_ROTORS + 1):  # the four rotor discs, then the hub
        if k < N_ROTORS:
            rotor_offset(dst_axes, k, dirs, arm, 0.0, off)
        else:
            off[0] = off[1] = off[2] = 0.0
        rx = dst[0] + off[0] - src[0]
        ry = dst[1] + off[1] - src[1]
        rz = dst[2] + off[2] - src[2]
        s = rx * dx + ry * dy + rz * dz
        if s <= 0.0:
            continue
        px, py, pz = rx - s * dx, ry - s * dy, rz - s * dz
        r2 = px * px + py * py + pz * pz
        a = s / l - S0
        hw = l * SPREAD * a
        q = 1.0 + PROFILE_A * r2 / (hw * hw)
        u = u_h * BD / a / (q * q)
        x = s / ramp
        if x < 1.0:
            u *= x * x * (3.0 - 2.0 * x)
        f = (half_cda if k < N_ROTORS else half_cda_body) * u * u
        fx, fy, fz = f * dx, f * dy, f * dz
        force[0] += fx
        force[1] += fy
        force[2] += fz
        torque[0] += off[1] * fz - off[2] * fy
        torque[1] += off[2] * fx - off[0] * fz
        torque[2] += off[0] * fy - off[1] * fx


@jit
def downwash_kernel(
    pos: np.ndarray,
    quat: np.ndarray,
    rotor_thrust: np.ndarray,
    n_per_copy: int,
    arm: float,
    dirs: np.ndarray,
    rho: float,
    rotor_r: float,
    half_cda: float,
    half_cda_body: float,
    ramp: float,
    force: np.ndarray,
    torque: np.ndarray,
    add_force: np.ndarray,
    add_torque: np.ndarray,
) -> None:
    """Set force, torque (N, 3) to the downwash of every drone on every other drone of its copy, and
    add the same to add_force, add_torque (N, 3) (the simulator's buffers of this physics step).

    pos (N, 3), quat (N, 4) (w, x, y, z), rotor_thrust (N, 4) the produced rotor thrusts; drones
    i and j interact only when i // n_per_copy == j // n_per_copy. The motor distance l = 2·arm;
    dirs (4, 2) the rotors' layout (``QuadParams.rotor_dirs``); half_cda = ½ ρ C_D π R² of a rotor
    disc, half_cda_body = ½ ρ C_D A of the hub (each × the vehicle's downwash gain). Each pair is
    :func:`jet_on_drone`.
    """
    N = pos.shape[0]
    l = 2.0 * arm
    axes = np.empty((N, 3, 3))
    for i in range(N):
        body_axes(quat, i, axes[i])
        for c in range(3):
            force[i, c] = 0.0
            torque[i, c] = 0.0
    off = np.empty(3)
    for i in range(N):
        T = rotor_thrust[i, 0] + rotor_thrust[i, 1] + rotor_thrust[i, 2] + rotor_thrust[i, 3]
        if T <= 0.0:
            continue
        u_h = induced_velocity(T, rho, rotor_r)
        dx, dy, dz = -axes[i, 2, 0], -axes[i, 2, 1], -axes[i, 2, 2]  # jet direction: −z of drone i
        c0 = (i // n_per_copy) * n_per_copy
        for j in range(c0, min(c0 + n_per_copy, N)):
            if j == i:
                continue
            jet_on_drone(
                pos[i], dx, dy, dz, u_h, l, ramp, pos[j], axes[j], dirs, arm, half_cda, half_cda_body, off, force[j],
                torque[j],
            )  # fmt: skip
    for j in range(N):
        for c in range(3):
            add_force[j, c] += force[j, c]
            add_torque[j, c] += torque[j, c]


@jit(inline=True)
def downwash_on(
    i: int,
    pos: np.ndarray,
    quat: np.ndarray,
    rotor_thrust: np.ndarray,
    arm: float,
    dirs: np.ndarray,
    rho: float,
    rotor_r: float,
    half_cda: float,
    half_cda_body: float,
    ramp: float,
    force: np.ndarray,
    torque: np.ndarray,
) -> None:
    """Set force, torque (3,) to the downwash of every other drone on drone ``i`` alone: row i of
    :func:`downwash_kernel` for one copy of N drones (the same pairs, :func:`jet_on_drone`, in the same order:
    the sources by index), at N − 1 pairs instead of N·(N − 1) (a drone's feedforward from its own view needs
    its own row only: swarm_mj.pipeline.period.viewed_feedforward)."""
    N = pos.shape[0]
    l = 2.0 * arm
    dst_axes, src_axes, off = np.empty((3, 3)), np.empty((3, 3)), np.empty(3)
    body_axes(quat, i, dst_axes)
    for c in range(3):
        force[c] = 0.0
        torque[c] = 0.0
    for j in range(N):
        if j == i:
            continue
        T = rotor_thrust[j, 0] + rotor_thrust[j, 1] + rotor_thrust[j, 2] + rotor_thrust[j, 3]
        if T <= 0.0:
            continue
        u_h = induced_velocity(T, rho, rotor_r)
        body_axes(quat, j, src_axes)
        dx, dy, dz = -src_axes[2, 0], -src_axes[2, 1], -src_axes[2, 2]  # jet direction: −z of drone j
        jet_on_drone(pos[j], dx, dy, dz, u_h, l, ramp, pos[i], dst_axes, dirs, arm, half_cda, half_cda_body, off,
                     force, torque)  # fmt: skip


@jit
def jet_on_samples(
    src_pos: np.ndarray,
    src_axis: np.ndarray,
    thrust: np.ndarray,
    src_arm: float,
    src_rotor_r: float,
    rho: float,
    dst_pos: np.ndarray,
    dst_quat: np.ndarray,
    dirs: np.ndarray,
    dst_arm: float,
    half_cda: float,
    half_cda_body: float,
    force: np.ndarray,
) -> None:
    """force (k, 3) = the push of a source drone's jet on a drone below it at each of k samples, by
    :func:`jet_on_drone` (the simulator's arithmetic), for ``swarm-mj validate downwash``: src_pos (k, 3),
    src_axis (k, 3) its thrust axis (body z, any length), thrust (k,) its total thrust (N), src_arm and
    src_rotor_r its arm and rotor radius (m: l = 2·src_arm, U_H from its rotors, the switch-on depth
    its rotor radius, as in the simulator); dst_pos (k, 3), dst_quat (k, 4) (w, x, y, z) the lower
    drone, dirs (4, 2) × dst_arm its rotors, half_cda, half_cda_body its plates (× the source's gain)."""
    k = src_pos.shape[0]
    axes = np.empty((k, 3, 3))
    off = np.empty(3)
    torque = np.empty(3)
    for i in range(k):
        body_axes(dst_quat, i, axes[i])
        for c in range(3):
            force[i, c] = 0.0
        T = thrust[i]
        if T <= 0.0:
            continue
        n = math.sqrt(src_axis[i, 0] ** 2 + src_axis[i, 1] ** 2 + src_axis[i, 2] ** 2)
        jet_on_drone(
            src_pos[i], -src_axis[i, 0] / n, -src_axis[i, 1] / n, -src_axis[i, 2] / n,
            induced_velocity(T, rho, src_rotor_r), 2.0 * src_arm, src_rotor_r, dst_pos[i], axes[i], dirs, dst_arm,
            half_cda, half_cda_body, off, force[i], torque,
        )  # fmt: skip


def plate_coefficients(
    rho: float, drag_coefficient: float, rotor_radius: float, body_area: float, gain: float
) -> tuple[float, float]:
    """(half_cda, half_cda_body): ½ ρ C_D A of a rotor disc (A = π R²) and of the hub (A = body_area),
    each × ``gain`` (x·1.0 == x: the paper's drone unchanged)."""
    half_cda = 0.5 * rho * drag_coefficient * math.pi * rotor_radius**2 * gain
    half_cda_body = 0.5 * rho * drag_coefficient * body_area * gain
    return half_cda, half_cda_body


class DownwashRecord(NamedTuple):
    """:class:`DownwashStage` for a compiled driver (swarm_mj.pipeline.records)."""

    n_per_copy: int  # drones per copy: jets act within a copy only
    arm: float  # L (m)
    dirs: np.ndarray  # (4, 2) rotor centres / L in the body frame (the vehicle's layout)
    rho: float  # air density (kg/m³)
    rotor_radius: float  # m
    half_cda: float  # ½·ρ·C_d·A of a rotor disc
    half_cda_body: float  # ½·ρ·C_d·A of the body
    force: np.ndarray  # (N, 3) this stage's force over the last physics step (N)
    torque: np.ndarray  # (N, 3)


@jit
def downwash_apply(rec: DownwashRecord, kin: Kinematics, force: np.ndarray, torque: np.ndarray) -> None:
    """The downwash stage's step: :func:`downwash_kernel` at the drones' state, added to force, torque (N, 3)."""
    downwash_kernel(
        kin.pos, kin.quat, kin.rotor_thrust, rec.n_per_copy, rec.arm, rec.dirs, rec.rho, rec.rotor_radius,
        rec.half_cda, rec.half_cda_body, rec.rotor_radius, rec.force, rec.torque, force, torque,
    )  # fmt: skip


class DownwashStage:
    """Force stage: the turbulent-jet downwash of every drone on the drones below it (module docstring).

    After each :meth:`apply`, ``force`` and ``torque`` (N, 3) hold what this stage added.
    """

    name = "downwash"

    def __init__(
        self,
        rho: float = AIR_DENSITY,
        rotor_radius: float = ROTOR_RADIUS,
        drag_coefficient: float = DISC_DRAG_COEFFICIENT,
        body_area: float = BODY_AREA,
        gain: float = 1.0,
    ) -> None:
        """``gain``: the upper drone's ``downwash_gain`` (every drone of a run is one vehicle), which
        multiplies the jet's force (and so its torque) on each drone below: it is folded into the
        drag coefficients ½·ρ·C_D·A, ``gain``·F (x·1.0 == x: the paper's drone unchanged)."""
        self.rho = float(rho)
        self.rotor_radius = float(rotor_radius)
        self.gain = float(gain)
        self.half_cda, self.half_cda_body = plate_coefficients(
            self.rho, float(drag_coefficient), self.rotor_radius, float(body_area), self.gain
        )
        self.force = np.zeros((0, 3))
        self.torque = np.zeros((0, 3))

    @classmethod
    def for_vehicle(cls, params: QuadParams) -> DownwashStage:
        """The stage for drones of parameters ``params``: their rotor radius, their hub plate
        (``QuadParams.body_area``: the vehicle file's ``hub_area``, else the paper drone's ``BODY_AREA`` ×
        ``size_scale``², docs/vehicles.md) and their ``downwash_gain`` (docs/validation.md); the arm L and
        the rotor layout are read from the simulator's vehicle at :meth:`reset`."""
        return cls(rotor_radius=params.rotor_radius, body_area=params.body_area, gain=params.downwash_gain)

    def reset(self, sim) -> None:
        N = sim.pos.shape[0]
        self.n_per_copy = int(sim.n)
        self.arm = float(sim.params.L)
        self.dirs = sim.params.rotor_dirs
        self.force = np.zeros((N, 3))
        self.torque = np.zeros((N, 3))
        self._record = DownwashRecord(
            n_per_copy=self.n_per_copy,
            arm=self.arm,
            dirs=self.dirs,
            rho=self.rho,
            rotor_radius=self.rotor_radius,
            half_cda=self.half_cda,
            half_cda_body=self.half_cda_body,
            force=self.force,
            torque=self.torque,
        )

    def reset_rows(self, sim, rows: np.ndarray) -> None:  # noqa: ANN001 - swarm_mj.physics.sim.Sim
        """As :meth:`reset` for the drones of ``rows`` (N,) bool (:meth:`~swarm_mj.physics.sim.Sim.reset_copies`)."""
        self.force[rows] = 0.0
        self.torque[rows] = 0.0

    def record(self) -> DownwashRecord:
        """This stage for a compiled driver (valid until the next :meth:`reset`)."""
        return self._record

    def apply(self, sim, force: np.ndarray, torque: np.ndarray) -> None:
        downwash_apply(self._record, sim.kinematics, force, torque)
