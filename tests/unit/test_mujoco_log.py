"""MuJoCo's warnings go to the ``swarm_mj.mujoco`` logger, not to ``MUJOCO_LOG.TXT`` in the working
directory (issue 47 item 10: a test run left one in the checkout)."""

from __future__ import annotations

import logging

import mujoco
import numpy as np

from swarm_mj.physics import world
from swarm_mj.physics.sim import Sim

XML = '<mujoco><worldbody><body pos="0 0 1"><freejoint/><geom size=".1"/></body></worldbody></mujoco>'


def _diverge() -> int:
    """One step of a free ball pushed with 1e30 N: MuJoCo's mjWARN_BADQACC. Returns its count."""
    m = mujoco.MjModel.from_xml_string(XML)
    d = mujoco.MjData(m)
    d.xfrc_applied[1, 0] = 1e30
    mujoco.mj_step(m, d)
    return int(d.warning[mujoco.mjtWarning.mjWARN_BADQACC].number)


def test_mujoco_warnings_are_logged_not_written_to_the_working_directory(tmp_path, monkeypatch, caplog) -> None:
    monkeypatch.chdir(tmp_path)
    log = tmp_path / "MUJOCO_LOG.TXT"
    assert mujoco.get_mju_user_warning() is world._mujoco_warning  # installed by importing the simulator
    before = mujoco.get_mju_user_warning()
    try:
        # the cause: with no handler (what a dm_control version that installs none leaves), MuJoCo
        # appends the warning to MUJOCO_LOG.TXT in the working directory
        mujoco.set_mju_user_warning(None)
        assert _diverge() == 1 and log.exists()
        log.unlink()
        world.route_mujoco_warnings()
        with caplog.at_level(logging.WARNING, logger="swarm_mj.mujoco"):
            assert _diverge() == 1
        assert not log.exists()
        assert "MuJoCo: Nan, Inf or huge value in QACC" in caplog.text
    finally:
        mujoco.set_mju_user_warning(before)


def test_the_simulators_divergence_writes_no_file(tmp_path, monkeypatch) -> None:
    """What tests/unit/test_pipeline.py does on purpose (a huge force), here in an empty folder."""
    monkeypatch.chdir(tmp_path)
    sim = Sim(world.build_world(1, positions=[[0.0, 0.0, 1.0]]))
    sim.step(np.zeros((1, 4)), np.array([1e12, 0.0, 0.0]))
    assert sim.data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number > 0
    assert list(tmp_path.iterdir()) == []
