"""``swarm-mj run NAME|FILE``: fly a scenario, write a Rerun recording and a summary."""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path


def add_parser(sub) -> None:
    p = sub.add_parser("run", help="fly a scenario and write a Rerun recording (.rrd)",
                       description="Fly a bundled scenario (see 'swarm-mj list') or a scenario TOML file. "
                                   "Writes NAME.rrd (open it with: rerun NAME.rrd).")
    p.add_argument("scenario", help="bundled scenario name or path to a .toml file")
    p.add_argument("-o", "--output", help="recording path (default: ./NAME.rrd)")
    p.add_argument("--no-record", action="store_true", help="do not write a recording")
    p.add_argument("--spawn", action="store_true", help="also open the Rerun viewer")
    p.add_argument("--summary", metavar="PATH", help="write the summary as JSON")
    p.add_argument("--gains", metavar="FILE", help="gains TOML file (as written by 'swarm-mj tune')")
    p.add_argument("--seed", type=int, help="override the scenario's seed")
    p.add_argument("--duration", type=float, help="override the scenario's duration (s)")
    p.add_argument("--anti-collision", choices=["clearance", "compensated", "layers", "paper", "off"], help="override the rule")
    p.add_argument("--aero", choices=["paper", "realistic"],
                   help="physics preset (default: the scenario's, 'paper' for every bundled one; docs/aero.md)")
    p.add_argument("--video", metavar="MP4", help="also render an MP4 video (EGL)")
    p.add_argument("--snapshot", metavar="PNG", help="also render a still image")
    p.add_argument("--snapshot-time", type=float, default=20.0, help="time of the still (s, default 20)")
    p.add_argument("--fps", type=int, default=30, help="video frame rate (default 30)")
    p.add_argument("--size", default="1280x720", help="video size WxH (default 1280x720)")
    p.add_argument("--quiet", action="store_true", help="no progress bar and no table")
    p.set_defaults(func=main)


def write_json_atomic(path: str | Path, data: dict) -> None:
    path = Path(path)
    tmp = path.with_name(path.name + ".partial")
    tmp.write_text(json.dumps(_finite(data), indent=2, default=_json_default, allow_nan=False) + "\n")
    os.replace(tmp, path)


def _finite(o):
    """Strict JSON: a non-finite number (a formation that never settled) becomes null."""
    import math

    import numpy as np

    if isinstance(o, dict):
        return {k: _finite(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_finite(v) for v in o]
    if isinstance(o, (float, np.floating)) and not math.isfinite(float(o)):
        return None
    return o


def _json_default(o):
    import numpy as np

    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(f"not JSON serialisable: {type(o)}")


def main(args: argparse.Namespace) -> int:
    from ..control.backstepping import load_gains
    from ..errors import UserError
    from ..recording import write_recording
    from ..report_table import format_summary
    from ..runner import run
    from ..scenario import load_scenario

    sc = load_scenario(args.scenario)
    if args.duration is not None and not args.duration > 0:
        raise UserError(f"--duration must be positive, got {args.duration}")
    gains = load_gains(args.gains) if args.gains else None
    if gains is not None:
        sc = sc.with_overrides(gains=gains, gains_source=str(args.gains))
    if args.video or args.snapshot:
        from ..video import check_video_args
        check_video_args(args)
    result = run(sc, anti_collision=args.anti_collision, seed=args.seed, aero=args.aero,
                 progress=None if not args.quiet else False, duration=args.duration)
    rc = 0
    if not args.no_record:
        out = Path(args.output) if args.output else Path(f"{sc.name}.rrd")
        write_recording(result, out, spawn=args.spawn,
                        safety_distance=sc.anti_collision_params.get("safety_distance", 0.8))
        if not args.quiet:
            print(f"recording: {out}  (open with: rerun {out})", file=sys.stderr)
    if args.summary:
        write_json_atomic(args.summary, result.summary)
    if not args.quiet:
        print(format_summary(result.summary, result.scenario))
    if result.error is not None:
        if isinstance(result.error, KeyboardInterrupt):
            print("swarm-mj: interrupted; the recording holds what ran", file=sys.stderr)
            return 130
        print(f"swarm-mj: error: {result.error} (the recording holds what ran)", file=sys.stderr)
        return 1
    if args.video or args.snapshot:
        from ..video import render_outputs
        rc = render_outputs(result, args)
    return rc
