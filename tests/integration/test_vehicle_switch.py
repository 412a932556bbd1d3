"""A vehicle is a switch everywhere (issue 47): ``--vehicle`` in the commands, ``vehicle=``/``aero=`` in the
environments, the vehicle's own gains where the scenario names none, the summary naming what flew, and the
paper's figures printed only beside the paper's experiment. Short flights (≤ 3 s)."""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

import numpy as np
import pytest

from swarm_mj.cli import main as cli_main
from swarm_mj.control.backstepping import load_gains
from swarm_mj.env import SwarmEnv
from swarm_mj.errors import UserError
from swarm_mj.experiments.report_table import format_summary
from swarm_mj.experiments.runner import run
from swarm_mj.scenario import load_scenario
from swarm_mj.wrappers import SwarmVectorEnv
from swarm_mj.wrappers.gymnasium import SwarmGymEnv
from swarm_mj.wrappers.pettingzoo import SwarmParallelEnv

REPO = Path(__file__).resolve().parents[2]
CF_FILE = REPO / "swarm_mj" / "vehicles" / "crazyflie21.toml"
CF = tomllib.loads(CF_FILE.read_text())  # the vehicle file as written, read here independently
PAPER_MASS = 0.486  # Table 1


def _cf_gains_file() -> Path:
    g = CF["gains"]
    for p in (CF_FILE.parent / g, REPO / "scenarios" / "gains" / g, REPO / "scenarios" / "gains" / f"{g}.toml"):
        if p.is_file():
            return p.resolve()
    raise AssertionError(f"the Crazyflie's gains file {g!r} not found")


def _drone_masses(env) -> np.ndarray:  # noqa: ANN001
    """Each drone's mass as MuJoCo's model holds it (what the physics flies)."""
    w = env.world
    return np.asarray(w.model.body_mass[w.body_ids])


def _run_cli(tmp_path: Path, monkeypatch, capsys, *args: str) -> tuple[int, dict, str, str]:  # noqa: ANN001
    monkeypatch.chdir(tmp_path)
    rc = cli_main(["run", *args, "--no-record", "--summary", "s.json"])
    out = capsys.readouterr()
    s = json.loads((tmp_path / "s.json").read_text()) if (tmp_path / "s.json").exists() else {}
    return rc, s, out.out, out.err


# --------------------------------------------------------------------------- the switches fly the vehicle's mass


def test_run_vehicle_flies_its_mass(tmp_path, monkeypatch, capsys) -> None:  # noqa: ANN001
    """`swarm-mj run circle --vehicle crazyflie21`: the Crazyflie's rotors (a paper drone hovers at 1.19 N
    a rotor, above the Crazyflie's whole range) and its own gains, named in the summary."""
    rc, s, out, _ = _run_cli(tmp_path, monkeypatch, capsys, "circle", "--vehicle", "crazyflie21", "--duration", "3")
    assert rc == 0
    assert (s["vehicle"], s["physics"], s["gains"]["origin"]) == ("crazyflie21", "paper", "vehicle")
    assert max(d["max_rotor_thrust_n"] for d in s["drones"].values()) <= CF["max_thrust"] + 1e-12
    assert PAPER_MASS * 9.81 / 4 > CF["max_thrust"]  # so no paper drone could have flown these rotors
    assert f"vehicle crazyflie21, physics paper, gains scenarios/gains/{_cf_gains_file().name} (the vehicle's)" in out


def test_env_vehicle_and_aero_fly_the_vehicles_mass() -> None:
    for env in (
        SwarmEnv("circle", vehicle="crazyflie21"),
        SwarmEnv(load_scenario("circle").with_overrides(vehicle="crazyflie21")),
        SwarmGymEnv("circle", vehicle="crazyflie21").env,
        SwarmParallelEnv("circle", vehicle=CF_FILE).env,
    ):
        assert env.params.m == CF["mass"]
        np.testing.assert_array_equal(_drone_masses(env), CF["mass"])
    real = SwarmEnv("circle", vehicle="crazyflie21", aero="realistic")
    assert real.scenario.aero.model == "realistic" and real.scenario.aero.motor_tau == CF["motor_tau"]
    assert real.sim.monitors, "the realistic preset's ground monitor"
    np.testing.assert_array_equal(_drone_masses(SwarmEnv("circle")), PAPER_MASS)  # unchanged without the switch
    with pytest.raises(UserError, match="vehicle= and aero= go to the SwarmEnv itself"):
        SwarmGymEnv(SwarmEnv("circle"), vehicle="crazyflie21")


def test_vector_env_vehicle() -> None:
    envs = SwarmVectorEnv("circle", 2, vehicle="crazyflie21", threads=1)
    try:
        assert envs.params.m == CF["mass"]
        np.testing.assert_array_equal(np.asarray(envs.physics.blocks[0].sim.params.m), CF["mass"])
    finally:
        envs.close()
    envs = SwarmVectorEnv("circle", 2, vehicle="crazyflie21", aero="realistic", threads=1)  # issue 48: any physics
    try:
        sim = envs.physics.blocks[0].sim
        assert envs.scenario.aero.model == "realistic" and sim.motor_lag and sim.monitors
        assert sim.params.m == CF["mass"]
    finally:
        envs.close()


# --------------------------------------------------------------------------- the vehicle's own gains


@pytest.mark.slow
def test_a_scenario_of_a_vehicle_without_gains_flies_the_vehicles(tmp_path, monkeypatch, capsys) -> None:  # noqa: ANN001
    """Issue 47, new user 1: it flew Table 4's, silently, in `run` while `stress --vehicle` flew the vehicle's."""
    f = tmp_path / "cf_step.toml"
    f.write_text(
        'duration = 3.0\n[vehicle]\nmodel = "crazyflie21"\n[leader]\ntrajectory = "step"\n'
        "params = { target = [1.0, 1.0, 1.0], yaw_deg = 25.0 }\n"
    )
    res = run(load_scenario(f), aero="realistic", progress=False)
    np.testing.assert_array_equal(res.scenario.gains, load_gains(_cf_gains_file()))
    rc, s, out, _ = _run_cli(tmp_path, monkeypatch, capsys, str(f), "--aero", "realistic")
    assert rc == 0 and s["gains"] == {"source": f"scenarios/gains/{_cf_gains_file().name}", "origin": "vehicle"}
    assert s["drones"] == res.summary["drones"]  # the CLI flew the same gains
    name = _cf_gains_file().name
    assert f"vehicle crazyflie21, physics realistic, gains scenarios/gains/{name} (the vehicle's)" in out
    # --gains wins over the vehicle's
    g = tmp_path / "g.toml"
    g.write_text(f"gains = {[4.0] * 12}\n")
    rc, s, out, _ = _run_cli(tmp_path, monkeypatch, capsys, str(f), "--gains", str(g), "--duration", "1")
    assert rc == 0 and s["gains"] == {"source": "g.toml", "origin": "option"}
    assert "gains g.toml (given for the run)" in out


# --------------------------------------------------------------------------- like with like


def _text(name: str, **kw) -> str:  # noqa: ANN003
    res = run(load_scenario(name), progress=False, duration=1.0, **kw)
    return format_summary(res.summary, res.scenario)


def test_paper_rows_only_beside_the_papers_drone_and_experiment() -> None:
    paper = _text("circle")
    assert "paper (Table 5)" in paper and "(paper: ~3 s)" in paper
    cf = run(load_scenario("circle").with_overrides(vehicle="crazyflie21"), progress=False, duration=1.0)
    text = format_summary(cf.summary, cf.scenario)
    assert "paper (Table 5)" not in text and "(paper: ~" not in text
    assert "paper (Table 5)" not in _text("crazyflie_circle")
    step = _text("step")
    assert "overshoot %  settling s" in step.split("axis", 1)[1].splitlines()[0].split("ss error")[1]
    cf_step = _text("crazyflie_step")
    assert "paper" not in cf_step.split("step response", 1)[1].split("max |roll|")[0]


def test_downwash_lines_only_under_physics_with_downwash() -> None:
    paper = _text("circle")
    assert "keep-out" not in paper and "jet" not in paper  # the paper's physics has no downwash
    real = _text("circle", aero="realistic")
    assert "downwash keep-out (the vehicle's ellipsoid" in real and "altitude dip in another drone's jet" in real
