"""Issue 16: every bad input refused before the run, nothing clobbered (items 1, 2, 5-9, 12, 13).

The reproducers of the issue, each through the CLI's ``main()`` in this process (a few in a
subprocess, as a user runs them). "Before any simulation" is checked by replacing
``swarm_mj.experiments.runner.run`` with a function that fails the test if called, and by checking that
no recording or summary was written; never by a wall clock.
"""

from __future__ import annotations

import json
import math
import os
import re
import stat
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest

from swarm_mj import cli
from swarm_mj.errors import OutputError, UserError
from swarm_mj.output.atomic import (
    check_output_path,
    dumps_strict,
    json_safe,
    replace_into,
    write_json_atomic,
    write_text_atomic,
)
from swarm_mj.scenario import MAX_SEED, START_CLEARANCE_M, load_scenario, parse_scenario, run_log_bytes, scenario_toml

#: A citation of a notes file outside the repository (an upper-case name as a file or with a §), not
#: docs/ (README.md excepted): the printed text cites docs/ only.
CITES_OUTSIDE = re.compile(r"\b(?!README\b)[A-Z]{4,}(?:\.md\b| §)")

CIRCLE = """
name = "c"
duration = {duration}
control_period = {control_period}
seed = 0
[leader]
trajectory = "{trajectory}"
start = [0.0, 0.0, 0.0]
{params}
[followers]
start = {followers}
[controller]
gains = {gains}
"""


def scenario_file(
    tmp_path: Path,
    *,
    duration="0.3",
    control_period="0.01",
    trajectory="circle",
    params="",
    followers="[[1.5, 0.0, 0.0], [-1.5, 0.0, 0.0]]",
    gains='"table4"',
    name="s.toml",
) -> Path:
    p = tmp_path / name
    p.write_text(
        CIRCLE.format(
            duration=duration,
            control_period=control_period,
            trajectory=trajectory,
            params=params,
            followers=followers,
            gains=gains,
        )
    )
    return p


@pytest.fixture
def no_flight(monkeypatch):
    """Fail the test if anything is flown (the runner's entry point or the environment)."""
    from swarm_mj.experiments import runner

    def boom(*a, **k):
        raise AssertionError("a simulation started before the bad input was refused")

    monkeypatch.setattr(runner, "run", boom)
    monkeypatch.setattr(runner, "SwarmEnv", boom, raising=False)


def cli_error(capsys, argv: list[str], code: int = 2) -> str:
    """Run ``swarm-mj ARGV`` in this process; assert the exit code and one ``swarm-mj: error:`` line."""
    rc = cli.main([str(a) for a in argv])
    err = capsys.readouterr().err
    assert rc == code, err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("swarm-mj: error: "), err
    assert "Traceback" not in err
    return lines[0]


# --------------------------------------------------------------------------- item 1: output paths first


@pytest.mark.parametrize("opt", [["-o", "nodir/x.rrd"], ["--no-record", "--summary", "nodir/s.json"]])
def test_output_path_in_a_missing_folder_is_refused_before_the_run(tmp_path, monkeypatch, capsys, no_flight, opt):
    monkeypatch.chdir(tmp_path)
    line = cli_error(capsys, ["run", "circle", *opt])
    assert "nodir" in line and "does not exist" in line
    assert list(tmp_path.iterdir()) == []


def test_summary_into_an_existing_folder_is_refused(tmp_path, monkeypatch, capsys, no_flight):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "d").mkdir()
    line = cli_error(capsys, ["run", "circle", "--no-record", "--summary", "d"])
    assert "--summary d" in line and "folder" in line
    assert list((tmp_path / "d").iterdir()) == []


@pytest.mark.skipif(os.geteuid() == 0, reason="root may write into a read-only folder")
def test_summary_into_a_read_only_folder_is_refused(tmp_path, monkeypatch, capsys, no_flight):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    line = cli_error(capsys, ["run", "circle", "--no-record", "--summary", ro / "s.json"])
    assert "not writable" in line


def test_recording_and_summary_at_the_same_path_are_refused(tmp_path, monkeypatch, capsys, no_flight):
    monkeypatch.chdir(tmp_path)
    line = cli_error(capsys, ["run", "circle", "-o", "x.rrd", "--summary", "x.rrd"])
    assert "same file" in line


@pytest.mark.parametrize("out", ["nodir/g.toml", "."])
def test_tune_output_checked_first(tmp_path, monkeypatch, capsys, out):
    monkeypatch.chdir(tmp_path)
    from swarm_mj.tuning import cost

    monkeypatch.setattr(cost, "tune_gains", lambda *a, **k: pytest.fail("tuned before checking -o"))
    cli_error(capsys, ["tune", "-o", out])


# --------------------------------------------------------------------------- item 2: the atomic writer


def test_json_safe_is_strict_and_converts_numpy():
    data = {
        "a": float("nan"),
        "b": [float("inf"), -np.inf, np.float32(1.5)],
        "c": np.arange(3),
        "d": np.int64(7),
        "e": (np.bool_(True), None),
        "f": {"g": np.array([np.nan, 2.0])},
    }
    text = dumps_strict(data)
    back = json.loads(text, parse_constant=lambda c: pytest.fail(f"non-strict constant {c}"))
    assert back == {
        "a": None,
        "b": [None, None, 1.5],
        "c": [0, 1, 2],
        "d": 7,
        "e": [True, None],
        "f": {"g": [None, 2.0]},
    }
    assert json_safe(float("nan")) is None


def test_regular_file_is_replaced_atomically_and_keeps_its_mode(tmp_path):
    p = tmp_path / "s.json"
    p.write_text("old")
    p.chmod(0o640)
    write_json_atomic(p, {"x": 1})
    assert json.loads(p.read_text()) == {"x": 1}
    assert stat.S_IMODE(p.stat().st_mode) == 0o640
    assert [q.name for q in tmp_path.iterdir()] == ["s.json"]  # no temporary file left


def test_symlink_is_written_through_to_its_target(tmp_path):
    target = tmp_path / "real.json"
    target.write_text("{}")
    link = tmp_path / "link.json"
    link.symlink_to(target.name)
    write_json_atomic(link, {"y": 2})
    assert link.is_symlink() and os.readlink(link) == "real.json"
    assert json.loads(target.read_text()) == {"y": 2}


def _fifo_reader(path: Path, out: list) -> threading.Thread:
    def read():
        with open(path, "rb") as f:
            out.append(f.read())

    t = threading.Thread(target=read, daemon=True)
    t.start()
    return t


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs here")
def test_fifo_is_written_in_place_never_replaced(tmp_path):
    fifo = tmp_path / "f"
    os.mkfifo(fifo)
    got: list = []
    t = _fifo_reader(fifo, got)
    write_json_atomic(fifo, {"z": float("nan")})
    t.join(30)
    assert stat.S_ISFIFO(os.stat(fifo).st_mode)
    assert json.loads(got[0]) == {"z": None}
    # the same for a finished temporary file (recordings, videos)
    tmp = tmp_path / "x.partial"
    tmp.write_bytes(b"payload")
    got.clear()
    t = _fifo_reader(fifo, got)
    replace_into(tmp, fifo)
    t.join(30)
    assert got == [b"payload"] and stat.S_ISFIFO(os.stat(fifo).st_mode) and not tmp.exists()


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs here")
def test_run_summary_into_a_fifo(tmp_path, capsys):
    fifo = tmp_path / "f"
    os.mkfifo(fifo)
    got: list = []
    t = _fifo_reader(fifo, got)
    rc = cli.main(["run", "circle", "--duration", "0.2", "--no-record", "--quiet", "--summary", str(fifo)])
    t.join(60)
    assert rc == 0, capsys.readouterr().err
    assert stat.S_ISFIFO(os.stat(fifo).st_mode)
    assert json.loads(got[0])["scenario"] == "circle"


@pytest.mark.skipif(
    not (
        os.path.exists("/dev/full") and stat.S_ISCHR(os.stat("/dev/full").st_mode) and os.access("/dev/full", os.W_OK)
    ),
    reason="no writable /dev/full",
)
def test_dev_full_is_a_one_line_error_and_stays_a_device(monkeypatch, capsys):
    # A regression must fail here, not replace the device node: os.replace may not be reached.
    monkeypatch.setattr(os, "replace", lambda *a: pytest.fail("tried to replace /dev/full"))
    with pytest.raises(OutputError, match="No space left"):
        write_text_atomic("/dev/full", "x" * 10)
    line = cli_error(
        capsys, ["run", "circle", "--duration", "0.2", "--no-record", "--quiet", "--summary", "/dev/full"], code=1
    )
    assert "/dev/full" in line
    assert stat.S_ISCHR(os.stat("/dev/full").st_mode)


def test_recording_through_a_symlink_keeps_the_link(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "runs").mkdir()
    link = tmp_path / "latest.rrd"
    link.symlink_to("runs/real.rrd")  # dangling until the run writes its target
    assert cli.main(["run", "circle", "--duration", "0.2", "--quiet", "-o", "latest.rrd"]) == 0, capsys.readouterr().err
    assert link.is_symlink() and (tmp_path / "runs" / "real.rrd").stat().st_size > 0
    assert not list(tmp_path.rglob("*.partial"))


def test_dash_is_standard_output(capsys):
    write_json_atomic("-", {"w": np.inf})
    assert json.loads(capsys.readouterr().out) == {"w": None}
    assert check_output_path("-", "--summary", allow_stdout=True) == Path("-")


# --------------------------------------------------------------------------- items 5-9: the scenario


@pytest.mark.parametrize(
    "trajectory, params, field, problem",
    [
        ("circle", 'params = { radius = "big" }', "leader.params.radius", "must be a number"),
        ("circle", 'params = { center = "origin" }', "leader.params.center", "list of 2 numbers"),
        ("step", 'params = { target = "up" }', "leader.params.target", "list of 3 numbers"),
        ("step", "params = { target = [1, 1] }", "leader.params.target", "list of 3 numbers"),
        ("circle", "params = { omega = nan }", "leader.params.omega", "finite"),
        ("circle", "params = { omega = 1e200 }", "leader.params", "not finite"),
        ("circle", "params = { altitude = -1.0 }", "leader.params", "below the ground"),
        ("circle", "params = { spin = 1.0 }", "leader.params.spin", "unknown parameter"),
        ("step", "params = { yaw_deg = true }", "leader.params.yaw_deg", "must be a number"),
    ],
)
def test_trajectory_parameters_named_before_the_run(
    tmp_path, monkeypatch, capsys, no_flight, trajectory, params, field, problem
):
    monkeypatch.chdir(tmp_path)
    f = scenario_file(tmp_path, trajectory=trajectory, params=params)
    line = cli_error(capsys, ["run", f, "--summary", "s.json"])
    assert f"{f}: {field}" in line and problem in line, line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.toml"]


@pytest.mark.parametrize(
    "followers, pair",
    [
        ("[[1.5, 0.0, 0.0], [1.5, 0.0, 0.0]]", "follower1 and follower2"),
        ("[[1.5, 0.0, 0.0], [1.61, 0.0, 0.0]]", "follower1 and follower2"),
        ("[[0.3, 0.4, 0.0], [-1.5, 0.0, 0.0]]", "leader and follower1"),
    ],
)
def test_explicit_starts_too_close_are_refused(tmp_path, monkeypatch, capsys, no_flight, followers, pair):
    monkeypatch.chdir(tmp_path)
    f = scenario_file(tmp_path, followers=followers)
    line = cli_error(capsys, ["run", f])
    assert "followers.start" in line and pair in line and f"{START_CLEARANCE_M:g} m" in line, line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.toml"]


def test_explicit_starts_spacing_boundary_and_ground():
    base = {"duration": 1.0, "leader": {"trajectory": "hover"}}
    ok = {**base, "followers": {"start": [[START_CLEARANCE_M, 0.0, 0.0], [0.0, START_CLEARANCE_M, 0.0]]}}
    assert parse_scenario(ok).n_followers == 2  # exactly the clearance: accepted
    near = {**base, "followers": {"start": [[START_CLEARANCE_M - 1e-3, 0.0, 0.0], [0.0, 2.0, 0.0]]}}
    with pytest.raises(UserError, match="apart"):
        parse_scenario(near)
    under = {**base, "followers": {"start": [[2.0, 0.0, -0.1]]}}
    with pytest.raises(UserError, match="below the ground"):
        parse_scenario(under)
    with pytest.raises(UserError, match="leader.start"):
        parse_scenario({**base, "leader": {"trajectory": "hover", "start": [0, 0, -1]}})
    # every bundled scenario passes
    from swarm_mj.scenario import bundled_scenarios

    for name in bundled_scenarios():
        load_scenario(name)


@pytest.mark.parametrize(
    "argv_tail, field, problem",
    [
        (["--duration", "inf"], "--duration", "finite"),
        (["--duration", "nan"], "--duration", "finite"),
        (["--duration", "1e9"], "--duration", "GiB"),
        (["--duration", "-1"], "--duration", "positive"),
        (["--duration", "0.001"], "--duration", "shorter than one control period"),
        (["--seed", "-1"], "--seed", ">= 0"),
        (["--seed", str(MAX_SEED + 1)], "--seed", str(MAX_SEED)),
        (["--gains", "/"], "/", "folder"),
    ],
)
def test_extreme_options_one_line(tmp_path, monkeypatch, capsys, no_flight, argv_tail, field, problem):
    monkeypatch.chdir(tmp_path)
    line = cli_error(capsys, ["run", "circle", *argv_tail])
    assert field in line and problem in line, line
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    "duration, control_period, field, problem",
    [
        ("1e9", "0.01", "duration", "GiB"),
        ("0.005", "0.01", "control_period", "longer than the duration"),
        ("0.3", "0.5", "control_period", "longer than the duration"),
        ("inf", "0.01", "duration", "finite"),
    ],
)
def test_file_durations_against_control_period_and_memory(
    tmp_path, monkeypatch, capsys, no_flight, duration, control_period, field, problem
):
    monkeypatch.chdir(tmp_path)
    f = scenario_file(tmp_path, duration=duration, control_period=control_period)
    line = cli_error(capsys, ["run", f])
    assert f"{f}: {field}" in line and problem in line, line


def test_memory_estimate_counts_steps_drones_and_fields(monkeypatch):
    from swarm_mj import scenario

    assert run_log_bytes(99, 6) == 8 * 100 * (33 * 6 + 35)
    assert scenario.available_memory_bytes() is None or scenario.available_memory_bytes() > 0
    avail = 2**30  # pretend 1 GiB is available
    monkeypatch.setattr(scenario, "available_memory_bytes", lambda: avail)
    # the largest accepted duration's log is at most half the memory; a little more is refused
    n = 6
    steps = int(0.5 * avail / (8 * (33 * n + 35)))
    scenario.check_duration(0.01 * (steps - 10), 0.01, n)
    with pytest.raises(UserError, match="MiB") as ei:
        scenario.check_duration(0.01 * (steps + 10), 0.01, n)
    assert "of the 1 GiB of memory available" in str(ei.value), str(ei.value)


@pytest.mark.parametrize("make", ["dir", "malformed", "missing", "unreadable"])
def test_gains_files_that_cannot_be_read(tmp_path, monkeypatch, capsys, no_flight, make):
    if make == "unreadable" and os.geteuid() == 0:
        pytest.skip("root reads any file")
    monkeypatch.chdir(tmp_path)
    g = tmp_path / "somedir"
    if make == "dir":
        g.mkdir()
    elif make == "malformed":
        g.write_text("gains = [1, 2, ")
    elif make == "unreadable":
        g.write_text("gains = [1.0]\n")
        g.chmod(0)
    f = scenario_file(tmp_path, gains='"somedir"')
    line = cli_error(capsys, ["run", f])
    assert "controller.gains" in line, line
    line = cli_error(capsys, ["run", "circle", "--gains", g])
    assert "somedir" in line


def test_gains_file_with_the_wrong_number_of_rows(tmp_path, monkeypatch, capsys, no_flight):
    monkeypatch.chdir(tmp_path)
    g = tmp_path / "g2.toml"
    g.write_text("gains = [" + ", ".join(["[" + ", ".join(["2.0"] * 12) + "]"] * 2) + "]\n")
    line = cli_error(capsys, ["run", "circle", "--gains", g])
    assert "g2.toml: gains" in line and "(2, 12)" in line


def test_reproducers_in_a_subprocess_leave_nothing(tmp_path):
    """Two of the issue's reproducers as a user types them: one line, exit 2, nothing written."""
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join([str(Path(__file__).resolve().parents[2]), os.environ.get("PYTHONPATH", "")]),
    }
    for argv in (["run", "circle", "--duration", "inf"], ["run", "circle", "-o", "nodir/x.rrd"]):
        p = subprocess.run(
            [sys.executable, "-m", "swarm_mj.cli", *argv],
            cwd=tmp_path,
            capture_output=True,
            text=True,
            env=env,
            timeout=300,
            stdin=subprocess.DEVNULL,
            check=False,
        )
        assert p.returncode == 2 and "Traceback" not in p.stderr, p.stderr
        assert len(p.stderr.strip().splitlines()) == 1
    assert list(tmp_path.iterdir()) == []


# --------------------------------------------------------------------------- item 12: one meaning of seed


def _random_start_table(seed: int = 0) -> dict:
    return {
        "duration": 0.5,
        "seed": seed,
        "leader": {"trajectory": "circle"},
        "followers": {"count": 3, "random_start": {"radius": 3.0, "min_spacing": 0.6, "seed": 11}},
        "wind": {"enabled": True},
    }


def test_with_overrides_seed_rederives_random_starts_and_wind():
    sc = parse_scenario(_random_start_table())
    s7 = sc.with_overrides(seed=7)
    assert s7.seed == 7 and s7.random_start.seed == 7
    assert not np.allclose(s7.initial_positions(), sc.initial_positions())
    # the file's seed 7 with its random starts seeded 7: the same scenario
    t = _random_start_table(7)
    t["followers"]["random_start"]["seed"] = 7
    np.testing.assert_array_equal(parse_scenario(t).initial_positions(), s7.initial_positions())
    with pytest.raises(UserError, match="seed"):
        sc.with_overrides(seed=-1)


def test_stress_seed_replayed_by_run(tmp_path, monkeypatch, capsys):
    """A stress case's seed flown again by ``swarm-mj run FILE --seed S``: the same contacts and
    the same minimum separation (the same starts and wind)."""
    from swarm_mj.commands.stress import StressCase, fly_case, stress_data

    monkeypatch.chdir(tmp_path)
    case = StressCase("paper", 3, 3, 2.5, 0.6, 1.0)
    row = fly_case(case)
    f = tmp_path / "stress.toml"
    f.write_text(scenario_toml(stress_data(StressCase("layers", 0, 3, 2.5, 0.6, 1.0))))
    rc = cli.main(
        ["run", str(f), "--seed", "3", "--anti-collision", "paper", "--no-record", "--quiet", "--summary", "s.json"]
    )
    assert rc == 0, capsys.readouterr().err
    s = json.loads(Path("s.json").read_text())
    assert s["contacts"] == row["contacts"]
    assert s["min_separation_m"] == row["min_separation_m"]
    # and a different seed flies different starts
    rc = cli.main(
        ["run", str(f), "--seed", "4", "--anti-collision", "paper", "--no-record", "--quiet", "--summary", "s4.json"]
    )
    assert rc == 0
    assert json.loads(Path("s4.json").read_text())["min_separation_m"] != row["min_separation_m"]


def test_stress_prints_the_replay_command(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    rc = cli.main(
        [
            "stress",
            "--rule",
            "off",
            "--starts",
            "2",
            "--followers",
            "2",
            "--duration",
            "0.3",
            "--workers",
            "1",
            "--save-scenario",
            "st.toml",
        ]
    )
    out = capsys.readouterr().out
    assert rc == 0
    replay = [ln for ln in out.splitlines() if "replay: swarm-mj run st.toml --seed" in ln]
    assert len(replay) == 1 and replay[0].endswith("--anti-collision off")
    assert load_scenario("st.toml").random_start is not None


def test_sweep_prints_a_replay_command_that_flies_the_same_run(tmp_path, monkeypatch, capsys):
    """The sweep's worst run (most contacts, else smallest separation) replayed by the command it
    prints: the same metrics (same random starts, same wind)."""
    import shlex

    monkeypatch.chdir(tmp_path)
    f = tmp_path / "rs.toml"
    f.write_text(scenario_toml(_random_start_table()))
    assert (
        cli.main(
            ["sweep", str(f), "--seeds", "3", "--duration", "0.3", "--workers", "1", "--quiet", "--json", "sw.json"]
        )
        == 0
    )
    out = capsys.readouterr().out
    line = next(ln for ln in out.splitlines() if "replay: swarm-mj run" in ln)
    argv = shlex.split(line.split("replay: ", 1)[1])[1:]
    runs = json.loads(Path("sw.json").read_text())["runs"]
    seed = int(argv[argv.index("--seed") + 1])
    worst = min(runs, key=lambda r: r["metrics"]["min_separation_m"])
    assert seed == worst["seed"]
    assert cli.main([*argv, "--no-record", "--quiet", "--summary", "r.json"]) == 0
    s = json.loads(Path("r.json").read_text())
    assert s["min_separation_m"] == worst["metrics"]["min_separation_m"]
    assert s["drones"]["leader"]["rmse"]["x"] == worst["metrics"]["rmse_x"]


# --------------------------------------------------------------------------- item 13: the summary text


def _fmt(summary: dict, sc) -> str:
    from swarm_mj.experiments.report_table import format_summary

    return format_summary(summary, sc)


def test_summary_text_of_a_short_run_that_never_settled(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    rc = cli.main(["run", "circle", "--duration", "0.5", "--no-record", "--summary", "s.json"])
    out = capsys.readouterr().out
    assert rc == 0
    s = json.loads(Path("s.json").read_text())
    assert s["formation"]["settling_s"] == [None]  # strict JSON: never settled -> null
    assert not re.search(r"never s\b", out) and "never settled" in out
    assert "once settled" not in out  # no "max 0.0 cm once settled"
    assert "from t = 10 s" not in out and ">10s" not in out  # a 0.5 s run has no steady part
    assert not CITES_OUTSIDE.search(out)
    # the same text from the summary read back from JSON
    text = _fmt(s, load_scenario("circle"))
    assert "never settled" in text and "once settled" not in text


def test_summary_text_of_a_long_run_cites_the_docs():
    sc = load_scenario("circle_single")
    s = {
        "scenario": "x",
        "sim_time_s": 20.0,
        "wall_time_s": 1.0,
        "real_time_factor": 20.0,
        "n_drones": 1,
        "seed": 0,
        "wind": False,
        "drones": {
            "leader": {
                "rmse": dict.fromkeys(("x", "y", "z", "roll_deg", "pitch_deg"), 0.1),
                "rmse_steady": dict.fromkeys(("x", "y", "z", "roll_deg", "pitch_deg"), 0.01),
                "max_rotor_thrust_n": 3.0,
            }
        },
    }
    text = _fmt(s, sc)
    assert "from t = 10 s on, docs/interpretations.md" in text and not CITES_OUTSIDE.search(text)


def test_interrupt_with_no_record_does_not_claim_a_recording(tmp_path, monkeypatch, capsys):
    from swarm_mj.experiments import runner

    real = runner.run

    def interrupted(*a, **k):
        res = real(*a, **k)
        res.error = KeyboardInterrupt()
        return res

    monkeypatch.setattr(runner, "run", interrupted)
    monkeypatch.chdir(tmp_path)
    rc = cli.main(["run", "circle", "--duration", "0.2", "--no-record", "--quiet"])
    err = capsys.readouterr().err
    assert rc == 130
    assert "interrupted" in err and "recording" not in err
    rc = cli.main(["run", "circle", "--duration", "0.2", "--quiet", "-o", "r.rrd"])
    err = capsys.readouterr().err
    assert rc == 130 and "the recording holds what ran" in err and Path("r.rrd").exists()


def test_no_nan_in_a_successful_summary_file(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert cli.main(["run", "step", "--duration", "0.3", "--no-record", "--quiet", "--summary", "s.json"]) == 0
    text = Path("s.json").read_text()
    json.loads(text, parse_constant=lambda c: pytest.fail(f"{c} in the summary"))
    assert not any(isinstance(v, float) and not math.isfinite(v) for v in _leaves(json.loads(text)))


def _leaves(o):
    if isinstance(o, dict):
        for v in o.values():
            yield from _leaves(v)
    elif isinstance(o, list):
        for v in o:
            yield from _leaves(v)
    else:
        yield o


def test_stress_barrier_formation_inside_its_keepout_is_one_line_exit_2(capsys):
    argv = ["stress", "--rule", "barrier", "--followers", "12", "--starts", "1", "--duration", "1", "--quiet"]
    assert cli.main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--diameter" in err[0] and "keep-out" in err[0], err
