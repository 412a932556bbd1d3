"""Sim's one loop over the physics steps of a period (Sim._fly_period): every way of applying a step's forces
(the compiled stages, Python stages after the compiled drag and wind, every stage in turn where the stages
do not start with drag and wind) and every period (compiled, or Python's one step a call) go through it,
and Python sees each step it must (its monitors and contacts)."""

from __future__ import annotations

import numpy as np

from swarm_mj.physics import _mjstep
from swarm_mj.physics.sim import Sim
from swarm_mj.physics.world import build_world


def _world(n: int = 3):
    return build_world(n, positions=np.column_stack([2.0 * np.arange(n), np.zeros(n), np.full(n, 2.0)]))


def _fly(sim: Sim, periods: int) -> np.ndarray:
    U = np.tile([sim.params.hover_thrust * 1.01, 0.001, -0.002, 0.0005], (sim.n_total, 1))
    wind = np.array([0.3, -0.2, 0.1])
    out = []
    for k in range(periods):
        sim.step(U, wind * (1 + 0.01 * k))
        out.append(np.concatenate([sim.qpos.ravel(), sim.qvel.ravel()]))
    return np.array(out)


class CountingMonitor:
    """A monitor without a compiled step: Python must see every physics step."""

    name = "counting"

    def reset(self, sim: Sim) -> None:
        self.steps = 0
        self.times: list[float] = []

    def reset_rows(self, sim: Sim, rows: np.ndarray) -> None:
        pass

    def after_step(self, sim: Sim) -> None:
        self.steps += 1
        self.times.append(sim.time)


def test_the_general_path_equals_the_fused_one():
    """Wind before drag (the stages then do not start with drag and wind: every stage adds into zeroed
    sums, Sim._stage_forces) gives (0 + F_wind) + (−K·v), the fused path −K·v + F_wind: the same sums
    (IEEE addition of two terms commutes), so the same flight bit for bit."""
    fused = Sim(_world())
    general = Sim(_world())
    general.stages[:2] = [general.wind, general.drag]
    general.reset()
    assert fused.not_compiled() is None
    assert general.not_compiled() == "force stages other than drag and wind first"
    a, b = _fly(fused, 100), _fly(general, 100)
    assert np.abs(a[-1] - a[0]).max() > 1e-3  # the drones moved
    np.testing.assert_array_equal(a, b)


def test_python_sees_every_physics_step_on_every_path(monkeypatch):
    """A Python monitor runs after each physics step, at the time of that step, whether the period is the
    compiled one (which then hands back after every step) or Python's; the flights are the same."""
    runs = []
    for available in (_mjstep.available(), False):
        with monkeypatch.context() as m:
            m.setattr(_mjstep, "available", lambda a=available: a)
            sim = Sim(_world(), monitors=[CountingMonitor()])
            assert sim.compile_period() == available
            states = _fly(sim, 20)
        mon = sim.monitors[0]
        dt = sim.model.opt.timestep
        assert mon.steps == 20 * sim.n_substeps
        np.testing.assert_allclose(mon.times, dt * np.arange(1, mon.steps + 1), rtol=0, atol=1e-12)
        runs.append(states)
    np.testing.assert_array_equal(runs[0], runs[1])
