"""Rotor mixing of paper eqs. (26)–(29) with per-rotor saturation (SPEC §1).

U1 = F1 + F2 + F3 + F4, U2 = F3 − F1, U3 = F4 − F2, U4 = F1 − F2 + F3 − F4.
"""

from __future__ import annotations

import numpy as np

# U = F @ MIX.T   (rows: U1..U4, columns: F1..F4)
MIX = np.array([
    [1.0, 1.0, 1.0, 1.0],
    [-1.0, 0.0, 1.0, 0.0],
    [0.0, -1.0, 0.0, 1.0],
    [1.0, -1.0, 1.0, -1.0],
])
UNMIX = np.linalg.inv(MIX)
_UNMIX_T = np.ascontiguousarray(UNMIX.T)
_MIX_T = np.ascontiguousarray(MIX.T)


def u_to_rotor(U: np.ndarray) -> np.ndarray:
    """Rotor thrusts F1..F4 (…, 4) that produce U1..U4 (…, 4): inverse of eqs. (26)–(29)."""
    return U @ _UNMIX_T


def rotor_to_u(F: np.ndarray) -> np.ndarray:
    """U1..U4 (…, 4) from rotor thrusts F1..F4 (…, 4): eqs. (26)–(29)."""
    return F @ _MIX_T


def saturate(U: np.ndarray, f_min: float, f_max: float) -> tuple[np.ndarray, np.ndarray]:
    """Map commanded U (n, 4) to rotors, clip each rotor to [f_min, f_max], map back.

    Returns (U_applied (n, 4), F (n, 4)): the wrench the motors can deliver and the rotor thrusts.
    The arithmetic is :func:`swarm_mj.kernels.saturate_kernel`, the one the simulator runs.
    """
    from .kernels import saturate_kernel

    U = np.ascontiguousarray(U, dtype=np.float64)
    U_out, F = np.empty_like(U), np.empty_like(U)
    saturate_kernel(U, _UNMIX_T, _MIX_T, float(f_min), float(f_max), U_out, F)
    return U_out, F
