"""Write what a replay draws: the H.264 MP4 (:func:`render_video`) and the PNG still (:func:`render_snapshot`).

Both are written to a temporary file next to the target and renamed into place, so a failure or
Ctrl-C leaves no half-written file (and an earlier file of that name untouched).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..errors import UserError
from ..output.progress import Progress
from ..physics.params import DEFAULT_PARAMS
from .replay import Replay, replay_world
from .style import DEFAULT_FPS, DEFAULT_SIZE, DEFAULT_SNAPSHOT_TIME, VideoStyle


def frame_times(t0: float, t1: float, fps: float) -> np.ndarray:
    """Times of the frames of a video of [t0, t1): ``round((t1 - t0) * fps)`` frames, 1/fps apart.

    A video of d seconds at f fps has round(d·f) frames (at least one); frame i shows the log
    sample nearest t0 + i/f.
    """
    n = max(1, int(round((t1 - t0) * fps)))
    return t0 + np.arange(n) / float(fps)


def _partial_path(path: Path) -> Path:
    return path.with_name(f".{path.stem}.partial{path.suffix}")


def _log_of(result_or_log):
    return getattr(result_or_log, "log", result_or_log)


def _world_of(result_or_log, world):
    """The model to replay into: ``world`` when given, else for a ``RunResult`` the swarm of its
    vehicle (``scenario.params``), with its landing gear where the physics has a solid ground
    (docs/aero.md); None where that is the paper drone's plain swarm, which ``Replay`` builds (a
    bare ``RunLog`` too)."""
    if world is not None:
        return world
    sc = getattr(result_or_log, "scenario", None)
    if sc is None:
        return None
    ground = bool(getattr(sc.aero, "ground", False))
    if not ground and sc.params == DEFAULT_PARAMS:
        return None
    return replay_world(_log_of(result_or_log), ground=ground, params=sc.params)


def _title(result_or_log) -> str | None:
    sc = getattr(result_or_log, "scenario", None)
    return getattr(sc, "name", None)


def render_video(
    result,
    path: str | Path,
    *,
    fps: float = DEFAULT_FPS,
    size: tuple[int, int] = DEFAULT_SIZE,
    start: float | None = None,
    end: float | None = None,
    style: VideoStyle | None = None,
    progress: bool | None = None,
    world=None,
    crf: int = 20,
) -> Path:
    """Write an H.264 MP4 of a run (``RunResult`` or ``RunLog``) replayed at ``fps``.

    Frames: :func:`frame_times` over [start, end] (default: the whole run). The file is
    written as ``.NAME.partial.mp4`` and renamed into place when complete.
    """
    import imageio.v2 as iio2

    log = _log_of(result)
    path = Path(path)
    w, h = size
    if w % 2 or h % 2:
        raise UserError(f"video size {w}x{h}: H.264 needs an even width and height")
    if not fps > 0:
        raise UserError(f"fps must be positive, got {fps}")
    t_first, t_last = float(log.t[0]), float(log.t[-1])
    t0 = t_first if start is None else max(t_first, float(start))
    t1 = t_last if end is None else min(t_last, float(end))
    if len(log.t) > 1 and t1 - t0 < 0.5 / fps:
        raise UserError(f"nothing to film between {t0:g} s and {t1:g} s")
    times = frame_times(t0, t1, fps) if len(log.t) > 1 else np.array([t0])
    tmp = _partial_path(path)
    bar = Progress(len(times), f"video {path.name}", progress, unit="frames")
    writer = None
    ok = False
    try:
        with Replay(log, _world_of(result, world), width=w, height=h, style=style) as rep:
            rep.title = _title(result)
            # macro_block_size=2: yuv420p needs even sizes, and nothing else is resized
            # (1280x720, 1920x1080 and 320x240 go through untouched).
            writer = iio2.get_writer(
                str(tmp),
                format="FFMPEG",
                mode="I",
                fps=float(fps),
                codec="libx264",
                pixelformat="yuv420p",
                macro_block_size=2,
                quality=None,
                output_params=["-crf", str(int(crf)), "-preset", "veryfast", "-movflags", "+faststart"],
            )
            for i, t in enumerate(times):
                writer.append_data(rep.render(float(t)))
                bar.update(i + 1)
            writer.close()
            writer = None
        os.replace(tmp, path)
        ok = True
    finally:
        bar.close()
        if writer is not None:
            try:
                writer.close()
            except Exception:
                pass
        if not ok:
            try:
                tmp.unlink()
            except FileNotFoundError:
                pass
    return path


def render_snapshot(
    result,
    path: str | Path,
    *,
    time: float = DEFAULT_SNAPSHOT_TIME,
    size: tuple[int, int] = DEFAULT_SIZE,
    style: VideoStyle | None = None,
    world=None,
) -> Path:
    """Write a PNG still of a run at ``time`` (the nearest log sample), with the video's camera."""
    import imageio.v3 as iio

    log = _log_of(result)
    path = Path(path)
    if time > float(log.t[-1]) + 1e-6 or time < float(log.t[0]) - 1e-6:
        raise UserError(f"snapshot time {time:g} s is outside the run ({log.t[0]:g} to {log.t[-1]:g} s)")
    w, h = size
    with Replay(log, _world_of(result, world), width=w, height=h, style=style) as rep:
        rep.title = _title(result)
        image = rep.render(float(time))
    tmp = _partial_path(path)
    try:
        iio.imwrite(tmp, image, extension=".png")
        os.replace(tmp, path)
    except BaseException:
        try:
            tmp.unlink()
        except FileNotFoundError:
            pass
        raise
    return path
