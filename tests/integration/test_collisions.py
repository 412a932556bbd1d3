"""Collisions counted by MuJoCo (issue 11, docs/interpretations.md §4): drone–drone contacts between different
drones' geoms, from the swarm runner, never from our own distance checks.

* the default rule ("layers") flies seeded random crossing starts and the paper's three
  starts (eqs. 31–33) without a single contact, and forms up within 4 s (paper ≈ 3 s);
* the paper's rule as printed ("paper") touches on a known start, where "layers" does not;
* ``anti_collision``: the default rule yields (the reactive part, paper Fig. 5), and with
  the rule off MuJoCo counts contacts (so these checks can fail);
* ``variable_diameter`` (eq. 34) re-forms within 3 s of each change of D.

Durations are cut to what each check needs; the whole file runs in well under two minutes.
"""

from __future__ import annotations

import argparse
import json

import numpy as np
import pytest

from swarm_mj.commands.stress import StressCase, add_parser, format_table, main, stress, stress_scenario
from swarm_mj.experiments.runner import run
from swarm_mj.physics.wind import ALWAYS_ON, WindConfig
from swarm_mj.scenario import load_scenario

pytestmark = pytest.mark.slow

SETTLE_LIMIT_S = 4.0  # issue 11: the paper's starts settle in at most 4 s (paper ≈ 3 s)
REFORM_LIMIT_S = 3.0  # issue 11 / paper Fig. 14: re-forming after a change of D within 3 s
TOL_M = 0.05  # "settled": every leader–follower distance within 5 cm of D (docs/interpretations.md §7)


def _fly(sc, rule: str | None = None):
    res = run(sc, anti_collision=rule, progress=False)
    assert res.error is None, res.summary.get("stopped")
    return res


def test_default_rule_flies_seeded_random_starts_without_contact():
    # 12 seeded starts of five followers within 3 m of the leader (flying the circle)
    for seed in range(12):
        res = _fly(stress_scenario(StressCase("layers", seed, 5, 3.0, 0.6, 8.0)))
        s = res.summary
        assert s["contacts"] == 0, (seed, res.contact_log[:3])
        assert s["formation"]["settling_s"][0] < 8.0, seed  # and formed up within the run


def test_default_rule_eight_followers_without_contact():
    for seed in range(2):
        res = _fly(stress_scenario(StressCase("layers", seed, 8, 3.0, 0.6, 8.0)))
        assert res.summary["contacts"] == 0, (seed, res.contact_log[:3])


def test_paper_rule_touches_where_the_layered_rule_does_not():
    # eq. (31) starts, leader on the circle: the printed rule lets drones meet (docs/interpretations.md §4)
    sc = load_scenario("circle").with_overrides(duration=3.0)
    paper = run(sc, anti_collision="paper", progress=False)
    assert paper.summary["contacts"] > 0
    assert paper.contact_log[0][0] < 3.0
    layers = _fly(sc, "layers")
    assert layers.summary["contacts"] == 0
    assert layers.summary["min_separation_airborne_m"] > paper.summary["min_separation_airborne_m"]


@pytest.mark.parametrize("name", ["scenario1", "scenario2", "scenario3"])
def test_paper_starts_no_contact_and_settle_within_4_s(name):
    res = _fly(load_scenario(name).with_overrides(duration=12.0))
    s = res.summary
    assert s["contacts"] == 0, res.contact_log[:3]
    assert s["min_separation_airborne_m"] > 0.3
    settle = s["formation"]["settling_s"][0]
    assert settle <= SETTLE_LIMIT_S, settle
    assert s["formation"]["max_distance_error_m"] <= TOL_M
    # after forming up every follower is back at the formation altitude (the leader's)
    z = res.log.pos[-1, :, 2]
    np.testing.assert_allclose(z[1:], z[0], atol=0.05)


@pytest.mark.parametrize("name", ["scenario2", "wind_swarm"])
def test_wind_from_the_start_no_contact(name):
    # the paper's wind (eqs. 35–37) on every drone from t = 0, while the swarm forms up
    sc = load_scenario(name).with_overrides(duration=10.0, wind=WindConfig(schedule=ALWAYS_ON))
    res = _fly(sc)
    assert res.summary["wind"] and res.summary["contacts"] == 0, res.contact_log[:3]
    assert res.summary["formation"]["settling_s"][0] < 10.0


def test_anti_collision_scenario_yields_and_the_rule_off_collides():
    sc = load_scenario("anti_collision")
    layers = _fly(sc)
    assert layers.summary["anti_collision"]["rule"] == "layers"
    assert layers.summary["anti_collision"]["yields"] >= 1
    assert layers.summary["contacts"] == 0, layers.contact_log[:3]
    off = run(sc.with_overrides(duration=4.0), anti_collision="off", progress=False)
    assert off.summary["anti_collision"]["rule"] == "off"
    assert off.summary["contacts"] > 0


def test_variable_diameter_reforms_within_3_s_of_each_change():
    res = _fly(load_scenario("variable_diameter"))
    s = res.summary["formation"]
    assert s["change_times_s"] == [0.0, 6.0, 11.0, 16.0]
    assert s["settling_s"][0] <= SETTLE_LIMIT_S
    assert all(x <= REFORM_LIMIT_S for x in s["settling_s"][1:]), s["settling_s"]
    assert s["max_distance_error_m"] <= TOL_M
    assert res.summary["contacts"] == 0


def test_stress_tool_table_and_json(tmp_path):
    table, rows = stress(["layers", "paper"], 2, StressCase("layers", 0, 5, 3.0, 0.6, 3.0), workers=2)
    assert set(table) == {"layers", "paper"} and len(rows) == 4
    for rule, r in table.items():
        assert r["starts"] == 2
        assert r["starts_with_contact"] == sum(x["contacts"] > 0 for x in rows if x["rule"] == rule)
        assert r["contacts"] == sum(x["contacts"] for x in rows if x["rule"] == rule)
    # the same seeds fly the same starts under both rules
    a = stress_scenario(StressCase("layers", 1, 5, 3.0, 0.6, 3.0)).initial_positions()
    b = stress_scenario(StressCase("paper", 1, 5, 3.0, 0.6, 3.0)).initial_positions()
    np.testing.assert_array_equal(a, b)
    text = format_table(table, 5)
    assert "layers" in text and "paper" in text
    ap = argparse.ArgumentParser()
    add_parser(ap.add_subparsers())
    out = tmp_path / "s.json"
    args = ap.parse_args(
        ["stress", "--rule", "off", "--starts", "1", "--duration", "2", "--workers", "1", "--json", str(out)]
    )
    assert main(args) == 0
    data = json.loads(out.read_text())
    assert data["table"]["off"]["starts"] == 1 and len(data["starts"]) == 1
    import mujoco

    assert data["machine"]["mujoco"] == mujoco.__version__  # what a contact count depends on
