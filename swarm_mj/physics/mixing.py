"""Rotor mixing of paper eqs. (26)–(29) with per-rotor saturation (docs/interpretations.md §1), and the
rotor layouts ("+" the paper's, "x" the Crazyflie's; docs/vehicles.md, "Rotor layout").

"+" (the paper): U1 = F1 + F2 + F3 + F4, U2 = F3 − F1, U3 = F4 − F2, U4 = F1 − F2 + F3 − F4.

"x" (rotors at 45° to the body axes, numbered as crazyflie-firmware's power_distribution_quadrotor.c:
1 front right, 2 back right, 3 back left, 4 front left), with c = 1/√2 (per-axis moment arm c·L):
U2 = c·(−F1 − F2 + F3 + F4), U3 = c·(−F1 + F2 + F3 − F4), U4 = −F1 + F2 − F3 + F4. U2, U3 stay "roll,
pitch torque / L" and U4 "yaw torque / L" (eq. 1), so the controller is the same for both layouts.
"""

from __future__ import annotations

import numpy as np

from .._jit import jit

# U = F @ MIX.T   (rows: U1..U4, columns: F1..F4)
MIX = np.array(
    [
        [1.0, 1.0, 1.0, 1.0],
        [-1.0, 0.0, 1.0, 0.0],
        [0.0, -1.0, 0.0, 1.0],
        [1.0, -1.0, 1.0, -1.0],
    ]
)
UNMIX = np.linalg.inv(MIX)
#: (4, 4) UNMIX.T, C-contiguous: F = U @ UNMIX_T
UNMIX_T = np.ascontiguousarray(UNMIX.T)
#: (4, 4) MIX.T, C-contiguous: U = F @ MIX_T
MIX_T = np.ascontiguousarray(MIX.T)

#: The rotor layouts a vehicle may have (``QuadParams.layout``).
LAYOUTS = ("+", "x")
_C = 1.0 / np.sqrt(2.0)
#: "x" mixing (module docstring): U = F @ MIX_X.T; the firmware's per-axis arm 0.707·ARM_LENGTH is c·L.
MIX_X = np.array(
    [
        [1.0, 1.0, 1.0, 1.0],
        [-_C, -_C, _C, _C],
        [-_C, _C, _C, -_C],
        [-1.0, 1.0, -1.0, 1.0],
    ]
)
#: Rotor centres F1..F4 in the body frame divided by the arm length L, per layout, (4, 2) each:
#: "+" rotor 1 at (0, −L), 2 at (+L, 0), 3 at (0, +L), 4 at (−L, 0) (assets/quadrotor.xml);
#: "x" rotor 1 at (c, −c)·L, 2 at (−c, −c)·L, 3 at (−c, c)·L, 4 at (c, c)·L.
ROTOR_DIRS = {
    "+": np.array([[0.0, -1.0], [1.0, 0.0], [0.0, 1.0], [-1.0, 0.0]]),
    "x": np.array([[_C, -_C], [-_C, -_C], [-_C, _C], [_C, _C]]),
}


#: The controller's ``[controller] mixer`` choices (:attr:`swarm_mj.scenario.Scenario.mixer_flown`).
MIXERS = ("auto", "clip", "attitude_priority", "yaw_last")


def u_to_rotor(U: np.ndarray) -> np.ndarray:
    """Rotor thrusts F1..F4 (…, 4) that produce U1..U4 (…, 4): inverse of eqs. (26)–(29)."""
    return U @ UNMIX_T


def rotor_to_u(F: np.ndarray) -> np.ndarray:
    """U1..U4 (…, 4) from rotor thrusts F1..F4 (…, 4): eqs. (26)–(29)."""
    return F @ MIX_T


def _saturate_samples():
    z = np.zeros((2, 4))
    return [(z, UNMIX_T, MIX_T, 0.0, 4.5, z.copy(), z.copy())]


@jit(samples=_saturate_samples)
def saturate_kernel(
    U: np.ndarray,
    unmix_t: np.ndarray,
    mix_t: np.ndarray,
    f_min: float,
    f_max: float,
    U_out: np.ndarray,
    F_out: np.ndarray,
) -> None:
    """Rotor mixing with per-rotor clipping (eqs. 26–29, docs/interpretations.md §1):
    F_out (n, 4) = clip(U (n, 4)·UNMIXᵀ, f_min, f_max), U_out (n, 4) = F_out·MIXᵀ."""
    n = U.shape[0]
    for i in range(n):
        for r in range(4):
            f = 0.0
            for c in range(4):
                f += U[i, c] * unmix_t[c, r]
            F_out[i, r] = min(max(f, f_min), f_max)
        for r in range(4):
            u = 0.0
            for c in range(4):
                u += F_out[i, c] * mix_t[c, r]
            U_out[i, r] = u


def saturate(
    U: np.ndarray, f_min: float, f_max: float, unmix_t: np.ndarray = UNMIX_T, mix_t: np.ndarray = MIX_T
) -> tuple[np.ndarray, np.ndarray]:
    """Map commanded U (n, 4) to rotors, clip each rotor to [f_min, f_max], map back.

    Returns (U_applied (n, 4), F (n, 4)): the wrench the motors can deliver and the rotor thrusts.
    The arithmetic is :func:`saturate_kernel`, the one the simulator runs; ``unmix_t``/``mix_t``
    are a vehicle's (:attr:`swarm_mj.physics.params.QuadParams.unmix_t`), the paper's by default.
    """
    U = np.ascontiguousarray(U, dtype=np.float64)
    U_out, F = np.empty_like(U), np.empty_like(U)
    saturate_kernel(U, unmix_t, mix_t, float(f_min), float(f_max), U_out, F)
    return U_out, F


@jit(inline=True)
def _collective_shift(lo: float, hi: float, f_min: float, f_max: float) -> float:
    """The shift of all four rotors, as small as it can be, that brings the lowest ``lo`` and the
    highest ``hi`` into [f_min, f_max] as far as they fit (0 where they already do)."""
    if lo < f_min:
        return min(f_min - lo, max(f_max - hi, 0.0))
    if hi > f_max:
        return -min(hi - f_max, max(lo - f_min, 0.0))
    return 0.0


@jit(inline=True)
def _remix(F: np.ndarray, shift: float, mix_t: np.ndarray, out: np.ndarray, i: int) -> None:
    """Row i of out (n, 4) = U of the rotor thrusts F (4,) each moved by ``shift``."""
    for r in range(4):
        u = 0.0
        for c in range(4):
            u += (F[c] + shift) * mix_t[c, r]
        out[i, r] = u


def _mixer_samples():
    """Warm-up arguments of the two desaturating mixers (same signature)."""
    return [(np.zeros((2, 4)), UNMIX_T, MIX_T, 0.0, 4.5, np.zeros((2, 4)))]


@jit(samples=_mixer_samples)
def attitude_priority_kernel(
    U: np.ndarray, unmix_t: np.ndarray, mix_t: np.ndarray, f_min: float, f_max: float, out: np.ndarray
) -> None:
    """:func:`attitude_priority` for U (n, 4) into out (n, 4): rows that need no shift are copied."""
    n = U.shape[0]
    F = np.empty(4)
    for i in range(n):
        lo = np.inf
        hi = -np.inf
        for r in range(4):
            f = 0.0
            for c in range(4):
                f += U[i, c] * unmix_t[c, r]
            F[r] = f
            lo = min(lo, f)
            hi = max(hi, f)
        shift = _collective_shift(lo, hi, f_min, f_max)
        if shift == 0.0:
            for c in range(4):
                out[i, c] = U[i, c]
            continue
        _remix(F, shift, mix_t, out, i)


def attitude_priority(
    U: np.ndarray, f_min: float, f_max: float, unmix_t: np.ndarray = UNMIX_T, mix_t: np.ndarray = MIX_T
) -> np.ndarray:
    """U1..U4 (n, 4) with the collective thrust U1 moved, as little as needed, so that the torques
    U2..U4 fit the rotors' range [f_min, f_max] (as far as they can): when a rotor would be
    clipped at f_min the other three are raised with it, when one would pass f_max all four are
    lowered. Ours (docs/interpretations.md §1; the "air mode" / desaturation of flight
    controllers such as PX4 and Betaflight); the paper clips each rotor on its own (eqs. 26–29),
    which at low thrust also clips the torque the attitude loop asked for. At the top of the range
    it is what crazyflie-firmware's ``powerDistributionCap`` does (all four lowered by the excess of
    the highest); at the bottom the firmware raises nothing (it clips each motor at its idle thrust),
    so this is not the firmware's power distribution (docs/vehicles.md). Rotors are still
    clipped afterwards by the simulator (:func:`saturate`). The arithmetic is
    :func:`attitude_priority_kernel`; ``unmix_t``/``mix_t`` are a vehicle's
    (:attr:`swarm_mj.physics.params.QuadParams.unmix_t`), the paper's by default."""
    U = np.ascontiguousarray(U, dtype=np.float64)
    out = np.empty_like(U)
    attitude_priority_kernel(U, unmix_t, mix_t, float(f_min), float(f_max), out)
    return out


@jit(samples=_mixer_samples)
def yaw_last_kernel(
    U: np.ndarray, unmix_t: np.ndarray, mix_t: np.ndarray, f_min: float, f_max: float, out: np.ndarray
) -> None:
    """:func:`yaw_last` for U (n, 4) into out (n, 4): rows that need neither are copied."""
    n = U.shape[0]
    F = np.empty(4)  # the rotors of U1, U2, U3 (no yaw)
    Y = np.empty(4)  # the rotors' share of the yaw U4
    room = f_max - f_min
    for i in range(n):
        for r in range(4):
            f = 0.0
            for c in range(3):
                f += U[i, c] * unmix_t[c, r]
            F[r] = f
            Y[r] = U[i, 3] * unmix_t[3, r]
        # the largest share s of the yaw, 0 ≤ s ≤ 1, whose rotor spread fits the range: for every pair
        # (r, q), F_r − F_q + s·(Y_r − Y_q) ≤ f_max − f_min; none where roll and pitch alone do not fit
        s = 1.0
        for r in range(4):
            for q in range(4):
                dy = Y[r] - Y[q]
                if F[r] - F[q] > room:
                    s = 0.0
                elif dy > 0.0:
                    s = min(s, (room - (F[r] - F[q])) / dy)
        lo = np.inf
        hi = -np.inf
        for r in range(4):
            F[r] += s * Y[r]
            lo = min(lo, F[r])
            hi = max(hi, F[r])
        # then the collective thrust moved, as little as needed, as attitude_priority_kernel does
        shift = _collective_shift(lo, hi, f_min, f_max)
        if s == 1.0 and shift == 0.0:  # it fits: copied, as attitude_priority_kernel copies
            for c in range(4):
                out[i, c] = U[i, c]
            continue
        _remix(F, shift, mix_t, out, i)


def yaw_last(
    U: np.ndarray, f_min: float, f_max: float, unmix_t: np.ndarray = UNMIX_T, mix_t: np.ndarray = MIX_T
) -> np.ndarray:
    """U1..U4 (n, 4) made to fit the rotors' range [f_min, f_max] in the order roll and pitch, yaw,
    collective thrust: the yaw torque U4 is scaled by the largest factor s, 0 ≤ s ≤ 1, whose rotor
    spread (highest minus lowest rotor) still fits the range (s = 0 where roll and pitch alone do not
    fit), then U1 is moved as :func:`attitude_priority` moves it. A command that fits is returned
    unchanged, and U2, U3 are never changed. PX4's multicopter mixer gives up yaw first in the same
    order (roll and pitch, then yaw, then thrust); ours, for a vehicle whose yaw is dear in rotor
    thrust (docs/vehicles.md, "Mixer": a Crazyflie yaw torque takes d/κ = 4.7 times the thrust
    difference of the same roll torque, d = L/√2 its per-axis arm). The arithmetic is
    :func:`yaw_last_kernel`; ``unmix_t``/``mix_t`` are a vehicle's, the paper's by default."""
    U = np.ascontiguousarray(U, dtype=np.float64)
    out = np.empty_like(U)
    yaw_last_kernel(U, unmix_t, mix_t, float(f_min), float(f_max), out)
    return out
