"""The look of a frame: :class:`VideoStyle` (camera, trails, quality) and the default sizes and colours."""

from __future__ import annotations

from dataclasses import dataclass

from ..errors import UserError

DEFAULT_FPS = 30
DEFAULT_SIZE = (1280, 720)
DEFAULT_SNAPSHOT_TIME = 20.0
MAX_SIZE = 8192

LEADER_RGB = (0.85, 0.12, 0.12)
FOLLOWER_RGB = (0.12, 0.40, 0.85)
REFERENCE_RGBA = (0.95, 0.65, 0.05, 0.9)


@dataclass
class VideoStyle:
    """Everything about the look of a frame; the defaults make docs/swarm.png."""

    elevation_deg: float = -38.0  # camera elevation (negative: looking down)
    azimuth_deg: float = 125.0  # camera azimuth at t = 0 (MuJoCo convention)
    orbit_deg_per_s: float = 0.0  # slow orbit; 0 = fixed azimuth
    fovy_deg: float = 40.0  # vertical field of view
    margin: float = 0.2  # fraction of the half-frame kept free around the swarm
    drone_radius: float = 0.35  # m, added around each drone centre when framing
    min_distance: float = 3.5  # m, never closer than this
    smooth_s: float = 0.8  # time constant of the camera's smoothing (s)
    zoom_window_s: float = 2.0  # look-ahead/behind of the zoom's envelope (s)
    trail_s: float = 10.0  # length of each drone's trail (s)
    trail_dt: float = 0.2  # s between trail vertices
    trail_px: float = 4.0  # trail width in pixels at 720 lines (scaled with the height)
    reference_px: float = 3.0  # reference path width in pixels at 720 lines
    reference_dt: float = 0.25  # s between reference-path vertices (at most 600 segments)
    reference: bool = True  # draw the leader's reference path
    trails: bool = True  # draw the trails
    markers: bool = True  # a coloured disc under each drone's hub (ownership colour)
    caption: bool = True  # time and legend in the image
    shadows: bool = True
    samples: int = 4  # multisample anti-aliasing (0 = off: about 2x faster on llvmpipe)

    @classmethod
    def preset(cls, quality: str = "high", **kw) -> VideoStyle:
        """``high``: anti-aliased, shadows (the default); ``fast``: neither (about 3x faster on CPU)."""
        if quality == "high":
            return cls(**kw)
        if quality == "fast":
            return cls(**{"samples": 0, "shadows": False, **kw})
        raise UserError(f"unknown quality {quality!r}; choose high or fast")
