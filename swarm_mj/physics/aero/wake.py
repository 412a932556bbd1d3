"""A wake that travels: the jet a lower drone meets was emitted earlier (docs/validation.md, "A wake that travels").

The turbulent-jet model of :mod:`swarm_mj.physics.aero.downwash` is a steady flow fixed to the upper drone.
Air leaving the rotors at time t_e moves down the jet at its centreline speed U_c(s) (and sideways
with the wind w), so what is at depth s below the rotors at time t left them at t − τ(s), from where
the drone *was* then:

    τ(s) = ∫₀ˢ ds' / U_c(s') = (s² / (2 l) − s0* s) / (U_H B_d)         (U_c = U_H B_d / (s/l − s0*))

and the wake's axis at depth s passes through p_u(t − τ) + w τ − s d(t − τ) (d the jet direction
then). A drone moving at constant horizontal speed v leaves its wake at depth s a distance v τ(s)
behind it (tests/unit/test_neural_swarm.py checks this analytic case).

The model's range is the published jet's: its fit holds in the far field, beyond about 2.5 motor
distances l below the drone (Bauersfeld et al. 2024); nearer, the four rotors' separate jets have not
merged and the formula is an extrapolation (docs/validation.md reports the validation per depth bin).
"""

from __future__ import annotations

import numpy as np

from .downwash import BD, S0


def transport_time(s: np.ndarray | float, u_h: np.ndarray | float, l: float) -> np.ndarray:
    """τ(s) (s): time for air to travel from the rotors to depth s (m) down the jet's centreline,
    ∫₀ˢ ds'/U_c(s') = (s²/(2 l) − s0* s)/(U_H B_d); 0 for s <= 0 or U_H <= 0 (no jet)."""
    s = np.maximum(np.asarray(s, float), 0.0)
    u_h = np.asarray(u_h, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        tau = (s * s / (2.0 * l) - S0 * s) / (u_h * BD)
    return np.where(u_h > 0.0, tau, 0.0)


def emitted_state(t: np.ndarray, tau: np.ndarray, times: np.ndarray, values: np.ndarray) -> np.ndarray:
    """values (k, c) of a source sampled at ``times`` (k,), interpolated at the emission times t − τ
    (clamped to the first sample): the source's state when the air now at the query left it."""
    te = np.clip(np.asarray(t, float) - np.asarray(tau, float), times[0], times[-1])
    v = np.asarray(values, float)
    if v.ndim == 1:
        return np.interp(te, times, v)
    return np.stack([np.interp(te, times, v[:, c]) for c in range(v.shape[1])], axis=1)


def wake_offset(t: np.ndarray, tau: np.ndarray, wind: np.ndarray | None = None) -> np.ndarray:
    """(k, 3) displacement w τ of the air that left the rotors τ ago, carried by a uniform wind w (m/s)."""
    w = np.zeros(3) if wind is None else np.asarray(wind, float)
    return np.asarray(tau, float)[:, None] * w[None, :] + 0.0 * np.asarray(t, float)[:, None]
