"""Vehicle parameters: paper Table 1 (:data:`swarm_mj.paper.TABLE1_VEHICLE`) plus the rotor
limits of docs/interpretations.md §1."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import UserError
from .paper import TABLE1_VEHICLE as T1


@dataclass(frozen=True)
class QuadParams:
    """Physical parameters of one quadrotor (paper Table 1, docs/interpretations.md §1).

    Units: kg, m, kg·m², N·s/m, N.
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

    def __post_init__(self) -> None:
        for name in ("m", "Ix", "Iy", "Iz", "L", "g"):
            v = getattr(self, name)
            if not np.isfinite(v) or v <= 0:
                raise UserError(f"vehicle parameter {name} must be a positive number, got {v!r}")
        for name in ("Kx", "Ky", "Kz"):
            v = getattr(self, name)
            if not np.isfinite(v) or v < 0:
                raise UserError(f"drag coefficient {name} must be >= 0, got {v!r}")
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


DEFAULT_PARAMS = QuadParams()
