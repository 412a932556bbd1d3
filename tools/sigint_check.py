"""Ctrl-C at random moments of a long run (issue 16): every SIGINT must end in exit status 130, one
line on stderr, no traceback, and a recording that ``rerun rrd verify`` accepts.

    python tools/sigint_check.py [--runs 20] [--seed 20261130] [--max-delay 12] [--dir /tmp/sigint]

Each run is ``swarm-mj run circle --duration 3000 -o DIR/k/c.rrd`` in a subprocess; SIGINT comes
after a seeded random delay in [0.5, max-delay] s, so some land while the program loads, some while
it compiles or builds the world, most while it flies. Prints one line per run and the tally; exits 1
if any run fails. Takes about 15 s per run on a 2-core machine.
"""

from __future__ import annotations

import argparse
import os
import random
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=20)
    ap.add_argument("--seed", type=int, default=20261130)
    ap.add_argument("--max-delay", type=float, default=12.0)
    ap.add_argument("--dir", type=Path, default=None, help="work folder (default: a new temporary one)")
    a = ap.parse_args()
    work = a.dir or Path(tempfile.mkdtemp(prefix="swarm-mj-sigint-"))
    rerun = Path(sys.executable).with_name("rerun")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    rng = random.Random(a.seed)
    ok = 0
    for k in range(a.runs):
        d = work / str(k)
        d.mkdir(parents=True, exist_ok=True)
        out = d / "c.rrd"
        out.unlink(missing_ok=True)
        p = subprocess.Popen(
            [sys.executable, "-m", "swarm_mj.cli", "run", "circle", "--duration", "3000", "-o", str(out), "--quiet"],
            cwd=d,
            env=env,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            # a background shell starts children with SIGINT ignored: give this one the default
            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
        )
        delay = rng.uniform(0.5, a.max_delay)
        time.sleep(delay)
        p.send_signal(signal.SIGINT)
        _, err = p.communicate(timeout=300)
        verified = out.exists() and (
            subprocess.run([str(rerun), "rrd", "verify", str(out)], capture_output=True, timeout=120).returncode == 0
        )
        lines = [line for line in err.splitlines() if line.strip()]
        good = p.returncode == 130 and len(lines) == 1 and "Traceback" not in err and verified
        ok += good
        size = out.stat().st_size if out.exists() else 0
        rec = "verified" if verified else "MISSING/BAD"
        print(
            f"{k:2d} SIGINT at {delay:5.2f} s: exit {p.returncode}, recording {rec} ({size} bytes), "
            f"stderr {lines[-1] if lines else ''!r}{'' if good else '  <- FAIL'}",
            flush=True,
        )
    print(f"{ok}/{a.runs} exit 130 with one line and a verified recording ({work})")
    return 0 if ok == a.runs else 1


if __name__ == "__main__":
    sys.exit(main())
