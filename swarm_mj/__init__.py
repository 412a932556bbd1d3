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


# Headless by default: MuJoCo reads MUJOCO_GL when it is imported (docs/libraries.md).
if "MUJOCO_GL" not in os.environ:
    _gl = _default_mujoco_gl()
    if _gl:
        os.environ["MUJOCO_GL"] = _gl

__version__ = "0.1.0"

#: The public API, imported on first use (so that MUJOCO_GL above is set before mujoco is imported).
_API = {
    "SwarmEnv": "swarm_mj.env",
    "StepRecord": "swarm_mj.env",
    "Command": "swarm_mj.env",
    "BacksteppingPolicy": "swarm_mj.control.policy",
    "load_scenario": "swarm_mj.scenario",
    "Scenario": "swarm_mj.scenario",
    "run": "swarm_mj.experiments.runner",
    "RunResult": "swarm_mj.experiments.runner",
    "Sim": "swarm_mj.physics.sim",
    "ForceStage": "swarm_mj.physics.sim",
    "build_world": "swarm_mj.physics.world",
}
__all__ = ["__version__", *_API]


def __getattr__(name: str):
    module = _API.get(name)
    if module is None:
        raise AttributeError(f"module 'swarm_mj' has no attribute {name!r}")
    import importlib

    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted([*globals(), *_API])
