"""The leader's start (docs/barrier.md, "the leader's start"): its trajectory joined from rest at its
start (``trajectories.joined_from_rest``), planned by the rule's planner (``planner.leader_start``, the
record's ``leader_join_s``, ``leader_climb_s``). Checked against finite differences and the closed form
of the rest-to-rest quintic, not against the code's own formulas."""

from __future__ import annotations

import numpy as np
import pytest

from swarm_mj.experiments.stress import StressCase, stress_scenario
from swarm_mj.formation.planner import leader_start
from swarm_mj.formation.rule_params import PRESETS
from swarm_mj.pipeline.swarm import leader_reference
from swarm_mj.trajectories import circle, hover, joined_from_rest

START = np.array([0.3, -0.2, 0.0])


def test_the_join_starts_at_rest_and_meets_the_trajectory():
    f = circle()
    g = joined_from_rest(f, START, 4.0, 2.5)
    r0 = g(np.array([0.0]))
    assert np.array_equal(r0.pos[0], START)
    assert np.all(r0.vel[0] == 0.0) and np.all(r0.acc[0] == 0.0)
    # from each axis's time on, the trajectory's own, bit for bit
    late = np.array([4.0, 6.0, 30.0])
    assert np.array_equal(g(late).pos, f(late).pos) and np.array_equal(g(late).acc, f(late).acc)
    z_late = np.array([2.5, 3.0, 3.9])
    assert np.array_equal(g(z_late).pos[:, 2], f(z_late).pos[:, 2])
    assert not np.allclose(g(z_late).pos[:, :2], f(z_late).pos[:, :2])  # the position still joins
    # continuous at each join: position, velocity and acceleration meet the trajectory's
    for T, axes in ((4.0, slice(0, 2)), (2.5, slice(2, 3))):
        before, at = g(np.array([T - 1e-7])), f(np.array([T]))
        for a, b in ((before.pos, at.pos), (before.vel, at.vel), (before.acc, at.acc)):
            assert np.allclose(a[0, axes], b[0, axes], atol=1e-5)


def test_the_joins_velocity_and_acceleration_are_its_positions_derivatives():
    g = joined_from_rest(circle(), START, 4.0, 2.5)
    t = np.linspace(0.0, 5.0, 50001)
    r = g(t)
    h = t[1] - t[0]
    vel_fd = np.gradient(r.pos, h, axis=0)
    acc_fd = np.gradient(r.vel, h, axis=0)
    inner = slice(2, -2)
    assert np.max(np.abs(vel_fd[inner] - r.vel[inner])) < 1e-4
    # the acceleration jumps nowhere (a kink at each join only in the jerk): its differences are small
    assert np.max(np.abs(acc_fd[inner] - r.acc[inner])) < 1e-3


@pytest.mark.parametrize(("d", "T"), [(2.0, 2.5), (3.0, 4.0)])
def test_a_rest_to_rest_join_peaks_at_the_closed_form(d, T):
    # joined onto a hover d away: the minimum-jerk quintic, peak speed 15/8·d/T at T/2 and peak
    # acceleration 10/√3·d/T² at (1/2 ∓ √3/6)·T (its closed form)
    g = joined_from_rest(hover(position=(d, 0.0, 1.0)), np.array([0.0, 0.0, 1.0]), T, 0.0)
    t = np.linspace(0.0, T, 200001)
    r = g(t)
    assert np.max(r.vel[:, 0]) == pytest.approx(15.0 / 8.0 * d / T, rel=1e-6)
    assert np.max(np.abs(r.acc[:, 0])) == pytest.approx(10.0 / np.sqrt(3.0) * d / T**2, rel=1e-6)
    assert t[np.argmax(r.acc[:, 0])] == pytest.approx((0.5 - np.sqrt(3.0) / 6.0) * T, abs=1e-4)


def test_the_planner_plans_the_leaders_start_only_where_its_record_says():
    f = circle()
    assert leader_start(PRESETS["jet-aware"], f, START) is f  # the paper's step: the trajectory itself
    assert leader_start(PRESETS["layers"], f, START) is f
    g = leader_start(PRESETS["barrier"], f, START)
    assert np.array_equal(g(np.array([0.0])).pos[0], START)
    # the scenario's leader flies its rule's plan; a [formation] key sets it
    case = StressCase("barrier", 3, 3, 2.5, 0.6, 8.0, aero="realistic")
    sc = stress_scenario(case)
    assert np.array_equal(leader_reference(sc)(np.array([0.0])).pos[0], sc.leader_start)
    step = sc.with_overrides(anti_collision_params={"leader_join_s": 0.0, "leader_climb_s": 0.0})
    assert np.array_equal(leader_reference(step)(np.array([0.0])).pos, f(np.array([0.0])).pos)
    alone = stress_scenario(StressCase("barrier", 3, 0, 2.5, 0.6, 8.0, aero="realistic"))  # no follower: no plan
    assert np.array_equal(leader_reference(alone)(np.array([0.0])).pos, f(np.array([0.0])).pos)
    jet = stress_scenario(StressCase("jet-aware", 3, 3, 2.5, 0.6, 8.0, aero="realistic"))
    assert np.array_equal(leader_reference(jet)(np.array([0.0])).pos, f(np.array([0.0])).pos)
