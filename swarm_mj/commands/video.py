"""``swarm-mj video NAME|FILE -o out.mp4``: fly a scenario and film it (headless, EGL).

The run is simulated first, then replayed from its log at the video's frame rate
(``swarm_mj.video``). No Rerun recording is written unless ``--record`` asks for one.

The video options are checked here, before anything is simulated (:func:`check_video_args`,
also used by ``swarm-mj run --video/--snapshot``), and :func:`render_outputs` writes what they
ask for once the run is done.
"""

from __future__ import annotations

import argparse
import math
import os
import re
import sys
from collections.abc import Sequence
from pathlib import Path

from ..errors import UserError
from ..video.style import DEFAULT_FPS, DEFAULT_SNAPSHOT_TIME, MAX_SIZE, VideoStyle
from . import AERO_NAMES, EXIT_EPILOG, EXIT_FLIGHT_FAILED, RULE_NAMES, add_sensing_argument, add_vehicle_argument

# --------------------------------------------------------------------------- option checks (before simulating)


def parse_size(text: str) -> tuple[int, int]:
    """``"1280x720"`` -> ``(1280, 720)``; raises :class:`UserError` on anything else."""
    m = re.fullmatch(r"\s*(\d+)\s*[xX×]\s*(\d+)\s*", str(text))
    if not m:
        raise UserError(f"--size must be WIDTHxHEIGHT in pixels, e.g. 1280x720, got {text!r}")
    w, h = int(m.group(1)), int(m.group(2))
    if not (16 <= w <= MAX_SIZE and 16 <= h <= MAX_SIZE):
        raise UserError(f"--size {w}x{h}: width and height must be between 16 and {MAX_SIZE} pixels")
    return w, h


def check_output_path(path: str | Path, suffixes: Sequence[str], option: str) -> Path:
    p = Path(path)
    if p.suffix.lower() not in suffixes:
        raise UserError(f"{option} {path}: the file name must end in {' or '.join(suffixes)}")
    folder = p.parent if str(p.parent) else Path(".")
    if not folder.is_dir():
        raise UserError(f"{option} {path}: folder {folder} does not exist")
    if not os.access(folder, os.W_OK):
        raise UserError(f"{option} {path}: folder {folder} is not writable")
    if p.is_dir():
        raise UserError(f"{option} {path}: is a folder")
    return p


def check_video_args(args, video_option: str = "--video") -> None:
    """Check the rendering options of ``swarm-mj run`` / ``swarm-mj video`` before simulating.

    Reads ``args.video``, ``args.snapshot``, ``args.snapshot_time``, ``args.fps``, ``args.size``
    and, where present, ``args.duration`` / ``args.scenario`` (to check the still's time and
    the video's window against the run's length). ``video_option``: the option that gave
    ``args.video``, as a message names it (``run --video``, ``video -o/--output``). Raises
    :class:`UserError`.
    """
    video = getattr(args, "video", None)
    snapshot = getattr(args, "snapshot", None)
    fps = getattr(args, "fps", DEFAULT_FPS)
    if video is not None or snapshot is not None:
        if not isinstance(fps, (int, float)) or not math.isfinite(fps) or fps <= 0:
            raise UserError(f"--fps must be a positive number of frames per second, got {fps}")
        if fps > 1000:
            raise UserError(f"--fps {fps} is more than 1000 frames per second")
        w, h = parse_size(getattr(args, "size", "1280x720"))
        if video is not None:
            check_output_path(video, (".mp4",), video_option)
            if w % 2 or h % 2:
                raise UserError(f"--size {w}x{h}: H.264 video needs an even width and height")
        if snapshot is not None:
            check_output_path(snapshot, (".png",), "--snapshot")
    duration = getattr(args, "duration", None)
    if duration is None and getattr(args, "scenario", None) is not None and (video or snapshot):
        from ..scenario import load_scenario

        duration = load_scenario(args.scenario).duration
    if snapshot is not None:
        ts = getattr(args, "snapshot_time", DEFAULT_SNAPSHOT_TIME)
        if ts is None or not math.isfinite(ts) or ts < 0:
            raise UserError(f"--snapshot-time must be a time >= 0 s, got {ts}")
        if duration is not None and ts > duration + 1e-9:
            raise UserError(
                f"--snapshot-time {ts:g} s is after the end of the run ({duration:g} s); lower it or raise --duration"
            )
    start, end = getattr(args, "start", None), getattr(args, "end", None)
    if start is not None and (not math.isfinite(start) or start < 0):
        raise UserError(f"--start must be a time >= 0 s, got {start}")
    if end is not None and (not math.isfinite(end) or end <= (start or 0.0)):
        raise UserError(f"--end must be after --start, got {end}")
    if duration is not None and start is not None and start >= duration:
        raise UserError(f"--start {start:g} s is not before the end of the run ({duration:g} s)")


# --------------------------------------------------------------------------- the command


def add_parser(sub) -> None:
    p = sub.add_parser(
        "video",
        help="fly a scenario and render an MP4 video (headless, EGL)",
        description="Fly a bundled scenario (see 'swarm-mj list') or a scenario TOML file, "
        "then replay it from its log into an H.264 MP4 (MuJoCo's renderer through "
        "EGL; no display needed). The camera keeps the whole swarm in view; the "
        "leader's reference path and the last 10 s of each drone's trail are drawn.",
        epilog=EXIT_EPILOG,
    )
    p.add_argument("scenario", help="bundled scenario name or path to a .toml file")
    p.add_argument("-o", "--output", metavar="MP4", help="video path (default: ./NAME.mp4)")
    p.add_argument("--fps", type=float, default=30, help="frame rate (default 30)")
    p.add_argument("--size", default="1280x720", help="frame size WxH, even numbers (default 1280x720)")
    p.add_argument(
        "--quality",
        choices=["high", "fast"],
        default="high",
        help="high: anti-aliased, with shadows (default); fast: neither, about 2-3x faster",
    )
    p.add_argument("--start", type=float, help="first second to film (default: the start of the run)")
    p.add_argument("--end", type=float, help="last second to film (default: the end of the run)")
    p.add_argument("--snapshot", metavar="PNG", help="also write a still image")
    p.add_argument("--snapshot-time", type=float, default=20.0, help="time of the still (s, default 20)")
    p.add_argument("--record", metavar="RRD", help="also write the Rerun recording of the run")
    add_vehicle_argument(p)  # --vehicle and --gains
    p.add_argument("--seed", type=int, help="override the scenario's seed")
    p.add_argument("--duration", type=float, help="override the scenario's duration (s)")
    p.add_argument("--anti-collision", choices=RULE_NAMES, help="override the rule")
    p.add_argument(
        "--aero",
        choices=AERO_NAMES,
        help="physics preset (default: the scenario's, 'paper' for every bundled one; docs/aero.md)",
    )
    add_sensing_argument(p)  # --sensing
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    from ..experiments.outcome import failure_line
    from ..experiments.runner import run
    from ..scenario import check_duration, check_seed
    from . import flown_scenario

    sc = flown_scenario(args)  # --vehicle, --aero, --gains, --sensing: the rule of swarm_mj/choices.py

    if args.duration is not None:
        check_duration(args.duration, sc.control_period, sc.n_drones, "--duration")
    if args.seed is not None:
        check_seed(args.seed, "--seed")
    args.video = args.output or f"{sc.name}.mp4"
    if args.duration is None:
        args.duration = sc.duration
    check_video_args(args, "-o/--output")
    if args.record:
        check_output_path(args.record, (".rrd",), "--record")
    if args.seed is not None:
        sc = sc.with_overrides(seed=args.seed)  # the wind and any random starts (as in 'swarm-mj run')
    result = run(
        sc,
        anti_collision=args.anti_collision,
        seed=args.seed,
        progress=None if not args.quiet else False,
        duration=args.duration,
    )
    if isinstance(result.error, KeyboardInterrupt):
        print("swarm-mj: interrupted", file=sys.stderr)
        return 130
    if args.record:
        from ..formation.rule_params import PaperParams
        from ..output.recording import write_recording

        d_bar = getattr(sc.rule_params, "safety_distance", PaperParams().safety_distance)  # off has none: Fig. 5's
        write_recording(result, Path(args.record), safety_distance=d_bar)
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
    failed = failure_line(result.summary.get("flight"))
    if failed:  # filmed to the end, but not as asked (EXIT_EPILOG)
        print(f"swarm-mj: {failed} (the video shows it)", file=sys.stderr)
        return rc or EXIT_FLIGHT_FAILED
    return rc


def render_outputs(result, args) -> int:
    """Render what ``args`` asks for (``--video``, ``--snapshot``); returns the exit status.

    Called by ``swarm-mj run`` after the recording is written and by ``swarm-mj video``.
    A renderer that cannot start raises :class:`RenderError` (one line, exit status 1).
    """
    from ..video.encode import render_snapshot, render_video

    size = parse_size(getattr(args, "size", "1280x720"))
    quiet = bool(getattr(args, "quiet", False))
    style = VideoStyle.preset(getattr(args, "quality", None) or "high")
    snapshot = getattr(args, "snapshot", None)
    video = getattr(args, "video", None)
    if snapshot:
        ts = getattr(args, "snapshot_time", DEFAULT_SNAPSHOT_TIME)
        out = render_snapshot(result, snapshot, time=float(ts), size=size, style=style)
        if not quiet:
            print(f"snapshot: {out}  (t = {ts:g} s, {size[0]}x{size[1]})", file=sys.stderr)
    if video:
        fps = getattr(args, "fps", DEFAULT_FPS)
        out = render_video(
            result,
            video,
            fps=fps,
            size=size,
            start=getattr(args, "start", None),
            end=getattr(args, "end", None),
            style=style,
            progress=None if not quiet else False,
        )
        if not quiet:
            print(f"video: {out}  ({fps:g} fps, {size[0]}x{size[1]}, H.264)", file=sys.stderr)
    return 0
