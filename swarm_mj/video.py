"""Headless video and still export by replaying a run's log (DESIGN "video").

Rendering is an *offline replay*: the run is simulated first (``runner.run``), then
the logged states (:class:`~swarm_mj.runner.RunLog`, one sample per control period)
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
options are checked by :func:`check_video_args` before anything is simulated
(:class:`~swarm_mj.errors.UserError`). Videos and stills are written to a temporary
file next to the target and renamed into place, so a failure or Ctrl-C leaves no
half-written file.
"""

from __future__ import annotations

import math
import os
import re
import sys
import time as _time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from .errors import RenderError, UserError

DEFAULT_FPS = 30
DEFAULT_SIZE = (1280, 720)
DEFAULT_SNAPSHOT_TIME = 20.0
MAX_SIZE = 8192

LEADER_RGB = (0.85, 0.12, 0.12)
FOLLOWER_RGB = (0.12, 0.40, 0.85)
REFERENCE_RGBA = (0.95, 0.65, 0.05, 0.9)

# What to install when EGL is missing (Debian 12 / Ubuntu package names):
#   libegl1          libEGL.so.1, the GLVND EGL loader PyOpenGL opens
#   libegl-mesa0     Mesa's EGL driver (the vendor libEGL loads, 50_mesa.json)
#   libgl1-mesa-dri  Mesa's DRI drivers, among them swrast (llvmpipe) for CPU rendering
#   libopengl0       libOpenGL.so.0, the GL entry points PyOpenGL loads with EGL
EGL_PACKAGES = "libegl1 libegl-mesa0 libgl1-mesa-dri libopengl0"


# --------------------------------------------------------------------------- style


@dataclass
class VideoStyle:
    """Everything about the look of a frame; the defaults make docs/swarm.png."""

    elevation_deg: float = -38.0        # camera elevation (negative: looking down)
    azimuth_deg: float = 125.0          # camera azimuth at t = 0 (MuJoCo convention)
    orbit_deg_per_s: float = 0.0        # slow orbit; 0 = fixed azimuth
    fovy_deg: float = 40.0              # vertical field of view
    margin: float = 0.2                 # fraction of the half-frame kept free around the swarm
    drone_radius: float = 0.35          # m, added around each drone centre when framing
    min_distance: float = 3.5           # m, never closer than this
    smooth_s: float = 0.8               # time constant of the camera's smoothing (s)
    zoom_window_s: float = 2.0          # look-ahead/behind of the zoom's envelope (s)
    trail_s: float = 10.0               # length of each drone's trail (s)
    trail_dt: float = 0.2               # s between trail vertices
    trail_px: float = 4.0               # trail width in pixels at 720 lines (scaled with the height)
    reference_px: float = 3.0           # reference path width in pixels at 720 lines
    reference_dt: float = 0.25          # s between reference-path vertices (at most 600 segments)
    reference: bool = True              # draw the leader's reference path
    trails: bool = True                 # draw the trails
    markers: bool = True                # a coloured disc under each drone's hub (ownership colour)
    caption: bool = True                # time and legend in the image
    shadows: bool = True
    samples: int = 4                    # multisample anti-aliasing (0 = off: about 2x faster on llvmpipe)

    @classmethod
    def preset(cls, quality: str = "high", **kw) -> "VideoStyle":
        """``high``: anti-aliased, shadows (the default); ``fast``: neither (about 3x faster on CPU)."""
        if quality == "high":
            return cls(**kw)
        if quality == "fast":
            return cls(**{"samples": 0, "shadows": False, **kw})
        raise UserError(f"unknown quality {quality!r}; choose high or fast")


# --------------------------------------------------------------------------- options


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


def check_video_args(args) -> None:
    """Check the rendering options of ``swarm-mj run`` / ``swarm-mj video`` before simulating.

    Reads ``args.video``, ``args.snapshot``, ``args.snapshot_time``, ``args.fps``, ``args.size``
    and, where present, ``args.duration`` / ``args.scenario`` (to check the still's time and
    the video's window against the run's length). Raises :class:`UserError`.
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
            check_output_path(video, (".mp4",), "--video")
            if w % 2 or h % 2:
                raise UserError(f"--size {w}x{h}: H.264 video needs an even width and height")
        if snapshot is not None:
            check_output_path(snapshot, (".png",), "--snapshot")
    duration = getattr(args, "duration", None)
    if duration is None and getattr(args, "scenario", None) is not None and (video or snapshot):
        from .scenario import load_scenario

        duration = load_scenario(args.scenario).duration
    if snapshot is not None:
        ts = getattr(args, "snapshot_time", DEFAULT_SNAPSHOT_TIME)
        if ts is None or not math.isfinite(ts) or ts < 0:
            raise UserError(f"--snapshot-time must be a time >= 0 s, got {ts}")
        if duration is not None and ts > duration + 1e-9:
            raise UserError(f"--snapshot-time {ts:g} s is after the end of the run ({duration:g} s); "
                            f"lower it or raise --duration")
    start, end = getattr(args, "start", None), getattr(args, "end", None)
    if start is not None and (not math.isfinite(start) or start < 0):
        raise UserError(f"--start must be a time >= 0 s, got {start}")
    if end is not None and (not math.isfinite(end) or end <= (start or 0.0)):
        raise UserError(f"--end must be after --start, got {end}")
    if duration is not None and start is not None and start >= duration:
        raise UserError(f"--start {start:g} s is not before the end of the run ({duration:g} s)")


# --------------------------------------------------------------------------- EGL


def mujoco_gl_backend() -> str:
    """The OpenGL backend MuJoCo chose when it was imported (MUJOCO_GL read at that time)."""
    try:
        from mujoco.rendering.classic import gl_context

        return str(getattr(gl_context, "_MUJOCO_GL", os.environ.get("MUJOCO_GL", ""))).strip().lower()
    except Exception:  # pragma: no cover - another mujoco layout
        return os.environ.get("MUJOCO_GL", "").strip().lower()


def libegl_loadable() -> bool:
    """Whether the dynamic loader can open libEGL.so.1 (Debian package libegl1)."""
    import ctypes

    try:
        ctypes.CDLL("libEGL.so.1")
    except OSError:
        return False
    return True


HEADLESS_BACKENDS = ("egl", "disable", "disabled", "off", "false", "0")


def describe_gl_failure(exc: BaseException) -> str:
    """One line: why the renderer could not start, and what to do about it."""
    backend = mujoco_gl_backend()
    text = " ".join(str(a) for a in getattr(exc, "args", ()) if a) or type(exc).__name__
    text = re.sub(r"\s+", " ", text).strip()
    low = text.lower()
    fix = (f"fix: apt-get install {EGL_PACKAGES} (Debian/Ubuntu; Mesa renders on the CPU) "
           f"or install a GPU driver with EGL")
    head = "headless rendering needs EGL (MUJOCO_GL=egl) and it failed"
    if sys.platform.startswith("linux") and backend in HEADLESS_BACKENDS and (
            "unable to load egl library" in low or not libegl_loadable()):
        return f"{head}: the EGL library libEGL.so.1 is not installed; {fix}"
    if backend != "egl":
        return (f"cannot render: MuJoCo was imported with MUJOCO_GL={backend or '(unset)'} and that failed "
                f"({type(exc).__name__}: {text}); for headless rendering set MUJOCO_GL=egl before anything "
                f"imports mujoco (or import swarm_mj first), and {fix}")
    if "egl device display" in low or "eglquerydevicesext" in low or "eglgetplatformdisplayext" in low:
        cause = "EGL found no driver that can render (Mesa's EGL and DRI drivers, or a GPU driver)"
    elif "pyopengl" in low or "no module named 'opengl'" in low:
        cause = "PyOpenGL is missing"
        fix = "fix: pip install pyopengl"
    else:
        cause = f"{type(exc).__name__}: {text}"
    return f"{head}: {cause}; {fix}"


def _default_renderer_factory(model: mujoco.MjModel, width: int, height: int) -> mujoco.Renderer:
    return mujoco.Renderer(model, height=height, width=width, max_geom=20000)


# Replaced in tests to simulate a machine without EGL.
renderer_factory: Callable[[mujoco.MjModel, int, int], mujoco.Renderer] = _default_renderer_factory


def open_renderer(model: mujoco.MjModel, width: int, height: int) -> mujoco.Renderer:
    """A :class:`mujoco.Renderer` of ``width`` x ``height``, or :class:`RenderError` in one line.

    Grows the model's offscreen buffer when the image is larger than it. Mesa's own
    warnings are silenced (``EGL_LOG_LEVEL=fatal`` unless set): the error says it all.
    """
    model.vis.global_.offwidth = max(int(model.vis.global_.offwidth), int(width))
    model.vis.global_.offheight = max(int(model.vis.global_.offheight), int(height))
    os.environ.setdefault("EGL_LOG_LEVEL", "fatal")
    try:
        renderer = renderer_factory(model, width, height)
    except (ImportError, OSError, RuntimeError, AttributeError, mujoco.FatalError) as exc:
        raise RenderError(describe_gl_failure(exc)) from exc
    except Exception as exc:  # e.g. a GLError from PyOpenGL: still a renderer that cannot start
        if type(exc).__module__.startswith("OpenGL"):
            raise RenderError(describe_gl_failure(exc)) from exc
        raise
    return renderer


# --------------------------------------------------------------------------- camera


def _ema_zero_phase(x: np.ndarray, dt: float, tau: float) -> np.ndarray:
    """Exponential smoothing forwards then backwards in time (no lag), along axis 0."""
    x = np.asarray(x, float)
    if tau <= 0 or len(x) < 2:
        return x.copy()
    a = 1.0 - math.exp(-dt / tau)
    y = x.copy()
    for k in range(1, len(y)):
        y[k] = y[k - 1] + a * (y[k] - y[k - 1])
    for k in range(len(y) - 2, -1, -1):
        y[k] = y[k + 1] + a * (y[k] - y[k + 1])
    return y


def _sliding_max(x: np.ndarray, half: int) -> np.ndarray:
    """max of x over [k - half, k + half] for each k (1-D)."""
    if half <= 0:
        return x.copy()
    n = len(x)
    pad = np.concatenate([np.full(half, -np.inf), x, np.full(half, -np.inf)])
    win = np.lib.stride_tricks.sliding_window_view(pad, 2 * half + 1)
    return win.max(axis=1)[:n]


def camera_axes(azimuth_deg: float, elevation_deg: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(forward, right, up) unit vectors of MuJoCo's free camera at this azimuth/elevation."""
    az, el = math.radians(azimuth_deg), math.radians(elevation_deg)
    fwd = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
    right = np.array([math.sin(az), -math.cos(az), 0.0])
    up = np.cross(right, fwd)
    return fwd, right, up


@dataclass
class CameraPath:
    """A free camera for every log sample: lookat (k, 3), distance (k,), azimuth (k,), elevation."""

    t: np.ndarray
    lookat: np.ndarray
    distance: np.ndarray
    azimuth: np.ndarray
    elevation: float
    fovy: float

    @classmethod
    def frame_swarm(cls, t: np.ndarray, pos: np.ndarray, aspect: float, style: VideoStyle) -> "CameraPath":
        """Keep every drone in frame: see the module docstring. ``pos`` is (k, n, 3)."""
        t = np.asarray(t, float)
        pos = np.asarray(pos, float)
        k = len(t)
        dt = float(np.median(np.diff(t))) if k > 1 else 0.01
        good = np.isfinite(pos).all(axis=2)                           # (k, n)
        p = np.where(good[..., None], pos, np.nan)
        lo, hi = np.nanmin(p, axis=1), np.nanmax(p, axis=1)           # (k, 3)
        centre = 0.5 * (lo + hi)
        centre = np.where(np.isfinite(centre), centre, 0.0)
        lookat = _ema_zero_phase(centre, dt, style.smooth_s)
        azimuth = style.azimuth_deg + style.orbit_deg_per_s * (t - t[0])
        ty = math.tan(math.radians(style.fovy_deg) / 2) * (1.0 - style.margin)
        tx = ty * aspect
        # Smallest distance d with every drone inside the frame: for a point at offset q from
        # lookat, camera depth z = q.fwd + d, and |q.right| + r <= tx z, |q.up| + r <= ty z.
        need = np.zeros(k)
        for j in range(k):
            fwd, right, up = camera_axes(float(azimuth[j]), style.elevation_deg)
            q = p[j][good[j]] - lookat[j]
            if len(q) == 0:
                continue
            r = style.drone_radius
            dx = (np.abs(q @ right) + r) / tx - q @ fwd + r
            dy = (np.abs(q @ up) + r) / ty - q @ fwd + r
            need[j] = max(dx.max(), dy.max())
        need = np.maximum(need, style.min_distance)
        half = int(round(style.zoom_window_s / dt)) if dt > 0 else 0
        envelope = _sliding_max(need, half)
        distance = np.maximum(_ema_zero_phase(envelope, dt, style.smooth_s), need)
        return cls(t, lookat, distance, azimuth, style.elevation_deg, style.fovy_deg)

    def index(self, time: float) -> int:
        return nearest_index(self.t, time)

    def mjv_camera(self, j: int) -> mujoco.MjvCamera:
        cam = mujoco.MjvCamera()
        cam.type = mujoco.mjtCamera.mjCAMERA_FREE
        cam.lookat[:] = self.lookat[j]
        cam.distance = float(self.distance[j])
        cam.azimuth = float(self.azimuth[j])
        cam.elevation = float(self.elevation)
        return cam


def nearest_index(t: np.ndarray, time: float) -> int:
    """Index of the sample of ``t`` (increasing) nearest ``time`` (clamped to the ends)."""
    k = int(np.searchsorted(t, time))
    if k <= 0:
        return 0
    if k >= len(t):
        return len(t) - 1
    return k if (t[k] - time) < (time - t[k - 1]) else k - 1


def project_points(glcam, points: np.ndarray, width: int, height: int) -> np.ndarray:
    """Pixel coordinates (x right, y down; (N, 2)) of world ``points`` (N, 3) seen by ``glcam``.

    ``glcam`` is the ``mjvGLCamera`` MuJoCo drew with: without stereo, the average of the
    scene's two eye cameras (:attr:`Replay.glcamera`, ``mujoco.mjv_averageCamera``); the
    frustum is the one ``mjr_render`` sets: its half-width follows the image's aspect ratio.
    Points behind the camera get NaN.
    """
    pts = np.atleast_2d(np.asarray(points, float))
    fwd = np.asarray(glcam.forward, float)
    up = np.asarray(glcam.up, float)
    right = np.cross(fwd, up)
    rel = pts - np.asarray(glcam.pos, float)
    z = rel @ fwd
    x = rel @ right
    y = rel @ up
    near = float(glcam.frustum_near)
    bottom, top = float(glcam.frustum_bottom), float(glcam.frustum_top)
    half_w = 0.5 * width / height * (top - bottom)
    centre = float(glcam.frustum_center)
    with np.errstate(divide="ignore", invalid="ignore"):
        xn = x * near / z
        yn = y * near / z
    u = (xn - (centre - half_w)) / (2 * half_w) * width
    v = (top - yn) / (top - bottom) * height
    out = np.column_stack([u, v])
    out[z <= 0] = np.nan
    return out


# --------------------------------------------------------------------------- replay


def _rgba(rgb: Sequence[float], a: float) -> np.ndarray:
    return np.array([rgb[0], rgb[1], rgb[2], a], dtype=np.float32)


class Replay:
    """Replays a :class:`~swarm_mj.runner.RunLog` into a MuJoCo model and renders frames.

    ``Replay(log)`` rebuilds the swarm with :func:`swarm_mj.world.build_world` (initial
    positions ``log.pos[0]``, names ``log.names``); pass ``world`` to reuse one. Use as a
    context manager (it holds an EGL context): ``with Replay(log, width=640, height=480) as
    r: image = r.render(20.0)``.
    """

    def __init__(self, log, world=None, *, width: int = DEFAULT_SIZE[0], height: int = DEFAULT_SIZE[1],
                 style: VideoStyle | None = None) -> None:
        from .world import build_world

        if len(log.t) < 1:
            raise UserError("the run has no samples to render")
        self.log = log
        self.style = style or VideoStyle()
        self.width, self.height = int(width), int(height)
        n = len(log.names)
        if world is None:
            p0 = np.nan_to_num(np.asarray(log.pos[0], float))
            world = build_world(n, positions=p0, names=list(log.names))
        if world.n_drones != n:
            raise UserError(f"the world has {world.n_drones} drones, the log {n}")
        self.world = world
        self.model = model = world.model
        if model.nq != 7 * n:
            raise UserError("the model must hold only the drones' free joints (7 qpos per drone)")
        self.n = n
        self._tune_model(model)
        self.data = mujoco.MjData(model)
        self.camera = CameraPath.frame_swarm(log.t, log.pos, self.width / self.height, self.style)
        self.option = mujoco.MjvOption()
        self.renderer = open_renderer(model, self.width, self.height)
        if not self.style.shadows:
            self.renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = False
        self._colors = [LEADER_RGB if i == 0 else FOLLOWER_RGB for i in range(n)]
        self._ref = self._reference_vertices()
        self._caption_font = None
        self.last_index = -1

    # -- model look -----------------------------------------------------------------
    def _tune_model(self, model: mujoco.MjModel) -> None:
        """Rendering-only changes to this replay's copy of the model (physics untouched)."""
        st = self.style
        model.vis.global_.fovy = st.fovy_deg
        # znear/zfar are in units of the model's extent: 5 cm to 300 m with extent >= 10 m.
        model.stat.extent = max(float(model.stat.extent), 10.0)
        model.vis.map.znear = 0.005
        model.vis.map.zfar = 30.0
        model.vis.map.shadowclip = 1.0          # shadow map covers +-extent around the (moving) sun
        model.vis.quality.offsamples = max(0, int(st.samples))
        # Softer headlight, a darker floor: the default look is washed out in a still.
        model.vis.headlight.ambient[:] = 0.32
        model.vis.headlight.diffuse[:] = 0.45
        model.vis.headlight.specular[:] = 0.1
        if model.nlight:
            model.light_diffuse[:] = 0.55
            model.light_specular[:] = 0.1
        self._light_pos0 = model.light_pos.copy()
        for m in range(model.nmat):
            if mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_MATERIAL, m) == "grid":
                model.mat_rgba[m] = (0.86, 0.88, 0.92, 1.0)
                model.mat_texrepeat[m] = (1.0, 1.0)
        # Rotor discs and hub in the drone's colour (the asset draws every rotor light blue).
        geom_drone = getattr(self.world, "geom_drone", None)
        if geom_drone is not None:
            for g in range(model.ngeom):
                i = int(geom_drone[g])
                if i < 0:
                    continue
                name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or ""
                rgb = LEADER_RGB if i == 0 else FOLLOWER_RGB
                if name.endswith(("rotor1", "rotor2", "rotor3", "rotor4")):
                    model.geom_rgba[g] = (*rgb, 0.6)
                elif name.endswith("hub"):
                    model.geom_rgba[g] = (*rgb, 1.0)
                elif name.endswith("nose"):      # heading marker: white, so red means "leader" only
                    model.geom_rgba[g] = (0.97, 0.97, 0.97, 1.0)

    def _reference_vertices(self) -> np.ndarray:
        log, st = self.log, self.style
        ref = np.asarray(log.slot[:, 0], float)
        ref = ref[np.isfinite(ref).all(axis=1)]
        if len(ref) < 2:
            return ref
        dt = float(np.median(np.diff(log.t))) if len(log.t) > 1 else 0.01
        step = max(1, int(round(st.reference_dt / dt)), int(math.ceil(len(ref) / 600)))
        idx = np.unique(np.r_[np.arange(0, len(ref), step), len(ref) - 1])
        return ref[idx]

    # -- state ----------------------------------------------------------------------
    def set_state(self, j: int) -> None:
        """Write log sample ``j`` into qpos (7 per drone: position, unit quaternion w x y z)."""
        qpos = self.data.qpos.reshape(self.n, 7)
        qpos[:, 0:3] = np.nan_to_num(self.log.pos[j])
        q = np.nan_to_num(self.log.quat[j])
        norm = np.linalg.norm(q, axis=1, keepdims=True)
        qpos[:, 3:7] = np.where(norm > 1e-9, q / np.maximum(norm, 1e-9), [1.0, 0.0, 0.0, 0.0])
        self.data.qvel[:] = 0.0
        self.data.time = float(self.log.t[j])
        # The sun follows the camera's target so the swarm stays inside its shadow map.
        if self.model.nlight:
            la = self.camera.lookat[j]
            self.model.light_pos[:, 0:2] = self._light_pos0[:, 0:2] + la[0:2]
        mujoco.mj_forward(self.model, self.data)

    # -- extra geoms ----------------------------------------------------------------
    def _add_line(self, scn, a, b, width_px: float, rgba) -> bool:
        if scn.ngeom >= scn.maxgeom:
            return False
        if not (np.isfinite(a).all() and np.isfinite(b).all()) or np.linalg.norm(b - a) < 1e-6:
            return True
        g = scn.geoms[scn.ngeom]
        mujoco.mjv_initGeom(g, mujoco.mjtGeom.mjGEOM_LINE, self._zero3, self._zero3, self._eye9, rgba)
        mujoco.mjv_connector(g, mujoco.mjtGeom.mjGEOM_LINE, width_px, a, b)
        g.category = mujoco.mjtCatBit.mjCAT_DECOR
        g.castshadow = False
        scn.ngeom += 1
        return True

    def _add_disc(self, scn, centre, radius, rgba) -> None:
        if scn.ngeom >= scn.maxgeom or not np.isfinite(centre).all():
            return
        g = scn.geoms[scn.ngeom]
        mujoco.mjv_initGeom(g, mujoco.mjtGeom.mjGEOM_CYLINDER, np.array([radius, 0.003, 0.0]),
                            np.asarray(centre, float), self._eye9, rgba)
        g.category = mujoco.mjtCatBit.mjCAT_DECOR
        g.castshadow = False
        scn.ngeom += 1

    _zero3 = np.zeros(3)
    _eye9 = np.eye(3).ravel()

    def _px(self, width_at_720: float) -> float:
        return max(1.0, width_at_720 * self.height / 720.0)

    def _decorate(self, j: int) -> None:
        scn = self.renderer.scene
        st, log = self.style, self.log
        if st.reference and len(self._ref) > 1:
            # dashed: every other segment, so the leader's own (solid) trail shows through
            rgba = np.array(REFERENCE_RGBA, dtype=np.float32)
            w = self._px(st.reference_px)
            for s in range(0, len(self._ref) - 1, 2):
                if not self._add_line(scn, self._ref[s], self._ref[s + 1], w, rgba):
                    break
        if st.trails and j > 0:
            t = log.t
            now = float(t[j])
            dt = float(np.median(np.diff(t))) if len(t) > 1 else 0.01
            stride = max(1, int(round(st.trail_dt / dt)))
            # vertices on a fixed grid of sample indices (no flicker), then the current sample
            k0 = nearest_index(t, max(float(t[0]), now - st.trail_s))
            first = int(math.ceil(k0 / stride) * stride)
            idx = np.unique(np.clip(np.r_[k0, np.arange(first, j, stride), j], 0, j))
            if len(idx) > 1:
                age = (now - t[idx[1:]]) / max(st.trail_s, 1e-9)
                alpha = 0.15 + 0.8 * (1.0 - np.clip(age, 0.0, 1.0))
                w = self._px(st.trail_px)
                for i in range(self.n):
                    pts = log.pos[idx, i]
                    rgb = self._colors[i]
                    for s in range(len(idx) - 1):
                        self._add_line(scn, pts[s], pts[s + 1], w, _rgba(rgb, float(alpha[s])))
        if st.markers:
            for i in range(self.n):
                self._add_disc(scn, log.pos[j, i] + np.array([0.0, 0.0, -0.03]), 0.16,
                               _rgba(self._colors[i], 0.9))

    def _caption(self, image: np.ndarray, j: int) -> np.ndarray:
        try:
            from PIL import Image, ImageDraw, ImageFont
        except ImportError:  # pragma: no cover - Pillow comes with imageio
            return image
        h = self.height
        size = max(10, int(round(h / 34)))
        if self._caption_font is None:
            try:
                self._caption_font = ImageFont.load_default(size=size)
            except TypeError:  # pragma: no cover - old Pillow
                self._caption_font = ImageFont.load_default()
        font = self._caption_font
        img = Image.fromarray(image)
        draw = ImageDraw.Draw(img, "RGBA")
        pad = max(4, size // 2)
        text = f"t = {self.log.t[j]:6.2f} s"
        name = getattr(self, "title", None)
        if name:
            text = f"{name}   {text}"
        items = [(LEADER_RGB, "leader"), (FOLLOWER_RGB, "followers"), (REFERENCE_RGBA[:3], "reference path")]
        if self.style.trails:
            items.append((None, f"trails: last {self.style.trail_s:g} s"))
        widths = [int(draw.textlength(label, font=font)) + int(size * (1.3 if rgb else 0) + size * 1.2)
                  for rgb, label in items]
        box_w = max(int(draw.textlength(text, font=font)), sum(widths) - int(size * 1.2)) + 2 * pad
        box_h = int(size * 2.6) + 2 * pad
        draw.rounded_rectangle([pad // 2, pad // 2, pad // 2 + box_w, pad // 2 + box_h], radius=pad,
                               fill=(255, 255, 255, 170))
        ink = (20, 20, 30, 255)
        draw.text((pad, pad), text, fill=ink, font=font)
        y = pad + int(size * 1.4)
        x = pad
        for rgb, label in items:
            if rgb is not None:
                col = tuple(int(255 * c) for c in rgb) + (255,)
                draw.rectangle([x, y + size * 0.25, x + size * 0.9, y + size * 0.95], fill=col)
                x += int(size * 1.3)
            draw.text((x, y), label, fill=ink, font=font)
            x += int(draw.textlength(label, font=font)) + int(size * 1.2)
        return np.asarray(img)

    # -- frames ---------------------------------------------------------------------
    def update(self, time: float, *, decorate: bool = True) -> int:
        """Set the replayed state and scene to the sample nearest ``time``; returns its index."""
        j = nearest_index(self.log.t, time)
        self.set_state(j)
        self.renderer.update_scene(self.data, camera=self.camera.mjv_camera(j), scene_option=self.option)
        if decorate:
            self._decorate(j)
        self.last_index = j
        return j

    def render(self, time: float, *, caption: bool | None = None, segmentation: bool = False) -> np.ndarray:
        """The frame at ``time`` (nearest log sample): (H, W, 3) uint8, or (H, W, 2) segmentation.

        Segmentation images (object id, object type per pixel) show the model's geoms only:
        the trails, reference path and markers are not model objects and are left out.
        """
        j = self.update(time, decorate=not segmentation)
        if segmentation:
            self.renderer.enable_segmentation_rendering()
            try:
                return self.renderer.render()
            finally:
                self.renderer.disable_segmentation_rendering()
        image = self.renderer.render()
        if self.style.caption if caption is None else caption:
            image = self._caption(image, j)
        return image

    @property
    def glcamera(self):
        """The OpenGL camera of the last frame (for :func:`project_points`).

        ``scene.camera`` holds the two stereo eyes, each shifted by half the model's
        inter-pupillary distance; without stereo MuJoCo draws with their average.
        """
        cams = self.renderer.scene.camera
        return mujoco.mjv_averageCamera(cams[0], cams[1])

    def close(self) -> None:
        r = getattr(self, "renderer", None)
        if r is not None:
            r.close()
            self.renderer = None

    def __enter__(self) -> "Replay":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __del__(self) -> None:  # pragma: no cover - best effort
        try:
            self.close()
        except Exception:
            pass


# --------------------------------------------------------------------------- outputs


def frame_times(t0: float, t1: float, fps: float) -> np.ndarray:
    """Times of the frames of a video of [t0, t1): ``round((t1 - t0) * fps)`` frames, 1/fps apart.

    A video of d seconds at f fps has round(d·f) frames (at least one); frame i shows the log
    sample nearest t0 + i/f.
    """
    n = max(1, int(round((t1 - t0) * fps)))
    return t0 + np.arange(n) / float(fps)


class FrameProgress:
    """``video [#####-----] 120/750 frames  12.3 fps`` on stderr."""

    def __init__(self, total: int, label: str = "video", enabled: bool | None = None) -> None:
        self.total, self.label = int(total), label
        self.enabled = sys.stderr.isatty() if enabled is None else bool(enabled)
        self._t0 = _time.perf_counter()
        self._last = -1.0

    def update(self, done: int) -> None:
        if not self.enabled:
            return
        now = _time.perf_counter()
        if done < self.total and now - self._last < 0.2:
            return
        self._last = now
        frac = done / max(self.total, 1)
        bar = "#" * int(25 * frac) + "-" * (25 - int(25 * frac))
        rate = done / max(now - self._t0, 1e-9)
        sys.stderr.write(f"\r{self.label} [{bar}] {done}/{self.total} frames  {rate:5.1f} fps")
        sys.stderr.flush()

    def close(self) -> None:
        if self.enabled:
            sys.stderr.write("\n")
            sys.stderr.flush()


def _partial_path(path: Path) -> Path:
    return path.with_name(f".{path.stem}.partial{path.suffix}")


def _log_of(result_or_log):
    return getattr(result_or_log, "log", result_or_log)


def _title(result_or_log) -> str | None:
    sc = getattr(result_or_log, "scenario", None)
    return getattr(sc, "name", None)


def render_video(result, path: str | Path, *, fps: float = DEFAULT_FPS, size: tuple[int, int] = DEFAULT_SIZE,
                 start: float | None = None, end: float | None = None, style: VideoStyle | None = None,
                 progress: bool | None = None, world=None, crf: int = 20) -> Path:
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
    bar = FrameProgress(len(times), f"video {path.name}", progress)
    writer = None
    ok = False
    try:
        with Replay(log, world, width=w, height=h, style=style) as rep:
            rep.title = _title(result)
            # macro_block_size=2: yuv420p needs even sizes, and nothing else is resized
            # (1280x720, 1920x1080 and 320x240 go through untouched).
            writer = iio2.get_writer(str(tmp), format="FFMPEG", mode="I", fps=float(fps), codec="libx264",
                                     pixelformat="yuv420p", macro_block_size=2, quality=None,
                                     output_params=["-crf", str(int(crf)), "-preset", "veryfast",
                                                    "-movflags", "+faststart"])
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


def render_snapshot(result, path: str | Path, *, time: float = DEFAULT_SNAPSHOT_TIME,
                    size: tuple[int, int] = DEFAULT_SIZE, style: VideoStyle | None = None, world=None) -> Path:
    """Write a PNG still of a run at ``time`` (the nearest log sample), with the video's camera."""
    import imageio.v3 as iio

    log = _log_of(result)
    path = Path(path)
    if time > float(log.t[-1]) + 1e-6 or time < float(log.t[0]) - 1e-6:
        raise UserError(f"snapshot time {time:g} s is outside the run ({log.t[0]:g} to {log.t[-1]:g} s)")
    w, h = size
    with Replay(log, world, width=w, height=h, style=style) as rep:
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


def render_outputs(result, args) -> int:
    """Render what ``args`` asks for (``--video``, ``--snapshot``); returns the exit status.

    Called by ``swarm-mj run`` after the recording is written and by ``swarm-mj video``.
    A renderer that cannot start raises :class:`RenderError` (one line, exit status 1).
    """
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
        out = render_video(result, video, fps=fps, size=size, start=getattr(args, "start", None),
                           end=getattr(args, "end", None), style=style, progress=None if not quiet else False)
        if not quiet:
            print(f"video: {out}  ({fps:g} fps, {size[0]}x{size[1]}, H.264)", file=sys.stderr)
    return 0
