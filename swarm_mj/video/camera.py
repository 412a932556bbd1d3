"""The video's camera: a free camera per log sample that keeps the whole swarm in frame (:class:`CameraPath`).

It looks at the centre of the swarm's bounding box (smoothed forwards and backwards in time, so
it does not lag), from a fixed elevation and azimuth (an optional slow orbit), at the smallest
distance that keeps every drone inside the frame with a margin, zooming out ahead of the swarm
spreading and back in slowly. Also :func:`project_points` (world to pixels, for tests and captions).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from .style import VideoStyle


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
    def frame_swarm(cls, t: np.ndarray, pos: np.ndarray, aspect: float, style: VideoStyle) -> CameraPath:
        """Keep every drone in frame: see the module docstring. ``pos`` is (k, n, 3)."""
        t = np.asarray(t, float)
        pos = np.asarray(pos, float)
        k = len(t)
        dt = float(np.median(np.diff(t))) if k > 1 else 0.01
        good = np.isfinite(pos).all(axis=2)  # (k, n)
        p = np.where(good[..., None], pos, np.nan)
        lo, hi = np.nanmin(p, axis=1), np.nanmax(p, axis=1)  # (k, 3)
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
        return cls(
            t=t, lookat=lookat, distance=distance, azimuth=azimuth, elevation=style.elevation_deg, fovy=style.fovy_deg
        )

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
