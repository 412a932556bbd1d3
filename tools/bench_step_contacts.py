"""Contacts of the paper's rule over the stress starts at two physics steps (issue 30; measurement only).

The starts of ``swarm-mj stress --rule paper --starts 100`` (``swarm_mj.experiments.stress.StressCase``: 5 followers
within 3 m of the leader, at least 0.6 m apart, seeds 0..99, 15 s, the paper's physics), flown with
``runner.run`` at RK4 5 ms (the default) and RK4 10 ms (the control period) through a scenario
override of ``timestep`` (the CLI has none). Per step it prints and writes (``--json``):

* the starts with a contact, and whether they are the same starts at both steps;
* ``contacts``: the run summary's rising edges of a drone pair's contact (a pair coming into contact,
  counted once until it separates: contact episodes);
* ``contact_steps``: the summary's physics steps with any drone-drone contact (a step count: halving
  the step count of a contact that lasts as long halves it);
* the change of each from 5 ms to 10 ms, against a +-10 % bar for the episodes.

    .venv/bin/python tools/bench_step_contacts.py [--starts 100] [--workers 2] [--json PATH]

The default timestep is not changed by this tool (every golden result depends on it).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

STEPS = (0.005, 0.01)  # RK4 physics steps compared (s)


def fly(job: tuple[int, float, int, float, float, float]) -> dict:
    """One stress start (seed) at one physics step: the summary's contact figures."""
    from swarm_mj.experiments.runner import run
    from swarm_mj.experiments.stress import StressCase, stress_scenario

    seed, timestep, followers, radius, min_spacing, duration = job
    case = StressCase("paper", seed, followers, radius, min_spacing, duration)
    sc = stress_scenario(case).with_overrides(timestep=timestep, integrator="RK4")
    res = run(sc, progress=False)
    s = res.summary
    return {
        "seed": seed,
        "timestep_s": timestep,
        "contacts": int(s["contacts"]),
        "contact_steps": int(s["contact_steps"]),
        "pairs": len({(int(c[1]), int(c[2])) for c in res.contact_log}),
        "stopped": bool(s.get("stopped")),
    }


def summarize(rows: list[dict]) -> dict:
    """Per step: starts with a contact (and which), the sums of contacts, contact steps and pairs."""
    out = {}
    for h in STEPS:
        rs = [r for r in rows if r["timestep_s"] == h]
        out[f"{h * 1e3:g} ms"] = {
            "starts": len(rs),
            "seeds_with_contact": sorted(r["seed"] for r in rs if r["contacts"] > 0),
            "contacts": sum(r["contacts"] for r in rs),
            "contact_steps": sum(r["contact_steps"] for r in rs),
            "pairs": sum(r["pairs"] for r in rs),
            "stopped": sum(r["stopped"] for r in rs),
        }
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--starts", type=int, default=100, help="stress starts, seeds 0.. (default 100)")
    ap.add_argument("--followers", type=int, default=5, help="followers per start (default 5)")
    ap.add_argument("--radius", type=float, default=3.0, help="start radius around the leader (m, default 3)")
    ap.add_argument("--min-spacing", type=float, default=0.6, help="minimum start spacing (m, default 0.6)")
    ap.add_argument("--duration", type=float, default=15.0, help="simulated seconds per start (default 15)")
    ap.add_argument("--workers", type=int, default=None, help="worker processes (default: the usable CPUs)")
    ap.add_argument("--json", metavar="PATH", help="write every run and the summary")
    a = ap.parse_args(argv)
    from swarm_mj.experiments.parallel import map_ordered

    jobs = [(seed, h, a.followers, a.radius, a.min_spacing, a.duration) for seed in range(a.starts) for h in STEPS]
    t0 = time.perf_counter()
    rows = map_ordered(fly, jobs, workers=a.workers)
    wall = time.perf_counter() - t0
    summ = summarize(rows)
    fine, coarse = (summ[f"{h * 1e3:g} ms"] for h in STEPS)
    same = fine["seeds_with_contact"] == coarse["seeds_with_contact"]
    for key, row in summ.items():
        print(
            f"RK4 {key}: {len(row['seeds_with_contact'])} of {row['starts']} starts with a contact; contacts "
            f"(episodes) {row['contacts']}; contact steps {row['contact_steps']}; pairs {row['pairs']}; "
            f"stopped {row['stopped']}"
        )
    change = {k: 100.0 * (coarse[k] - fine[k]) / fine[k] for k in ("contacts", "contact_steps", "pairs") if fine[k]}
    print(f"same starts with a contact: {same}")
    print("10 ms vs 5 ms: " + ", ".join(f"{k} {v:+.1f} %" for k, v in change.items()))
    if "contacts" in change:
        print(f"episodes within +-10 %: {abs(change['contacts']) <= 10.0}")
    print(f"({len(jobs)} runs in {wall:.0f} s)")
    if a.json:
        Path(a.json).write_text(
            json.dumps({"summary": summ, "same_starts": same, "change_pct": change, "rows": rows}, indent=1) + "\n"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
