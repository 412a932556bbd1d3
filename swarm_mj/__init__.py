"""swarm-mj: a MuJoCo-physics quadrotor swarm (backstepping + FPA, pentagon formation, wind)."""

from __future__ import annotations

import os
import sys


def _default_mujoco_gl() -> str | None:
    """EGL (headless) on Linux when libEGL can be opened; else rendering off, so that
    importing mujoco does not fail: the simulation works and ``swarm_mj.video`` says
    what to install. Elsewhere MuJoCo's own default."""
    if not sys.platform.startswith("linux"):
        return None
    import ctypes

    try:
        ctypes.CDLL("libEGL.so.1")
    except OSError:
        return "disable"
    return "egl"


# Headless by default: MuJoCo reads MUJOCO_GL when it is imported (PLATFORM.md).
if "MUJOCO_GL" not in os.environ:
    _gl = _default_mujoco_gl()
    if _gl:
        os.environ["MUJOCO_GL"] = _gl

__version__ = "0.1.0"
