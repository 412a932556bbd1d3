"""Import swarm_mj first so that MUJOCO_GL is chosen before any test imports mujoco; shared fixtures."""

import pytest

import swarm_mj  # noqa: F401


@pytest.fixture
def touchdown_scenario():
    """One drone under the realistic physics (docs/aero.md) that takes off from rest, flies a
    descending circle and touches down on the floor after about 2.5 s (one ground contact)."""
    from swarm_mj.scenario import parse_scenario

    return parse_scenario(
        {
            "name": "touchdown",
            "duration": 3.0,
            "leader": {
                "trajectory": "circle",
                "start": [0.0, 2.5, 0.0],
                "params": {"radius": 2.5, "omega": 0.08, "altitude": 0.9, "climb_rate": -0.3},
            },
            "aero": {"model": "realistic"},
        },
        "<touchdown>",
    )
