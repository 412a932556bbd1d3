"""One composition of the control period (issue 48): every driver flies ``period.fly_chunk``.

The chunk driver calls it compiled (its bit-identity with the step path: test_fast_path.py). The other
drivers run its Python body with their own stages (swarm_mj/pipeline/stepper.py, the tuner's
``_GroupPeriod``): here each driver's stages are recorded as they are called over its periods, and the order
must be the period's, the same for every driver.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from swarm_mj import _jit
from swarm_mj.control.policy import BacksteppingPolicy
from swarm_mj.env import SwarmEnv
from swarm_mj.experiments.runner import RunLog
from swarm_mj.paper import TABLE4_GAINS
from swarm_mj.pipeline import period as period_mod
from swarm_mj.pipeline.stepper import StepPeriod
from swarm_mj.scenario import load_scenario
from swarm_mj.tuning import evaluator as evaluator_mod
from swarm_mj.tuning.evaluator import BatchEvaluator, StepCostSettings

#: The stages of one period, in the order ``period.fly_chunk`` calls them (its composition, as a user of it
#: relies on: the references before the command, the input rows before the physics, the output rows
#: before the health check, the observation last).
ORDER = [
    "_period_rules", "_period_inputs", "command", "all_finite", "log_inputs", "_period_view_log", "hold_wind",
    "hold_inputs", "physics_steps", "log_outputs", "unhealthy", "observe_into", "_period_sense",
]  # fmt: skip


def _recording(monkeypatch, module) -> list[str]:
    """Every stage call of the period bodies ``module`` makes from now on, by name (the stages wrapped)."""
    calls: list[str] = []
    make = _jit.python_body

    def recorded(fn, stages=None):
        if stages is None or fn is not period_mod.fly_chunk:
            return make(fn, stages)
        names = [name for name in fn.py_func.__code__.co_names if name in ORDER]
        wrapped = {}
        for name in names:
            stage = stages.get(name, getattr(period_mod, name))  # (a compiled callee: typed at each call)
            wrapped[name] = lambda *a, _n=name, _s=stage: (calls.append(_n), _s(*a))[1]
        return make(fn, {**stages, **wrapped})

    monkeypatch.setattr(module, "python_body", recorded)
    return calls


def _periods(calls: list[str]) -> list[list[str]]:
    """The recorded calls cut into periods (each starts with the rule's stage)."""
    out: list[list[str]] = []
    for name in calls:
        if name == ORDER[0]:
            out.append([])
        out[-1].append(name)
    return out


def test_the_period_calls_its_stages_in_the_order_the_drivers_rely_on():
    code = period_mod.fly_chunk.py_func.__code__
    assert [n for n in code.co_names if n in ORDER] == ORDER


def test_the_environment_flies_the_period(monkeypatch):
    from swarm_mj.pipeline import stepper

    calls = _recording(monkeypatch, stepper)
    sc = load_scenario("circle").with_overrides(duration=0.1)
    env = SwarmEnv(sc, terminate_on_contact=False)
    policy = BacksteppingPolicy(sc, env.params)
    ts = env.reset()
    for _ in range(3):
        ts = env.step(policy.command(ts.observation))
    assert _periods(calls) == [ORDER] * 3


def test_a_runs_step_by_step_periods_fly_the_period(monkeypatch):
    from swarm_mj.pipeline import stepper

    calls = _recording(monkeypatch, stepper)
    sc = load_scenario("anti_collision").with_overrides(duration=0.1)
    env = SwarmEnv(sc, terminate_on_contact=False, raise_on_divergence=True)
    policy = BacksteppingPolicy(sc, env.params)
    log = RunLog.allocate(env.names, env.n_steps + 1)
    env.reset()
    step = StepPeriod(env, policy, log)
    for _ in range(4):
        step.fly_next()
    step.sample()
    periods = _periods(calls)
    assert periods[:4] == [ORDER] * 4
    assert periods[4] == ORDER  # the last sample: its stages called, nothing flown
    assert env.k == 4 and np.isfinite(log.U[:4]).all() and np.isnan(log.U[4]).all()
    assert np.isfinite(log.pos[:5]).all()


def test_the_tuner_flies_the_period(monkeypatch):
    calls = _recording(monkeypatch, evaluator_mod)
    ev = BatchEvaluator(2, StepCostSettings(t_sim=0.05, bars=None))
    cost = ev.evaluate(np.tile(TABLE4_GAINS, (2, 1)))
    assert np.isfinite(cost).all()
    assert _periods(calls) == [ORDER] * ev.K


def test_the_vector_env_flies_the_period(monkeypatch):
    pytest.importorskip("gymnasium")
    from swarm_mj.pipeline import stepper
    from swarm_mj.wrappers.vector import SwarmVectorEnv

    calls = _recording(monkeypatch, stepper)
    env = SwarmVectorEnv("circle", num_envs=2)
    env.reset(seed=1)
    for _ in range(2):
        env.step(np.zeros(env.action_space.shape))
    env.close()
    assert _periods(calls) == [ORDER] * 2


def test_python_body_takes_stages_by_name_and_refuses_a_name_the_function_never_calls(monkeypatch):
    seen: list[str] = []
    body = _jit.python_body(period_mod.all_finite)
    assert body(np.ones(3)) and not body(np.array([1.0, np.nan]))
    with pytest.raises(ValueError, match="calls no hold_wnd"):
        _jit.python_body(period_mod.fly_chunk, {"hold_wnd": lambda *a: None})
    react = {
        "drone_views": lambda *a: (None, None, None),
        "_period_rules": lambda *a: (seen.append("r"), (True,) * 4)[1],
    }
    stepped = _jit.python_body(period_mod.fly_chunk, react)
    clock = SimpleNamespace(T=0.01)  # (what the period reads of the simulator before the rule)
    assert stepped(3, 0, 5, False, clock, *[None] * 11) == (period_mod.REACT, 3, 0)  # REACT at 3, from the stage
    assert seen == ["r"]
    monkeypatch.setattr(_jit, "AVAILABLE", False)  # without Numba too
    assert _jit.python_body(period_mod.fly_chunk, react)(0, 0, 2, False, clock, *[None] * 11) == (
        period_mod.REACT,
        0,
        0,
    )
    assert seen == ["r", "r"]
