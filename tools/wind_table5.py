"""Paper Table 5 beside ours: circle and lemniscate, no wind / wind, feedforward on / off.

    .venv/bin/python tools/wind_table5.py [--seeds 0 1 2] [--json out.json]

Runs the bundled single-drone scenarios (180 s each, ~4 s of wall time each) and prints
RMSE (eq. 38) of x, y (m), roll, pitch (deg), whole run and from t = 10 s on (docs/interpretations.md §7),
with the paper's Table 5 and docs/interpretations.md §7's independent-model figures beside them, and the
issue-5 bars: lemniscate under wind (feedforward on) x <= 0.0321, y <= 0.0249 m; circle
under wind x whole-run <= 2 x 0.0398 m, y from 10 s <= 2 x 0.0689 m. With several seeds
the wind rows show the worst seed and the spread (the turbulence is seeded).
"""

from __future__ import annotations

import argparse
import json
import sys

from swarm_mj.experiments.runner import run
from swarm_mj.paper import PAPER_TABLE5

ROWS = [  # (label, scenario, trajectory, wind, feedforward)
    ("circle, no wind", "circle_single", "circle", False, True),
    ("circle, wind, ff on", "wind_circle", "circle", True, True),
    ("circle, wind, ff off", "wind_circle_noff", "circle", True, False),
    ("lemniscate, no wind", "lemniscate_single", "lemniscate", False, True),
    ("lemniscate, wind, ff on", "wind_lemniscate", "lemniscate", True, True),
    ("lemniscate, wind, ff off", "wind_lemniscate_noff", "lemniscate", True, False),
]
KEYS = ("x", "y", "roll_deg", "pitch_deg")
# docs/interpretations.md §7, independent eq.-(1) model, whole run from the ground at the origin (m).
INDEPENDENT_MODEL = {
    "circle_single": {"y": 0.160},
    "wind_circle": {"y": 0.160},
    "lemniscate_single": {"x": 0.0014, "y": 0.0007},
    "wind_lemniscate": {"x": 0.0017, "y": 0.0008},
    "wind_lemniscate_noff": {"x": 0.0335, "y": 0.0108},
}


def _fmt(r: dict) -> str:
    return " ".join(f"{r[k]:>8.4f}" for k in KEYS)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int, nargs="+", default=[0])
    ap.add_argument("--json", help="write every figure as JSON")
    args = ap.parse_args(argv)
    out: dict = {}
    for label, name, traj, wind, ff in ROWS:
        seeds = args.seeds if wind else args.seeds[:1]  # no wind: nothing is random
        per = []
        for s in seeds:
            res = run(name, seed=s, progress=False)
            if res.error is not None:
                print(f"{name} seed {s}: stopped: {res.error}", file=sys.stderr)
                return 1
            d = res.summary["drones"]["leader"]
            per.append({"seed": s, "rmse": d["rmse"], "rmse_steady": d["rmse_steady"]})
        out[name] = {"label": label, "trajectory": traj, "wind": wind, "feedforward": ff, "runs": per}

    print(
        "RMSE (eq. 38): x, y in m; roll, pitch in deg.  whole = whole run; >10s = from t = 10 s on "
        "(docs/interpretations.md §7)"
    )
    print(f"seeds: {args.seeds}" + ("  (wind rows: worst seed over the seeds)" if len(args.seeds) > 1 else ""))
    print(f"{'':<26} {'':<6} {'x':>8} {'y':>8} {'roll':>8} {'pitch':>8}")
    for name, o in out.items():
        worst = {key: {k: max(r[key][k] for r in o["runs"]) for k in KEYS} for key in ("rmse", "rmse_steady")}
        print(f"{o['label']:<26} {'whole':<6} {_fmt(worst['rmse'])}")
        print(f"{'':<26} {'>10s':<6} {_fmt(worst['rmse_steady'])}")
        paper = PAPER_TABLE5[(o["trajectory"], o["wind"])]
        note = "" if o["feedforward"] or not o["wind"] else "   (paper uses feedforward: reported only)"
        print(f"{'':<26} {'paper':<6} {_fmt(paper)}{note}")
        ind = INDEPENDENT_MODEL.get(name)
        if ind:
            print(
                f"{'':<26} {'indep.':<6} "
                + " ".join(f"{ind[k]:>8.4f}" if k in ind else f"{'':>8}" for k in KEYS)
                + "   (interpretations.md §7 model)"
            )
        if len(o["runs"]) > 1:
            lo = {k: min(r["rmse"][k] for r in o["runs"]) for k in KEYS}
            print(f"{'':<26} {'min':<6} {_fmt(lo)}   (whole run, best seed)")
        o["worst"] = worst
    lem, cir = out["wind_lemniscate"]["worst"], out["wind_circle"]["worst"]
    bars = [
        ("lemniscate wind x whole <= 0.0321", lem["rmse"]["x"], 0.0321),
        ("lemniscate wind y whole <= 0.0249", lem["rmse"]["y"], 0.0249),
        ("circle wind x whole <= 2 x 0.0398", cir["rmse"]["x"], 2 * 0.0398),
        ("circle wind y >10s  <= 2 x 0.0689", cir["rmse_steady"]["y"], 2 * 0.0689),
    ]
    print()
    ok = True
    for label, v, bar in bars:
        passed = v <= bar
        ok &= passed
        print(f"{'PASS' if passed else 'FAIL'}  {label}: {v:.4f}")
    print(
        f"note: circle whole-run y {cir['rmse']['y']:.4f} m vs the paper's 0.0689 m: the drone starts on the "
        "ground at the origin, 2.5 m from the circle's start, and the whole-run RMSE is that first flight "
        "(docs/interpretations.md §7; the paper does not say where its drone starts)."
    )
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(out, fh, indent=2)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
