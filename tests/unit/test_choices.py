"""The vehicle and the gains a run flies, chosen by one rule (swarm_mj/choices.py; issue 47, "a vehicle is a
switch everywhere"), the outcome of a flight (swarm_mj/experiments/outcome.py; "runs never claim what did not
happen"), where the paper's figures are printed (experiments/report_table.py) and the hint after a tune.
No flight here: scenarios are parsed, never flown (tests/integration/test_vehicle_switch.py flies them)."""

from __future__ import annotations

import re
import tomllib
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from swarm_mj.choices import GAINS_ORIGINS, choose_gains, gains_name, gains_text
from swarm_mj.cli import build_parser
from swarm_mj.commands import EXIT_EPILOG, EXIT_FLIGHT_FAILED
from swarm_mj.commands.tune import run_hint
from swarm_mj.control.backstepping import TABLE4_GAINS, load_gains
from swarm_mj.errors import UserError
from swarm_mj.experiments.outcome import TAKEOFF_GRACE_S, failure_line, flight_outcome
from swarm_mj.experiments.report_table import paper_comparable
from swarm_mj.physics.aero.ground import TAKEOFF_CLEARANCE
from swarm_mj.physics.aero.presets import REALISTIC_MOTOR_TAU, parse_aero, with_aero
from swarm_mj.physics.params import DEFAULT_PARAMS
from swarm_mj.scenario import flown, load_scenario, parse_scenario
from swarm_mj.vehicles import load_vehicle

REPO = Path(__file__).resolve().parents[2]
CF_FILE = REPO / "swarm_mj" / "vehicles" / "crazyflie21.toml"
CF_TOML = tomllib.loads(CF_FILE.read_text())  # the vehicle file as written, read here independently
BASE = {"duration": 1.0, "leader": {"trajectory": "hover", "start": [0.0, 0.0, 0.0]}}


def _cf_gains_file() -> Path:
    """The Crazyflie's gains file: its file's ``gains``, a path relative to the vehicle file or a bundled
    gains file's name (scenarios/gains/NAME.toml)."""
    g = CF_TOML["gains"]
    for p in (CF_FILE.parent / g, REPO / "scenarios" / "gains" / g, REPO / "scenarios" / "gains" / f"{g}.toml"):
        if p.is_file():
            return p.resolve()
    raise AssertionError(f"the Crazyflie's gains file {g!r} not found")


# --------------------------------------------------------------------------- the gains rule


def test_the_gains_rule_in_its_order() -> None:
    a, b = np.full(12, 1.0), np.full(12, 2.0)
    cf = _cf_gains_file()
    assert choose_gains(option=(a, "a"), scenario=(b, "b"), vehicle=cf).origin == "option"
    c = choose_gains(scenario=(b, "b"), vehicle=cf)
    assert c.origin == "scenario" and c.gains is b
    c = choose_gains(vehicle=cf)
    assert c.origin == "vehicle" and np.array_equal(c.gains, load_gains(cf)) and c.source == str(cf)
    c = choose_gains()
    assert c.origin == "default" and c.source == "table4" and np.array_equal(c.gains, TABLE4_GAINS)
    assert list(GAINS_ORIGINS) == ["option", "scenario", "vehicle", "default"]


def test_a_scenario_without_gains_flies_its_vehicles() -> None:
    """Issue 47, new user 1: [vehicle] crazyflie21 and no [controller] gains flew Table 4's, silently."""
    sc = parse_scenario({**BASE, "vehicle": {"model": "crazyflie21"}})
    assert sc.gains_origin == "vehicle" and Path(sc.gains_source) == _cf_gains_file()
    assert np.array_equal(sc.gains, load_gains(_cf_gains_file()))
    named = parse_scenario({**BASE, "vehicle": {"model": "crazyflie21"}, "controller": {"gains": "table4"}})
    assert named.gains_origin == "scenario" and np.array_equal(named.gains, TABLE4_GAINS)
    paper = parse_scenario(BASE)
    assert (paper.gains_origin, paper.gains_source) == ("default", "table4")
    assert np.array_equal(paper.gains, TABLE4_GAINS)


# --------------------------------------------------------------------------- the vehicle switch


def test_with_overrides_vehicle_flies_the_vehicle() -> None:
    """Issue 47, new user 2: with_overrides(vehicle=...) changed the label only (params.m stayed 0.486)."""
    sc = load_scenario("circle").with_overrides(vehicle="crazyflie21")
    assert sc.vehicle == "crazyflie21"
    assert sc.params.m == CF_TOML["mass"] and sc.params.f_max == CF_TOML["max_thrust"]
    assert sc.params.L == CF_TOML["arm_length"]
    assert sc.vehicle_mixer == CF_TOML.get("mixer")
    assert sc.gains_origin == "vehicle" and np.array_equal(sc.gains, load_gains(_cf_gains_file()))
    assert sc.start_clearance < load_scenario("circle").start_clearance  # its size
    # and back: the paper's drone, Table 4 (its file names no gains)
    back = sc.with_overrides(vehicle="paper")
    assert back.params == DEFAULT_PARAMS and back.gains_origin == "default"
    assert np.array_equal(back.gains, TABLE4_GAINS)


def test_the_rotor_lag_follows_the_vehicle_unless_the_scenario_sets_its_own() -> None:
    real = with_aero(load_scenario("circle"), "realistic")
    assert real.aero.motor_tau == REALISTIC_MOTOR_TAU  # the paper's drone gives none: the preset's
    cf = real.with_overrides(vehicle="crazyflie21")
    assert cf.aero.motor_tau == CF_TOML["motor_tau"]
    assert cf.with_overrides(vehicle="paper").aero.motor_tau == REALISTIC_MOTOR_TAU
    assert load_scenario("circle").with_overrides(vehicle="crazyflie21").aero.motor_tau == 0  # paper physics
    own = load_scenario("circle").with_overrides(aero=parse_aero({"model": "realistic", "motor_tau": 0.03}))
    assert own.with_overrides(vehicle="crazyflie21").aero.motor_tau == 0.03


def test_chosen_gains_survive_a_vehicle_change() -> None:
    g = np.full(12, 3.0)
    sc = load_scenario("circle").with_overrides(gains=g).with_overrides(vehicle="crazyflie21")
    assert sc.gains_origin == "option" and np.array_equal(sc.gains, g)
    # the scenario's own gains (crazyflie_step names a gains file) stay on another vehicle
    step = load_scenario("crazyflie_step")
    other = step.with_overrides(vehicle="paper")
    assert other.gains_origin == "scenario" and np.array_equal(other.gains, step.gains)


def test_a_vehicle_too_big_for_the_starts_is_refused() -> None:
    """crazyflie_circle's starts are 0.5 m apart: the paper's drone touches rotors below 0.7 m."""
    with pytest.raises(UserError, match=r"followers\.start \(flown with vehicle paper\).*0\.7 m apart"):
        load_scenario("crazyflie_circle").with_overrides(vehicle="paper")


def test_the_vehicle_in_the_scenario_document_for_sweeps(tmp_path) -> None:  # noqa: ANN001
    f = tmp_path / "v.toml"
    f.write_text(CF_FILE.read_text().replace('name = "crazyflie21"', 'name = "mine"'))
    # the copy names the Crazyflie's gains by an absolute path (a relative one is relative to the vehicle file)
    f.write_text(re.sub(r"(?m)^gains = .*$", f'gains = "{_cf_gains_file()}"', f.read_text()))
    sc = flown("circle", vehicle=f)
    assert sc.raw["vehicle"] == {"model": str(f.resolve())}
    again = parse_scenario(sc.raw, sc.path)  # what `sweep --param` re-reads
    assert again.params == sc.params and again.gains_origin == "vehicle"


def test_an_unknown_vehicle_is_one_line_naming_the_option() -> None:
    with pytest.raises(UserError, match=r"^--vehicle: unknown vehicle 'nope': neither a bundled vehicle"):
        flown("circle", vehicle="nope", where=("--vehicle", "--aero", "--gains"))
    with pytest.raises(UserError, match=r"^aero: unknown aero model 'windy'"):
        flown("circle", aero="windy")


def test_the_gains_as_the_summary_names_them() -> None:
    assert gains_text(gains_name("table4"), "default") == "Table 4 (the default)"
    assert gains_text(gains_name(str(_cf_gains_file())), "vehicle") == (
        f"scenarios/gains/{_cf_gains_file().name} (the vehicle's)"
    )
    assert gains_text("inline", "scenario") == "inline (the scenario's)"


# --------------------------------------------------------------------------- one option, four commands


def test_vehicle_and_gains_are_one_option_in_every_flying_command() -> None:
    sub = next(a for a in build_parser()._actions if a.dest == "command").choices
    helps = {}
    for cmd in ("run", "video", "sweep", "stress"):
        acts = {a.dest: a for a in sub[cmd]._actions}
        assert acts["vehicle"].metavar == "NAME|FILE" and acts["gains"].metavar == "FILE", cmd
        helps[cmd] = (acts["vehicle"].help.split("(default")[0], acts["gains"].help)
    assert len(set(helps.values())) == 1, helps
    assert sub["run"].epilog == EXIT_EPILOG and f"; {EXIT_FLIGHT_FAILED} the run flew" in EXIT_EPILOG


def test_the_readme_documents_every_exit_status() -> None:
    import swarm_mj.commands as c

    text = (REPO / "README.md").read_text()
    section = text[text.index("### Exit status") :].split("\n## ")[0]
    for name in ("EXIT_OK", "EXIT_ERROR", "EXIT_USER", "EXIT_FLIGHT_FAILED", "EXIT_INTERRUPTED"):
        assert re.search(rf"^\| `?{getattr(c, name)}`? \|", section, re.M), name


# --------------------------------------------------------------------------- the outcome of a flight


def _log(z: np.ndarray, ref: np.ndarray, T: float = 0.01) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t = np.arange(len(z)) * T
    return t, z, ref


def test_a_drone_that_never_leaves_the_ground_never_took_off() -> None:
    k = 301  # 3 s
    ref = np.full((k, 2), 1.0)
    z = np.stack([np.linspace(0.0, 1.0, k), np.full(k, 0.02)], axis=1)  # the leader climbs, drone 1 sits
    out = flight_outcome(*_log(z, ref), ["leader", "follower1"], crashed=[])
    assert out == {"ok": False, "never_took_off": ["follower1"], "crashed": [], "lost": []}
    assert failure_line(out) == "flight failed: follower1 never took off"
    # a climb just above the clearance is a take-off; just below it is not
    z[100:, 1] = 0.02 + TAKEOFF_CLEARANCE * 1.01
    assert flight_outcome(*_log(z, ref), ["leader", "follower1"], [])["ok"]
    z[100:, 1] = 0.02 + TAKEOFF_CLEARANCE * 0.99
    assert flight_outcome(*_log(z, ref), ["leader", "follower1"], [])["never_took_off"] == ["follower1"]


def test_no_verdict_on_a_take_off_asked_too_late_or_never() -> None:
    k = 301
    z = np.zeros((k, 1))
    late = np.zeros((k, 1))
    late[-int(TAKEOFF_GRACE_S / 0.01) + 1 :] = 1.0  # asked less than the grace before the end
    assert flight_outcome(*_log(z, late), ["leader"], [])["ok"]
    assert flight_outcome(*_log(z, np.full((k, 1), 2 * TAKEOFF_CLEARANCE)), ["leader"], [])["ok"]  # not above
    early = np.zeros((k, 1))
    early[-int(TAKEOFF_GRACE_S / 0.01) - 1 :] = 1.0
    assert flight_outcome(*_log(z, early), ["leader"], [])["never_took_off"] == ["leader"]


def test_a_drone_back_on_the_ground_is_lost_and_a_crash_is_named() -> None:
    k = 301
    up_down = np.concatenate([np.linspace(0, 1, 150), np.linspace(1, 0.01, k - 150)])[:, None]
    out = flight_outcome(*_log(up_down, np.full((k, 1), 1.0)), ["leader"], crashed=[0, 0])
    assert out == {"ok": False, "never_took_off": [], "crashed": ["leader"], "lost": ["leader"]}
    assert failure_line(out) == "flight failed: leader crashed; leader was lost"
    landed = flight_outcome(*_log(up_down, np.concatenate([np.ones(150), np.zeros(k - 150)])[:, None]), ["a"], [])
    assert landed["ok"]  # asked to land: not lost
    assert failure_line(landed) is None and failure_line(None) is None


# --------------------------------------------------------------------------- like with like


def test_the_papers_figures_only_beside_the_papers_experiment() -> None:
    assert paper_comparable(load_scenario("circle")) and paper_comparable(load_scenario("step"))
    assert not paper_comparable(load_scenario("circle").with_overrides(vehicle="crazyflie21"))
    assert not paper_comparable(load_scenario("crazyflie_step"))  # the Crazyflie
    small = load_scenario("circle").with_overrides(trajectory_params={"radius": 1.0})
    assert not paper_comparable(small)  # the paper's drone on another circle
    assert paper_comparable(load_scenario("circle").with_overrides(trajectory_params={"radius": 2.5}))


# --------------------------------------------------------------------------- the hint after a tune


@pytest.mark.parametrize("vehicle", ["paper", "crazyflie21"])
def test_the_hint_flies_the_tuned_vehicle(vehicle: str) -> None:
    """Issue 47, new user 5: `tune --vehicle crazyflie21` suggested `run step`, the paper's drone."""
    params = load_vehicle(vehicle).params()
    hint = run_hint(vehicle, params, (1.0, 1.0, 1.0), 25.0, "g.toml")
    m = re.fullmatch(r"swarm-mj run (\S+) --gains g\.toml", hint)
    assert m, hint
    sc = load_scenario(m.group(1))
    assert sc.params == params and sc.trajectory == "step" and sc.n_followers == 0


def test_the_hint_for_a_vehicle_no_scenario_flies_names_it() -> None:
    params = replace(load_vehicle("crazyflie21").params(), m=0.05)
    hint = run_hint("my v.toml", params, (1.0, 1.0, 1.0), 25.0, "g.toml")
    m = re.fullmatch(r"swarm-mj run (\S+) --vehicle 'my v.toml' --gains g\.toml", hint)
    assert m, hint
    assert load_scenario(m.group(1)).trajectory == "step"


def test_stress_starts_fly_the_vehicles_gains_unless_given() -> None:
    """`stress --vehicle` flew the vehicle's gains by its own code; now by the one rule, as every scenario."""
    from swarm_mj.experiments.stress import StressCase, stress_scenario

    sc = stress_scenario(StressCase("layers", 3, 2, 3.0, 0.6, 1.0, vehicle="crazyflie21"))
    assert sc.gains_origin == "vehicle" and np.array_equal(sc.gains, load_gains(_cf_gains_file()))
    assert stress_scenario(StressCase("layers", 3, 2, 3.0, 0.6, 1.0)).gains_origin == "default"
