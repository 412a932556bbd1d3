"""The formation layer's bad input through the command line (docs/interpretations.md §4): an impossible
random follower start is refused by ``swarm-mj run`` before anything flies (one line, exit 2, nothing
written). The rules themselves are checked without physics in tests/unit/test_formation.py."""

from __future__ import annotations

import subprocess
import sys


def test_impossible_random_start_reaches_the_cli_as_one_line_and_exit_2(tmp_path):
    f = tmp_path / "bad.toml"
    f.write_text(
        'duration = 5.0\n[leader]\ntrajectory = "circle"\n[followers]\ncount = 6\n'
        "[followers.random_start]\nradius = 1.0\nmin_spacing = 2.0\nseed = 1\n"
    )
    p = subprocess.run(
        [sys.executable, "-m", "swarm_mj.cli", "run", "bad.toml", "--no-record"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert p.returncode == 2, (p.returncode, p.stderr)
    lines = [ln for ln in p.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1, p.stderr
    assert "bad.toml" in lines[0] and "followers.random_start" in lines[0]
    assert p.stdout == ""
    assert sorted(x.name for x in tmp_path.iterdir()) == ["bad.toml"]  # nothing flown, nothing written
