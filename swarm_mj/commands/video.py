"""``swarm-mj video NAME|FILE -o out.mp4``: fly a scenario and film it (headless, EGL).

The run is simulated first, then replayed from its log at the video's frame rate
(``swarm_mj.video``). No Rerun recording is written unless ``--record`` asks for one.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def add_parser(sub) -> None:
    p = sub.add_parser("video", help="fly a scenario and render an MP4 video (headless, EGL)",
                       description="Fly a bundled scenario (see 'swarm-mj list') or a scenario TOML file, "
                                   "then replay it from its log into an H.264 MP4 (MuJoCo's renderer through "
                                   "EGL; no display needed). The camera keeps the whole swarm in view; the "
                                   "leader's reference path and the last 10 s of each drone's trail are drawn.")
    p.add_argument("scenario", help="bundled scenario name or path to a .toml file")
    p.add_argument("-o", "--output", metavar="MP4", help="video path (default: ./NAME.mp4)")
    p.add_argument("--fps", type=float, default=30, help="frame rate (default 30)")
    p.add_argument("--size", default="1280x720", help="frame size WxH, even numbers (default 1280x720)")
    p.add_argument("--quality", choices=["high", "fast"], default="high",
                   help="high: anti-aliased, with shadows (default); fast: neither, about 2-3x faster")
    p.add_argument("--start", type=float, help="first second to film (default: the start of the run)")
    p.add_argument("--end", type=float, help="last second to film (default: the end of the run)")
    p.add_argument("--snapshot", metavar="PNG", help="also write a still image")
    p.add_argument("--snapshot-time", type=float, default=20.0, help="time of the still (s, default 20)")
    p.add_argument("--record", metavar="RRD", help="also write the Rerun recording of the run")
    p.add_argument("--gains", metavar="FILE", help="gains TOML file (as written by 'swarm-mj tune')")
    p.add_argument("--seed", type=int, help="override the scenario's seed")
    p.add_argument("--duration", type=float, help="override the scenario's duration (s)")
    p.add_argument("--anti-collision", choices=["clearance", "compensated", "layers", "paper", "off"], help="override the rule")
    p.add_argument("--aero", choices=["paper", "realistic"],
                   help="physics preset (default: the scenario's, 'paper' for every bundled one; docs/aero.md)")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    from ..control.backstepping import load_gains
    from ..errors import UserError
    from ..runner import run
    from ..scenario import load_scenario
    from ..video import check_output_path, check_video_args, render_outputs

    sc = load_scenario(args.scenario)
    if args.duration is not None and not args.duration > 0:
        raise UserError(f"--duration must be positive, got {args.duration}")
    args.video = args.output or f"{sc.name}.mp4"
    if args.duration is None:
        args.duration = sc.duration
    check_video_args(args)
    if args.record:
        check_output_path(args.record, (".rrd",), "--record")
    gains = load_gains(args.gains) if args.gains else None
    if gains is not None:
        sc = sc.with_overrides(gains=gains, gains_source=str(args.gains))
    result = run(sc, anti_collision=args.anti_collision, seed=args.seed, aero=args.aero,
                 progress=None if not args.quiet else False, duration=args.duration)
    if isinstance(result.error, KeyboardInterrupt):
        print("swarm-mj: interrupted", file=sys.stderr)
        return 130
    if args.record:
        from ..recording import write_recording

        write_recording(result, Path(args.record),
                        safety_distance=sc.anti_collision_params.get("safety_distance", 0.8))
        if not args.quiet:
            print(f"recording: {args.record}  (open with: rerun {args.record})", file=sys.stderr)
    if result.error is not None:
        # A diverged run is still filmed up to where it stopped: that is what one wants to see.
        t_end = float(result.log.t[-1])
        if args.snapshot and args.snapshot_time > t_end:
            args.snapshot_time = t_end
        if args.end is None or args.end > t_end:
            args.end = t_end
        if args.start is not None and args.start >= t_end:
            args.start = None
    rc = render_outputs(result, args)
    if result.error is not None:
        print(f"swarm-mj: error: {result.error} (the video shows what ran)", file=sys.stderr)
        return 1
    return rc
