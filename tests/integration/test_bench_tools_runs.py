"""tools/bench_peers.py's crazyflow flight, in its own process, writes its log (issue 30; when crazyflow
is installed). The other benchmark tools' pieces are checked in tests/unit/test_bench_tools.py."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

TOOLS = Path(__file__).resolve().parents[2] / "tools"


@pytest.mark.skipif(importlib.util.find_spec("crazyflow") is None, reason="crazyflow not installed (.[bench])")
def test_crazyflow_flight_writes_its_log(tmp_path):
    out = tmp_path / "cf.npz"
    cmd = [sys.executable, str(TOOLS / "bench_peers.py"), "--crazyflow-flight", str(out), "--duration", "0.5"]
    subprocess.run(cmd, check=True, cwd=tmp_path, capture_output=True, timeout=600)
    log = np.load(out)
    assert log["pos"].shape == (50, 6, 3) and log["t"].shape == (50,)
    assert np.isfinite(log["pos"]).all()
    # the drones climb toward the circle's height of 1 m from the ground
    assert (log["pos"][-1, :, 2] > log["pos"][0, :, 2]).all()
