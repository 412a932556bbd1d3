"""The one step pipeline over whole runs and in other processes (issue 16 items 3, 4; issue 17): a
hover in an absurd wind ends diverged with exit 1 and its recording kept, Ctrl-C at a random moment
of ``swarm-mj run`` exits 130 with a readable recording, a run restores the SIGINT handler, and the
public API imports from the package in a fresh interpreter. The stages, copies, health mask and step
record are checked in tests/unit/test_pipeline.py."""

from __future__ import annotations

import importlib
import os
import random
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from helpers import start_until_progress

CLI = [sys.executable, "-m", "swarm_mj.cli"]
RERUN = Path(sys.executable).with_name("rerun")


HURRICANE = (
    'description = "hover in a wind of 1e6 m/s from t = 0"\nduration = 3.0\n\n[leader]\n'
    'trajectory = "hover"\n\n[wind]\nmean = [1e6, 0.0]\nschedule = [[0.0, inf, "xy"]]\n'
)


def test_hover_in_an_absurd_wind_ends_diverged_with_exit_1_and_the_recording_kept(tmp_path):
    """Issue 16 item 3: MuJoCo's automatic reset kept the drone at its start and the run exited 0."""
    (tmp_path / "hurricane.toml").write_text(HURRICANE)
    p = subprocess.run(
        [*CLI, "run", "hurricane.toml", "-o", "h.rrd", "--summary", "h.json", "--quiet"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=300,
        stdin=subprocess.DEVNULL,
    )
    assert p.returncode == 1, (p.returncode, p.stderr)
    assert "Traceback" not in p.stderr
    assert "diverged" in p.stderr and "mjWARN_BADQACC" in p.stderr
    assert (tmp_path / "h.rrd").stat().st_size > 0
    if RERUN.exists():
        v = subprocess.run(
            [str(RERUN), "rrd", "verify", str(tmp_path / "h.rrd")], capture_output=True, text=True, timeout=120
        )
        assert v.returncode == 0, v.stderr


# --------------------------------------------------------------------------- Ctrl-C


def _interrupt_once(tmp_path: Path, delay: float) -> tuple[int, str]:
    proc, master, err = start_until_progress(
        [*CLI, "run", "circle", "--duration", "3000", "-o", "X.rrd"], tmp_path, subprocess.DEVNULL, 0.05
    )
    try:
        time.sleep(delay)
        proc.send_signal(signal.SIGINT)
        t_end = time.monotonic() + 180
        while proc.poll() is None and time.monotonic() < t_end:
            r, _, _ = select.select([master], [], [], 0.2)
            if r:
                try:
                    err += os.read(master, 4096)
                except OSError:
                    break
        proc.wait(timeout=5)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        os.close(master)
    return proc.returncode, err.decode(errors="replace")


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_ctrl_c_at_a_random_moment_exits_130_with_a_readable_recording(tmp_path, seed):
    """Issue 16 item 4: SIGINT inside a compiled kernel gave SystemError and lost the recording."""
    delay = random.Random(seed).uniform(0.0, 2.0)
    rc, text = _interrupt_once(tmp_path, delay)
    assert rc == 130, (rc, text)
    assert "Traceback" not in text and "SystemError" not in text, text
    out = tmp_path / "X.rrd"
    assert out.exists() and out.stat().st_size > 0
    if RERUN.exists():
        v = subprocess.run([str(RERUN), "rrd", "verify", str(out)], capture_output=True, text=True, timeout=120)
        assert v.returncode == 0, v.stderr


def test_the_sigint_handler_is_restored_after_a_run():
    from swarm_mj.experiments.runner import run

    before = signal.getsignal(signal.SIGINT)
    run("step", duration=0.05, progress=False)
    assert signal.getsignal(signal.SIGINT) is before


def test_public_api_imports_from_the_package():
    p = subprocess.run(
        [
            sys.executable,
            "-c",
            "import os, sys\n"
            "from swarm_mj import SwarmEnv, BacksteppingPolicy, load_scenario, run\n"
            "import swarm_mj\n"
            "assert 'MUJOCO_GL' in os.environ or not sys.platform.startswith('linux')\n"
            "assert run.__module__ == 'swarm_mj.experiments.runner' and SwarmEnv.__module__ == 'swarm_mj.env'\n"
            "print(swarm_mj.__version__)",
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert p.returncode == 0, p.stderr
    assert p.stdout.strip() == importlib.import_module("swarm_mj").__version__
