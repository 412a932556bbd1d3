"""The registry of compiled steps and named rules (swarm_mj/pipeline/registry.py): one explicit table per
kind, every entry consistent with what it names, and a run's capability to fly on the chunk driver read
from it (swarm_mj/pipeline/fast.py, ``why_not``)."""

from __future__ import annotations

import numpy as np
import pytest

from swarm_mj import _jit
from swarm_mj.env import SwarmEnv
from swarm_mj.formation import anticollision
from swarm_mj.physics.aero.presets import with_aero
from swarm_mj.pipeline import registry
from swarm_mj.scenario import load_scenario


def test_each_rule_is_registered_under_its_own_name_and_anticollision_reads_the_same_table():
    assert anticollision.ANTI_COLLISION_RULES is registry.ANTI_COLLISION_RULES
    for name, cls in registry.ANTI_COLLISION_RULES.items():
        assert cls.name == name
        assert type(anticollision.make_rule(name, 3)) is cls


def test_every_kernel_is_a_compiled_function_of_a_module_the_drivers_cache_is_checked_against():
    tables = (registry.FORCE_KERNELS, registry.MONITOR_KERNELS, registry.RULE_KERNELS, registry.FILTER_KERNELS)
    for table in tables:
        for record, kernel in table.items():
            assert hasattr(record, "_fields"), record  # a NamedTuple record: Numba types it field by field
            module = getattr(kernel, "py_func", kernel).__module__
            assert module in _jit.KERNEL_MODULES, (record, module)


def test_the_realistic_stages_and_monitors_have_their_compiled_steps():
    env = SwarmEnv(with_aero(load_scenario("circle").with_overrides(duration=0.1), "realistic"))
    assert env.sim.force_stages and env.sim.monitors
    assert env.sim.not_compiled() is None
    assert env.sim.monitors_not_compiled() is None


@pytest.mark.parametrize("name", list(registry.ANTI_COLLISION_RULES))
def test_a_rule_flies_fast_by_what_its_record_has_registered(name):
    rule = anticollision.make_rule(name, 3)
    rule.reset(np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]]))
    why = registry.why_not_compiled(rule, registry.RULE_KERNELS, "rule", "step")
    # the chunk driver's rule stage is the layered planner's formed step (no rule: the same, switched off);
    # the paper's rule has none, and flies step by step
    assert (why is None) == (name != "paper"), why
    filt = rule.separation_filter
    if filt is not None:
        assert registry.why_not_compiled(filt, registry.FILTER_KERNELS, "filter", "step") is None


def test_a_record_without_a_kernel_is_refused_by_name():
    class Stage:
        name = "mine"

        def record(self) -> tuple:
            return ()

    why = registry.why_not_compiled(Stage(), registry.FORCE_KERNELS, "force stage", "kernel")
    assert why == "the force stage 'mine' has no compiled kernel"
