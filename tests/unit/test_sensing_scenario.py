"""A scenario's sensing record (issue 49): the ``[sensing]`` table, its alias ``[formation]
sensing_range`` (docs/sensing.md, "The alias"), ``Scenario.with_overrides(sensing=...)`` and
``--sensing PRESET`` on ``run``, ``stress``, ``sweep`` and ``video``. Nothing flies here."""

from __future__ import annotations

import math

import pytest

from swarm_mj.cli import build_parser
from swarm_mj.cli import main as cli_main
from swarm_mj.commands import SENSING_NAMES, flown_scenario
from swarm_mj.errors import UserError
from swarm_mj.experiments.stress import StressCase, stress_data, stress_scenario
from swarm_mj.experiments.sweep import apply_param, seeded
from swarm_mj.scenario import bundled_scenarios, flown, load_scenario, parse_scenario
from swarm_mj.sensing.params import PRESETS, SensingParams

MINIMAL = {"duration": 5.0, "leader": {"trajectory": "hover"}}
#: The rules' own decision range where nothing sets one (docs/anticollision.md, LayersParams.sensing_range).
RULES_DEFAULT_M = 4.0
COMMANDS = ("run", "stress", "sweep", "video")


def _doc(**tables) -> dict:
    return {**MINIMAL, **tables}


def _preset_values(sp: SensingParams, name: str) -> None:
    """Every numeric field of ``sp`` is the preset's value, as PRESETS writes it."""
    for key, v in PRESETS[name].items():
        assert getattr(sp, key) == v, key


# --------------------------------------------------------------------------- the [sensing] table


def test_no_sensing_table_is_the_oracle() -> None:
    sc = parse_scenario(MINIMAL, "x.toml")
    assert sc.sensing.preset == "perfect"
    _preset_values(sc.sensing, "perfect")


def test_the_table_parses_into_the_record() -> None:
    sc = parse_scenario(_doc(sensing={"preset": "mocap", "latency_s": 0.05, "packet_loss": 0.2}), "x.toml")
    assert sc.sensing.preset == "mocap"
    assert sc.sensing.latency_s == 0.05 and sc.sensing.packet_loss == 0.2  # the file's
    assert sc.sensing.position_noise_m == PRESETS["mocap"]["position_noise_m"]  # the preset's where left out
    assert sc.sensing.rate_hz == PRESETS["mocap"]["rate_hz"]
    every = parse_scenario(_doc(sensing={"preset": "uwb", "rate_hz": 0}), "x.toml")
    assert every.sensing.rate_hz is None and every.sensing.every_period  # 0: every control period
    assert "sensing" in parse_scenario(_doc(sensing={}), "x.toml").raw


@pytest.mark.parametrize(
    ("table", "message"),
    [
        ({"latency": 0.1}, "x.toml: sensing: unknown key 'latency'; did you mean 'latency_s'?"),
        ({"preset": "gps"}, "x.toml: sensing.preset: unknown preset 'gps'; choose one of perfect, mocap, uwb"),
        ({"packet_loss": "high"}, "x.toml: sensing.packet_loss: must be a number"),
        ({"packet_loss": 1.0}, "x.toml: sensing.packet_loss: must be >= 0 and < 1"),
        ({"position_noise_m": -0.1}, "x.toml: sensing.position_noise_m: must be >= 0"),
        ({"latency_s": True}, "x.toml: sensing.latency_s: must be a number"),
        ({"range_m": 0.0}, "x.toml: sensing.range_m: must be > 0"),
        ({"rate_hz": math.nan}, "x.toml: sensing.rate_hz: must be finite"),
    ],
)
def test_a_bad_key_or_value_is_one_line_naming_it(table: dict, message: str) -> None:
    with pytest.raises(UserError) as e:
        parse_scenario(_doc(sensing=table), "x.toml")
    assert str(e.value).startswith(message) and "\n" not in str(e.value)


def test_a_sensing_that_is_not_a_table_is_one_line() -> None:
    with pytest.raises(UserError, match=r"^x\.toml: sensing: must be a table$"):
        parse_scenario(_doc(sensing=3), "x.toml")


# --------------------------------------------------------------------------- the alias


def test_alias_formation_range_is_the_channels_range() -> None:
    sc = parse_scenario(_doc(formation={"sensing_range": 2.5}), "x.toml")
    assert sc.sensing.range_m == 2.5 and sc.sensing_range == 2.5
    assert sc.rule_params.sensing_range == 2.5


def test_alias_sensing_range_m_is_the_rules_range() -> None:
    sc = parse_scenario(_doc(sensing={"preset": "uwb", "range_m": 3.0}), "x.toml")
    assert sc.sensing.range_m == 3.0 and sc.sensing_range == 3.0
    assert sc.rule_params.sensing_range == 3.0
    assert sc.sensing.position_noise_m == PRESETS["uwb"]["position_noise_m"]


def test_alias_neither_keeps_the_rules_default_and_no_channel_range() -> None:
    sc = parse_scenario(_doc(sensing={"preset": "mocap"}), "x.toml")
    assert sc.sensing_range == RULES_DEFAULT_M and math.isinf(sc.sensing.range_m)
    assert sc.rule_params.sensing_range == RULES_DEFAULT_M


def test_alias_both_set_is_one_line_naming_range_m() -> None:
    doc = _doc(formation={"sensing_range": 2.0}, sensing={"range_m": 3.0})
    with pytest.raises(UserError) as e:
        parse_scenario(doc, "x.toml")
    assert str(e.value).startswith("x.toml: sensing.range_m: set range_m or its alias") and "\n" not in str(e.value)


# --------------------------------------------------------------------------- with_overrides(sensing=...)


def test_with_overrides_a_preset_name() -> None:
    sc = load_scenario("circle")  # sets no range: the channel has none, the rules their default
    mocap = sc.with_overrides(sensing="mocap")
    assert mocap.sensing.preset == "mocap" and mocap.sensing_range == sc.sensing_range == RULES_DEFAULT_M
    _preset_values(mocap.sensing, "mocap")
    assert sc.sensing.preset == "perfect"  # a copy
    with pytest.raises(UserError, match=r"^sensing: unknown sensing preset 'gps'; choose one of perfect, mocap, uwb$"):
        sc.with_overrides(sensing="gps")


def test_with_overrides_keeps_the_alias_of_the_file() -> None:
    """The preset replaces the [sensing] table, not [formation]: the file's sensing_range stays the range."""
    doc = _doc(formation={"sensing_range": 2.5})
    sc = parse_scenario(doc, "x.toml").with_overrides(sensing="uwb")
    assert sc.sensing.preset == "uwb" and sc.sensing.range_m == 2.5 and sc.sensing_range == 2.5
    again = parse_scenario(sc.raw, "x.toml")  # what a sweep's --param re-reads
    assert again.sensing == sc.sensing and again.sensing_range == sc.sensing_range


def test_with_overrides_a_record_with_a_range_sets_the_rules_range() -> None:
    sc = parse_scenario(_doc(formation={"sensing_range": 2.5}), "x.toml")
    new = sc.with_overrides(sensing=SensingParams(preset="mocap", range_m=3.0, latency_s=0.04))
    assert new.sensing.range_m == 3.0 and new.sensing_range == 3.0 and new.sensing.latency_s == 0.04
    again = parse_scenario(new.raw, "x.toml")
    assert again.sensing == new.sensing and again.sensing_range == new.sensing_range


def test_with_overrides_replaces_the_files_table_as_a_whole() -> None:
    sc = parse_scenario(_doc(sensing={"preset": "uwb", "range_m": 3.0, "latency_s": 0.2}), "x.toml")
    new = sc.with_overrides(sensing="mocap")
    assert new.sensing == SensingParams(preset="mocap")  # the file's latency and range gone with its table
    assert new.sensing_range == RULES_DEFAULT_M  # the rules' range came from that table
    again = parse_scenario(new.raw, "x.toml")
    assert again.sensing == new.sensing and again.sensing_range == new.sensing_range


def test_perfect_on_a_bundled_scenario_changes_nothing() -> None:
    sc = load_scenario("scenario1")
    same = sc.with_overrides(sensing="perfect")
    assert same.sensing == sc.sensing and same.sensing_range == sc.sensing_range


def test_a_sweep_keeps_the_sensing_on_every_start() -> None:
    sc = flown("circle", sensing="mocap")
    assert seeded(sc, 7).sensing == sc.sensing
    swept = apply_param(sc, "formation.sensing_range", 3.0)
    assert swept.sensing.preset == "mocap" and swept.sensing.range_m == 3.0 and swept.sensing_range == 3.0
    assert swept.sensing.latency_s == PRESETS["mocap"]["latency_s"]


# --------------------------------------------------------------------------- --sensing PRESET


def _args(cmd: str, *extra: str):
    scenario = () if cmd == "stress" else ("circle",)
    return build_parser().parse_args([cmd, *scenario, *extra])


def test_sensing_names_are_the_presets() -> None:
    assert tuple(PRESETS) == SENSING_NAMES


@pytest.mark.parametrize("cmd", COMMANDS)
def test_the_option_is_parsed_by_every_flying_command(cmd: str) -> None:
    assert _args(cmd, "--sensing", "mocap").sensing == "mocap"
    assert _args(cmd).sensing is None  # the scenario's
    if cmd != "stress":
        assert flown_scenario(_args(cmd, "--sensing", "uwb")).sensing == SensingParams(preset="uwb")
        assert flown_scenario(_args(cmd)).sensing == SensingParams()


def test_the_option_is_one_option() -> None:
    sub = next(a for a in build_parser()._actions if a.dest == "command").choices
    acts = [next(a for a in sub[cmd]._actions if a.dest == "sensing") for cmd in COMMANDS]
    assert len({(a.help, tuple(a.choices), a.metavar) for a in acts}) == 1
    assert tuple(acts[0].choices) == SENSING_NAMES and "docs/sensing.md" in acts[0].help


@pytest.mark.parametrize("cmd", COMMANDS)
def test_a_bad_preset_exits_2_with_one_error_line(cmd: str, capsys: pytest.CaptureFixture[str]) -> None:
    scenario = [] if cmd == "stress" else ["circle"]
    with pytest.raises(SystemExit) as e:
        cli_main([cmd, *scenario, "--sensing", "gps"])
    assert e.value.code == 2
    err = capsys.readouterr().err
    errors = [line for line in err.splitlines() if "error:" in line]
    assert len(errors) == 1 and "--sensing" in errors[0] and "'gps'" in errors[0]


def test_every_stress_start_flies_the_preset() -> None:
    case = StressCase(
        rule="layers", seed=3, followers=3, radius=3.0, min_spacing=0.6, duration=5.0, sensing="uwb", sensing_range=3.5
    )
    sc = stress_scenario(case)
    assert sc.sensing.preset == "uwb" and sc.sensing.range_m == 3.5 and sc.sensing_range == 3.5  # the alias
    assert sc.sensing.packet_loss == PRESETS["uwb"]["packet_loss"]
    oracle = stress_data(StressCase(rule="layers", seed=3, followers=3, radius=3.0, min_spacing=0.6, duration=5.0))
    assert "sensing" not in oracle  # perfect: the scenario written as before


# --------------------------------------------------------------------------- bundled scenarios


@pytest.mark.parametrize("name", sorted(bundled_scenarios()))
def test_bundled_scenarios_fly_the_oracle(name: str) -> None:
    sc = load_scenario(name)
    assert "sensing" not in sc.raw and sc.sensing.preset == "perfect"
    _preset_values(SensingParams(preset=sc.sensing.preset), "perfect")
    assert sc.sensing.range_m == sc.raw.get("formation", {}).get("sensing_range", math.inf)  # the alias
    assert sc.sensing_range == sc.raw.get("formation", {}).get("sensing_range", RULES_DEFAULT_M)


def test_scenario1_keeps_the_rules_range() -> None:
    sc = load_scenario("scenario1")
    assert sc.sensing.preset == "perfect" and sc.sensing_range == 4.0
