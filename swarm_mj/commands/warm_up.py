"""``swarm-mj warm-up``: compile every kernel into Numba's on-disk cache now (the fast path too).

A first ``swarm-mj run`` compiles the per-step kernels itself and the chunk driver in the background
(``swarm_mj/pipeline/fast.py``); this does both in the foreground, for the paper's and the realistic physics,
e.g. once after installing, so that every later run starts fast.
"""

from __future__ import annotations

import argparse
import sys


def add_parser(sub) -> None:
    p = sub.add_parser("warm-up", help="compile every kernel now, so that later runs start fast")
    p.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    from .. import _jit
    from ..experiments import runner
    from ..pipeline import fast

    if not _jit.AVAILABLE:
        print("Numba is not in use (SWARM_MJ_NO_JIT or not installed): nothing to compile", file=sys.stderr)
        return 0
    print("compiling the per-step kernels…", file=sys.stderr, flush=True)
    t_kernels = _jit.warm_up(everything=True)
    sigs = runner.preset_signatures()
    if all(fast.compiled(sig) for sig in sigs):
        t_fast = 0.0
    else:
        print("compiling the fast path…", file=sys.stderr, flush=True)
        t_fast = fast.compile_now(sigs)
    ok = all(fast.compiled(sig) for sig in sigs)
    print(
        f"kernels ready in {t_kernels:.1f} s; fast path "
        + (f"ready in {t_fast:.1f} s" if ok else "not available here (runs fly step by step)"),
        file=sys.stderr,
    )
    return 0
