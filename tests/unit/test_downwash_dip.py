"""The downwash-dip measurement (docs/interpretations.md, "downwash dip") on hand-made logs.

Every expected value is worked out here from the definition (jet axis along −body z, depth s,
radial offset r, edge r0 + spread·s + radius), not taken from the code under test.
"""

from __future__ import annotations

import math

import numpy as np

from swarm_mj.metrics import (
    DRONE_RADIUS_M,
    JET_R0_M,
    JET_REACH_M,
    JET_SPREAD,
    downwash_dip,
    in_jet,
)

UPRIGHT = np.array([1.0, 0.0, 0.0, 0.0])


def _log(upper: list, lower: list, lower_ref_z: list, quat_upper=UPRIGHT):
    """Two drones over k samples: drone 0 at ``upper`` (k, 3), drone 1 at ``lower`` (k, 3)."""
    pos = np.stack([np.asarray(upper, float), np.asarray(lower, float)], axis=1)  # (k, 2, 3)
    k = pos.shape[0]
    pos_d = pos.copy()
    pos_d[:, 1, 2] = lower_ref_z
    quat = np.tile(UPRIGHT, (k, 2, 1))
    quat[:, 0] = quat_upper
    return np.arange(k) * 0.01, pos, pos_d, quat


def test_dip_is_the_sinking_since_entering_the_jet_not_the_lag_it_had():
    # drone 1 sits 1 m under drone 0 (in its jet) except at samples 0 and 5, where it is 2 m to
    # the side; e = reference − altitude
    e = [0.30, 0.12, 0.10, 0.15, 0.19, 0.40, 0.00, 0.05]
    inside = [False, True, True, True, True, False, True, True]
    lower = [[0.1 if k else 2.0, 0.0, 1.0] for k in inside]
    t, pos, pos_d, quat = _log([[0, 0, 2.0]] * 8, lower, [1.0 + x for x in e])
    d = downwash_dip(t, pos, pos_d, quat)
    # stretch 1 (samples 1-4) entered 0.12 m low: it sank 0.19 − 0.12 = 0.07 m more; stretch 2
    # (samples 6-7) entered on its reference and sank 0.05 m; the 0.30 and 0.40 m outside count for nothing
    assert math.isclose(d["worst_m"], 0.07, abs_tol=1e-12)
    assert (d["drone"], d["above"]) == (1, 0) and math.isclose(d["t_s"], 0.04)
    assert math.isclose(d["below_ref_worst_m"], 0.19, abs_tol=1e-12)
    assert math.isclose(d["time_in_jet_s"], 6 * 0.01)
    assert d["per_drone_m"][0] == 0.0


def test_only_drones_inside_the_jets_edge_count():
    edge_at_1m = JET_R0_M + JET_SPREAD * 1.0 + DRONE_RADIUS_M  # jet edge + rotor span, 1 m down
    for offset, counted in ((edge_at_1m - 0.05, True), (edge_at_1m + 0.05, False)):
        # on its reference when the stretch begins, 8 cm low a sample later
        t, pos, pos_d, quat = _log([[0, 0, 2.0]] * 2, [[offset, 0, 1.0], [offset, 0, 0.92]], [1.0, 1.0])
        d = downwash_dip(t, pos, pos_d, quat)
        assert math.isclose(d["worst_m"], 0.08 if counted else 0.0, abs_tol=1e-12)
    # the drone above is not in the jet of the one below (the jet points down)
    t, pos, pos_d, quat = _log([[0, 0, 1.0]] * 2, [[0, 0, 2.0], [0, 0, 1.9]], [2.0, 2.0])
    assert downwash_dip(t, pos, pos_d, quat)["worst_m"] == 0.0


def test_jet_reach_and_take_off():
    top = JET_REACH_M + 0.1
    t, pos, pos_d, quat = _log(
        [[0, 0, top], [0, 0, top], [0, 0, top], [0, 0, top + 1.4]],
        [[0, 0, 0.05], [0, 0, 0.15], [0, 0, 0.12], [0, 0, 1.0]],
        [0.5, 0.5, 0.5, 1.5],
    )
    jet = in_jet(pos, quat)
    assert not jet[:, 0, 0].any() and not jet[3, 0, 1]  # depth reach + 0.5 m: out of reach
    assert jet[1, 0, 1] and jet[2, 0, 1]  # depth reach − 0.05 m: in reach
    d = downwash_dip(t, pos, pos_d, quat)
    # sample 0: on the ground (never above 0.1 m yet): not counted; samples 1-2: airborne, in the
    # jet, 0.35 then 0.38 m low: it sank 0.03 m; sample 3 (0.5 m low): out of reach
    assert math.isclose(d["worst_m"], 0.03, abs_tol=1e-12) and d["t_s"] == 0.02


def test_the_jet_follows_the_upper_drones_tilt():
    # upper drone pitched 30° about +y: body z = (sin 30°, 0, cos 30°), the jet leaves along −z_b
    a = math.radians(30.0)
    q = np.array([math.cos(a / 2), 0.0, math.sin(a / 2), 0.0])
    depth = 1.5
    axis = -np.array([math.sin(a), 0.0, math.cos(a)])
    on_axis = np.array([0, 0, 3.0]) + depth * axis  # straight down the tilted jet
    straight_below = np.array([0, 0, 3.0 - depth])  # 0.75 m off the tilted axis... check:
    s = float((straight_below - [0, 0, 3.0]) @ axis)
    r = math.sqrt(depth**2 - s**2)
    assert r > 0.7  # a real offset, so the case matters
    edge = JET_R0_M + JET_SPREAD * s + DRONE_RADIUS_M
    _, pos, _, quat = _log([[0, 0, 3.0]] * 2, [on_axis, straight_below], [on_axis[2] + 0.1] * 2, quat_upper=q)
    jet = in_jet(pos, quat)
    assert jet[0, 0, 1]
    assert bool(jet[1, 0, 1]) == (r < edge)
    # a different geometry (a narrower jet) changes the answer only where it should
    jet_narrow = in_jet(pos, quat, spread=0.0, r0=0.1, radius=0.1)
    assert jet_narrow[0, 0, 1] and not jet_narrow[1, 0, 1]


def test_no_pair_no_dip():
    t = np.arange(3) * 0.01
    one = np.zeros((3, 1, 3))
    d = downwash_dip(t, one, one, np.tile(UPRIGHT, (3, 1, 1)))
    assert d["worst_m"] == 0.0 and d["drone"] == -1
