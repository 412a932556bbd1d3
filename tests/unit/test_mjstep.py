"""``swarm_mj/physics/_mjstep.py``: MuJoCo's ``mj_step`` called from a compiled kernel is the same function on the
same memory as ``mujoco.mj_step`` (bit for bit), and the ``ncon`` view reads ``MjData.ncon``."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from swarm_mj import _jit
from swarm_mj.physics import _mjstep

pytestmark = pytest.mark.skipif(not (_jit.AVAILABLE and _mjstep.available()), reason="no compiled mj_step here")

XML = """<mujoco><option timestep="0.005" integrator="RK4"/><worldbody><geom type="plane" size="5 5 .1"/>
  <body pos="0 0 1"><freejoint/><geom size=".1"/></body>
  <body pos="0.05 0 1.5"><freejoint/><geom type="box" size=".1 .05 .02"/></body></worldbody></mujoco>"""

if _jit.AVAILABLE:
    import numba

    @numba.njit(cache=False)
    def _steps(fn, m, d, n, ncon, out):
        for i in range(n):
            _mjstep.step_call(fn, m, d)
            out[i] = ncon[0]


def test_kernel_mj_step_matches_python_bit_for_bit_and_ncon_reads_through():
    m = mujoco.MjModel.from_xml_string(XML)
    a, b = mujoco.MjData(m), mujoco.MjData(m)
    a.xfrc_applied[2] = b.xfrc_applied[2] = (0.3, 0.0, 0.0, 0.0, 0.01, 0.0)
    seen_py = np.zeros(400, dtype=np.int64)
    for i in range(400):
        mujoco.mj_step(m, a)
        seen_py[i] = a.ncon
    seen = np.zeros(400, dtype=np.int64)
    view = _mjstep.ncon_view(b)
    assert view is not None
    _steps(np.uint64(_mjstep.mj_step_address()), np.uint64(m._address), np.uint64(b._address), 400, view, seen)
    assert np.array_equal(a.qpos, b.qpos) and np.array_equal(a.qvel, b.qvel)
    assert a.time == b.time
    np.testing.assert_array_equal(seen, seen_py)
    assert seen.min() == 0 and seen.max() >= 2  # in the air, then the sphere and the box on the floor and each other
    assert view[0] == b.ncon
