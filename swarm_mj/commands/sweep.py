"""``swarm-mj sweep SCENARIO --seeds N [--param KEY=V1,V2,...]``: seeded runs, mean/std/worst."""

from __future__ import annotations

import argparse
import sys
import tomllib
from typing import Any

from ..errors import UserError
from . import AERO_NAMES, EXIT_EPILOG, EXIT_ERROR, EXIT_FLIGHT_FAILED, add_sensing_argument, add_vehicle_argument


def add_parser(sub) -> None:
    p = sub.add_parser(
        "sweep",
        help="many seeded runs of a scenario: mean, std and worst case of the key metrics",
        description="Fly a scenario once per seed (0..N-1: wind turbulence and random starts) and, with "
        "--param, once per value of one scenario field; print the mean, standard deviation and "
        "worst case (max for errors and settling, min for separation) of the leader's RMSE "
        "(whole run and from t = 10 s), and for swarms the contacts, minimum separation, "
        "formation settling and formation distance error. Results do not depend on --workers.",
        epilog="examples: swarm-mj sweep wind_lemniscate --seeds 20;  "
        "swarm-mj sweep wind_circle --seeds 10 --param wind.sigma=0.4,0.8,1.2;  "
        "swarm-mj sweep circle --seeds 1 --param formation.diameter=1,1.5,2.  "
        + EXIT_EPILOG.replace("the run", "a run"),
    )
    p.add_argument("scenario", help="bundled scenario name or path to a .toml file")
    p.add_argument("--seeds", type=int, default=20, metavar="N", help="seeds 0..N-1 (default 20)")
    p.add_argument(
        "--param",
        metavar="KEY=V1,V2,...",
        help="sweep one scenario field (dotted TOML key), e.g. wind.sigma=0.4,0.8,1.2 or "
        "formation.diameter=1,1.5,2 or formation.anti_collision=layers,paper,off",
    )
    p.add_argument("--workers", type=int, metavar="W", help="local worker processes (default: all CPUs)")
    p.add_argument(
        "--ray",
        metavar="ADDRESS",
        help="run on a Ray cluster ('auto', 'ray://host:port', or 'local'); extra swarm-mj[ray]",
    )
    p.add_argument("--json", metavar="PATH", help="write every run and the statistics as JSON")
    p.add_argument("--duration", type=float, metavar="S", help="override the scenario's duration (s)")
    add_vehicle_argument(p)  # --vehicle and --gains
    p.add_argument(
        "--aero",
        choices=AERO_NAMES,
        help="physics preset (default: the scenario's, 'paper' for every bundled one; docs/aero.md)",
    )
    add_sensing_argument(p)  # --sensing
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.set_defaults(func=main)


# --------------------------------------------------------------------------- --param KEY=V1,V2,...


def _split_top(text: str) -> list[str]:
    """Split on commas that are not inside brackets or quotes."""
    parts: list[str] = []
    cur: list[str] = []
    depth, quote = 0, None
    for ch in text:
        if quote:
            cur.append(ch)
            if ch == quote:
                quote = None
            continue
        if ch in "\"'":
            quote = ch
        elif ch in "[{":
            depth += 1
        elif ch in "]}":
            depth -= 1
        elif ch == "," and depth == 0:
            parts.append("".join(cur).strip())
            cur = []
            continue
        cur.append(ch)
    parts.append("".join(cur).strip())
    return parts


def _literal(tok: str) -> Any:
    try:
        return tomllib.loads(f"v = {tok}")["v"]
    except tomllib.TOMLDecodeError:
        return tok


def parse_param(text: str) -> tuple[str, list[Any]]:
    """``"wind.sigma=0.4,0.8,1.2"`` → ``("wind.sigma", [0.4, 0.8, 1.2])``."""
    example = "expected KEY=V1,V2,... e.g. wind.sigma=0.4,0.8,1.2 or formation.diameter=1,1.5,2"
    if "=" not in text:
        raise UserError(f"bad --param {text!r}: {example}")
    key, _, vals = text.partition("=")
    key = key.strip()
    parts = key.split(".")
    if not key or any(not p or not p.replace("_", "").isalnum() for p in parts):
        raise UserError(f"bad --param {text!r}: key {key!r} must be a dotted name; {example}")
    toks = _split_top(vals)
    if not vals.strip() or any(t == "" for t in toks):
        raise UserError(f"bad --param {text!r}: empty value; {example}")
    values = [_literal(t) for t in toks]
    if len({repr(v) for v in values}) != len(values):
        raise UserError(f"bad --param {text!r}: repeated value")
    return key, values


def main(args: argparse.Namespace) -> int:
    from ..experiments.sweep import format_sweep, sweep
    from ..output.atomic import write_json_atomic
    from ..scenario import MAX_SEED
    from . import flown_scenario

    if not 1 <= args.seeds <= MAX_SEED + 1:  # the seeds are 0..N-1
        raise UserError(f"--seeds must be >= 1 and <= {MAX_SEED + 1}, got {args.seeds}")
    if args.workers is not None and args.workers < 1:
        raise UserError(f"--workers must be >= 1, got {args.workers}")
    param, values = parse_param(args.param) if args.param else (None, None)
    sc = flown_scenario(args)  # --vehicle, --aero, --gains, --sensing: the rule of swarm_mj/choices.py
    if args.duration is not None:
        from ..scenario import check_duration

        check_duration(args.duration, sc.control_period, sc.n_drones, "--duration")
    if args.json:
        from ..output.atomic import check_output_path

        check_output_path(args.json, "--json", allow_stdout=True)
    res = sweep(
        sc,
        args.seeds,
        param,
        values,
        workers=args.workers,
        ray_address=args.ray,
        duration=args.duration,
        progress=not args.quiet,
    )
    if args.json:
        write_json_atomic(args.json, res.to_dict(), inf_as_string=True)
    print(format_sweep(res))
    print(replay_line(args, res))
    sys.stdout.flush()
    failed = [r for r in res.runs if r.get("flight_failed")]
    if failed:  # flew to the end, but not as asked (EXIT_EPILOG)
        r = failed[0]
        what = f"{res.param}={res.values[r['value_index']]!r} " if res.param else ""  # as its progress line
        print(f"swarm-mj: {len(failed)} of {len(res.runs)} runs failed; {what}seed {r['seed']}: {r['flight_failed']}")
    if any(r["stopped"] for r in res.runs):
        return EXIT_ERROR
    return EXIT_FLIGHT_FAILED if failed else 0


def replay_line(args: argparse.Namespace, res) -> str:
    """The ``swarm-mj run`` command that flies the sweep's worst run again (its seed means the
    same wind and random starts there): most contacts, else smallest separation, else the
    largest leader RMSE x."""
    import math
    import shlex

    best = None
    for vi, v in enumerate(res.values):
        for r in (r for r in res.runs if r["value_index"] == vi):
            m = r["metrics"]
            sep = m.get("min_separation_m", math.inf)
            key = (
                m.get("stopped", 0),
                m.get("contacts", 0),
                -sep if math.isfinite(sep) else -math.inf,
                m.get("rmse_x", 0) if math.isfinite(m.get("rmse_x", 0)) else math.inf,
            )
            if best is None or key > best[0]:
                best = (key, r["seed"], v)
    assert best is not None, "a sweep has at least one run"
    _, seed, value = best
    cmd = ["swarm-mj", "run", args.scenario, "--seed", str(seed)]
    if args.duration is not None:
        cmd += ["--duration", repr(float(args.duration))]
    for opt in ("vehicle", "aero", "gains", "sensing"):  # what the sweep flew
        if getattr(args, opt, None):
            cmd += [f"--{opt}", str(getattr(args, opt))]
    note = ""
    if res.param == "formation.anti_collision":
        cmd += ["--anti-collision", str(value)]
    elif res.param:
        note = f"  (with {res.param} = {value!r} in the scenario file)"
    return f"worst run: seed {seed}; replay: {shlex.join(cmd)}{note}"
