"""``swarm-mj stress``: fly many seeded random starts and count MuJoCo contacts per rule (SPEC §4).

Each start puts ``--followers`` followers on the ground at random within ``--radius`` of the
leader, at least ``--min-spacing`` apart (``scenario.random_follower_starts``, seeded
``--seed0``, ``--seed0`` + 1, ...), the leader flying the circle (SPEC §3). The same starts
are flown with every ``--rule``, in parallel over ``--workers`` processes, and for each rule
this prints: starts flown, starts with any drone–drone contact (counted by MuJoCo), total
contacts, runs that crashed (a drone knocked into the floor: the run stops there), the
crashes into the ground (``--aero realistic``: a touchdown too fast or too tilted, docs/aero.md),
the smallest 3D centre distance seen while every drone was airborne, and the median and worst
formation settling time (every leader distance within 5 cm of D; inf: never settled), and the
worst altitude dip of a drone in another drone's jet (``downwash_dip_worst_m``, see
``metrics.downwash_dip``).

Each drone sees the others within ``--sensing-range`` (default 4 m; the layered rule caps
its speeds so that it can stop within it, see ``formation.anticollision.LayeredRule``).
Short runs (``--duration`` 15 s) are enough to form up.

    swarm-mj stress --rule layers --rule paper --starts 100 --followers 5
    python -m swarm_mj.commands.stress ...      (the same, before "stress" is in cli.COMMANDS)
"""

from __future__ import annotations

import argparse
import os
import sys
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass

import numpy as np

RULES = ("clearance", "compensated", "layers", "paper", "off")


@dataclass(frozen=True)
class StressCase:
    """One flight: a rule, a seed and the random-start request."""

    rule: str
    seed: int
    followers: int
    radius: float
    min_spacing: float
    duration: float
    sensing_range: float = 4.0
    trajectory: str = "circle"
    diameter: float = 1.0
    aero: str = "paper"           # physics preset (docs/aero.md)


def stress_scenario(case: StressCase):
    """The :class:`~swarm_mj.scenario.Scenario` of one case: leader at the origin on the
    ground flying ``case.trajectory``, random follower starts seeded ``case.seed``."""
    from ..scenario import parse_scenario

    data = {"name": f"stress-{case.rule}-{case.seed}", "duration": case.duration, "seed": case.seed,
            "leader": {"trajectory": case.trajectory, "start": [0.0, 0.0, 0.0]},
            "followers": {"count": case.followers,
                          "random_start": {"radius": case.radius, "min_spacing": case.min_spacing,
                                           "seed": case.seed}},
            "formation": {"diameter": case.diameter, "anti_collision": case.rule,
                          "sensing_range": case.sensing_range},
            "aero": {"model": case.aero}}
    return parse_scenario(data, "<stress>")


def fly_case(case: StressCase) -> dict:
    """Fly one case with :func:`swarm_mj.runner.run`; the numbers the table needs."""
    from ..runner import run

    res = run(stress_scenario(case), progress=False)
    s = res.summary
    settle = s["formation"]["settling_s"][0] if s["formation"]["settling_s"] else float("inf")
    return {"rule": case.rule, "seed": case.seed, "contacts": int(s["contacts"]),
            "contact_log": [list(c) for c in res.contact_log],
            "min_separation_m": float(s["min_separation_m"]),
            "min_separation_airborne_m": float(s.get("min_separation_airborne_m", float("inf"))),
            "settling_s": float(settle), "yields": int(s["anti_collision"]["yields"]),
            "stopped": s.get("stopped"), "crashes": int(s.get("crashes", 0)),
            "ground_contacts": int(s.get("ground_contacts", 0)),
            "downwash_dip_m": float(s.get("downwash_dip_worst_m", 0.0)),
            "time_in_jet_s": float(s.get("downwash_dip", {}).get("time_in_jet_s", 0.0))}


def summarize_rule(rows: list[dict]) -> dict:
    """Per-rule line of the table from the rows of :func:`fly_case`."""
    settle = np.array([r["settling_s"] for r in rows], dtype=float)
    return {"starts": len(rows), "starts_with_contact": sum(r["contacts"] > 0 for r in rows),
            "contacts": sum(r["contacts"] for r in rows),
            "min_separation_airborne_m": min((r["min_separation_airborne_m"] for r in rows), default=float("inf")),
            "settling_median_s": float(np.median(settle)) if len(settle) else float("nan"),
            "settling_worst_s": float(settle.max()) if len(settle) else float("nan"),
            "seeds_with_contact": [r["seed"] for r in rows if r["contacts"] > 0],
            "downwash_dip_worst_m": max((r["downwash_dip_m"] for r in rows), default=0.0),
            "downwash_dip_worst_seed": max(rows, key=lambda r: r["downwash_dip_m"])["seed"] if rows else None,
            "time_in_jet_worst_s": max((r["time_in_jet_s"] for r in rows), default=0.0),
            "crashes": sum(r.get("crashes", 0) for r in rows),
            "seeds_with_crash": [r["seed"] for r in rows if r.get("crashes", 0) > 0],
            "ground_contacts": sum(r.get("ground_contacts", 0) for r in rows),
            "stopped": [r["seed"] for r in rows if r["stopped"]]}


def stress(rules: list[str], starts: int, followers: int, radius: float, min_spacing: float,
           duration: float, seed0: int = 0, workers: int | None = None,
           sensing_range: float = 4.0, aero: str = "paper") -> tuple[dict, list[dict]]:
    """Fly ``starts`` seeded random starts with each rule, in parallel; (per-rule table, rows)."""
    from ..errors import UserError
    from ..scenario import RandomStart, check_random_start_feasible

    if starts < 1 or followers < 1:
        raise UserError("--starts and --followers must be at least 1")
    if duration <= 0:
        raise UserError("--duration must be positive")
    if sensing_range <= 0:
        raise UserError("--sensing-range must be positive")
    if workers is not None and workers < 1:
        raise UserError("--workers must be at least 1")
    check_random_start_feasible(followers, RandomStart(radius=radius, min_spacing=min_spacing), "<stress>")
    cases = [StressCase(rule, seed0 + k, followers, radius, min_spacing, duration, sensing_range, aero=aero)
             for rule in rules for k in range(starts)]
    workers = max(1, min(workers or os.cpu_count() or 1, len(cases)))
    if workers == 1:
        rows = [fly_case(c) for c in cases]
    else:
        with ProcessPoolExecutor(max_workers=workers) as pool:
            rows = list(pool.map(fly_case, cases, chunksize=max(1, len(cases) // (4 * workers))))
    table = {rule: summarize_rule([r for r in rows if r["rule"] == rule]) for rule in rules}
    return table, rows


def format_table(table: dict, followers: int) -> str:
    """The per-rule table as text."""
    head = (f"{'rule':<9} {'starts':>6} {'w/contact':>9} {'contacts':>8} {'crashed':>7} {'crashes':>7} "
            f"{'min sep (m)':>11} {'settle med (s)':>14} {'settle worst (s)':>16} {'dip (m)':>8}"
            f"   ({followers} followers)")
    lines = [head]
    for rule, r in table.items():
        lines.append(f"{rule:<9} {r['starts']:>6} {r['starts_with_contact']:>9} {r['contacts']:>8} "
                     f"{len(r['stopped']):>7} {r.get('crashes', 0):>7} {r['min_separation_airborne_m']:>11.3f} "
                     f"{r['settling_median_s']:>14.2f} {r['settling_worst_s']:>16.2f} "
                     f"{r['downwash_dip_worst_m']:>8.3f}")
        if r["seeds_with_contact"]:
            seeds = r["seeds_with_contact"]
            lines.append(f"         seeds with contact: {', '.join(map(str, seeds[:20]))}"
                         f"{' ...' if len(seeds) > 20 else ''}")
    return "\n".join(lines)


def add_parser(sub) -> None:
    p = sub.add_parser("stress", help="fly many seeded random starts and count contacts per rule",
                       description=__doc__.split("\n\n")[1].replace("\n", " "))
    p.add_argument("--rule", action="append", choices=RULES, help="rule to fly (repeatable; default: clearance, paper)")
    p.add_argument("--starts", type=int, default=100, help="number of seeded starts (default 100)")
    p.add_argument("--followers", type=int, default=5, help="followers per start (default 5)")
    p.add_argument("--radius", type=float, default=3.0, help="starts within this distance of the leader (m, default 3)")
    p.add_argument("--min-spacing", type=float, default=0.6, help="minimum start spacing (m, default 0.6)")
    p.add_argument("--duration", type=float, default=15.0, help="simulated seconds per start (default 15)")
    p.add_argument("--seed0", type=int, default=0, help="first seed (default 0)")
    p.add_argument("--sensing-range", type=float, default=4.0,
                   help="how far each drone sees the others (m, default 4; the layered rule's speeds "
                        "are capped so that it can stop within it)")
    p.add_argument("--workers", type=int, default=None, help="processes (default: os.cpu_count())")
    p.add_argument("--aero", choices=["paper", "realistic"],
                   help="physics preset (default: paper; docs/aero.md)")
    p.add_argument("--json", metavar="PATH", help="also write the table and every start's numbers as JSON")
    p.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    rules = list(dict.fromkeys(args.rule or ["clearance", "paper"]))
    table, rows = stress(rules, args.starts, args.followers, args.radius, args.min_spacing, args.duration,
                         args.seed0, args.workers, args.sensing_range, aero=args.aero or "paper")
    print(format_table(table, args.followers))
    if args.json:
        from .run import write_json_atomic

        write_json_atomic(args.json, {"settings": {k: v for k, v in vars(args).items() if k != "func"},
                                      "table": table, "starts": rows})
    return 0


if __name__ == "__main__":          # usable before "stress" is listed in cli.COMMANDS
    from ..errors import SwarmError

    ap = argparse.ArgumentParser(prog="swarm-mj stress")
    add_parser(ap.add_subparsers())
    ns = ap.parse_args(["stress", *sys.argv[1:]])
    try:
        sys.exit(main(ns))
    except SwarmError as exc:
        print(f"swarm-mj: error: {exc}", file=sys.stderr)
        sys.exit(exc.exit_code)
