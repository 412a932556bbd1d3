"""``anti_collision = "barrier"`` (the jet-aware planner guarded by the barrier filter) and
``"barrier-lanes"`` (the lane rule) flown in MuJoCo (docs/barrier.md): the keep-out invariant in the
summary, the lane rule's references within their leash of the drones, and the take-off gate holding
a follower that starts inside another drone's keep-out."""

from __future__ import annotations

import numpy as np
import pytest

from swarm_mj.experiments.report_table import format_summary
from swarm_mj.experiments.runner import run
from swarm_mj.experiments.stress import StressCase, stress_scenario
from swarm_mj.formation.barrier import BarrierParams, BarrierRule, keepout_radii
from swarm_mj.metrics import keepout_min_distance, keepout_time_s

pytestmark = pytest.mark.slow


@pytest.mark.parametrize("rule", ["barrier", "barrier-lanes"])
@pytest.mark.parametrize("aero", ["paper", "realistic"])
def test_barrier_flies_a_random_start(aero, rule):
    res = run(stress_scenario(StressCase(rule, 3, 3, 2.5, 0.6, 8.0, aero=aero)), progress=False)
    s, log = res.summary, res.log
    assert s["anti_collision_rule"] == rule
    radii = keepout_radii()
    # the summary's keys are the metrics of the log (an independent path to the same numbers)
    assert s["keepout_min_distance"] == pytest.approx(keepout_min_distance(log.pos, radii))
    assert s["keepout_time_s"] == pytest.approx(keepout_time_s(log.t, log.pos, radii))
    assert s["keepout_time_s"] == 0.0 and s["contacts"] == 0 and s["crashes"] == 0
    # the text summary (what `swarm-mj run` prints) states the invariant too
    line = f"closest ρ {s['keepout_min_distance']:.3f} (1 = on it), 0.00 s with an airborne pair inside"
    assert line in format_summary(s, res.scenario)
    if rule == "barrier":
        return  # a free drone's reference is its planner's path (no leash)
    # every follower's reference within the leash of the drone (after the period that moved it)
    lag = np.linalg.norm(log.pos_d[:, 1:] - log.pos[:, 1:], axis=2)
    assert lag.max() <= BarrierParams().leash_m + 0.05


def test_take_off_gate_holds_a_follower_under_a_lower_index():
    """Follower 2 stands 0.3 m from follower 1: it stays on the ground (its reference its own
    position, at its start altitude) while 1 is within gate_rho of it."""
    rule = BarrierRule(3)
    pos = np.array([[5.0, 0.0, 0.05], [0.0, 0.0, 0.05], [0.3, 0.0, 0.05]])
    rule.reset(pos)
    slot = pos + np.array([0.0, 0.0, 2.0])
    z = np.zeros((3, 3))
    p_d, v_d, a_d = rule.references(0.0, pos, slot, z, z, 2.0)
    p_d, v_d, a_d = rule.references(0.01, pos, slot, z, z, 2.0)
    np.testing.assert_allclose(p_d[2], pos[2])
    np.testing.assert_allclose(a_d[2], 0.0)
    assert a_d[1, 2] > 0.0  # the lower index climbs
    far = pos.copy()
    far[1] = [0.0, 0.0, 5.0]  # follower 1 well above: gate open
    p_d, v_d, a_d = rule.references(0.02, far, slot, z, z, 2.0)
    assert a_d[2, 2] > 0.0


@pytest.mark.parametrize(("aero", "chosen"), [("paper", "layers"), ("realistic", "jet-aware")])
def test_auto_says_which_rule_it_chose_and_why(aero, chosen):
    """``anti_collision = "auto"`` (the circle's): the summary names the rule auto chose for the
    physics (``AUTO_CHOICE``, by whether it has downwash, not by the scenario) and the reason, and
    the text summary prints it; a rule named explicitly has no such key."""
    from swarm_mj.experiments.report_table import format_summary
    from swarm_mj.formation.anticollision import AUTO_CHOICE

    res = run("circle", aero=aero, duration=0.5, progress=False)
    s = res.summary
    assert res.scenario.anti_collision == "auto"
    assert s["anti_collision_rule"] == chosen
    assert s["anti_collision_auto"] == {"rule": chosen, "why": AUTO_CHOICE[aero == "realistic"][1]}
    assert f"auto chose '{chosen}': {s['anti_collision_auto']['why']}" in format_summary(s, res.scenario)
    named = run("circle", aero=aero, duration=0.5, progress=False, anti_collision=chosen).summary
    assert "anti_collision_auto" not in named
