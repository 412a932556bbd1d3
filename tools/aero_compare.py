"""The paper's physics beside the realistic one (issue 15): contacts, crashes, the worst downwash dip
and settling, for the default rule under downwash (``jet-aware``, what ``auto`` flies under
``--aero realistic``), the layered rule it was built from (``layers``, the default under the
paper's physics) and the paper's rule as printed (``paper``).

    .venv/bin/python tools/aero_compare.py [--starts 20] [--workers 2] [--json report/aero_compare.json]

Two parts, each flown under ``--aero paper`` and ``--aero realistic`` (docs/aero.md):

* **random starts**: ``--starts`` seeded random starts of five followers (the ``swarm-mj stress``
  defaults: within 3 m, at least 0.6 m apart, 15 s, the leader on the circle) with every rule;
  per rule and physics: starts flown, starts with a drone–drone contact, contacts, ground
  crashes, diverged runs, the worst downwash dip (``downwash_dip_worst_m``, docs/interpretations.md),
  formation settling median and worst, the smallest 3D separation while all are airborne;
* **bundled scenarios**: every bundled swarm scenario with the default rule, and the
  anti-collision scenarios (``anti_collision``, ``scenario1..3``) with each rule, at their own
  durations (``--duration`` cuts them): contacts, crashes, the worst dip, the settling after
  the start, the smallest separation.

Writes the rows to ``--json`` (default ``report/aero_compare.json``) and prints them.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

RULES = ("jet-aware", "layers", "paper")
AEROS = ("paper", "realistic")


def swarm_scenarios() -> list[str]:
    """Every bundled scenario with followers (a new one is compared without editing this tool)."""
    from swarm_mj.scenario import bundled_scenarios, load_scenario

    return [name for name in bundled_scenarios() if load_scenario(name).n_followers > 0]


RULE_SCENARIOS = ("anti_collision", "scenario1", "scenario2", "scenario3")


def _finite(x):
    """x, or None for a missing, infinite or NaN number (JSON has neither)."""
    import math

    return None if x is None or not math.isfinite(x) else x


def fly_scenario(job: tuple[str, str, str, float | None]) -> dict:
    """One bundled scenario under one rule and physics: the comparison's numbers."""
    from swarm_mj.experiments.runner import run
    from swarm_mj.physics.aero.presets import with_aero
    from swarm_mj.scenario import load_scenario

    name, rule, aero, duration = job
    sc = with_aero(load_scenario(name), aero)
    if duration is not None:
        sc = sc.with_overrides(duration=min(duration, sc.duration))
    res = run(sc, anti_collision=rule, progress=False)
    s = res.summary
    settle = s["formation"]["settling_s"]
    return {
        "part": "scenario",
        "scenario": name,
        "rule": s.get("anti_collision_rule", rule),  # "auto" resolved for the physics
        "default": rule == "auto",
        "aero": aero,
        "duration_s": sc.duration,
        "contacts": int(s["contacts"]),
        "crashes": int(s.get("crashes", 0)),
        "ground_contacts": int(s.get("ground_contacts", 0)),
        "downwash_dip_worst_m": float(s["downwash_dip_worst_m"]),
        "settling_s": _finite(settle[0]) if settle else None,
        "settling_all_s": [_finite(x) for x in settle],
        "min_separation_m": _finite(s["min_separation_m"]),
        "min_separation_airborne_m": _finite(s.get("min_separation_airborne_m")),
        "stopped": s.get("stopped"),
    }


def stress_rows(starts: int, workers: int) -> list[dict]:
    """The random-start part: every rule under every physics."""
    from swarm_mj.commands.stress import StressCase, stress

    out = []
    for aero in AEROS:
        table, _ = stress(list(RULES), starts, StressCase("", 0, 5, 3.0, 0.6, 15.0, 4.0, aero=aero), workers)
        for rule, r in table.items():
            out.append(
                {
                    "part": "stress",
                    "rule": rule,
                    "aero": aero,
                    "starts": r["starts"],
                    "starts_with_contact": r["starts_with_contact"],
                    "contacts": r["contacts"],
                    "crashes": r.get("crashes", 0),
                    "diverged": len(r["stopped"]),
                    "downwash_dip_worst_m": r["downwash_dip_worst_m"],
                    "settling_median_s": _finite(r["settling_median_s"]),
                    "settling_worst_s": _finite(r["settling_worst_s"]),
                    "min_separation_airborne_m": _finite(r["min_separation_airborne_m"]),
                }
            )
    return out


def _f(x, fmt: str) -> str:
    return "–" if x is None else fmt.format(x)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--starts", type=int, default=20, help="random starts per rule and physics (default 20)")
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--duration", type=float, default=None, help="cut the bundled scenarios to this (s)")
    ap.add_argument("--json", default="report/aero_compare.json")
    ap.add_argument("--skip-stress", action="store_true", help="only the bundled scenarios")
    args = ap.parse_args(argv)
    rows = [] if args.skip_stress else stress_rows(args.starts, args.workers)
    jobs = [(name, "auto", aero, args.duration) for aero in AEROS for name in swarm_scenarios()]
    jobs += [(name, rule, aero, args.duration) for aero in AEROS for rule in RULES for name in RULE_SCENARIOS]
    with ProcessPoolExecutor(max_workers=max(1, args.workers)) as pool:
        rows += list(pool.map(fly_scenario, jobs))
    print(
        f"{'part':<9} {'what':<18} {'rule':<9} {'aero':<9} {'contacts':>8} {'crashes':>7} {'dip (m)':>8} "
        f"{'settle (s)':>14} {'min sep (m)':>11}"
    )
    for r in rows:
        what = f"{r['starts']} starts" if r["part"] == "stress" else r["scenario"]
        settle = (
            f"{_f(r['settling_median_s'], '{:.2f}')} / {_f(r['settling_worst_s'], '{:.2f}')}"
            if r["part"] == "stress"
            else _f(r["settling_s"], "{:.2f}")
        )
        contacts = f"{r['contacts']} ({r['starts_with_contact']})" if r["part"] == "stress" else str(r["contacts"])
        print(
            f"{r['part']:<9} {what:<18} {r['rule']:<9} {r['aero']:<9} {contacts:>8} {r['crashes']:>7} "
            f"{r['downwash_dip_worst_m']:>8.3f} {settle:>14} {_f(r['min_separation_airborne_m'], '{:.3f}'):>11}"
        )
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(args.json).with_suffix(".tmp")
        tmp.write_text(json.dumps({"settings": vars(args), "rows": rows}, indent=1))
        tmp.replace(args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
