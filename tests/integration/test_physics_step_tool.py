"""tools/accuracy.py end to end, in its own process (issue 20, docs/physics_step.md): the study on the
step scenario, shortened, writes its JSON, markdown and docs page. The flight it compares and the
tool's pieces are checked in tests/unit/test_physics_step.py."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_tool_runs_end_to_end(tmp_path):
    """The study on the step scenario, shortened: JSON, markdown and the docs page come out."""
    js, md, doc = tmp_path / "a.json", tmp_path / "a.md", tmp_path / "physics_step.md"
    env = {**os.environ, "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    r = subprocess.run(
        [
            sys.executable,
            str(ROOT / "tools" / "accuracy.py"),
            "--scenarios",
            "step",
            "--duration",
            "2",
            "--settings",
            "RK4:1,RK4:5,RK4:10",
            "--json",
            str(js),
            "--markdown",
            str(md),
            "--docs",
            str(doc),
        ],
        check=False,
        capture_output=True,
        text=True,
        env=env,
        cwd=tmp_path,
    )
    assert r.returncode == 0, r.stderr
    d = json.loads(js.read_text())
    rows = d["cases"][0]["rows"]
    assert [x["label"] for x in rows] == ["RK4 1 ms", "RK4 5 ms", "RK4 10 ms"]
    assert rows[0]["max_deviation_m"] == 0.0
    assert 0.0 < rows[2]["max_deviation_m"] < 1e-3
    assert "RK4 10 ms" in md.read_text() and "zero-order hold" in doc.read_text()
