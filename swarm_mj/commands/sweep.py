"""``swarm-mj sweep SCENARIO --seeds N [--param KEY=V1,V2,...]``: seeded runs, mean/std/worst."""

from __future__ import annotations

import argparse
import sys


def add_parser(sub) -> None:
    p = sub.add_parser(
        "sweep", help="many seeded runs of a scenario: mean, std and worst case of the key metrics",
        description="Fly a scenario once per seed (0..N-1: wind turbulence and random starts) and, with "
                    "--param, once per value of one scenario field; print the mean, standard deviation and "
                    "worst case (max for errors and settling, min for separation) of the leader's RMSE "
                    "(whole run and from t = 10 s), and for swarms the contacts, minimum separation, "
                    "formation settling and formation distance error. Results do not depend on --workers.",
        epilog="examples: swarm-mj sweep wind_lemniscate --seeds 20;  "
               "swarm-mj sweep wind_circle --seeds 10 --param wind.sigma=0.4,0.8,1.2;  "
               "swarm-mj sweep circle --seeds 1 --param formation.diameter=1,1.5,2")
    p.add_argument("scenario", help="bundled scenario name or path to a .toml file")
    p.add_argument("--seeds", type=int, default=20, metavar="N", help="seeds 0..N-1 (default 20)")
    p.add_argument("--param", metavar="KEY=V1,V2,...",
                   help="sweep one scenario field (dotted TOML key), e.g. wind.sigma=0.4,0.8,1.2 or "
                        "formation.diameter=1,1.5,2 or formation.anti_collision=layers,paper,off")
    p.add_argument("--workers", type=int, metavar="W", help="local worker processes (default: all CPUs)")
    p.add_argument("--ray", metavar="ADDRESS",
                   help="run on a Ray cluster ('auto', 'ray://host:port', or 'local'); extra swarm-mj[ray]")
    p.add_argument("--json", metavar="PATH", help="write every run and the statistics as JSON")
    p.add_argument("--duration", type=float, metavar="S", help="override the scenario's duration (s)")
    p.add_argument("--gains", metavar="FILE", help="gains TOML file (as written by 'swarm-mj tune')")
    p.add_argument("--aero", choices=["paper", "realistic"],
                   help="physics preset (default: the scenario's, 'paper' for every bundled one; docs/aero.md)")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    from ..errors import UserError
    from ..scenario import load_scenario
    from ..sweep import format_sweep, parse_param, progress_to_stderr, sweep
    from .run import write_json_atomic

    if args.seeds < 1:
        raise UserError(f"--seeds must be >= 1, got {args.seeds}")
    if args.workers is not None and args.workers < 1:
        raise UserError(f"--workers must be >= 1, got {args.workers}")
    if args.duration is not None and not args.duration > 0:
        raise UserError(f"--duration must be positive, got {args.duration}")
    param, values = parse_param(args.param) if args.param else (None, None)
    sc = load_scenario(args.scenario)
    if args.gains:
        from ..control.backstepping import load_gains
        sc = sc.with_overrides(gains=load_gains(args.gains), gains_source=str(args.gains))
    if args.aero:
        from ..aero import with_aero
        sc = with_aero(sc, args.aero)
    res = sweep(sc, args.seeds, param, values, workers=args.workers, ray_address=args.ray,
                duration=args.duration, progress=None if args.quiet else progress_to_stderr)
    if args.json:
        write_json_atomic(args.json, _jsonable(res.to_dict()))
    print(format_sweep(res))
    sys.stdout.flush()
    return 1 if any(r["stopped"] for r in res.runs) else 0


def _jsonable(o):
    """Infinities as the strings "inf"/"-inf" and NaN as null: strict JSON."""
    import math

    if isinstance(o, dict):
        return {k: _jsonable(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_jsonable(v) for v in o]
    if isinstance(o, float):
        if math.isnan(o):
            return None
        if math.isinf(o):
            return "inf" if o > 0 else "-inf"
    return o
