"""The separation step of the anti-collision (paper Fig. 5, §4; docs/interpretations.md §4;
docs/anticollision.md): functions of the drones' positions, their predicted closest approach
and a keep-out shape that adjust the planner's altitude targets (:mod:`.planner`), and the
interface of a reference-level separation filter (:class:`SeparationFilter`).

Conventions (n drones, index 0 the leader): ``positions`` (n, 3); ``h`` (n, n) horizontal
centre distances, +inf on the diagonal; ``soon`` (n, n) the smallest horizontal distance of
each pair predicted over a horizon (:func:`closest_approach`), +inf for a pair not sensed;
``offset`` (n,) the altitude offset of each drone from the formation altitude, changed in place,
with each decision appended to ``events`` as ``{t, drone, other, action}``. The priority of
Fig. 5: drone i yields to drone j < i (a follower always yields to the leader).

The keep-out shape is a vertical cylinder around each drone: radius ``keep_out`` (arm + rotor
radius + a margin, :meth:`~swarm_mj.formation.rule_params.LayersParams.keep_out`) in plan view;
two drones' cylinders overlap under the centre distance ``overlap``. Vertically a drone keeps
``hop`` from any drone whose cylinder overlaps its own.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from .layered import react_needed


def closest_approach(positions: np.ndarray, vel: np.ndarray, horizon: float | np.ndarray) -> np.ndarray:
    """(n, n) smallest horizontal distance of each pair over the next ``horizon`` s (a number, or
    (n, 1): drone i's own), predicting the relative motion as a straight line (velocities ``vel``
    (n, 3)); +inf on the diagonal.

    Invariant: ≤ the present distance, and equal to it for a pair moving apart (the time of
    closest approach is clipped to [0, horizon])."""
    d = positions[None, :, :2] - positions[:, None, :2]  # (n, n, 2) j − i
    dv = vel[None, :, :2] - vel[:, None, :2]  # (n, n, 2)
    vv = np.einsum("ijk,ijk->ij", dv, dv)
    tc = np.clip(-np.einsum("ijk,ijk->ij", d, dv) / np.maximum(vv, 1e-9), 0.0, horizon)
    m = d + tc[:, :, None] * dv
    out = np.sqrt(np.einsum("ijk,ijk->ij", m, m))
    np.fill_diagonal(out, np.inf)
    return out


def closing_only(
    positions: np.ndarray, vel: np.ndarray, h: np.ndarray, soon: np.ndarray, closing_min: float
) -> np.ndarray:
    """``soon`` (n, n) where two drones close faster than ``closing_min`` (m/s), else their present
    distance ``h`` (n, n); unseen pairs (+inf in ``soon``) stay +inf. Assumption: velocities
    estimated from positions jitter by a few cm/s, so a prediction is trusted only for a pair
    that really closes."""
    d = positions[None, :, :2] - positions[:, None, :2]  # (n, n, 2) j − i
    dv = vel[None, :, :2] - vel[:, None, :2]
    closing = -np.einsum("ijk,ijk->ij", d, dv) / np.maximum(h, 1e-9)  # (n, n) > 0: approaching
    return np.where(np.isinf(soon) | (closing > closing_min), soon, h)


def fig5_react(
    t: float,
    positions: np.ndarray,
    h: np.ndarray,
    active: np.ndarray,
    offset: np.ndarray,
    events: list[dict],
    safety: float,
    hop: float,
    hysteresis: float,
) -> None:
    """Fig. 5 as printed among the drones flagged ``active`` (n,): a drone i closer than ``safety``
    (D̄) to some j < i takes the offset +``hop`` if it is not below that nearest j, else −``hop``;
    it returns to 0 once every active j < i is beyond D̄ + ``hysteresis``.

    Invariant: every offset is 0 or ±hop; an offset is set only while a drone it yields to is
    within D̄. Assumption: one hop takes a drone clear of the drone it yields to (true for one
    pair; two drones that both yield upwards to a third end level, the case of
    :func:`stacked_react`)."""
    if not react_needed(offset, h, safety):
        return  # nobody held, nobody inside D̄: nothing to trigger or release
    lower = np.tri(h.shape[0], k=-1, dtype=bool)  # [i, j]: j < i, so i yields to j
    yields = (h < safety) & lower & active[:, None] & active[None, :]
    trig = yields.any(axis=1) & (offset == 0.0)
    if trig.any():
        hh = np.where(yields, h, np.inf)
        for i in np.flatnonzero(trig):
            j = int(np.argmin(hh[i]))
            up = positions[i, 2] >= positions[j, 2]
            offset[i] = hop if up else -hop
            events.append({"t": t, "drone": int(i), "other": j, "action": "up" if up else "down"})
    held = offset != 0.0
    if held.any():
        clear = ~((h < safety + hysteresis) & lower & active[None, :]).any(axis=1)
        for i in np.flatnonzero(held & clear):
            offset[i] = 0.0
            events.append({"t": t, "drone": int(i), "other": -1, "action": "release"})


def offset_candidates(hop: float, lowest: float, hops_down: int, hops_up: int) -> tuple[float, ...]:
    """The offsets a yielding drone may take: k·``hop`` for k = −hops_down … hops_up, none below
    ``lowest`` (the floor clearance less the formation altitude) but 0."""
    return tuple(o for o in (float(k) * hop for k in range(-hops_down, hops_up + 1)) if o >= lowest or o == 0.0)


def stacked_react(
    t: float,
    positions: np.ndarray,
    h: np.ndarray,
    active: np.ndarray,
    offset: np.ndarray,
    events: list[dict],
    slot_h: np.ndarray,
    safety: float,
    hop: float,
    hysteresis: float,
    candidates: tuple[float, ...],
) -> None:
    """Fig. 5 with the slots and stacked offsets (the jet-aware rule's 2.–3.), in index order: drone
    i yields to each active j < i within ``safety`` now (D̄ + ``hysteresis`` once it holds an
    offset) or whose slot is within D̄ of its own (``slot_h`` (n, n)); it keeps its offset while
    that is at least ``hop`` from the offset of every drone it yields to, else takes the candidate
    nearest 0 that is (up first when it is not below the nearest one), or ``hop`` above them all.

    Invariant (after the call): for every active i and every active j < i it yields to,
    |offset[i] − offset[j]| ≥ hop − 1e-9 — two drones within D̄ (or bound for slots within D̄)
    are a hop apart in altitude, whatever the number of drones involved. The followers are taken
    in index order so that offset[j] is final when i reads it."""
    n = h.shape[0]
    lower = np.tri(n, k=-1, dtype=bool)
    slot = (slot_h < safety) & lower  # (n, n) [i, j]: i yields to j by the slots
    for i in range(1, n):
        if not active[i]:
            continue
        cur = float(offset[i])
        reach = safety + (hysteresis if cur != 0.0 else 0.0)
        yields = active[:i] & ((h[i, :i] < reach) | slot[i, :i])
        js = np.flatnonzero(yields)
        if js.size == 0:
            if cur != 0.0:
                offset[i] = 0.0
                events.append({"t": t, "drone": i, "other": -1, "action": "release"})
            continue
        others = offset[js]
        if bool(np.all(np.abs(cur - others) >= hop - 1e-9)):
            continue  # its offset still keeps it clear of every drone it yields to
        j = int(js[np.argmin(h[i, js])])
        up = positions[i, 2] >= positions[j, 2]
        order = sorted(candidates, key=lambda o: (abs(o), (o < 0.0) if up else (o > 0.0)))
        # (every candidate taken, when it yields to more drones than there are candidates: above them all)
        new = next((o for o in order if bool(np.all(np.abs(o - others) >= hop - 1e-9))), float(others.max()) + hop)
        if new != cur:
            offset[i] = new
            events.append({"t": t, "drone": i, "other": j, "action": "up" if new > cur else "down"})


def never_through(
    positions: np.ndarray, z_target: np.ndarray, who: np.ndarray, soon: np.ndarray, overlap: float, hop: float
) -> np.ndarray:
    """``z_target`` (n,) of the drones flagged ``who`` (n,) held ``hop`` clear of every drone whose
    keep-out cylinder overlaps theirs (``soon`` (n, n) < ``overlap``): not above z_j − hop for one
    above, not below z_j + hop for one below; a drone boxed in between keeps its altitude.

    Invariant: a held drone's altitude target never crosses the altitude of a drone that overlaps
    it in plan view (its altitude path then never passes through it, the paths being monotone
    towards their targets)."""
    near = (soon < overlap) & who[:, None]
    if not near.any():
        return z_target
    z = positions[:, 2]
    above = z[None, :] > z[:, None]  # [i, j]: j above i
    lo = np.where(near & ~above, z[None, :] + hop, -np.inf).max(axis=1)
    hi = np.where(near & above, z[None, :] - hop, np.inf).min(axis=1)
    held = np.where(lo > hi, z, np.minimum(np.maximum(z_target, lo), hi))
    return np.where(who, held, z_target)


def hold_above(z: np.ndarray, z_target: np.ndarray, below: np.ndarray, hop: float) -> np.ndarray:
    """``z_target`` (n,) raised to ``hop`` above the highest drone j flagged in ``below`` (n, n)
    [i, j] for each drone i (altitudes ``z`` (n,)); rows with no flag unchanged.

    Invariant: z_target[i] ≥ z[j] + hop for every flagged j."""
    if not below.any():
        return z_target
    zmax = np.where(below, z[None, :], -np.inf).max(axis=1)  # (n,) highest such drone
    return np.where(np.isfinite(zmax), np.maximum(z_target, zmax + hop), z_target)


def descending_onto(
    z: np.ndarray, z_target: np.ndarray, who: np.ndarray, others: np.ndarray, near: np.ndarray, band: float
) -> np.ndarray:
    """(n, n) [i, j]: drone i (flagged ``who``) would descend onto drone j (flagged ``others``):
    j is ``near`` (n, n), below i, and above i's target less ``band``."""
    return near & who[:, None] & others[None, :] & (z[None, :] < z[:, None]) & (z[None, :] > z_target[:, None] - band)


# --------------------------------------------------------------------------- a reference-level filter
@dataclass(frozen=True)
class Sensed:
    """What a drone may use to separate itself (decentralised: docs/interpretations.md §4)."""

    t: float
    positions: np.ndarray  # (n, 3) m
    velocities: np.ndarray  # (n, 3) m/s, estimated from successive positions
    seen: np.ndarray  # (n, n) bool: drone i senses drone j (within sensing_range; the leader always)
    keep_out: float  # m, each drone's keep-out radius in plan view
    dt: float  # s since the last call (0 at the first)


def seen_within(positions: np.ndarray, sensing_range: float) -> np.ndarray:
    """(n, n) drone i senses drone j: within ``sensing_range`` (3D); the leader (column 0) always
    (the slots are built from its position); not itself."""
    rel = positions[None, :, :] - positions[:, None, :]
    seen = np.einsum("ijk,ijk->ij", rel, rel) < sensing_range**2  # (n, n)
    seen[:, 0] = True
    np.fill_diagonal(seen, False)
    return seen


class SeparationFilter(Protocol):
    """A separation step acting on the planner's references rather than its targets (e.g. a
    barrier certificate): each call gets the references the planner (and the altitude
    separation above) produced and returns the position, velocity and acceleration references to
    fly (all three: a filter that changed only the acceleration would be pulled back onto the
    nominal path by the controller's position and velocity feedback).

    Contract: vectorised over drones; it may change only the rows flagged ``steer`` (n,) (the
    leader's row 0 is its trajectory); row i may depend only on drone i's own references and on
    ``sensed`` rows j with ``sensed.seen[i, j]`` (decentralised); it returns new arrays (it does
    not write into its arguments); with nothing to separate it returns the references unchanged
    (bit for bit). It holds its own state, cleared by ``reset``, and appends its decisions to
    ``events`` as ``{t, drone, other, action}``, which the planner moves into its own."""

    events: list[dict]

    def reset(self, n: int) -> None:
        """Start of a run of n drones."""
        ...

    def __call__(
        self, sensed: Sensed, pos_d: np.ndarray, vel_d: np.ndarray, acc_d: np.ndarray, steer: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(pos_d, vel_d, acc_d) (n, 3) to fly, from the nominal references pos_d, vel_d, acc_d (n, 3)."""
        ...
