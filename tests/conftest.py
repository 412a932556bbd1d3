"""Import swarm_mj first so that MUJOCO_GL is chosen before any test imports mujoco."""

import swarm_mj  # noqa: F401
