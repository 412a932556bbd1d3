"""``swarm-mj run NAME|FILE``: fly a scenario, write a Rerun recording and a summary."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from ..output.interrupt import CooperativeInterrupt
from . import AERO_NAMES, EXIT_EPILOG, EXIT_FLIGHT_FAILED, RULE_NAMES, add_sensing_argument, add_vehicle_argument


def add_parser(sub) -> None:
    p = sub.add_parser(
        "run",
        help="fly a scenario and write a Rerun recording (.rrd)",
        description="Fly a bundled scenario (see 'swarm-mj list') or a scenario TOML file. "
        "Writes NAME.rrd (open it with: rerun NAME.rrd).",
        epilog=EXIT_EPILOG,
    )
    p.add_argument(
        "scenario",
        help="bundled scenario name, path to a .toml file, or a folder of 'swarm-mj export' (docs/export.md)",
    )
    p.add_argument("-o", "--output", help="recording path (default: ./NAME.rrd)")
    p.add_argument("--no-record", action="store_true", help="do not write a recording")
    p.add_argument(
        "--spawn",
        action="store_true",
        help="also open the desktop Rerun viewer (without a display: a note, the recording kept)",
    )
    p.add_argument("--summary", metavar="PATH", help="write the summary as JSON")
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
    p.add_argument("--video", metavar="MP4", help="also render an MP4 video (EGL)")
    p.add_argument("--snapshot", metavar="PNG", help="also render a still image")
    p.add_argument("--snapshot-time", type=float, default=20.0, help="time of the still (s, default 20)")
    p.add_argument("--fps", type=int, default=30, help="video frame rate (default 30)")
    p.add_argument("--size", default="1280x720", help="video size WxH (default 1280x720)")
    p.add_argument("--quiet", action="store_true", help="no progress bar and no table")
    from .view import add_web_arguments

    add_web_arguments(p)  # --web, --port: serve the recording to a browser after the run
    p.set_defaults(func=main)


def write_json_atomic(path: str | Path, data: dict) -> None:
    """Strict JSON, written atomically (kept here for the callers of ``commands.run``; see
    :mod:`swarm_mj.output.atomic`)."""
    from ..output.atomic import write_json_atomic as _write

    _write(path, data)


def check_args(args: argparse.Namespace, sc) -> None:
    """Every option of ``swarm-mj run`` checked against the scenario before anything flies:
    --seed, --duration (finite, at least one control period, a log that fits in memory),
    every output path (-o, --summary, --video, --snapshot). Raises :class:`UserError`."""
    from ..errors import UserError
    from ..output.atomic import check_output_path
    from ..scenario import check_duration, check_seed

    if args.seed is not None:
        check_seed(args.seed, "--seed")
    if args.duration is not None:
        check_duration(args.duration, sc.control_period, sc.n_drones, "--duration")
    if not args.no_record:
        check_output_path(args.output if args.output else f"{sc.name}.rrd", "-o/--output")
    if args.summary:
        check_output_path(args.summary, "--summary", allow_stdout=True)
    outs = [
        ("-o/--output", None if args.no_record else (args.output or f"{sc.name}.rrd")),
        ("--summary", args.summary),
        ("--video", args.video),
        ("--snapshot", args.snapshot),
    ]
    seen: dict[str, str] = {}
    for opt, p in outs:
        if p is None or p == "-":
            continue
        key = os.path.realpath(p)
        if key in seen:
            raise UserError(f"{opt} {p}: the same file as {seen[key]}")
        seen[key] = opt


def main(args: argparse.Namespace) -> int:
    # Ctrl-C from here until the run ends stops the run at its start or where it is (exit 130, the
    # recording of what ran written); afterwards (writing files, serving, video) it interrupts as usual.
    interrupt = CooperativeInterrupt()
    interrupt.__enter__()
    try:
        return _main(args, interrupt)
    finally:
        interrupt.__exit__()


def _main(args: argparse.Namespace, interrupt: CooperativeInterrupt) -> int:
    from ..errors import UserError
    from ..experiments.outcome import failure_line
    from ..experiments.report_table import format_summary
    from ..experiments.runner import run
    from ..export.flyback import is_export, load_export
    from . import flown_scenario

    exported = load_export(args.scenario) if is_export(args.scenario) else None  # each drone flies its own pieces
    sc = flown_scenario(args, exported.scenario if exported else None)  # --vehicle, --aero, --gains, --sensing
    check_args(args, sc)
    if args.seed is not None:
        sc = sc.with_overrides(seed=args.seed)  # the wind and any random starts, as sweep/stress call seed s
    if args.duration is not None:
        sc = sc.with_overrides(duration=args.duration)
    if args.video or args.snapshot:
        from ..video import check_video_args

        check_video_args(args)
    if args.web:
        from ..output.viewer import check_port

        if args.no_record:
            raise UserError("--web serves the recording: it cannot go with --no-record")
        check_port(args.port)  # before flying; checked again when the server starts
    result = run(
        sc,
        anti_collision=args.anti_collision,
        seed=args.seed,
        progress=None if not args.quiet else False,
        duration=args.duration,
        interrupt=interrupt,
        make_policy=exported.policy if exported else None,
    )
    interrupt.__exit__()  # the run is over: Ctrl-C interrupts writing, serving and rendering as usual
    if exported is not None:
        result.summary["export"] = exported.tracking(result.log)
    rc = 0
    out = None
    if not args.no_record:
        # imported here: Rerun's import costs ~0.3 s of start-up, needed only when recording
        from ..formation.rule_params import PaperParams
        from ..output.recording import write_recording

        out = Path(args.output) if args.output else Path(f"{sc.name}.rrd")
        d_bar = getattr(sc.rule_params, "safety_distance", PaperParams().safety_distance)  # off has none: Fig. 5's
        write_recording(result, out, safety_distance=d_bar)
        if not args.quiet:
            print(f"recording: {out}  (open with: swarm-mj view {out})", file=sys.stderr)
        if args.spawn:  # after the file is complete, so that the recording is kept whatever happens
            from ..output.viewer import spawn_note

            print(spawn_note(out), file=sys.stderr)
    if args.summary:
        write_json_atomic(args.summary, result.summary)
    if not args.quiet:  # with --summary - the JSON alone goes to standard output
        print(format_summary(result.summary, result.scenario), file=sys.stderr if args.summary == "-" else sys.stdout)
        if exported is not None:
            print(exported.line(result.summary), file=sys.stderr if args.summary == "-" else sys.stdout)
    if result.error is not None:
        kept = "; the recording holds what ran" if not args.no_record else ""
        if isinstance(result.error, KeyboardInterrupt):
            print(f"swarm-mj: interrupted{kept}", file=sys.stderr)
            return 130
        print(f"swarm-mj: error: {result.error}{f' ({kept[2:]})' if kept else ''}", file=sys.stderr)
        return _serve(args, out, 1)
    if args.video or args.snapshot:
        from ..video import render_outputs

        rc = render_outputs(result, args)
    failed = failure_line(result.summary.get("flight"))
    if failed:  # it flew to the end, but not as asked: say so, and never exit 0 (EXIT_EPILOG)
        print(f"swarm-mj: {failed}", file=sys.stderr)
        rc = rc or EXIT_FLIGHT_FAILED
    return _serve(args, out, rc)


def _serve(args: argparse.Namespace, out: Path | None, rc: int) -> int:
    """``--web``: serve the recording until Ctrl-C (exit 130), or ``rc`` when the run failed."""
    if not args.web:
        return rc
    assert out is not None  # --web cannot go with --no-record (main checks), so the recording exists
    from ..output.viewer import serve_until_interrupted

    try:
        served = serve_until_interrupted(out, args.port)
    except KeyboardInterrupt:
        if rc:  # the run's own failure is the exit status
            print("swarm-mj: stopped the web viewer", file=sys.stderr)
            return rc
        raise
    return rc or served
