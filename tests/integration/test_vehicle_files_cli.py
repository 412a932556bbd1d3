"""Issue 47 on the command line: a vehicle file that cannot hover with margin, or that has an unknown
key, is refused by every command that takes it, exit 2 and one line, before anything is flown or
written (items 3, 4); a scenario with a ``[formation.barrier]`` table flies under a rule without a
barrier filter (item 8). The checks themselves: tests/unit/test_vehicles.py, tests/unit/test_scenario.py."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from swarm_mj import cli
from swarm_mj.vehicles import _HERE

CF = (_HERE / "crazyflie21.toml").read_text()


def _cf_file(folder: Path, name: str, old: str, new: str) -> Path:
    """A copy of the bundled Crazyflie's file with one line's start ``old`` replaced by ``new``."""
    lines = [new if ln.startswith(old) else ln for ln in CF.splitlines()]
    assert lines != CF.splitlines()
    p = folder / name
    p.write_text("\n".join(lines) + "\n")
    return p


@pytest.fixture
def no_flight(monkeypatch):
    """Fail the test if anything is flown (the runner's entry point or the environment)."""
    from swarm_mj.experiments import runner

    def boom(*a, **k):
        raise AssertionError("a simulation started before the bad vehicle was refused")

    monkeypatch.setattr(runner, "run", boom)
    monkeypatch.setattr(runner, "SwarmEnv", boom, raising=False)


def _error_line(capsys, argv: list[str]) -> str:
    rc = cli.main([str(a) for a in argv])
    err = capsys.readouterr().err
    assert rc == 2, err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("swarm-mj: error: ") and "Traceback" not in err, err
    return lines[0]


def test_a_vehicle_that_cannot_hover_is_refused_by_every_command(tmp_path, monkeypatch, capsys, no_flight):
    """The issue's example: the Crazyflie's file with mass = 0.067 kg."""
    monkeypatch.chdir(tmp_path)
    heavy = _cf_file(tmp_path, "cf_heavy.toml", "mass =", "mass = 0.067")
    f_max = float(re.search(r"^max_thrust = ([0-9.]+)", CF, re.M)[1])
    figure = f"thrust-to-weight {4 * f_max / (0.067 * 9.81):.2f} "
    (tmp_path / "s.toml").write_text(
        'duration = 2.0\n[leader]\ntrajectory = "hover"\n[vehicle]\nmodel = "cf_heavy.toml"\n'
    )
    before = sorted(tmp_path.iterdir())
    for argv in (
        ["run", "s.toml"],
        ["run", "circle", "--vehicle", heavy],
        ["stress", "--vehicle", heavy, "--starts", "1", "--workers", "1"],
        ["tune", "--vehicle", heavy, "-o", "g.toml"],
    ):
        line = _error_line(capsys, argv)
        assert line.count(heavy.name) == 1 and figure in line and "below the minimum 1.4" in line, (argv, line)
    assert sorted(tmp_path.iterdir()) == before  # nothing written


def test_a_vehicle_file_with_a_typo_is_refused_with_a_did_you_mean(tmp_path, monkeypatch, capsys, no_flight):
    monkeypatch.chdir(tmp_path)
    typo = _cf_file(tmp_path, "cf_typo.toml", "motor_tau", "motor_ta = 0.05")
    for argv in (["run", "circle", "--vehicle", typo], ["stress", "--vehicle", typo, "--starts", "1"]):
        line = _error_line(capsys, argv)
        assert line == f"swarm-mj: error: {typo}: unknown key 'motor_ta'; did you mean 'motor_tau'?"


BARRIER_TABLE = """description = "a [formation.barrier] table"
duration = 2.0
[leader]
trajectory = "hover"
params = {position = [0.0, 0.0, 1.0]}
[followers]
start = [[1.0, 0.0, 0.0]]
[formation]
anti_collision = "barrier"
[formation.barrier]
gain = 2.5
"""


def test_a_barrier_table_flies_under_a_rule_without_a_filter(tmp_path, monkeypatch, capsys):
    """Item 8: ``--anti-collision jet-aware`` and a sweep over the rules were exit 2; they fly."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "b.toml").write_text(BARRIER_TABLE)
    assert cli.main(["run", "b.toml", "--anti-collision", "jet-aware", "--no-record", "--quiet"]) == 0
    assert "error" not in capsys.readouterr().err
    argv = ["sweep", "b.toml", "--param", "formation.anti_collision=barrier,jet-aware", "--seeds", "1"]
    assert cli.main([*argv, "--workers", "1", "--quiet"]) == 0
    assert "error" not in capsys.readouterr().err
