"""swarm-mj: a MuJoCo-physics quadrotor swarm (backstepping + FPA, pentagon formation, wind)."""

from __future__ import annotations

import os

# Headless by default: MuJoCo/dm_control read MUJOCO_GL at import time (PLATFORM.md).
os.environ.setdefault("MUJOCO_GL", "egl")

__version__ = "0.1.0"
