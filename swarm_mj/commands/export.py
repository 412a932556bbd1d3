"""``swarm-mj export crazyflie SCENARIO -o DIR``: a flown scenario as pieces for real Crazyflies.

Flies the scenario, fits each drone's flown path from --from to --to with the Crazyflie commander's
degree-7 pieces, checks them (tolerance, memory, thrust, tilt, keep-out, take-off) and, only when every
check passes, writes DIR: one uav_trajectories CSV per drone, path.csv, manifest.json, upload.py (cflib)
and scenario.toml (what 'swarm-mj run DIR' flies the set back with). A refusal is one line naming the
failed checks, exit status 2, nothing written (docs/export.md).
"""

from __future__ import annotations

import argparse
import math
import sys

from . import AERO_NAMES, EXIT_EPILOG, RULE_NAMES, add_vehicle_argument

#: What ``export`` writes for (one target so far).
TARGETS = ("crazyflie",)


def add_parser(sub) -> None:
    p = sub.add_parser(
        "export",
        help="fit a flown scenario as Crazyflie trajectory pieces, checked, with a cflib upload script",
        description=__doc__.split("\n\n")[1].replace("\n", " "),
        epilog=EXIT_EPILOG,
    )
    p.add_argument("target", choices=TARGETS, help="what to export for: crazyflie (its high-level commander)")
    p.add_argument("scenario", help="bundled scenario name or path to a .toml file")
    p.add_argument("-o", "--output", required=True, metavar="DIR", help="the folder to write (new, or an earlier set)")
    p.add_argument(
        "--from",
        dest="t_from",
        type=float,
        metavar="T0",
        help="the plan's start (s; default: when the swarm has formed, every drone within 5 cm of its slot)",
    )
    p.add_argument(
        "--to", dest="t_to", type=float, metavar="T1", help="the plan's end (s; default: the scenario's end)"
    )
    add_vehicle_argument(p)  # --vehicle and --gains
    p.add_argument("--aero", choices=AERO_NAMES, help="physics preset flown (default: the scenario's)")
    p.add_argument("--anti-collision", choices=RULE_NAMES, help="override the rule flown")
    p.add_argument("--seed", type=int, help="override the scenario's seed")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=main)


def _times(args: argparse.Namespace, sc) -> float:  # noqa: ANN001 - a Scenario
    """--from and --to checked before anything flies; returns --to (s)."""
    from ..errors import UserError
    from ..export.poly import MIN_SAMPLES
    from ..scenario import check_duration

    T = sc.control_period
    t_to = sc.duration if args.t_to is None else args.t_to
    check_duration(t_to, T, sc.n_drones, "--to")
    if args.t_from is not None:
        if not math.isfinite(args.t_from) or args.t_from < 0:
            raise UserError(f"--from: must be a time >= 0 s, got {args.t_from:g}")
        if t_to - args.t_from < 2 * MIN_SAMPLES * T:
            raise UserError(
                f"--from {args.t_from:g} s: the plan must last at least {2 * MIN_SAMPLES * T:g} s "
                f"before --to {t_to:g} s"
            )
    return float(t_to)


def main(args: argparse.Namespace) -> int:
    from ..export.checks import BYTES_PER_PIECE, MEMORY_BYTES
    from ..export.crazyflie import cflib_note, check_output_folder, export_crazyflie
    from ..scenario import check_seed
    from . import flown_scenario

    sc = flown_scenario(args)  # --vehicle, --aero, --gains
    if args.seed is not None:
        sc = sc.with_overrides(seed=check_seed(args.seed, "--seed"))
    if args.anti_collision is not None:
        sc = sc.with_overrides(anti_collision=args.anti_collision)
    t_to = _times(args, sc)
    out = check_output_folder(args.output)
    man, checks = export_crazyflie(sc, out, args.t_from, t_to, progress=False if args.quiet else None)
    t0, t1 = man["time_span_s"]
    why = "" if args.t_from is not None else " (the swarm formed; --from 0 for the take-off)"
    n_p = [d["pieces"] for d in man["drones"]]
    print(
        f"exported {man['scenario']} from {t0:.2f} s{why} to {t1:.2f} s into {out}: {len(n_p)} drone(s), "
        f"{min(n_p)}-{max(n_p)} pieces each (at most {max(n_p) * BYTES_PER_PIECE} of {MEMORY_BYTES} bytes)"
    )
    for c in checks:
        print(f"  {c.name}: {c.text}")
    note = cflib_note()
    if note:
        print(f"note: {note}", file=sys.stderr)
    print(f"fly it back: swarm-mj run {out} --aero realistic; upload: python {out}/upload.py URI ... (one per drone)")
    return 0
