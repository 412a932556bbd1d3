"""Speed of headless video export (swarm_mj.video) next to the simulation's own speed.

In one process: fly a scenario once (``runner.run``: wall time, control steps/s, real-time
factor), then for each frame size replay its log and time
  * render:          set qpos, mj_forward, update_scene, trails/reference, mjr_render,
                     read pixels, caption (no encoding),
  * render + encode: ``render_video`` (the above plus H.264 through imageio-ffmpeg, file
                     written), on a window of the same run,
and print frames per second beside the simulation's speed as ratios:
  * "video x real time": frames/s divided by the video's fps (1.0 = films as fast as it plays);
  * "sim / film": how many times the simulation's real-time factor exceeds the filming's,
    i.e. how much longer filming a run takes than simulating it.

    .venv/bin/python tools/bench_video.py [--scenario circle] [--duration 20] [--frames 60]
                                          [--sizes 640x480 1280x720] [--fps 30]

Rendering is MuJoCo's OpenGL renderer through EGL; on a machine without a GPU that is
Mesa's llvmpipe, on the CPU (docs/libraries.md), so the numbers depend on the cores available.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import swarm_mj  # noqa: F401  (sets MUJOCO_GL before mujoco is imported)
from swarm_mj.experiments.runner import run
from swarm_mj.video import Replay, VideoStyle, frame_times, mujoco_gl_backend, parse_size, render_video


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenario", default="circle", help="scenario to fly (default circle)")
    ap.add_argument("--duration", type=float, default=20.0, help="simulated seconds (default 20)")
    ap.add_argument("--frames", type=int, default=40, help="frames timed per size and mode (default 60)")
    ap.add_argument("--sizes", nargs="+", default=["640x480", "1280x720"], help="frame sizes WxH")
    ap.add_argument("--fps", type=float, default=30.0, help="video frame rate (default 30)")
    ap.add_argument(
        "--quality",
        nargs="+",
        default=["high", "fast"],
        choices=["high", "fast"],
        help="render quality presets to time (default: both)",
    )
    args = ap.parse_args(argv)
    if args.duration <= 0 or args.frames < 2 or args.fps <= 0:
        ap.error("--duration and --fps must be > 0, --frames >= 2")

    t0 = time.perf_counter()
    result = run(args.scenario, duration=args.duration, progress=False)
    sim_wall = time.perf_counter() - t0
    if result.error is not None:
        print(f"the run stopped: {result.error}", file=sys.stderr)
        return 1
    log = result.log
    sim_time = float(log.t[-1] - log.t[0])
    steps = len(log.t) - 1
    sim_rtf = sim_time / sim_wall
    print(
        f"scenario {args.scenario}, {sim_time:g} s simulated, {len(log.names)} drones, "
        f"MUJOCO_GL={mujoco_gl_backend()}, {os.cpu_count()} CPUs"
    )
    print(
        f"simulation: {sim_wall:6.2f} s wall  {steps / sim_wall:8.0f} control steps/s  "
        f"{sim_rtf:6.1f}x real time  (includes building the model)"
    )
    print()
    print(
        f"{'size':>10}  {'quality':<8} {'mode':<14} {'frames/s':>9} {'ms/frame':>9} {'video x real time':>18} "
        f"{'sim / film':>11}"
    )
    for size_text in args.sizes:
        w, h = parse_size(size_text)
        for quality in args.quality:
            style = VideoStyle.preset(quality)
            # frames spread over the run (trails and framing as in a real video)
            times = np.linspace(float(log.t[0]), float(log.t[-1]), args.frames)
            with Replay(log, width=w, height=h, style=style) as rep:
                rep.render(float(times[0]))  # warm-up (shaders, buffers)
                t1 = time.perf_counter()
                for t in times:
                    rep.render(float(t))
                dt_render = time.perf_counter() - t1
            fps_render = args.frames / dt_render
            # render + encode: a window at the end of the run holding args.frames frames at args.fps
            start = max(float(log.t[0]), float(log.t[-1]) - args.frames / args.fps)
            n = len(frame_times(start, float(log.t[-1]), args.fps))
            with tempfile.TemporaryDirectory() as tmp:
                out = Path(tmp) / "bench.mp4"
                t1 = time.perf_counter()
                render_video(result, out, fps=args.fps, size=(w, h), start=start, style=style, progress=False)
                dt_video = time.perf_counter() - t1
                mb = out.stat().st_size / 1e6
            fps_video = n / dt_video
            for mode, fps in (("render", fps_render), ("render+encode", fps_video)):
                film_rtf = fps / args.fps
                print(
                    f"{w:>5}x{h:<4}  {quality:<8} {mode:<14} {fps:9.1f} {1000 / fps:9.1f} {film_rtf:17.2f}x "
                    f"{sim_rtf / film_rtf:10.0f}x"
                )
            print(
                f"{'':>10}  {'':<8} ({n} frames: {mb:.2f} MB, about {mb / n * args.fps * 60:.0f} MB per video "
                f"minute; render+encode includes opening the renderer)"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
