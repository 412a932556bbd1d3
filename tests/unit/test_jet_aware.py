"""The default rule under downwash (``jet-aware``, docs/interpretations.md §4) and the controller's
attitude-priority desaturation (docs/interpretations.md §1): kinematic checks against a hand
calculation, no MuJoCo."""

from __future__ import annotations

import numpy as np
import pytest

from swarm_mj.formation.anticollision import (
    CROSS,
    FORMED,
    OVERLAP_M,
    JetAwareRule,
    PaperRule,
    make_rule,
    resolve_rule,
)
from swarm_mj.formation.rule_params import JetAwareParams
from swarm_mj.physics.mixing import MIX, attitude_priority

HOP = 0.4
HOLD = JetAwareParams().crossing_hold  # 7. of JetAwareRule: how far beyond D̄ the early hold starts
FAR = np.array([[0.0, 0.0, 2.0], [10.0, 0.0, 2.0], [0.0, 10.0, 2.0]])  # setpoints far apart


def _h(p: np.ndarray) -> np.ndarray:
    d = np.linalg.norm(p[:, None, :2] - p[None, :, :2], axis=-1)
    np.fill_diagonal(d, np.inf)
    return d


def test_auto_is_barrier_under_downwash_and_layers_otherwise():
    assert resolve_rule("auto", downwash=True) == "barrier"
    assert resolve_rule("auto", downwash=False) == "layers"
    assert resolve_rule("paper", downwash=True) == "paper"
    assert isinstance(make_rule("jet-aware", 3), JetAwareRule)
    assert make_rule("jet-aware", 3).downwash_feedforward and not make_rule("layers", 3).downwash_feedforward


def test_two_drones_yielding_to_the_leader_do_not_end_at_the_same_altitude():
    # leader at the origin, followers 0.5 m from it and 0.71 m from each other, all level:
    # as printed both yield upwards to the leader, to the same altitude, within D̄ of each other
    p = np.array([[0.0, 0.0, 2.0], [0.5, 0.0, 2.0], [0.0, 0.5, 2.0]])
    paper = PaperRule(3)
    paper._react(0.0, p, _h(p), np.ones(3, dtype=bool))
    np.testing.assert_array_equal(paper.offset, [0.0, HOP, HOP])
    rule = JetAwareRule(3)
    rule.reset(p)
    rule.set_slots(FAR)  # slots far apart: only the measured distances count
    rule._react(0.0, p, _h(p), np.ones(3, dtype=bool))
    # follower 1: +hop (the printed rule); follower 2: at least hop from 0 (leader) and +hop
    # (follower 1): nearest the formation altitude is −hop
    np.testing.assert_array_equal(rule.offset, [0.0, HOP, -HOP])
    # one drone to yield to, at the formation altitude: the printed rule's hop
    q = np.array([[0.0, 0.0, 2.0], [0.5, 0.0, 2.0], [3.0, 0.0, 2.0]])
    rule.reset(q)
    rule.set_slots(FAR)
    rule._react(0.0, q, _h(q), np.ones(3, dtype=bool))
    np.testing.assert_array_equal(rule.offset, [0.0, HOP, 0.0])
    # released once beyond D̄ + hysteresis
    q[1, 0] = 0.86
    rule._react(0.1, q, _h(q), np.ones(3, dtype=bool))
    np.testing.assert_array_equal(rule.offset, [0.0, 0.0, 0.0])


def test_followers_whose_slots_are_within_the_safety_distance_yield_before_they_meet():
    # eight followers at D = 1 m: neighbours' slots 0.77 m apart; drones still 3 m apart
    rule = JetAwareRule(3)
    p = np.array([[0.0, 0.0, 2.0], [3.0, 0.0, 2.0], [-3.0, 0.0, 2.0]])
    rule.reset(p)
    slots = np.array([[0.0, 0.0, 2.0], [0.0, 1.0, 2.0], [0.7071, 0.7071, 2.0]])
    rule.set_slots(slots)
    rule._react(0.0, p, _h(p), np.ones(3, dtype=bool))
    np.testing.assert_array_equal(rule.offset, [0.0, 0.0, HOP])  # follower 2 yields to follower 1
    rule._react(0.1, p, _h(p), np.ones(3, dtype=bool))  # kept, not released by the distance
    np.testing.assert_array_equal(rule.offset, [0.0, 0.0, HOP])


def test_a_formed_follower_never_changes_altitude_through_a_drone_under_it():
    rule = JetAwareRule(3)
    p = np.array([[0.0, 0.0, 2.0], [0.0, 1.0, 3.0], [0.3, 1.0, 2.5]])  # follower 2 0.3 m aside, 0.5 m under 1
    rule.reset(p)
    rule.phase[:] = FORMED
    soon = _h(p)
    formed = np.array([False, True, True])
    z_t = rule._through(p, np.array([2.0, 2.0, 2.0]), formed, soon)
    # follower 1 (above) is held hop above follower 2, follower 2 (below) hop under follower 1
    np.testing.assert_allclose(z_t, [2.0, 2.5 + HOP, 2.0])
    # beside it (outlines clear in plan view): free to descend
    p[2, 0] = OVERLAP_M + 0.05
    np.testing.assert_allclose(rule._through(p, np.array([2.0, 2.0, 2.0]), formed, _h(p)), [2.0, 2.0, 2.0])


def test_a_descending_formed_follower_holds_early_over_a_crossing_drone():
    # 7. of JetAwareRule: follower 1 has joined and descends to 2.0 m; follower 2 crosses 0.3 m
    # under it. Held hop above it from D̄ + crossing_hold out (the layered rule: from D̄)
    rule = JetAwareRule(3)
    p = np.array([[0.0, 0.0, 2.0], [0.0, 1.0, 3.0], [0.0, 2.0, 2.7]])
    rule.reset(p)
    rule.phase[:] = [FORMED, FORMED, CROSS]
    formed = np.array([False, True, False])
    target = np.array([2.0, 2.0, 3.2])
    for gap, held in ((0.79, True), (0.8 + HOLD - 0.01, True), (0.8 + HOLD + 0.01, False)):
        soon = np.full((3, 3), np.inf)
        soon[1, 2] = soon[2, 1] = gap  # follower 2 now or soon that far from follower 1
        z_t = rule._over_crossing(p[:, 2], soon, target, formed)
        assert z_t[1] == pytest.approx(2.7 + HOP if held else 2.0), gap
        assert z_t[2] == 3.2  # the crossing drone is not a formed one: its target is left alone
    # a drone that has joined (not crossing) or is above does not hold it
    rule.phase[2] = FORMED
    soon[1, 2] = soon[2, 1] = 0.5
    assert rule._over_crossing(p[:, 2], soon, target, formed)[1] == 2.0
    rule.phase[2] = CROSS
    p[2, 2] = 3.3
    assert rule._over_crossing(p[:, 2], soon, target, formed)[1] == 2.0


def test_never_through_predicts_only_for_drones_closing_fast():
    # follower 2 beside follower 1 (outlines 5 cm clear), 0.5 m under it; follower 1 wants to descend
    rule = JetAwareRule(3)
    p = np.array([[0.0, 0.0, 2.0], [0.0, 1.0, 3.0], [OVERLAP_M + 0.05, 1.0, 2.5]])
    rule.reset(p)
    h = _h(p)
    soon = h.copy()
    soon[1, 2] = soon[2, 1] = 0.3  # what a straight-line prediction over 1 s gives for them
    formed = np.array([False, True, True])
    target = np.array([2.0, 2.0, 2.0])
    for closing, held in ((0.1, False), (0.4, False), (0.8, True)):  # m/s; CLOSING_MIN_MPS = 0.5
        rule.vel[:] = 0.0
        rule.vel[2, 0] = -closing  # follower 2 moving towards follower 1
        z_t = rule._through(p, target, formed, rule._closing(p, h, soon))
        # jitter (a few cm/s in a formed swarm) predicts an overlap that does not come: not held
        assert bool(np.isclose(z_t[1], 2.5 + HOP)) is held, (closing, z_t)
    # unseen pairs (+inf in the prediction) stay unseen
    soon[1, 2] = soon[2, 1] = np.inf
    assert np.isinf(rule._closing(p, h, soon)[1, 2])


# --------------------------------------------------------------------------- the mixer


def _rotors(U: np.ndarray) -> np.ndarray:
    """F1..F4 from U1..U4 by solving eqs. (26)–(29) directly (independent of the product's UNMIX)."""
    return np.linalg.solve(MIX, U.T).T


def test_joined_followers_descend_gentler_than_the_others_during_the_transition():
    # 6. of JetAwareRule: a follower that has dropped over its slot descends at up to
    # formed_descent_accel (3 m/s²), one still climbing or crossing at the layered rule's 5 m/s²
    rule = JetAwareRule(3)
    rule.reset(np.array([[0.0, 0.0, 5.0], [3.0, 0.0, 5.0], [0.0, 3.0, 5.0]]))
    rule.phase[1] = FORMED  # joined; follower 2 still climbing (CLIMB)
    assert rule.z_down_formed[1] == 3.0 and rule.z_down[1] == 5.0
    target, target_vel = np.full(3, 1.0), np.zeros(3)  # 4 m below: both descend
    lowest = np.zeros(3)
    for _ in range(60):  # 0.6 s: the jerk-limited accelerations reach their limits
        rule._advance_altitude(0.01, target, target_vel)
        lowest = np.minimum(lowest, rule.za)
    assert lowest[1] == pytest.approx(-3.0) and lowest[2] == pytest.approx(-5.0)
    # each row as the layered rule's kernel moves it with its own limit, bit for bit
    alone = JetAwareRule(3, formed_descent_accel=5.0)  # no gentler descent: the layered rule's step
    alone.reset(np.array([[0.0, 0.0, 5.0], [3.0, 0.0, 5.0], [0.0, 3.0, 5.0]]))
    for _ in range(60):
        alone._advance_altitude(0.01, target, target_vel)
    assert np.array_equal(alone.zp[2], rule.zp[2]) and not np.array_equal(alone.zp[1], rule.zp[1])


def test_attitude_priority_leaves_a_feasible_command_alone():
    U = np.array([[4.9, 0.2, -0.1, 0.05]])
    np.testing.assert_array_equal(attitude_priority(U, 0.0, 4.5), U)


@pytest.mark.parametrize(
    "U",
    [
        [0.8, 1.2, -0.3, 0.1],  # low thrust, a large roll torque: F1 would be negative
        [17.0, -1.5, 0.4, 0.2],  # high thrust: F1 would pass f_max
    ],
)
def test_attitude_priority_keeps_the_torques_and_moves_the_thrust_just_enough(U):
    U = np.array([U])
    F = _rotors(U)
    assert F.min() < 0.0 or F.max() > 4.5  # the paper's per-rotor clip would change the torques
    out = attitude_priority(U, 0.0, 4.5)
    Fo = _rotors(out)
    np.testing.assert_allclose(out[0, 1:], U[0, 1:], atol=1e-12)  # U2..U4 kept
    assert Fo.min() >= -1e-12 and Fo.max() <= 4.5 + 1e-12
    # the collective moved by exactly the deficit (or the excess) of the worst rotor, times four
    shift = -F.min() if F.min() < 0.0 else 4.5 - F.max()
    np.testing.assert_allclose(out[0, 0], U[0, 0] + 4.0 * shift, atol=1e-12)


def test_a_drone_yielding_to_every_altitude_goes_above_them_all():
    rule = JetAwareRule(8)
    p = np.zeros((8, 3))
    p[:, 2] = 2.0
    p[:, 0] = np.arange(8) * 0.05  # all within D̄ of each other
    rule.reset(p)
    rule.set_slots(np.column_stack([np.arange(8) * 10.0, np.zeros(8), np.full(8, 2.0)]))
    rule.offset[:7] = [0.0, 0.4, -0.4, 0.8, -0.8, 1.2, 0.0]
    rule._react(0.0, p, _h(p), np.ones(8, dtype=bool))
    # followers 1..5 keep theirs; 6 (at the leader's 0) finds 0, ±0.4, ±0.8, 1.2 taken: above them
    # all, 1.6; then 7 finds 1.6 taken too: 2.0
    np.testing.assert_allclose(rule.offset, [0.0, 0.4, -0.4, 0.8, -0.8, 1.2, 1.6, 2.0])


def test_no_offset_takes_a_follower_near_the_floor():
    # formation altitude 1 m, follower 3 below the others: with 0 and ±0.4 taken it would go down to
    # −0.8, 0.2 m above the floor; it goes up to +0.8 instead
    rule = JetAwareRule(4)
    p = np.array([[0.0, 0.0, 1.0], [0.2, 0.0, 1.4], [0.0, 0.2, 0.6], [0.1, 0.1, 0.9]])  # 3 below the leader
    rule.reset(p)
    rule.update(0.0, p, np.column_stack([np.arange(4) * 10.0, np.zeros(4), np.ones(4)]), 1.0)
    rule.offset[:3] = [0.0, 0.4, -0.4]
    rule._react(0.0, p, _h(p), np.ones(4, dtype=bool))
    assert rule.offset[3] == pytest.approx(0.8)
