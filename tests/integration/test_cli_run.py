"""``swarm-mj run`` end to end (issue 4 "Done when"), the CLI in a subprocess as a user runs it.

* the summary JSON has the stable keys, and the same scenario and seed give the same summary;
* bad input: one line on stderr naming the file, the field and the problem, exit status 2,
  no traceback, no recording written and an existing one left alone;
* a diverging run: a clear message, exit status 1, the recording of what ran is written;
* Ctrl-C: exit status 130 and a readable recording, no ``.partial`` left behind.
"""

from __future__ import annotations

import json
import os
import select
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from helpers import start_until_progress

CLI = [sys.executable, "-m", "swarm_mj.cli"]
RERUN = Path(sys.executable).with_name("rerun")
VOLATILE = {"wall_time_s", "real_time_factor"}


def swarm(*args, cwd: Path, timeout: float = 300) -> subprocess.CompletedProcess:
    return subprocess.run(
        [*CLI, *map(str, args)], cwd=cwd, capture_output=True, text=True, timeout=timeout, stdin=subprocess.DEVNULL
    )


def one_error_line(p: subprocess.CompletedProcess) -> str:
    assert "Traceback" not in p.stderr, p.stderr
    lines = [ln for ln in p.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1, p.stderr
    assert lines[0].startswith("swarm-mj: error: "), lines[0]
    return lines[0]


def verify_rrd(path: Path) -> None:
    assert path.exists() and path.stat().st_size > 0
    assert not path.with_name(path.name + ".partial").exists()
    if RERUN.exists():
        p = subprocess.run([str(RERUN), "rrd", "verify", str(path)], capture_output=True, text=True, timeout=120)
        assert p.returncode == 0, p.stderr


def rrd_leader_times_and_positions(path: Path) -> tuple[np.ndarray, np.ndarray]:
    rr = pytest.importorskip("rerun")
    pytest.importorskip("datafusion")
    with rr.server.Server(datasets={"ds": [str(path)]}) as server:
        client = server.client()
        dataset = client.get_dataset("ds")
        df = dataset.filter_contents(["/world/drones/leader"]).reader(index="sim_time").to_pandas()
    t = df["sim_time"].to_numpy().astype("timedelta64[ns]").astype(np.int64) / 1e9
    pos = np.array(
        [np.stack(list(v)).astype(np.float64)[0] for v in df["/world/drones/leader:Transform3D:translation"]]
    )
    return t, pos


# --------------------------------------------------------------------------- summary


@pytest.fixture(scope="module")
def circle_summaries(tmp_path_factory):
    """Two runs of the same scenario and seed, each in its own process."""
    d = tmp_path_factory.mktemp("summ")
    out = []
    for i in range(2):
        p = swarm(
            "run", "circle", "--duration", 20, "--seed", 3, "--no-record", "--quiet", "--summary", f"s{i}.json", cwd=d
        )
        assert p.returncode == 0, p.stderr
        out.append(json.loads((d / f"s{i}.json").read_text()))
    assert not list(d.glob("*.rrd")), "--no-record must not write a recording"
    return out


def test_summary_has_the_stable_keys(circle_summaries):
    s = circle_summaries[0]
    assert s["scenario"] == "circle"
    assert s["sim_time_s"] == pytest.approx(20.0)
    assert isinstance(s["wall_time_s"], float) and isinstance(
        s["real_time_factor"], float
    )  # present; speed is benched in tools/
    assert set(s["drones"]) == {"leader", "follower1", "follower2", "follower3", "follower4", "follower5"}
    for name, d in s["drones"].items():
        assert set(d["rmse"]) >= {"x", "y", "z", "roll_deg", "pitch_deg"}, name
        assert all(isinstance(v, float) and np.isfinite(v) for v in d["rmse"].values())
        assert 0 <= d["max_rotor_thrust_n"] <= 4.5
        assert "step" not in d  # step metrics only for the step
    assert isinstance(s["contacts"], int) and s["contacts"] >= 0
    assert s["min_separation_m"] > 0
    assert isinstance(s["formation"]["settling_s"], list)
    assert s["formation"]["max_distance_error_m"] >= 0
    assert isinstance(s["anti_collision"]["events"], int)


def test_same_scenario_and_seed_give_identical_summaries(circle_summaries):
    a, b = ({k: v for k, v in s.items() if k not in VOLATILE} for s in circle_summaries)
    assert a == b
    assert a["seed"] == 3


def test_step_summary_has_step_metrics(tmp_path):
    p = swarm("run", "step", "--no-record", "--quiet", "--summary", "step.json", cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    s = json.loads((tmp_path / "step.json").read_text())
    assert s["scenario"] == "step" and s["sim_time_s"] == pytest.approx(10.0)
    d = s["drones"]["leader"]
    for ax in ("x", "y", "z", "psi"):
        assert set(d["step"][ax]) >= {"overshoot_pct", "settling_s", "steady_state_error"}
        assert all(np.isfinite(v) for v in d["step"][ax].values())
    assert 0 < d["max_rotor_thrust_n"] <= 4.5
    assert s["contacts"] == 0


def test_run_writes_the_recording_named_after_the_scenario(tmp_path):
    p = swarm("run", "step", "--duration", 2, "--quiet", cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    verify_rrd(tmp_path / "step.rrd")


# --------------------------------------------------------------------------- bad input

GOOD = 'description = "ok"\nduration = 5.0\n\n[leader]\ntrajectory = "hover"\n'

BAD_FILES = {
    # name: (file text, strings the one line must contain besides the path)
    "syntax": ('duration = 5.0\n[leader\ntrajectory = "hover"\n', ["line 2"]),
    "unknown_key": (GOOD + 'colour = "red"\n', ["colour", "unknown"]),
    "unknown_nested_key": (GOOD + "speed = 3.0\n", ["leader", "speed", "unknown"]),
    "missing_duration": ('[leader]\ntrajectory = "hover"\n', ["duration", "missing"]),
    "negative_D": (
        'duration = 5.0\n[leader]\ntrajectory = "circle"\n[followers]\nstart = [[1.0, 0.0, 0.0]]\n'
        "[formation]\ndiameter = -1.0\n",
        ["formation.diameter", "positive", "-1"],
    ),
    "unknown_trajectory": (
        'duration = 5.0\n[leader]\ntrajectory = "spiral"\n',
        ["leader.trajectory", "spiral", "unknown"],
    ),
    "bad_gains": (GOOD + "[controller]\ngains = [1.0, 2.0]\n", ["controller.gains", "12"]),
}


@pytest.mark.parametrize("case", sorted(BAD_FILES))
def test_bad_scenario_file_gives_one_line_and_exit_2(tmp_path, case):
    text, needles = BAD_FILES[case]
    f = tmp_path / f"{case}.toml"
    f.write_text(text)
    existing = tmp_path / "out.rrd"
    existing.write_bytes(b"previous recording")
    p = swarm("run", f.name, "-o", existing.name, "--summary", "s.json", cwd=tmp_path)
    assert p.returncode == 2, (p.returncode, p.stderr)
    line = one_error_line(p)
    assert f.name in line, line
    for n in needles:
        assert n in line, (n, line)
    assert existing.read_bytes() == b"previous recording"  # not destroyed
    assert not (tmp_path / "s.json").exists()
    assert sorted(x.name for x in tmp_path.iterdir()) == sorted([f.name, existing.name])


def test_nonexistent_path_gives_one_line_and_exit_2(tmp_path):
    p = swarm("run", "nowhere/missing.toml", cwd=tmp_path)
    assert p.returncode == 2
    line = one_error_line(p)
    assert "nowhere/missing.toml" in line and "not found" in line


def test_unknown_bundled_name_gives_one_line_and_exit_2(tmp_path):
    p = swarm("run", "circel", cwd=tmp_path)
    assert p.returncode == 2
    line = one_error_line(p)
    assert "circel" in line and "unknown scenario" in line
    assert "circle" in line  # lists what is bundled
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize(
    "args,needles",
    [
        (["--duration", "-1"], ["--duration", "positive"]),
        (["--gains", "nope.toml"], ["nope.toml", "not found"]),
    ],
)
def test_bad_options_give_one_line_and_exit_2(tmp_path, args, needles):
    p = swarm("run", "step", *args, cwd=tmp_path)
    assert p.returncode == 2
    line = one_error_line(p)
    for n in needles:
        assert n in line, line
    assert not list(tmp_path.glob("*.rrd"))


# --------------------------------------------------------------------------- divergence

# Attitude gains far beyond what a 10-ms zero-order hold can carry: the attitude loop is unstable
# in discrete time, the drone flips during the step and falls through the floor (about 1 s).
DIVERGING = (
    'description = "absurd attitude gains: diverges"\nduration = 10.0\n\n[leader]\ntrajectory = "step"\n\n'
    "[controller]\ngains = [1000.0, 1000.0, 1000.0, 1000.0, 1000.0, 1000.0, "
    "4.8548, 7.0579, 4.4025, 6.6385, 6.1893, 3.5344]\n"
)


def test_diverging_run_exits_1_with_a_message_and_a_readable_recording(tmp_path):
    (tmp_path / "diverge.toml").write_text(DIVERGING)
    out = tmp_path / "d.rrd"
    out.write_bytes(b"previous recording")  # replaced (atomically) by what ran
    p = swarm("run", "diverge.toml", "-o", out.name, "--summary", "d.json", "--quiet", cwd=tmp_path)
    assert p.returncode == 1, (p.returncode, p.stderr)
    line = one_error_line(p)
    assert "diverged" in line, line
    verify_rrd(out)
    assert out.read_bytes() != b"previous recording"
    t, pos = rrd_leader_times_and_positions(out)
    assert 0.0 < t[-1] < 10.0  # stopped early, what ran is there
    assert np.isfinite(pos).all()
    s = json.loads((tmp_path / "d.json").read_text())
    assert s["sim_time_s"] == pytest.approx(t[-1], abs=1e-6)
    assert "stopped" in s


# --------------------------------------------------------------------------- Ctrl-C


def test_interrupted_run_exits_130_with_a_readable_recording(tmp_path):
    proc, master, err = start_until_progress(
        [*CLI, "run", "circle", "-o", "X.rrd", "--summary", "X.json"], tmp_path, subprocess.PIPE, 0.2
    )
    try:
        proc.send_signal(signal.SIGINT)
        proc.communicate(timeout=120)
        while True:
            r, _, _ = select.select([master], [], [], 0.2)
            if not r:
                break
            try:
                chunk = os.read(master, 4096)
            except OSError:
                break
            if not chunk:
                break
            err += chunk
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        os.close(master)
    text = err.decode(errors="replace")
    assert proc.returncode == 130, (proc.returncode, text)
    assert "Traceback" not in text, text
    assert "interrupted" in text
    out = tmp_path / "X.rrd"
    verify_rrd(out)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["X.json", "X.rrd"]
    t, pos = rrd_leader_times_and_positions(out)
    assert 0.0 < t[-1] < 180.0 and np.isfinite(pos).all()
    s = json.loads((tmp_path / "X.json").read_text())
    assert "stopped" in s and s["sim_time_s"] == pytest.approx(t[-1], abs=1e-6)
