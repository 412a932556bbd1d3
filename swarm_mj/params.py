"""Vehicle parameters: paper Table 1 plus the rotor limits of SPEC §1."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import UserError


@dataclass(frozen=True)
class QuadParams:
    """Physical parameters of one quadrotor (paper Table 1, SPEC §1).

    Units: kg, m, kg·m², N·s/m, N.
    """

    m: float = 0.486
    Ix: float = 0.0038
    Iy: float = 0.0038
    Iz: float = 0.0071
    L: float = 0.25
    Kx: float = 0.0056
    Ky: float = 0.0056
    Kz: float = 0.0064
    g: float = 9.81
    f_min: float = 0.0  # per-rotor thrust range (N), SPEC §1
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
