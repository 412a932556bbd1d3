"""``swarm-mj report [-o report/] [--quick] [--workers W]``: the paper's experiments beside ours."""

from __future__ import annotations

import argparse


def add_parser(sub) -> None:
    p = sub.add_parser(
        "report",
        help="run the paper's experiments; write a Markdown report with plots and results.json",
        description="Fly every experiment of the paper (step, Table 5 with and without wind, the swarm "
        "scenarios, variable D, anti-collision, wind robustness over 20 seeds, FPA convergence) in "
        "worker processes and write OUT/README.md (each paper figure or table beside ours), "
        "OUT/results.json (every number) and the PNG figures. Needs matplotlib "
        "(pip install 'swarm-mj[report]').",
    )
    p.add_argument("-o", "--output", default="report", metavar="DIR", help="output folder (default: report/)")
    p.add_argument(
        "--quick",
        action="store_true",
        help="short runs and few seeds (seconds, for checking the pipeline; not the paper's numbers)",
    )
    p.add_argument("--workers", type=int, metavar="W", help="worker processes (default: all CPUs)")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    from ..errors import UserError
    from ..report import build_report

    if args.workers is not None and args.workers < 1:
        raise UserError(f"--workers must be >= 1, got {args.workers}")
    res = build_report(args.output, quick=args.quick, workers=args.workers, progress=not args.quiet)
    print(
        f"report: {args.output}/README.md ({len(res['figures'])} figures, results.json) in "
        f"{res['meta']['wall_s']:.0f} s"
    )
    return 0
