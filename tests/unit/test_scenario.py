"""Scenario files: every bundled scenario loads, and every mistake is one UserError naming the file, the
field and the problem (issue 4). ``swarm-mj list`` listing them all: tests/integration/test_scenario_cli.py."""

from __future__ import annotations

import numpy as np
import pytest

from swarm_mj.control.backstepping import TABLE4_GAINS
from swarm_mj.errors import UserError
from swarm_mj.physics.aero.presets import preset
from swarm_mj.scenario import bundled_scenarios, load_scenario, parse_scenario

BUNDLED = bundled_scenarios()

# The scenarios the issues and docs/interpretations.md name; more may be bundled.
REQUIRED = {
    "step",
    "lemniscate_single",
    "circle_single",
    "circle",
    "lemniscate",
    "ascending_orbit",
    "scenario1",
    "scenario2",
    "scenario3",
    "variable_diameter",
    "anti_collision",
    "wind_circle",
    "wind_lemniscate",
    "wind_swarm",
}


def test_required_scenarios_are_bundled():
    assert REQUIRED <= set(BUNDLED), sorted(REQUIRED - set(BUNDLED))


@pytest.mark.parametrize("name", sorted(BUNDLED))
def test_every_bundled_scenario_loads(name):
    sc = load_scenario(name)
    assert sc.name == name
    assert sc.description.strip(), "a bundled scenario needs a description for 'swarm-mj list'"
    assert sc.duration > 0
    starts = sc.initial_positions()
    assert starts.shape == (sc.n_drones, 3) and np.isfinite(starts).all()
    ref = sc.make_trajectory()(np.linspace(0.0, sc.duration, 11))
    assert np.isfinite(ref.pos).all()
    assert sc.diameter_schedule()(0.0) > 0
    # loading by path gives the same scenario
    by_path = load_scenario(str(BUNDLED[name]))
    assert by_path.name == name and by_path.duration == sc.duration
    np.testing.assert_array_equal(by_path.gains, sc.gains)


def test_bundled_scenarios_match_spec_basics():
    step = load_scenario("step")
    assert step.trajectory == "step" and step.n_followers == 0
    np.testing.assert_array_equal(step.leader_start, [0, 0, 0])
    ref = step.make_trajectory()(0.0)
    np.testing.assert_allclose(ref.pos[0], [1, 1, 1])
    np.testing.assert_allclose(ref.yaw[0], np.deg2rad(25))
    lem = load_scenario("lemniscate_single")
    assert lem.trajectory == "lemniscate" and lem.duration == 180.0 and not lem.wind.enabled
    for name in ("circle", "lemniscate", "ascending_orbit", "scenario1", "scenario2", "scenario3"):
        assert load_scenario(name).n_drones == 6
    vd = load_scenario("variable_diameter")
    np.testing.assert_allclose(vd.diameter_schedule()(np.array([0.0, 6.0, 11.0, 16.0, 29.0])), [1, 1.7, 1.2, 2, 2])
    assert vd.duration == 30.0


# --------------------------------------------------------------------------- defaults and validation

MINIMAL = {"duration": 5.0, "leader": {"trajectory": "hover"}}


def _with(**changes) -> dict:
    d = {k: (dict(v) if isinstance(v, dict) else v) for k, v in MINIMAL.items()}
    for k, v in changes.items():
        if v is None:
            d.pop(k, None)
        else:
            d[k] = v
    return d


def test_defaults_of_a_minimal_scenario():
    sc = parse_scenario(MINIMAL, "x.toml")
    assert (
        sc.control_period == 0.01 and sc.timestep == 0.005 and sc.integrator == "RK4"
    )  # docs/interpretations.md §1, §2
    np.testing.assert_array_equal(sc.gains, TABLE4_GAINS)
    np.testing.assert_allclose(
        TABLE4_GAINS, [4.4025, 9.3048, 6.4184, 5.0494, 7.6955, 2.2141, 4.8548, 7.0579, 4.4025, 6.6385, 6.1893, 3.5344]
    )
    assert sc.wind_feedforward is True and not sc.wind.enabled
    # the rule and the mixer follow the physics (docs/interpretations.md §1, §4)
    assert sc.anti_collision == "auto" and sc.rule == "layers" and not sc.attitude_priority_on
    real = sc.with_overrides(aero=preset("realistic"))
    assert real.rule == "barrier" and real.attitude_priority_on
    assert sc.with_overrides(mixer="attitude_priority").attitude_priority_on
    assert not real.with_overrides(mixer="clip").attitude_priority_on
    assert sc.rule_params.safety_distance == 0.8 and sc.rule_params.hop == 0.4  # paper Fig. 5
    assert sc.anti_collision_params == {}  # nothing set: every value is the preset's
    assert sc.n_drones == 1 and sc.names == ["leader"]
    assert sc.steady_after == 10.0


@pytest.mark.parametrize(
    "data,field,problem",
    [
        (_with(duration=None), "duration", "missing"),
        (_with(duration=-3.0), "duration", "positive"),
        (_with(duration="ten"), "duration", "number"),
        (_with(colour=3), "colour", "unknown"),
        (_with(leader={"trajectory": "hover", "speed": 2}), "leader", "speed"),
        (_with(leader={"trajectory": "spiral"}), "leader.trajectory", "spiral"),
        (_with(leader={"start": [0, 0, 0]}), "leader.trajectory", "missing"),
        (_with(leader={"trajectory": "circle", "params": {"radius": 2, "wobble": 1}}), "leader.params", "wobble"),
        (_with(leader={"trajectory": "hover", "start": [0, 0]}), "leader.start", "3"),
        (_with(leader=None), "leader", "missing"),
        (_with(timestep=0.003), "timestep", "divide"),
        (_with(integrator="leapfrog"), "integrator", "leapfrog"),
        (_with(seed=-1), "seed", ">= 0"),
        (_with(followers={"start": [[1, 0, 0]]}, formation={"diameter": -1.0}), "formation.diameter", "positive"),
        (
            _with(followers={"start": [[1, 0, 0]]}, formation={"diameter": [[0, 1.0], [5, -2.0]]}),
            "formation.diameter",
            "positive",
        ),
        (
            _with(followers={"start": [[1, 0, 0]]}, formation={"diameter": [[1, 1.0], [5, 2.0]]}),
            "formation.diameter",
            "start at 0",
        ),
        (
            _with(followers={"start": [[1, 0, 0]]}, formation={"anti_collision": "magic"}),
            "formation.anti_collision",
            "magic",
        ),
        (
            _with(followers={"start": [[1, 0, 0]]}, formation={"safety_distance": 0}),
            "formation.safety_distance",
            "positive",
        ),
        (_with(followers={"count": 2, "start": [[1, 0, 0]]}), "followers.start", "2"),
        (_with(followers={"count": 2}), "followers", "start"),
        (
            _with(followers={"count": 30, "random_start": {"radius": 1.0, "min_spacing": 0.8}}),
            "followers.random_start",
            "room",
        ),
        (_with(controller={"gains": [1.0] * 11}), "controller.gains", "shape"),
        (_with(controller={"gains": [1.0] * 11 + [-2.0]}), "controller.gains", "positive"),
        (_with(controller={"gains": "missing_gains.toml"}), "missing_gains.toml", "not found"),
        (_with(controller={"wind_feedforward": "yes"}), "controller.wind_feedforward", "true or false"),
        (_with(controller={"attitude_map": "quat"}), "controller.attitude_map", "quat"),
        (_with(controller={"feedforward": True}), "controller", "feedforward"),
        (_with(wind={"enabled": True, "speed": 3}), "wind.speed", "unknown"),
    ],
    ids=lambda v: v if isinstance(v, str) else None,
)
def test_mistakes_name_file_field_and_problem(tmp_path, data, field, problem):
    path = str(tmp_path / "bad_scenario.toml")
    with pytest.raises(UserError) as ei:
        parse_scenario(data, path)
    msg = str(ei.value)
    assert "\n" not in msg
    assert msg.count(path) == 1, msg  # the file named once (issue 47 item 9)
    assert field in msg, msg
    assert problem in msg, msg


@pytest.mark.parametrize(
    ("data", "expected"),
    [
        (_with(formaton={}), "unknown key 'formaton'; did you mean 'formation'?"),
        (
            _with(formation={"sensing_rnge": 3.0}),
            "formation: unknown key 'sensing_rnge'; did you mean 'sensing_range'?",
        ),
        (
            _with(formation={"zzz": 1}),
            "formation: unknown key 'zzz'; the {n} allowed keys are listed in docs/anticollision.md, "
            '"Setting a parameter"',
        ),
        (_with(controller={"gain": "x"}), "controller: unknown key 'gain'; did you mean 'gains'?"),
        (
            _with(controller={"qqq": 1}),
            "controller: unknown key 'qqq'; allowed: attitude_map, downwash_feedforward, gains",
        ),
        (_with(formation={"barrier": {"gian": 2.0}}), "formation.barrier: unknown key 'gian'; did you mean 'gain'?"),
        (_with(vehicle={"modle": "paper"}), "vehicle: unknown key 'modle'; did you mean 'model'?"),
        (_with(colour=3), "unknown key 'colour'; allowed: aero, control_period, controller, description, duration,"),
    ],
)
def test_an_unknown_key_is_one_short_line_with_a_did_you_mean(data, expected):
    """Issue 47 item 9: an unknown key of a table of 45 was one 715-character line listing them all."""
    from swarm_mj.scenario import _FORMATION_KEYS

    with pytest.raises(UserError) as ei:
        parse_scenario(data, "x.toml")
    msg = str(ei.value)
    assert msg.startswith("x.toml: " + expected.replace("{n}", str(len(_FORMATION_KEYS)))), msg
    assert "\n" not in msg and len(msg) < 200, (len(msg), msg)


def test_a_scenario_naming_a_vehicle_that_cannot_hover_is_refused(tmp_path):
    """Issue 47 item 3 at load time: a scenario naming a copy of the Crazyflie's file with mass = 0.067 kg."""
    from swarm_mj.vehicles import _HERE

    text = (_HERE / "crazyflie21.toml").read_text()
    heavy = tmp_path / "cf_heavy.toml"
    heavy.write_text("\n".join("mass = 0.067" if ln.startswith("mass =") else ln for ln in text.splitlines()))
    with pytest.raises(UserError) as ei:
        parse_scenario(_with(vehicle={"model": "cf_heavy.toml"}), str(tmp_path / "s.toml"))
    msg = str(ei.value)
    assert msg.startswith(f"{heavy}: thrust-to-weight ") and "below the minimum 1.4" in msg and "\n" not in msg


def test_gains_file_is_resolved_relative_to_the_scenario(tmp_path):
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "g.toml").write_text("gains = [" + ", ".join(["2.5"] * 12) + "]\n")
    sc_path = tmp_path / "sub" / "s.toml"
    sc_path.write_text('duration = 1.0\n[leader]\ntrajectory = "hover"\n[controller]\ngains = "g.toml"\n')
    sc = load_scenario(str(sc_path))
    np.testing.assert_array_equal(sc.gains, np.full(12, 2.5))


def test_per_drone_inline_gains(tmp_path):
    g = np.arange(1, 25, dtype=float).reshape(2, 12)
    sc = parse_scenario(_with(followers={"start": [[1, 0, 0]]}, controller={"gains": g.tolist()}), "x.toml")
    np.testing.assert_array_equal(sc.gains, g)


def test_load_scenario_file_errors(tmp_path):
    bad = tmp_path / "syntax.toml"
    bad.write_text('duration = 5.0\n[leader\ntrajectory = "hover"\n')
    with pytest.raises(UserError) as ei:
        load_scenario(str(bad))
    assert str(bad) in str(ei.value) and "line 2" in str(ei.value)
    with pytest.raises(UserError, match="not found"):
        load_scenario(str(tmp_path / "nope.toml"))
    with pytest.raises(UserError, match="folder"):
        load_scenario(str(tmp_path) + "/")
    with pytest.raises(UserError, match="circel"):
        load_scenario("circel")


def test_cli_rule_and_aero_names_are_the_registries():
    """The command line's choices (written out so that building the parser stays light) are the
    rules of ANTI_COLLISION_RULES (the default first) and the presets of AERO_MODELS."""
    from swarm_mj.commands import AERO_NAMES, RULE_NAMES
    from swarm_mj.formation.anticollision import ANTI_COLLISION_RULES, AUTO
    from swarm_mj.physics.aero.presets import AERO_MODELS

    assert (AUTO, *ANTI_COLLISION_RULES) == RULE_NAMES
    assert tuple(AERO_MODELS) == AERO_NAMES
    assert RULE_NAMES[0] == "auto"  # the default of a scenario (test_defaults_of_a_minimal_scenario)
