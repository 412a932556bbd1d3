"""The barrier's keep-out geometry (docs/barrier.md, "keep-out"; the mathematics: swarm_mj/formation/barrier.py):
the ellipsoidal keep-out of a vehicle and the control-barrier constraint (B) of one pair of drones."""

from __future__ import annotations

import numpy as np

from .._jit import jit
from ..physics.params import DEFAULT_PARAMS, QuadParams

#: Ratio of the keep-out's vertical to its horizontal radius: Preiss et al. (Crazyswarm, ICRA 2017)
#: 0.3/0.12 = 2.5, the Crazyflie firmware 0.9/0.3 = 3 (docs/barrier.md, "keep-out").
DOWNWASH_MULTIPLE = 3.0


def keepout_radii(
    vehicle: QuadParams = DEFAULT_PARAMS,
    rotor_radius: float | None = None,
    downwash_multiple: float = DOWNWASH_MULTIPLE,
    margin: float = 0.0,
) -> np.ndarray:
    """Radii (a, a, c) (3,) of the pairwise keep-out of a vehicle (m): a = 2·(L + r_rotor) + 2·margin,
    the centre distance at which two level drones' rotor tips touch (plus each drone's margin);
    c = downwash_multiple·2·(L + r_rotor) + 2·margin (docs/barrier.md, "keep-out"). ``rotor_radius``:
    the vehicle's own by default."""
    span = float(vehicle.L) + float(vehicle.rotor_radius if rotor_radius is None else rotor_radius)
    a = 2.0 * span + 2.0 * margin
    c = float(downwash_multiple) * 2.0 * span + 2.0 * margin
    return np.array([a, a, c])


@jit
def pair_row(p: np.ndarray, v: np.ndarray, radii: np.ndarray, gain: float, A: np.ndarray):
    """:func:`pair_constraint` with share 1, its A written into ``A`` (3,): returns (b, h, ḣ)."""
    h = -1.0
    hd = 0.0
    qd2 = 0.0
    for c in range(3):
        q = p[c] / radii[c]
        qd = v[c] / radii[c]
        h += q * q
        hd += 2.0 * q * qd
        qd2 += qd * qd
        A[c] = 2.0 * q / radii[c]
    b = -2.0 * qd2 - 2.0 * gain * hd - gain * gain * h
    return b, h, hd


@jit
def split_rhs(b, i, j, filters, priority_share, A, sensed_acc):
    """Drone i's side of the split of pair (i, j)'s (B) (docs/barrier.md, "Decentralised split"), the
    right-hand side of A·u_i ≥ it: against a drone j that does not filter, all of it plus A·â_j (its
    acceleration: it does not give way); a burden (b > 0) by priority, the lower index taking
    ``priority_share``; room (b ≤ 0) in halves."""
    if not filters[j]:
        return b + A[0] * sensed_acc[j, 0] + A[1] * sensed_acc[j, 1] + A[2] * sensed_acc[j, 2]
    if b > 0.0:
        return b * (priority_share if i < j else 1.0 - priority_share)
    return b * 0.5


@jit(on_demand=True, samples=lambda: [(np.array([1.0, 0, 0]), np.zeros(3), np.ones(3), 3.0, 0.5)])
def pair_constraint(p: np.ndarray, v: np.ndarray, radii: np.ndarray, gain: float, share: float):
    """One drone's half-space of (B) for a pair: (A (3,), b_share, h, ḣ) with A·u_i ≥ b_share.

    p = p_i − p_j, v = v_i − v_j (3,); q = S·p, S = diag(1/radii); h = ‖q‖² − 1, ḣ = 2 qᵀq̇;
    A = 2·S·q; b = −2‖q̇‖² − 2k·ḣ − k²·h; b_share = share·b (plus nothing for the other drone:
    its share is its own constraint, or 0 taken for its acceleration when it does not filter)."""
    A = np.empty(3)
    b, h, hd = pair_row(p, v, radii, gain, A)
    return A, share * b, h, hd
