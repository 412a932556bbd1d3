"""``swarm-mj warm-up``: compile every kernel into Numba's on-disk cache now (the fused path too).

A first ``swarm-mj run`` compiles the per-step kernels itself and the fused path in the background
(``swarm_mj/fused.py``); this does both in the foreground, e.g. once after installing, so that
every later run starts fast.
"""

from __future__ import annotations

import argparse
import sys


def add_parser(sub) -> None:
    p = sub.add_parser("warm-up", help="compile every kernel now, so that later runs start fast")
    p.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    from .. import _jit, fused

    if not _jit.AVAILABLE:
        print("Numba is not in use (SWARM_MJ_NO_JIT or not installed): nothing to compile", file=sys.stderr)
        return 0
    print("compiling the per-step kernels…", file=sys.stderr, flush=True)
    t_kernels = _jit.warm_up()
    if fused.compiled():
        t_fused = 0.0
    else:
        print("compiling the fused path…", file=sys.stderr, flush=True)
        t_fused = fused.compile_now()
    ok = fused.compiled()
    print(
        f"kernels ready in {t_kernels:.1f} s; fused path "
        + (f"ready in {t_fused:.1f} s" if ok else "not available here (runs fly step by step)"),
        file=sys.stderr,
    )
    return 0
