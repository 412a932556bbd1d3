"""The two force stages every simulator (:class:`swarm_mj.physics.sim.Sim`) has first: :class:`DragStage` (paper
eq. 1) and :class:`WindStage` (eq. 37), each a :class:`swarm_mj.physics.sim.ForceStage`."""

from __future__ import annotations

import numpy as np

from .kernels import add_drag_kernel


class DragStage:
    """Paper eq. (1)'s linear drag −(Kx·ẋ, Ky·ẏ, Kz·ż) (world frame), from the velocity at the start
    of each physics step."""

    name = "drag"

    def reset(self, sim) -> None:  # noqa: ANN001 - swarm_mj.physics.sim.Sim
        self.neg_drag = -sim.params.drag  # (3,)

    def reset_rows(self, sim, rows: np.ndarray) -> None:  # noqa: ANN001 - swarm_mj.physics.sim.Sim
        """Nothing per drone."""

    def apply(self, sim, force: np.ndarray, torque: np.ndarray) -> None:  # noqa: ANN001 - swarm_mj.physics.sim.Sim
        add_drag_kernel(sim.vel, self.neg_drag, force)


class WindStage:
    """The wind force F^w (paper eq. 37) of the current control period, (N, 3) world frame, held
    (zero-order) over the period: :meth:`Sim.step` sets it (:attr:`force`)."""

    name = "wind"

    def __init__(self) -> None:
        self.force = np.zeros((0, 3))

    def reset(self, sim) -> None:  # noqa: ANN001 - swarm_mj.physics.sim.Sim
        self.force = np.zeros((sim.n_total, 3))  # (N, 3)

    def reset_rows(self, sim, rows: np.ndarray) -> None:  # noqa: ANN001 - swarm_mj.physics.sim.Sim
        self.force[rows] = 0.0

    def set(self, force: np.ndarray | None) -> None:
        """The force (N, 3) or (3,) for the coming period (None: zero)."""
        if force is None:
            self.force[:] = 0.0
        else:
            self.force[:] = force

    def apply(self, sim, force: np.ndarray, torque: np.ndarray) -> None:  # noqa: ANN001 - swarm_mj.physics.sim.Sim
        force += self.force
