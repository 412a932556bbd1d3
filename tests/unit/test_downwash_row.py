"""One drone's row of the downwash (:func:`swarm_mj.physics.aero.downwash.downwash_on`, what a drone's
feedforward from its own view computes) is the simulator's whole kernel's row (:func:`downwash_kernel`), bit for
bit, over random positions, attitudes and thrusts (drones stacked so that the jets reach)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from swarm_mj.physics.aero.downwash import downwash_kernel, downwash_on
from swarm_mj.physics.params import DEFAULT_PARAMS


@settings(max_examples=60, deadline=None)
@given(n=st.integers(2, 7), seed=st.integers(0, 2**32 - 1))
def test_a_drones_row_is_the_kernels_row(n, seed):
    rng = np.random.default_rng(seed)
    pos = rng.uniform(-0.3, 0.3, (n, 3))
    pos[:, 2] = rng.uniform(0.0, 1.5, n)  # a column: most pairs in each other's jet
    quat = rng.normal(size=(n, 4)) * np.array([4.0, 0.3, 0.3, 0.3])  # near level (not normalised: the kernels' q)
    rotor = rng.uniform(0.0, 0.2, (n, 4))
    rotor[rng.random(n) < 0.2] = 0.0  # some drones without thrust (no jet)
    pos[1] = pos[0] - [0.0, 0.0, 0.4]  # drone 1 right under drone 0, which has thrust: its row is not zero
    quat[:2] = [1.0, 0.0, 0.0, 0.0]
    rotor[0] = 0.1
    p = DEFAULT_PARAMS
    args = (float(p.L), p.rotor_dirs, 1.2, 0.023, 0.02, 0.005, 0.023)
    force, torque, add_f, add_t = (np.zeros((n, 3)) for _ in range(4))
    downwash_kernel(pos, quat, rotor, n, *args, force, torque, add_f, add_t)
    assert force[1, 2] < 0.0  # the comparison is not of zeros: drone 0's jet pushes drone 1 down
    for i in range(n):
        f, t = np.full(3, np.nan), np.full(3, np.nan)
        downwash_on(i, pos, quat, rotor, *args, f, t)
        assert np.array_equal(f, force[i]) and np.array_equal(t, torque[i]), i
