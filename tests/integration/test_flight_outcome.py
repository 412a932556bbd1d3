"""Runs never claim what did not happen (issue 47): a run in which a drone never takes off or crashes exits
3 and says so in one line, settling reads "never"; a tune whose every candidate diverged writes no gains
file and exits 3; the hint after a tune flies the tuned vehicle.

A vehicle that cannot lift is refused where a vehicle file is loaded, so the drones are held down here
by a Vehicle built in the test with its thrust below its weight (the load check bypassed), handed to the
commands through the one place they resolve a vehicle (``resolve_vehicle``, as ``swarm_mj.scenario`` imports it)."""

from __future__ import annotations

import json
import re
import tomllib
from dataclasses import replace
from pathlib import Path

import pytest

from swarm_mj import scenario as scenario_module  # where scenarios and --vehicle resolve a vehicle
from swarm_mj.cli import main as cli_main
from swarm_mj.commands import EXIT_FLIGHT_FAILED
from swarm_mj.experiments.runner import run
from swarm_mj.scenario import load_scenario
from swarm_mj.vehicles import Vehicle, load_vehicle

G = 9.81
CF = load_vehicle("crazyflie21")


def weak(share: float) -> Vehicle:
    """The Crazyflie with its four rotors' most thrust ``share`` of its weight."""
    f = share * CF.mass * G / 4
    v = replace(CF, name="weak", extra={**CF.extra, "max_thrust": f})
    assert 4 * v.params().f_max < v.params().m * G  # it cannot lift, by the numbers
    return v


@pytest.fixture
def held_down(monkeypatch):  # noqa: ANN001, ANN201
    """``--vehicle weak`` resolves to a Crazyflie whose rotors give 97 % of its weight."""
    real = scenario_module.resolve_vehicle
    monkeypatch.setattr(
        scenario_module,
        "resolve_vehicle",
        lambda model, base, where: ("weak", weak(0.97), None) if model == "weak" else real(model, base, where),
    )


def _one_line(err: str) -> str:
    assert "Traceback" not in err
    lines = [ln for ln in err.splitlines() if ln.startswith("swarm-mj: ")]
    assert len(lines) == 1, err
    return lines[0]


def test_a_swarm_that_never_took_off_exits_3_and_never_settled(tmp_path, monkeypatch, capsys, held_down) -> None:  # noqa: ANN001
    """Issue 47, new user 3: no drone took off and the run printed settling 0.00 s, RMSE 0, exit 0."""
    monkeypatch.chdir(tmp_path)
    argv = ["run", "crazyflie_circle", "--vehicle", "weak", "--aero", "realistic", "--duration", "3"]
    rc = cli_main([*argv, "--no-record", "--summary", "s.json"])
    out = capsys.readouterr()
    assert rc == EXIT_FLIGHT_FAILED == 3
    assert _one_line(out.err) == "swarm-mj: flight failed: leader never took off"
    s = json.loads(Path("s.json").read_text())
    assert s["flight"] == {"ok": False, "never_took_off": ["leader"], "crashed": [], "lost": []}
    assert s["formation"]["settling_s"] == [None]  # never (strict JSON), not 0
    assert "formation settling: never settled" in out.out and "0.00 s (D change" not in out.out
    assert "FLIGHT FAILED: leader never took off" in out.out


def test_held_down_under_the_papers_physics_too() -> None:
    """No ground there: the drone sinks, never rising above its start (the run does not stop: 3 s)."""
    res = run(load_scenario("crazyflie_hover").with_overrides(vehicle=weak(0.995), duration=3.0), progress=False)
    assert res.error is None and res.log.pos[:, 0, 2].max() <= res.log.pos[0, 0, 2]
    assert res.summary["flight"]["never_took_off"] == ["leader"]


def test_a_crash_exits_3(tmp_path, monkeypatch, capsys) -> None:  # noqa: ANN001
    """A drone starting 2 m up on rotors giving half its weight falls: a ground crash (> 1 m/s)."""
    monkeypatch.setattr(scenario_module, "resolve_vehicle", lambda model, base, where: ("weak", weak(0.5), None))
    monkeypatch.chdir(tmp_path)
    Path("drop.toml").write_text(
        'duration = 3.0\n[leader]\ntrajectory = "hover"\nstart = [0.0, 0.0, 2.0]\n'
        "params = { position = [0.0, 0.0, 2.0] }\n"
    )
    rc = cli_main(["run", "drop.toml", "--vehicle", "weak", "--aero", "realistic", "--no-record", "--quiet"])
    assert rc == 3
    assert _one_line(capsys.readouterr().err) == "swarm-mj: flight failed: leader crashed"


def test_a_sweep_with_a_failed_flight_exits_3(tmp_path, monkeypatch, capsys, held_down) -> None:  # noqa: ANN001
    monkeypatch.chdir(tmp_path)
    argv = ["sweep", "crazyflie_hover", "--vehicle", "weak", "--aero", "realistic", "--seeds", "1"]
    rc = cli_main([*argv, "--duration", "2", "--workers", "1", "--quiet", "--json", "w.json"])
    out = capsys.readouterr().out
    assert rc == 3
    assert "1 of 1 runs failed; seed 0: flight failed: leader never took off" in out
    assert "replay: swarm-mj run crazyflie_hover --seed 0 --duration 2.0 --vehicle weak --aero realistic" in out
    assert json.loads(Path("w.json").read_text())["runs"][0]["flight_failed"] is not None


def test_the_papers_runs_exit_0(tmp_path, monkeypatch, capsys) -> None:  # noqa: ANN001
    monkeypatch.chdir(tmp_path)
    for argv in (["circle"], ["anti_collision", "--aero", "realistic"], ["crazyflie_circle", "--aero", "realistic"]):
        assert cli_main(["run", *argv, "--duration", "3", "--no-record", "--quiet"]) == 0, argv


# --------------------------------------------------------------------------- tune


def test_tune_refuses_when_every_candidate_diverged(tmp_path, monkeypatch, capsys) -> None:  # noqa: ANN001
    """Issue 47, new user 3: tune wrote a gains file with ISE inf/nan, exited 0 and suggested a run."""
    import swarm_mj.vehicles

    monkeypatch.setattr(swarm_mj.vehicles, "load_vehicle", lambda name: weak(0.5))  # falls below the floor
    out = tmp_path / "g.toml"
    out.write_text("gains = [1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1]  # kept\n")
    before = out.read_text()
    argv = ["tune", "--vehicle", "weak", "--population", "4", "--iterations", "1", "--t-sim", "3"]
    rc = cli_main([*argv, "--workers", "1", "--threads", "1", "-o", str(out), "--quiet"])
    err = capsys.readouterr().err
    assert rc == 3
    line = _one_line(err)
    assert line.startswith("swarm-mj: error: no candidate flew the step") and "no gains file written" in line
    assert out.read_text() == before


@pytest.mark.slow
def test_tune_hint_flies_the_tuned_vehicle(tmp_path, capsys) -> None:  # noqa: ANN001
    """Issue 47, new user 5: `tune --vehicle crazyflie21` ended with `try: swarm-mj run step --gains …`."""
    out = tmp_path / "g.toml"
    argv = ["tune", "--vehicle", "crazyflie21", "--population", "4", "--iterations", "1", "--t-sim", "3"]
    assert cli_main([*argv, "--workers", "1", "--seed", "1", "-o", str(out)]) == 0
    last = capsys.readouterr().out.strip().splitlines()[-1]
    m = re.fullmatch(
        rf"written: {re.escape(str(out))}   \(try: swarm-mj run (\S+) --gains {re.escape(str(out))}\)", last
    )
    assert m, last
    assert load_scenario(m.group(1)).params == CF.params()  # a scenario of the vehicle tuned, by its data
    header = [ln for ln in out.read_text().splitlines() if ln.startswith("# Use:")]
    assert header == [
        f'# Use: swarm-mj run {m.group(1)} --gains FILE, or [controller] gains = "FILE" in a scenario of this vehicle.'
    ]
    assert tomllib.loads(out.read_text())["settings"]["vehicle"] == "crazyflie21"


@pytest.mark.egl
def test_a_video_of_a_failed_flight_exits_3(tmp_path, monkeypatch, capsys, held_down) -> None:  # noqa: ANN001
    monkeypatch.chdir(tmp_path)
    argv = ["video", "crazyflie_hover", "--vehicle", "weak", "--aero", "realistic", "--duration", "2"]
    rc = cli_main([*argv, "--size", "64x48", "--fps", "5", "--quality", "fast", "-o", "v.mp4", "--quiet"])
    assert rc == 3 and Path("v.mp4").stat().st_size > 0
    assert _one_line(capsys.readouterr().err) == "swarm-mj: flight failed: leader never took off (the video shows it)"
