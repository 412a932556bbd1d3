"""A constant updraft over a disc: the worked example of a new force stage (docs/design.md, "A new force stage").

Every drone whose centre of mass is over the disc of ``radius`` around ``centre`` (x, y) is pushed
up by ``lift`` newtons (world frame), whatever its height; outside, nothing. It is a toy (a thermal
over a sunny field), kept to show the three parts a compiled force stage has: its record, its
kernel (registered for that record in swarm_mj/pipeline/registry.py), and the stage object the simulator holds.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..._jit import jit
from ...pipeline.records import Kinematics


class UpdraftRecord(NamedTuple):
    """:class:`UpdraftStage` for a compiled driver (swarm_mj.pipeline.records)."""

    centre: np.ndarray  # (2,) x, y of the disc's centre (m)
    radius: float  # m
    lift: float  # upward force on a drone over the disc (N)
    force: np.ndarray  # (N, 3) this stage's force over the last physics step (N)


@jit
def updraft_apply(rec: UpdraftRecord, kin: Kinematics, force: np.ndarray, torque: np.ndarray) -> None:
    """force[i] += (0, 0, lift) for each drone i with |(x, y) − centre| ≤ radius; rec.force the same alone."""
    for i in range(kin.pos.shape[0]):
        dx = kin.pos[i, 0] - rec.centre[0]
        dy = kin.pos[i, 1] - rec.centre[1]
        f = rec.lift if dx * dx + dy * dy <= rec.radius * rec.radius else 0.0
        rec.force[i, 2] = f
        force[i, 2] += f


class UpdraftStage:
    """Force stage: a constant updraft of ``lift`` N over the disc (``centre`` (x, y), ``radius``) (m)."""

    name = "updraft"

    def __init__(self, centre: tuple[float, float] = (0.0, 0.0), radius: float = 1.0, lift: float = 0.5) -> None:
        self.centre = np.array(centre, dtype=float).reshape(2)
        self.radius = float(radius)
        self.lift = float(lift)
        self.force = np.zeros((0, 3))

    def reset(self, sim) -> None:  # noqa: ANN001 - swarm_mj.physics.sim.Sim
        self.force = np.zeros((sim.n_total, 3))
        self._record = UpdraftRecord(centre=self.centre, radius=self.radius, lift=self.lift, force=self.force)

    def reset_rows(self, sim, rows: np.ndarray) -> None:  # noqa: ANN001 - swarm_mj.physics.sim.Sim
        self.force[rows] = 0.0

    def record(self) -> UpdraftRecord:
        return self._record

    def apply(self, sim, force: np.ndarray, torque: np.ndarray) -> None:  # noqa: ANN001
        updraft_apply(self._record, sim.kinematics, force, torque)
