"""Each drone's own view on the chunk driver (docs/sensing.md, "Cost"): a run under a sensing model gives the
same numbers bit for bit on the chunk driver as step by step (the sensing stage's tick, every drone's copy of
the rule, the payloads and the viewed feedforward are the same compiled functions on both), through
everything it hands back to Python, and it does fly a good part of the run in chunks.

These tests FAIL where the chunk driver does not exist (no compiled ``mj_step``); only an explicit
``SWARM_MJ_NO_JIT=1`` (Numba switched off on purpose) skips them.
"""

from __future__ import annotations

import numpy as np
import pytest
from helpers import assert_same_runs

from swarm_mj import _jit
from swarm_mj.experiments.runner import run
from swarm_mj.scenario import load_scenario

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(not _jit.ENABLED, reason="SWARM_MJ_NO_JIT set: Numba switched off on purpose"),
]

VIEWS = ("pos", "mask", "age", "held_pos", "held_tick")


def _same(a, b) -> None:
    assert_same_runs(a, b)
    for f in VIEWS:  # what each drone believed and held, period by period
        assert np.array_equal(getattr(a.log.views, f), getattr(b.log.views, f), equal_nan=True), f"views.{f}"


@pytest.mark.parametrize(
    ("name", "rule", "sensing", "aero", "fused_share"),
    [
        ("anti_collision", "barrier", "mocap", "realistic", 0.5),  # relaxations and the viewed feedforward
        ("anti_collision", "layers", "uwb", None, 0.2),  # Fig. 5 acting between chunks, 10-Hz messages
    ],
)
def test_bit_identical_to_step_by_step(name, rule, sensing, aero, fused_share):
    sc = load_scenario(name).with_overrides(duration=8.0, anti_collision=rule, sensing=sensing)
    a = run(sc, progress=False, fused=False, aero=aero)
    b = run(sc, progress=False, fused=True, aero=aero)
    assert a.extra["fused_periods"] == 0
    assert b.extra["fast_path"] == "on", b.extra  # the run qualified: the comparison is not vacuous
    _same(a, b)
    K = len(a.log.t) - 1
    assert b.extra["fused_periods"] > fused_share * K, b.extra


def test_a_policy_that_reads_the_truth_does_not_fly_a_sensing_env_in_chunks():
    # the chunk driver runs one copy of the rule per drone under a sensing model: a policy built without it
    # (one rule on the true state) beside an environment with it is refused, saying why, not flown wrong
    from swarm_mj.control.policy import BacksteppingPolicy
    from swarm_mj.env import SwarmEnv
    from swarm_mj.pipeline import fast

    sc = load_scenario("circle").with_overrides(duration=0.1)
    env = SwarmEnv(sc, sensing="mocap", terminate_on_contact=False)
    env.reset()
    why = fast.why_not(env, BacksteppingPolicy(sc, env.params))
    assert why is not None and "disagree on the sensing model" in why
    assert fast.why_not(env, BacksteppingPolicy(env.scenario, env.params)) is None


@pytest.mark.parametrize("rule", ["paper", "off", "stagger", "layers", "jet-aware", "barrier"])
def test_every_rule_under_a_sensing_model_is_answered(rule):
    # each drone's copy of any named rule: the chunk driver says whether it flies it (paper has no compiled
    # step, stagger no compiled check: a reason each; the others none), never an AttributeError from a rule
    # without a record
    from swarm_mj.control.policy import BacksteppingPolicy
    from swarm_mj.env import SwarmEnv
    from swarm_mj.pipeline import fast

    sc = load_scenario("circle").with_overrides(duration=0.1, anti_collision=rule)
    env = SwarmEnv(sc, sensing="mocap", terminate_on_contact=False)
    env.reset()
    why = fast.why_not(env, BacksteppingPolicy(env.scenario, env.params))
    if rule == "paper":
        assert why == "the 'paper' rule has no compiled step"
    elif rule == "stagger":
        assert why is not None and "the 'stagger' rule has no compiled check" in why
    else:
        assert why is None, why
