"""Headless video and still export by replaying a run's log (docs/design.md, "Video").

Rendering is an *offline replay*: the run is simulated first (``runner.run``), then
the logged states (:class:`~swarm_mj.experiments.runner.RunLog`, one sample per control period)
are written into the ``qpos`` of a fresh ``MjData`` of the same swarm model, one
frame at a time, at the video's frame rate (the log sample nearest each frame time),
and drawn with MuJoCo's own renderer (:class:`mujoco.Renderer`) through EGL. So the
cost of a video depends on its length and frame rate, not on the physics timestep,
and a video can be made from a finished run at any time.

The camera (:class:`CameraPath`) is computed from the whole log before the first
frame: it looks at the centre of the swarm's bounding box (smoothed forwards and
backwards in time, so it does not lag), from a fixed elevation and azimuth (an
optional slow orbit), at the smallest distance that keeps every drone inside the
frame with a margin, zooming out ahead of the swarm spreading and back in slowly.
A still at time t and the video's frame at time t use the same camera.

Drawn on top of the model (user geoms added to the ``MjvScene`` after
``update_scene``): the leader's reference path (the whole run, thin), each drone's
trail over the last ``trail_s`` seconds (leader red, followers blue, fading), and a
small caption (time, legend) drawn into the image.

Errors: a renderer that cannot start (no EGL, no driver) raises
:class:`~swarm_mj.errors.RenderError` with one line naming the cause and the fix;
options are checked by ``commands/video.py``'s :func:`check_video_args` before anything is
simulated (:class:`~swarm_mj.errors.UserError`). Videos and stills are written to a temporary
file next to the target and renamed into place, so a failure or Ctrl-C leaves no
half-written file.

The rooms: :mod:`.gl` (MUJOCO_GL, EGL probing, the renderer, one-line failures), :mod:`.style`
(:class:`VideoStyle`, sizes, colours), :mod:`.camera` (:class:`CameraPath`), :mod:`.replay`
(:class:`Replay`), :mod:`.encode` (:func:`render_video`, :func:`render_snapshot`).

Names are loaded on first use (``from swarm_mj.video import Replay`` imports MuJoCo; importing
``swarm_mj.video.gl`` alone does not, so that :func:`.gl.import_mujoco` can run first).
The option checks and :func:`render_outputs` live in ``swarm_mj/commands/video.py`` and are
still importable from here.
"""

from __future__ import annotations

import importlib
from typing import Any

_WHERE = {
    "swarm_mj.video.style": [
        "DEFAULT_FPS",
        "DEFAULT_SIZE",
        "DEFAULT_SNAPSHOT_TIME",
        "MAX_SIZE",
        "LEADER_RGB",
        "FOLLOWER_RGB",
        "REFERENCE_RGBA",
        "VideoStyle",
    ],
    "swarm_mj.video.gl": [
        "EGL_PACKAGES",
        "HEADLESS_BACKENDS",
        "describe_gl_failure",
        "import_mujoco",
        "libegl_loadable",
        "mujoco_gl_backend",
        "open_renderer",
    ],
    "swarm_mj.video.camera": ["CameraPath", "camera_axes", "nearest_index", "project_points"],
    "swarm_mj.video.replay": ["Replay"],
    "swarm_mj.video.encode": ["frame_times", "render_snapshot", "render_video"],
    "swarm_mj.commands.video": ["check_output_path", "check_video_args", "parse_size", "render_outputs"],
}
_MODULE_OF = {name: mod for mod, names in _WHERE.items() for name in names}
__all__ = sorted(_MODULE_OF)


def __getattr__(name: str) -> Any:
    mod = _MODULE_OF.get(name)
    if mod is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(mod), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
