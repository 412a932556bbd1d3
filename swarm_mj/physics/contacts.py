"""Which drones touch: the pairs of drones whose geoms are in MuJoCo's contact list (the simulator's
contact counting, :meth:`swarm_mj.physics.sim.Sim.after_physics_step`, and
:meth:`~swarm_mj.physics.sim.Sim.drone_contacts`)."""

from __future__ import annotations

import mujoco
import numpy as np


def touching_pairs(data: mujoco.MjData, geom_drone: np.ndarray) -> set[tuple[int, int]]:
    """The pairs (i, j), i < j, of drones with a geom in contact in ``data`` now; ``geom_drone`` (ngeom,)
    is the drone of each geom (−1: none, e.g. the floor)."""
    pairs: set[tuple[int, int]] = set()
    if data.ncon:
        g1 = geom_drone[data.contact.geom1[: data.ncon]]
        g2 = geom_drone[data.contact.geom2[: data.ncon]]
        for a, b in zip(g1.tolist(), g2.tolist()):
            if a >= 0 and b >= 0 and a != b:
                pairs.add((min(a, b), max(a, b)))
    return pairs
