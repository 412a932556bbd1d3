"""Vehicle parameters: paper Table 1 (:data:`swarm_mj.paper.TABLE1_VEHICLE`) plus the rotor
limits of docs/interpretations.md §1; other vehicles come from vehicle files (docs/vehicles.md,
:func:`swarm_mj.vehicles.load_vehicle` and :meth:`swarm_mj.vehicles.Vehicle.params`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import UserError
from ..paper import TABLE1_VEHICLE as T1
from .aero.constants import BODY_AREA
from .mixing import LAYOUTS, MIX, MIX_T, MIX_X, ROTOR_DIRS, UNMIX_T

#: Rotor radius of the paper's drone (m): docs/interpretations.md §1 (the paper gives none).
PAPER_ROTOR_RADIUS = 0.09


@dataclass(frozen=True)
class QuadParams:
    """Physical parameters of one quadrotor (paper Table 1, docs/interpretations.md §1).

    Units: kg, m, kg·m², N·s/m, N.

    ``rotor_radius`` (m) is the propeller radius; ``collision_radius`` (m, None: ``L``) the radius
    of the disc through the motors that touches other drones (the paper's 2L collision distance,
    §4); ``yaw_coefficient`` κ (m) the rotors' drag-torque-to-thrust ratio: the yaw torque is
    κ·(F1 − F2 + F3 − F4) (docs/vehicles.md); None is the paper's model, yaw torque L·U4 with
    U4 = F1 − F2 + F3 − F4 (eq. 29). The controller's U4 is always "yaw torque / L" (eq. 1), so
    a vehicle with κ maps U to rotor thrusts with :attr:`mix_t` / :attr:`unmix_t`. ``motor_tau``
    (s) is the vehicle's rotor time constant: the lag of a physics preset with lag (``--aero
    realistic``) unless the scenario's ``[aero]`` sets its own (:func:`swarm_mj.physics.aero.presets.vehicle_lag`);
    None (the paper's drone): the preset's. ``downwash_gain`` (dimensionless) multiplies the
    force of this vehicle's jet on the drones below it (the vehicle file's ``downwash_gain``, the
    one ``swarm-mj validate downwash`` checks; 1 for the paper's drone: docs/validation.md).
    ``layout`` is the rotor layout, ``"+"`` (the paper's: rotors on the body axes) or ``"x"`` (rotors
    at 45°, the Crazyflie's; :mod:`swarm_mj.physics.mixing`); ``hub_area`` (m², None: the paper
    drone's hub ``BODY_AREA`` scaled by ``size_scale``²) the plate at the centre that a jet from above
    meets (:attr:`body_area`); ``height`` (m, None: the paper drone's rotor disc scaled by
    ``size_scale``) the height of the colliding body (docs/vehicles.md).
    """

    m: float = T1["m"]
    Ix: float = T1["Ix"]
    Iy: float = T1["Iy"]
    Iz: float = T1["Iz"]
    L: float = T1["L"]
    Kx: float = T1["Kx"]
    Ky: float = T1["Ky"]
    Kz: float = T1["Kz"]
    g: float = T1["g"]
    f_min: float = 0.0  # per-rotor thrust range (N), docs/interpretations.md §1
    f_max: float = 4.5
    rotor_radius: float = PAPER_ROTOR_RADIUS
    collision_radius: float | None = None
    yaw_coefficient: float | None = None
    motor_tau: float | None = None  # s, the vehicle's rotor time constant (None: the aero preset's)
    downwash_gain: float = 1.0  # on the jet model's force on the drones below (docs/validation.md, "Calibration")
    layout: str = "+"  # rotor layout: "+" (the paper's) or "x"
    hub_area: float | None = None  # m², the hub plate a jet meets (None: BODY_AREA × size_scale²)
    height: float | None = None  # m, the colliding body's height (None: the paper drone's disc, scaled)

    def __post_init__(self) -> None:
        for name in ("m", "Ix", "Iy", "Iz", "L", "g"):
            v = getattr(self, name)
            if not np.isfinite(v) or v <= 0:
                raise UserError(f"vehicle parameter {name} must be a positive number, got {v!r}")
        for name in ("Kx", "Ky", "Kz"):
            v = getattr(self, name)
            if not np.isfinite(v) or v < 0:
                raise UserError(f"drag coefficient {name} must be >= 0, got {v!r}")
        for name in ("rotor_radius", "collision_radius", "yaw_coefficient", "motor_tau", "downwash_gain"):
            v = getattr(self, name)
            if v is not None and (not np.isfinite(v) or v <= 0):
                raise UserError(f"vehicle parameter {name} must be a positive number, got {v!r}")
        for name in ("height",):
            v = getattr(self, name)
            if v is not None and (not np.isfinite(v) or v <= 0):
                raise UserError(f"vehicle parameter {name} must be a positive number, got {v!r}")
        if self.hub_area is not None and (not np.isfinite(self.hub_area) or self.hub_area < 0):
            raise UserError(f"vehicle parameter hub_area must be a number >= 0 (m²), got {self.hub_area!r}")
        if self.layout not in LAYOUTS:
            choices = ", ".join(map(repr, LAYOUTS))
            raise UserError(f"vehicle parameter layout must be one of {choices}, got {self.layout!r}")
        if not (0 <= self.f_min < self.f_max):
            raise UserError(f"rotor thrust range must satisfy 0 <= f_min < f_max, got [{self.f_min}, {self.f_max}]")

    @property
    def inertia(self) -> np.ndarray:
        """Diagonal inertia (Ix, Iy, Iz), shape (3,)."""
        return np.array([self.Ix, self.Iy, self.Iz])

    @property
    def drag(self) -> np.ndarray:
        """World-frame linear drag coefficients (Kx, Ky, Kz), shape (3,)."""
        return np.array([self.Kx, self.Ky, self.Kz])

    @property
    def hover_thrust(self) -> float:
        """U1 that balances gravity: m·g (N)."""
        return self.m * self.g

    @property
    def size_scale(self) -> float:
        """L over the paper's L (1.0 for the paper's drone): the factor by which the drawn parts, the
        landing gear and the rotor plane height of ``assets/quadrotor.xml`` scale (docs/vehicles.md)."""
        return self.L / T1["L"]

    @property
    def rotor_span(self) -> float:
        """Centre to rotor tip, ``L + rotor_radius`` (m)."""
        return self.L + self.rotor_radius

    @property
    def contact_radius(self) -> float:
        """Radius of the colliding disc (m): ``collision_radius``, else L (the paper's)."""
        return self.L if self.collision_radius is None else self.collision_radius

    @property
    def body_area(self) -> float:
        """The hub plate (m²) a jet from above meets at the centre (:mod:`swarm_mj.physics.aero.downwash`):
        ``hub_area``, else the paper drone's ``BODY_AREA`` × ``size_scale``²."""
        s = self.size_scale
        return BODY_AREA * s * s if self.hub_area is None else float(self.hub_area)

    @property
    def rotor_dirs(self) -> np.ndarray:
        """(4, 2) rotor centres F1..F4 in the body frame (x, y) divided by L, of :attr:`layout`
        (:data:`swarm_mj.physics.mixing.ROTOR_DIRS`; the same array for every vehicle of a layout)."""
        return ROTOR_DIRS[self.layout]

    @property
    def mix_t(self) -> np.ndarray:
        """(4, 4) U = F @ mix_t with U2, U3 = roll, pitch torque / L and U4 = yaw torque / L, of the
        vehicle's :attr:`layout` (:mod:`swarm_mj.physics.mixing`). For "+": the paper's
        :data:`~swarm_mj.physics.mixing.MIX_T` (the same array) without ``yaw_coefficient``, else its
        yaw column scaled by κ/L, so that L·U4 = κ·(F1 − F2 + F3 − F4). For "x": ``MIX_X``ᵀ, its yaw
        column scaled by κ/L likewise (L·U4 = κ·(−F1 + F2 − F3 + F4))."""
        if self.layout == "+" and self.yaw_coefficient is None:
            return MIX_T
        mix = (MIX if self.layout == "+" else MIX_X).copy()
        if self.yaw_coefficient is not None:
            mix[3] *= self.yaw_coefficient / self.L
        return np.ascontiguousarray(mix.T)

    @property
    def unmix_t(self) -> np.ndarray:
        """(4, 4) F = U @ unmix_t, the inverse of :attr:`mix_t`
        (:data:`~swarm_mj.physics.mixing.UNMIX_T` for the paper)."""
        if self.layout == "x":
            return np.ascontiguousarray(np.linalg.inv(self.mix_t))
        if self.yaw_coefficient is None:
            return UNMIX_T
        unmix_t = UNMIX_T.copy()  # inv(diag(1, 1, 1, k)·MIX) = inv(MIX)·diag(1, 1, 1, 1/k)
        unmix_t[3] *= self.L / self.yaw_coefficient
        return unmix_t


DEFAULT_PARAMS = QuadParams()
