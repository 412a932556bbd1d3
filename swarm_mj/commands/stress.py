"""``swarm-mj stress``: fly many seeded random starts and count MuJoCo contacts per rule (docs/interpretations.md §4).

Each start puts ``--followers`` followers on the ground at random within ``--radius`` of the
leader, at least ``--min-spacing`` apart (``scenario.random_follower_starts``, seeded
``--seed0``, ``--seed0`` + 1, ...), the leader flying the circle (docs/interpretations.md §3). The same starts
are flown with every ``--rule``, in parallel over ``--workers`` processes, and for each rule
this prints: starts flown, starts with any drone–drone contact (counted by MuJoCo), total
contacts, runs that crashed (a drone knocked into the floor: the run stops there), the
crashes into the ground (``--aero realistic``: a touchdown too fast or too tilted, docs/aero.md),
the smallest 3D centre distance seen while every drone was airborne, and the median and worst
formation settling time (every leader distance within 5 cm of D; inf: never settled), and the
worst altitude dip of a drone in another drone's jet (``downwash_dip_worst_m``, see
``metrics.downwash_dip``).

Each drone sees the others within ``--sensing-range`` (default 4 m; the layered rule caps
its speeds so that it can stop within it, see ``formation.planner.LayeredRule``).
Short runs (``--duration`` 15 s) are enough to form up.

    swarm-mj stress --rule layers --rule paper --starts 100 --followers 5

The flights themselves are :mod:`swarm_mj.experiments.stress`.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from ..experiments.parallel import machine_description
from ..experiments.stress import (  # noqa: F401
    RULES,
    StressCase,
    fly_case,
    format_table,
    replay_lines,
    stress,
    stress_data,
    stress_scenario,
    summarize_rule,
)
from . import AERO_NAMES, RULE_NAMES, add_sensing_argument, add_vehicle_argument


def add_parser(sub) -> None:
    p = sub.add_parser(
        "stress",
        help="fly many seeded random starts and count contacts per rule",
        description=__doc__.split("\n\n")[1].replace("\n", " "),
    )
    p.add_argument(
        "--rule",
        action="append",
        choices=RULE_NAMES,
        help="rule to fly (repeatable; default: auto, paper; auto is barrier under "
        "--aero realistic, layers under the paper's physics)",
    )
    p.add_argument("--starts", type=int, default=100, help="number of seeded starts (default 100)")
    p.add_argument("--followers", type=int, default=5, help="followers per start (default 5)")
    p.add_argument("--radius", type=float, default=3.0, help="starts within this distance of the leader (m, default 3)")
    p.add_argument("--min-spacing", type=float, default=0.6, help="minimum start spacing (m, default 0.6)")
    p.add_argument(
        "--diameter",
        type=float,
        default=1.0,
        help="formation diameter D: each follower's distance from the leader (m, default 1; "
        "the barrier needs its keep-out between neighbours, e.g. D >= 1.32 m for 12 followers)",
    )
    p.add_argument("--duration", type=float, default=15.0, help="simulated seconds per start (default 15)")
    p.add_argument("--seed0", type=int, default=0, help="first seed (default 0)")
    p.add_argument(
        "--sensing-range",
        type=float,
        default=4.0,
        help="how far each drone sees the others (m, default 4; the layered rule's speeds "
        "are capped so that it can stop within it)",
    )
    p.add_argument(
        "--workers", type=int, default=None, help="worker processes (default: the CPUs this process may use)"
    )
    p.add_argument("--aero", choices=AERO_NAMES, help="physics preset (default: paper; docs/aero.md)")
    add_vehicle_argument(p, default="the paper's drone")  # --vehicle and --gains
    add_sensing_argument(p)  # --sensing: every start's [sensing] preset, its range --sensing-range
    p.add_argument("--json", metavar="PATH", help="also write the table and every start's numbers as JSON")
    p.add_argument(
        "--save-scenario",
        metavar="TOML",
        help="write the flown scenario as a file: 'swarm-mj run TOML --seed S --anti-collision RULE' "
        "replays start S exactly",
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    rules = args.rule or ["auto", "paper"]  # stress() resolves "auto" for the physics
    save = getattr(args, "save_scenario", None)
    if args.json:
        from ..output.atomic import check_output_path

        check_output_path(args.json, "--json", allow_stdout=True)
    if save:
        from ..output.atomic import check_output_path

        check_output_path(save, "--save-scenario", (".toml",))
    vehicle, gains = args.vehicle, args.gains
    if vehicle is not None:  # its gains, unless --gains: the rule of swarm_mj/choices.py, as every start is parsed
        from ..choices import resolve_vehicle

        _, v, model = resolve_vehicle(vehicle, Path.cwd(), "--vehicle")
        v.params()  # one clear line now if the file cannot fly
        vehicle = model or vehicle  # a file by its absolute path: the workers' folder may differ
    if gains is not None:
        from ..control.backstepping import load_gains

        load_gains(gains)
        gains = str(Path(gains).resolve())
    case = StressCase(
        rule=rules[0],
        seed=args.seed0,
        followers=args.followers,
        radius=args.radius,
        min_spacing=args.min_spacing,
        duration=args.duration,
        sensing_range=args.sensing_range,
        diameter=args.diameter,
        aero=args.aero or "paper",
        vehicle=vehicle,
        gains=gains,
        sensing=args.sensing or "perfect",
    )
    table, rows = stress(rules, args.starts, case, args.workers, progress=not args.quiet)
    if save:
        from ..output.atomic import write_text_atomic
        from ..scenario import scenario_toml

        write_text_atomic(
            save,
            "# written by swarm-mj stress; replay start S with rule R:\n"
            "#   swarm-mj run THIS_FILE --seed S --anti-collision R\n" + scenario_toml(stress_data(case)),
        )
    doc = {
        "settings": {k: v for k, v in vars(args).items() if k not in ("func", "quiet")}
        | {"aero": case.aero, "sensing": case.sensing},
        # the versions the numbers came from: a contact count moves with MuJoCo's (docs/libraries.md)
        "machine": machine_description(),
        "table": table,
        "starts": rows,
    }
    if args.json and args.json != "-":
        from ..output.atomic import write_json_atomic

        write_json_atomic(args.json, doc)  # first: a reader that stops reading the table (| head) loses nothing
    print(format_table(table, args.followers, case.sensing))
    print("\n".join(replay_lines(table, rows, save)))
    if args.json == "-":
        from ..output.atomic import write_json_atomic

        write_json_atomic(args.json, doc)
    return 0
