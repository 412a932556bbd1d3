"""Golden summaries: fly a fixed set of runs of the paper's drone and compare their summaries to 1e-9.

    python tools/golden.py write DIR [--rev REV]   # fly the set with this tree (or git REV) into DIR
    python tools/golden.py compare BASE NEW        # every number of BASE's summaries in NEW's, to 1e-9

The set: six runs under the paper's physics (circle, anti_collision, scenario1-3, wind_circle), three
under ``--aero realistic`` (circle, anti_collision, lemniscate) and ``swarm-mj stress`` 20 x 5 under both
(auto and paper; auto and barrier). A refactoring that must not change a flight (issue 48's bar) writes
the set at the base commit (``--rev``: a temporary git worktree) and at the new tree, then compares. Keys
that time the run (wall time, speed, the machine, output paths) are ignored; new keys in NEW are allowed.
Exit status 0 when identical, 1 with the differences listed.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
PAPER = ("circle", "anti_collision", "scenario1", "scenario2", "scenario3", "wind_circle")
REALISTIC = ("circle", "anti_collision", "lemniscate")
STRESS = {
    "stress_paper": ["--rule", "auto", "--rule", "paper"],
    "stress_real": ["--rule", "auto", "--rule", "barrier", "--aero", "realistic"],
}
IGNORED = {"wall_time_s", "real_time_factor", "machine", "json", "workers", "gains_source", "save_scenario"}


def _cli(src: Path, out: Path, args: list[str]) -> None:
    env = dict(os.environ, PYTHONPATH=str(src), MUJOCO_GL=os.environ.get("MUJOCO_GL", "egl"))
    p = subprocess.run([sys.executable, "-m", "swarm_mj.cli", *args], cwd=out, env=env, capture_output=True, text=True)
    if p.returncode not in (0, 3):  # 3: a flight that lost a drone is still a summary to compare
        raise SystemExit(f"golden: swarm-mj {' '.join(args)} failed ({p.returncode}): {p.stderr.strip()[-500:]}")


def write(src: Path, out: Path) -> None:
    """Fly the set with the package in ``src`` and write its summaries (JSON) into ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    runs = [(s, s, []) for s in PAPER] + [(f"{s}_real", s, ["--aero", "realistic"]) for s in REALISTIC]
    for name, scenario, extra in runs:
        print(f"golden: {name}", flush=True)
        _cli(src, out, ["run", scenario, *extra, "--no-record", "--quiet", "--summary", str(out / f"{name}.json")])
    for name, extra in STRESS.items():
        print(f"golden: {name}", flush=True)
        _cli(
            src,
            out,
            ["stress", "--starts", "20", *extra, "--quiet", "--workers", "2", "--json", str(out / f"{name}.json")],
        )


def differences(a: object, b: object, path: str = "") -> list[str]:
    """Where ``b`` differs from ``a``: numbers beyond 1e-9 (relative above 1), anything else unequal;
    keys of ``a`` in :data:`IGNORED` are skipped and keys only in ``b`` are allowed."""
    if isinstance(a, dict):
        if not isinstance(b, dict):
            return [f"{path}: not a table"]
        out = []
        for k, v in a.items():
            if k in IGNORED:
                continue
            out += [f"{path}.{k}: missing"] if k not in b else differences(v, b[k], f"{path}.{k}")
        return out
    if isinstance(a, list):
        if not isinstance(b, list) or len(a) != len(b):
            return [f"{path}: lists differ"]
        return [d for i, (x, y) in enumerate(zip(a, b)) for d in differences(x, y, f"{path}[{i}]")]
    if isinstance(a, float) and isinstance(b, int | float) and not isinstance(b, bool):
        same = a == b or (math.isnan(a) and math.isnan(b)) or abs(a - b) <= 1e-9 * max(1.0, abs(a))
        return [] if same else [f"{path}: {a!r} vs {b!r}"]
    return [] if a == b else [f"{path}: {a!r:.80} vs {b!r:.80}"]


def compare(base: Path, new: Path) -> list[str]:
    """Every difference of the summaries in ``new`` from those in ``base`` (a summary missing counts)."""
    out = []
    for f in sorted(base.glob("*.json")):
        g = new / f.name
        out += (
            [f"{f.name}: not written"]
            if not g.exists()
            else differences(json.loads(f.read_text()), json.loads(g.read_text()), f.name)
        )
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    w = sub.add_parser("write", help="fly the set into DIR")
    w.add_argument("dir", type=Path)
    w.add_argument("--rev", help="fly a git revision's package (a temporary worktree) instead of this tree")
    c = sub.add_parser("compare", help="compare two written sets")
    c.add_argument("base", type=Path)
    c.add_argument("new", type=Path)
    a = ap.parse_args(argv)
    if a.cmd == "compare":
        diffs = compare(a.base, a.new)
        print("\n".join(diffs[:60]) or "IDENTICAL")
        print(f"{len(diffs)} differences")
        return 1 if diffs else 0
    out = a.dir.resolve()
    if a.rev is None:
        write(REPO, out)
        return 0
    with tempfile.TemporaryDirectory() as tmp:
        tree = Path(tmp) / "tree"
        subprocess.run(
            ["git", "-C", str(REPO), "worktree", "add", "--detach", str(tree), a.rev], check=True, capture_output=True
        )
        try:
            write(tree, out)
        finally:
            subprocess.run(
                ["git", "-C", str(REPO), "worktree", "remove", "--force", str(tree)], check=False, capture_output=True
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
