"""Where the drones start: explicit starts checked for spacing, and seeded random follower starts
(docs/interpretations.md, "starts"). Below :mod:`swarm_mj.scenario` and :mod:`swarm_mj.choices`, which
both check starts (a scenario's own, and a scenario's flown with another vehicle)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import UserError


@dataclass(frozen=True)
class RandomStart:
    """Seeded random follower starts on the ground around the leader (issue: random crossing starts)."""

    radius: float = 3.0
    min_spacing: float = 0.6
    seed: int = 0
    max_tries: int = 20000


#: Centre distance below which two level drones may already touch on the ground: rotor tip
#: to rotor tip is 2·(L + rotor radius) = 2·(0.25 + 0.09) = 0.68 m along a body axis (the
#: drone's geometry, ``assets/quadrotor.xml``), plus 2 cm. Measured in MuJoCo: two followers
#: 0.60 m or 0.65 m apart along x are in contact from the first physics step; 0.70 m apart
#: they are not. Random starts keep at least this spacing; explicit starts closer than this
#: (3D centre distance, whatever the heights) are refused (docs/interpretations.md, "starts").
START_CLEARANCE_M = 0.70

#: Largest distance a scenario may ask for (random start radius, spacing): the simulator stops
#: a run when a drone is farther than 1 km from the origin (``sim.Sim(max_distance=1e3)``).
MAX_RANGE_M = 1000.0


def check_start_spacing(starts: np.ndarray, names: list[str], where: str, clearance: float = START_CLEARANCE_M) -> None:
    """Explicit starts: on or above the ground (z >= 0), within :data:`MAX_RANGE_M` of the origin
    and every two drones at least ``clearance`` (the vehicle's :attr:`Scenario.start_clearance`,
    :data:`START_CLEARANCE_M` for the paper's drone) apart (3D centre distance), as random
    starts are."""
    below = np.flatnonzero(starts[:, 2] < 0)
    if len(below):
        i = int(below[0])
        raise UserError(f"{names[i]} starts below the ground (z = {starts[i, 2]:g} m); z must be >= 0", where=where)
    far = np.flatnonzero(np.linalg.norm(starts, axis=1) > MAX_RANGE_M)
    if len(far):
        raise UserError(
            f"{names[int(far[0])]} starts farther than {MAX_RANGE_M:g} m from the origin, where the "
            f"simulator stops the run",
            where=where,
        )
    d = np.linalg.norm(starts[:, None, :] - starts[None, :, :], axis=-1)  # (n, n)
    d[np.diag_indices(len(starts))] = np.inf
    i, j = map(int, np.unravel_index(np.argmin(d), d.shape))
    if d[i, j] < clearance:
        i, j = sorted((i, j))
        raise UserError(
            f"{names[i]} and {names[j]} start {d[i, j]:.3g} m apart; starts must be at least "
            f"{clearance:g} m apart (rotor tips touch below two rotor spans)",
            where=where,
        )


def random_follower_starts(
    leader: np.ndarray, n: int, rs: RandomStart, where: str = "", clearance: float = START_CLEARANCE_M
) -> np.ndarray:
    """n follower starts (n, 3) on the ground within ``rs.radius`` of the leader (seeded
    random crossing starts; docs/interpretations.md, "starts"), every two drones (leader included) at least
    max(``rs.min_spacing``, ``clearance``) apart (``clearance``: the vehicle's, :data:`START_CLEARANCE_M`
    for the paper's drone); rejection sampling, seeded.

    The floor of 0.70 m keeps a start from being a contact before anything flies: with a
    smaller spacing two drones lined up along x or y would overlap their rotors at t = 0,
    and MuJoCo would count that against whatever rule is flown.
    """
    check_random_start_feasible(n, rs, where, clearance)
    spacing = max(rs.min_spacing, clearance)
    rng = np.random.default_rng(rs.seed)
    pts = np.empty((n + 1, 2))  # (n + 1, 2) leader first
    pts[0] = np.asarray(leader[:2], float)
    placed, tries = 1, 0
    while placed < n + 1:
        tries += 1
        if tries > rs.max_tries:
            raise UserError(
                f"could not place {n} followers at least {spacing:g} m apart within "
                f"{rs.radius:g} m of the leader after {rs.max_tries} tries; lower min_spacing "
                f"or raise radius",
                where=f"{where}: followers.random_start",
            )
        r = rs.radius * np.sqrt(rng.uniform())
        a = rng.uniform(0, 2 * np.pi)
        p = pts[0] + r * np.array([np.cos(a), np.sin(a)])
        if np.hypot(*(pts[:placed] - p).T).min() >= spacing:
            pts[placed] = p
            placed += 1
    return np.column_stack([pts[1:], np.full(n, float(leader[2]))])


def check_random_start_feasible(n: int, rs: RandomStart, where: str = "", clearance: float = START_CLEARANCE_M) -> None:
    """Refuse, before anything is simulated, a request no placement can meet.

    Disks of radius s/2 around n + 1 points (the leader and n followers, s the effective
    spacing max(min_spacing, ``clearance``)) that lie within r of the leader
    fit in a disk of radius r + s/2 without overlapping, so (n + 1)·(s/2)² ≤
    0.9069·(r + s/2)² is necessary (0.9069 = π/√12, the densest packing of equal disks in
    the plane). Requests that pass may still be too tight for rejection sampling; those
    are refused after ``max_tries`` draws, still before anything flies.
    """
    s, r = rs.min_spacing, rs.radius
    wr = f"{where}: followers.random_start"
    if not (np.isfinite(r) and np.isfinite(s)) or r <= 0 or s <= 0:
        raise UserError("radius and min_spacing must be positive", where=wr)
    if r > MAX_RANGE_M or s > MAX_RANGE_M:
        raise UserError(
            f"radius and min_spacing must be at most {MAX_RANGE_M:g} m (a drone farther than that "
            f"from the origin stops the run)",
            where=wr,
        )
    if n < 0:
        raise UserError(f"follower count must be >= 0, got {n}", where=wr)
    se = max(s, clearance)
    if (n + 1) * (se / 2) ** 2 > 0.9069 * (r + se / 2) ** 2:
        raise UserError(
            f"cannot place {n} followers {se:g} m apart (and from the leader) within "
            f"{r:g} m of the leader: not enough room (the packing bound allows at most "
            f"{max(int(0.9069 * (r + se / 2) ** 2 / (se / 2) ** 2) - 1, 0)} followers); lower min_spacing "
            f"or raise radius",
            where=wr,
        )
