"""``swarm-mj list`` in its own process lists every bundled scenario with its description (issue 4).
The scenario files themselves are checked in tests/unit/test_scenario.py."""

from __future__ import annotations

import subprocess
import sys
import tomllib

from swarm_mj.scenario import bundled_scenarios

BUNDLED = bundled_scenarios()


def test_swarm_mj_list_lists_every_bundled_scenario_with_its_description():
    p = subprocess.run([sys.executable, "-m", "swarm_mj.cli", "list"], capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    lines = [ln for ln in p.stdout.splitlines() if ln.strip()]
    listed = {}
    for ln in lines:
        name, _, desc = ln.partition(" ")
        listed[name] = desc.strip()
    assert set(listed) == set(BUNDLED)
    for name, path in BUNDLED.items():
        assert listed[name] == tomllib.loads(path.read_text())["description"]
