"""Unit tests of the formation layer (paper §4, Fig. 4b, Fig. 5, eq. 34; docs/interpretations.md §4).

Slots and the D schedule are checked against their closed forms; the anti-collision rules
are driven without physics: a "kinematic" swarm whose drones sit exactly where the rule
last told them to be (their setpoints), so that each test isolates the rule's decisions.
Random follower starts are checked for spacing, reproducibility and for refusing an
impossible request before anything is simulated (through the CLI, one line and exit 2:
tests/integration/test_formation_cli.py).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from swarm_mj.errors import UserError
from swarm_mj.formation.anticollision import (
    CLIMB,
    CROSS,
    FORMED,
    LayeredRule,
    NoRule,
    PaperRule,
    make_rule,
)
from swarm_mj.formation.barrier import BarrierParams
from swarm_mj.formation.rule_params import PRESETS
from swarm_mj.formation.slots import DiameterSchedule, polygon_offsets, slot_positions
from swarm_mj.scenario import (
    START_CLEARANCE_M,
    RandomStart,
    check_random_start_feasible,
    parse_scenario,
    random_follower_starts,
)

T = 0.01  # control period (s), docs/interpretations.md §2


# --------------------------------------------------------------------------- slots, D(t)


@pytest.mark.parametrize("n_f", [1, 2, 3, 5, 8, 12])
def test_polygon_slots_are_a_regular_polygon_of_circumradius_D(n_f):
    D = 1.7
    off = polygon_offsets(n_f, D)  # (n_f, 3)
    assert off.shape == (n_f, 3)
    np.testing.assert_allclose(np.hypot(off[:, 0], off[:, 1]), D, atol=1e-12)
    np.testing.assert_allclose(off[:, 2], 0.0)
    ang = np.arctan2(off[:, 1], off[:, 0])
    expected = np.pi / 2 + 2 * np.pi * np.arange(n_f) / n_f  # docs/interpretations.md §4: π/2 + 2π(k−1)/n_f
    np.testing.assert_allclose(np.cos(ang - expected), 1.0, atol=1e-12)
    if n_f > 1:  # adjacent slots 2·D·sin(π/n_f) apart
        gaps = np.linalg.norm(off - np.roll(off, -1, axis=0), axis=1)
        np.testing.assert_allclose(gaps, 2 * D * math.sin(math.pi / n_f), atol=1e-12)


def test_pentagon_adjacent_followers_clear_the_safety_distance():
    # docs/interpretations.md §4: with D the circumradius, adjacent followers are 1.18·D apart (> 0.8 m for D = 1)
    off = polygon_offsets(5, 1.0)
    assert np.linalg.norm(off[0] - off[1]) == pytest.approx(1.1756, abs=1e-4)


def test_slot_positions_follow_the_leader_at_its_altitude():
    leader = np.array([0.3, -1.2, 2.4])
    slots = slot_positions(leader, 1.5, polygon_offsets(5, 1.0))
    np.testing.assert_allclose(slots[:, 2], 2.4)
    np.testing.assert_allclose(np.linalg.norm(slots[:, :2] - leader[:2], axis=1), 1.5)
    np.testing.assert_allclose(slots[0], [0.3, 0.3, 2.4], atol=1e-12)  # follower 1 at π/2


def test_diameter_schedule_is_eq_34():
    D = DiameterSchedule([[0.0, 1.0], [6.0, 1.7], [11.0, 1.2], [16.0, 2.0]])
    t = np.array([0.0, 5.99, 6.0, 10.99, 11.0, 15.99, 16.0, 30.0])
    np.testing.assert_array_equal(D(t), [1.0, 1.0, 1.7, 1.7, 1.2, 1.2, 2.0, 2.0])
    np.testing.assert_array_equal(D.change_times, [0.0, 6.0, 11.0, 16.0])
    assert DiameterSchedule(1.3)(100.0) == 1.3


@pytest.mark.parametrize(
    "bad, needle",
    [
        (-1.0, "positive"),
        ([[0.0, 1.0], [5.0, 0.0]], "positive"),
        ([[1.0, 1.0]], "start at 0"),
        ([[0.0, 1.0], [5.0, 2.0], [5.0, 3.0]], "increase"),
        ([], "empty"),
        ("wide", "number"),
    ],
)
def test_diameter_schedule_refuses_bad_input(bad, needle):
    with pytest.raises(UserError, match=needle):
        DiameterSchedule(bad)


# --------------------------------------------------------------------------- the paper's rule


def _pair(dx: float, z1: float = 2.0, z2: float = 2.0) -> np.ndarray:
    """Leader far away, followers 1 and 2 ``dx`` apart horizontally."""
    return np.array([[10.0, 10.0, 2.0], [0.0, 0.0, z1], [dx, 0.0, z2]])


def test_paper_rule_higher_index_hops_up_and_keeps_xy():
    rule = PaperRule(3)
    pos = _pair(0.7)
    rule.reset(pos)
    pos_d, steer = rule.update(0.0, pos, pos.copy(), 2.0)
    assert not steer.any()  # the paper's rule steers nobody
    np.testing.assert_allclose(pos_d[:, :2], pos[:, :2])  # (x, y) unchanged (Fig. 5)
    np.testing.assert_allclose(pos_d[:, 2], [2.0, 2.0, 2.4])  # follower 2 yields, +0.4 m
    assert [(e["drone"], e["other"], e["action"]) for e in rule.events] == [(2, 1, "up")]


def test_paper_rule_hops_down_when_below_and_releases_with_hysteresis():
    rule = PaperRule(3)
    pos = _pair(0.7, z1=2.0, z2=1.9)
    rule.reset(pos)
    pos_d, _ = rule.update(0.0, pos, pos.copy(), 2.0)
    assert pos_d[2, 2] == pytest.approx(1.9 - 0.4)  # below the other: down
    # still inside D̄ + hysteresis: keeps the offset; beyond it: released
    for dx, expected in ((0.84, -0.4), (0.86, 0.0)):
        pos = _pair(dx, z1=2.0, z2=1.5)
        pos_d, _ = rule.update(0.1, pos, pos.copy(), 2.0)
        assert rule.offset[2] == pytest.approx(expected)
    assert rule.events[-1]["action"] == "release"


def test_paper_rule_leader_never_yields_and_nobody_reacts_beyond_D_bar():
    rule = PaperRule(2)
    pos = np.array([[0.0, 0.0, 2.0], [0.6, 0.0, 2.0]])
    rule.reset(pos)
    rule.update(0.0, pos, pos.copy(), 2.0)
    assert rule.offset[0] == 0.0 and rule.offset[1] == pytest.approx(0.4)
    rule = PaperRule(3)
    pos = _pair(0.81)
    rule.reset(pos)
    pos_d, _ = rule.update(0.0, pos, pos.copy(), 2.0)
    np.testing.assert_allclose(pos_d, pos)
    assert rule.events == []


def test_off_rule_passes_setpoints_through():
    rule = NoRule(3)
    pos = _pair(0.1)
    rule.reset(pos)
    pos_d, steer = rule.update(0.0, pos, pos + 1.0, 2.0)
    np.testing.assert_allclose(pos_d, pos + 1.0)
    assert not steer.any()


def test_make_rule_names_and_refusal():
    assert isinstance(make_rule("layers", 6), LayeredRule)
    assert isinstance(make_rule("paper", 6), PaperRule) and not isinstance(make_rule("paper", 6), LayeredRule)
    assert isinstance(make_rule("off", 6), NoRule)
    with pytest.raises(UserError, match="layers, paper, off, jet-aware"):
        make_rule("magic", 6)


# --------------------------------------------------------------------------- the layered rule, kinematic


def fly_kinematic(rule, starts: np.ndarray, leader_fn, D: float = 1.0, duration: float = 10.0):
    """Drones sit exactly at their setpoints (the leader on ``leader_fn(t)``); returns the
    positions (k, n, 3), the phases (k, n) and the rule."""
    n = len(starts)
    unit = polygon_offsets(n - 1, 1.0)
    pos = starts.astype(float).copy()
    rule.reset(pos)
    hist, phases = [], []
    for k in range(int(round(duration / T)) + 1):
        t = k * T
        pos[0] = leader_fn(t)
        pos_d = np.vstack([pos[:1], pos[0] + D * unit])
        pos_d, _ = rule.update(t, pos, pos_d, float(pos[0, 2]))
        pos[1:] = pos_d[1:]
        hist.append(pos.copy())
        phases.append(getattr(rule, "phase", np.zeros(n, int)).copy())
    return np.array(hist), np.array(phases), rule


def _hover(p):
    p = np.asarray(p, float)
    return lambda t: p


def _climb_to(p, rate=2.0):
    """Leader rising from the ground at ``rate`` m/s to p."""
    p = np.asarray(p, float)
    return lambda t: np.array([p[0], p[1], min(p[2], rate * t)])


def _min_pair_distance(hist: np.ndarray) -> float:
    i, j = np.triu_indices(hist.shape[1], 1)
    return float(np.linalg.norm(hist[:, i] - hist[:, j], axis=-1).min())


EQ31 = np.array(
    [[0.0, 0.0, 0.0], [1.5, 0.0, 0.0], [3.0, 0.0, 0.0], [-1.5, 0.0, 0.0], [-3.0, 0.0, 0.0], [0.0, -1.5, 0.0]]
)


def test_layered_rule_forms_the_pentagon_from_eq_31():
    hist, phases, rule = fly_kinematic(LayeredRule(6), EQ31, _climb_to([0.0, 0.0, 2.0]), duration=12.0)
    end = hist[-1]
    slots = end[0] + polygon_offsets(5, 1.0)
    np.testing.assert_allclose(end[1:], slots, atol=0.02)  # at its slot, at the leader's altitude
    assert (phases[-1] == FORMED).all()
    kinds = {(e["drone"], e["action"]) for e in rule.events}
    for k in range(1, 6):
        assert (k, "cross") in kinds and ((k, "drop") in kinds or (k, "rise") in kinds)


def test_layered_rule_crosses_on_separate_layers():
    hist, phases, rule = fly_kinematic(LayeredRule(6), EQ31, _hover([0.0, 0.0, 2.0]), duration=12.0)
    crossing = (phases == CROSS) & ~np.zeros_like(phases, bool)
    for k in range(1, 6):
        zk = hist[:, k, 2][crossing[:, k]]
        assert len(zk)
        layer = 2.0 + 0.4 * k  # formation altitude + k·hop
        assert zk.min() >= layer - rule.climb_tol - 1e-9, k  # crossing starts near its layer
        assert zk.max() <= layer + 1e-6, k  # and never rises past it
    # drones whose columns pass within two rotor spans of each other are a layer apart
    i, j = np.triu_indices(6, 1)
    h = np.linalg.norm(hist[:, i, :2] - hist[:, j, :2], axis=-1)
    dz = np.abs(hist[:, i, 2] - hist[:, j, 2])
    close = h < 0.7
    assert close.any()  # the starts do make them cross
    assert dz[close].min() > 0.3


@pytest.mark.parametrize("n_f", [1, 3, 8])
def test_layered_rule_any_number_of_followers(n_f):
    rng = np.random.default_rng(n_f)
    starts = np.vstack(
        [[0.0, 0.0, 0.0], random_follower_starts(np.zeros(3), n_f, RandomStart(radius=3.0, seed=int(rng.integers(99))))]
    )
    hist, phases, _ = fly_kinematic(LayeredRule(n_f + 1), starts, _climb_to([0.0, 0.0, 2.0]), duration=15.0)
    end = hist[-1]
    slots = end[0] + polygon_offsets(n_f, 1.0)
    np.testing.assert_allclose(end[1:, :2], slots[:, :2], atol=0.02)
    if 2 * math.sin(math.pi / n_f) > 0.8:  # neighbours beyond D̄: all level
        np.testing.assert_allclose(end[1:, 2], 2.0, atol=0.02)
    else:  # within D̄ (8 followers, D = 1 m): the
        assert (np.abs(end[1:, 2] - 2.0) <= 0.4 + 0.02).all()  # paper's rule keeps them a hop apart
    assert (phases[-1] == FORMED).all()
    assert _min_pair_distance(hist[hist[:, :, 2].min(axis=1) > 0.1]) > 0.35


def test_layered_rule_steers_followers_only_and_hands_consistent_references():
    rule = LayeredRule(6)
    pos = EQ31.copy()
    rule.reset(pos)
    unit = polygon_offsets(5, 1.0)
    prev = None
    for k in range(300):
        t = k * T
        pos_d = np.vstack([pos[:1], pos[0] + unit])
        pos_d, steer = rule.update(t, pos, pos_d, 0.0)
        assert not steer[0] and steer[1:].all()
        np.testing.assert_array_equal(pos_d[0], pos[0])  # the leader flies its own reference
        if prev is not None:  # the velocity handed over is the path's
            np.testing.assert_allclose((pos_d[1:] - prev[1:]) / T, rule.vel_d[1:], atol=1e-9)
        prev = pos_d.copy()
        pos[1:] = pos_d[1:]


@pytest.mark.parametrize("make", [lambda: LayeredRule(6), lambda: PaperRule(6), lambda: NoRule(6)])
def test_references_are_update_with_the_steered_rows_taken_from_the_rule(make):
    """rule.references (what the policy calls; compiled for the formed swarm) == update() plus the
    merge by hand, in transit and once formed (12 s of the eq.-31 start)."""
    a, b = make(), make()
    pos = EQ31.copy()
    pos[:, 2] = 0.0
    a.reset(pos)
    b.reset(pos)
    unit = polygon_offsets(5, 1.0)
    rng = np.random.default_rng(0)
    vel_in, acc_in = rng.normal(size=(6, 3)), rng.normal(size=(6, 3))
    formed_seen = False
    for k in range(1200):
        t = k * T
        pos[0] = [0.0, 0.0, min(2.0, 2.0 * t)]
        pos_d = np.vstack([pos[:1], pos[0] + unit])
        want_pos, steer = a.update(t, pos, pos_d, float(pos[0, 2]))
        want_vel, want_acc = vel_in.copy(), acc_in.copy()
        want_vel[steer] = a.vel_d[steer]
        want_acc[steer] = a.acc_d[steer]
        got_pos, got_vel, got_acc = b.references(t, pos, pos_d, vel_in, acc_in, float(pos[0, 2]))
        np.testing.assert_array_equal(got_pos, want_pos)
        np.testing.assert_array_equal(got_vel, want_vel)
        np.testing.assert_array_equal(got_acc, want_acc)
        formed_seen |= bool(getattr(b, "_all_formed", False))
        pos[1:] = want_pos[1:]
    assert formed_seen or not isinstance(b, LayeredRule)  # both paths of the layered rule ran


def test_altitude_path_respects_its_limits_and_does_not_overshoot():
    rule = LayeredRule(2)
    rule.reset(np.zeros((2, 3)))
    for z0, z1 in ((4.0, 2.0), (0.0, 3.6)):
        rule.reset(np.array([[0.0, 0.0, 0.0], [0.0, 0.0, z0]]))
        zs, vs, acc = [], [], []
        for _ in range(600):
            rule._advance_altitude(T, np.array([0.0, z1]), np.zeros(2))
            zs.append(rule.zp[1]), vs.append(rule.zv[1]), acc.append(rule.za[1])
        zs, vs, acc = map(np.array, (zs, vs, acc))
        assert abs(zs[-1] - z1) < 1e-3
        assert (zs <= max(z0, z1) + 1e-9).all() and (zs >= min(z0, z1) - 1e-9).all()  # no overshoot
        assert vs.min() >= -rule.z_down[0] - 1e-9 and vs.max() <= rule.z_up[0] + 1e-9
        assert acc.min() >= -rule.z_down[1] - 1e-9 and acc.max() <= rule.z_up[1] + 1e-9


def test_climb_is_slow_enough_to_stop_under_a_drone_first_seen_at_the_sensing_range():
    for sensing in (1.5, 2.0, 4.0):
        rule = LayeredRule(2, sensing_range=sensing)
        v, a = rule.z_up[0], rule.z_down[1]
        lag = (rule.z_up[1] + a) / rule.jerk + 1.0 / rule.k_v
        assert v * v / (1.6 * a) + v * lag <= sensing - rule.hop - 0.2 + 1e-9


def _cross_past_a_hovering_follower(**overrides: object) -> tuple[LayeredRule, float, float, bool]:
    """Follower 2 crosses towards its slot; follower 1 hovers in its way at the same altitude.
    Returns the rule, the closest x-distance of the two, follower 2's final x, and whether its
    path was ever blocked."""
    rule = LayeredRule(3, **overrides)
    pos = np.array([[10.0, 0.0, 2.0], [0.0, 0.0, 2.8], [-3.0, 0.0, 2.8]])
    rule.reset(pos)
    rule.phase[1:] = CROSS
    rule.start_xy[:] = pos[:, :2]
    far = np.array([[10.0, 0.0, 2.0], [0.0, 0.0, 2.8], [3.0, 0.0, 2.8]])  # slot of 2 beyond follower 1
    closest, blocked = np.inf, False
    for k in range(600):
        pos_d, _ = rule.update(k * T, pos, far.copy(), 2.0)
        pos[2] = pos_d[2]  # follower 2 flies; 1 stays put
        pos[2, 2] = 2.8  # (and both keep one altitude)
        rule.zp[2] = 2.8
        closest = min(closest, abs(pos[2, 0] - pos[1, 0]))
        blocked |= bool(rule.blocked.any())
    return rule, closest, float(pos[2, 0]), blocked


def test_crossing_follower_brakes_for_a_lower_index_drone_on_its_altitude():
    rule, closest, _, _ = _cross_past_a_hovering_follower()
    assert any(e["action"] == "hold" and e["drone"] == 2 and e["other"] == 1 for e in rule.events)
    assert closest > 0.6  # it stopped outside the rotors' reach
    assert np.linalg.norm(rule.path_v[2]) < 0.05  # and holds there


def test_drop_waits_while_a_drone_in_transit_is_under_the_slot():
    rule = LayeredRule(3)
    leader = np.array([0.0, 0.0, 2.0])
    slot1 = leader + polygon_offsets(2, 1.0)[0]
    pos = np.array([leader, slot1 + [0.0, 0.0, 0.4], slot1 + [0.3, 0.0, -1.5]])  # 2 climbs under 1
    rule.reset(pos)
    rule.phase[1], rule.phase[2] = CROSS, CLIMB
    rule.path_p[1] = slot1[:2]
    pos_d = np.vstack([leader, leader + polygon_offsets(2, 1.0)])
    for k in range(50):
        rule.update(k * T, pos, pos_d.copy(), 2.0)
    assert rule.phase[1] == CROSS  # does not drop onto follower 2
    pos[2, :2] += [5.0, 5.0]  # follower 2 gone
    for k in range(50, 100):
        rule.update(k * T, pos, pos_d.copy(), 2.0)
    assert rule.phase[1] == FORMED


def _descend_over_a_climbing_follower(rule: LayeredRule) -> tuple[float, float]:
    """Follower 1 has joined over its slot at 3.5 m and descends to the formation's 2 m; follower 2
    climbs 0.3 m beside its column, at 1.8 m (within ``clearance`` under 1's target), and stays
    there. Returns the least and the last height of 1 over 2 (follower 1 flies its references)."""
    leader = np.array([0.0, 0.0, 2.0])
    slot1 = leader + polygon_offsets(2, 1.0)[0]
    pos = np.array([leader, slot1 + [0.0, 0.0, 1.5], slot1 + [0.3, 0.0, -0.2]])
    rule.reset(pos)
    rule.phase[1], rule.phase[2] = FORMED, CLIMB
    rule.path_p[1] = slot1[:2]
    pos_d = np.vstack([leader, leader + polygon_offsets(2, 1.0)])
    gaps = []
    for k in range(400):
        out, _ = rule.update(k * T, pos, pos_d.copy(), 2.0)
        pos[1] = out[1]  # follower 1 flies; 2 stays where it is
        gaps.append(pos[1, 2] - pos[2, 2])
    return min(gaps), gaps[-1]


def test_a_descending_follower_holds_the_rules_height_over_a_drone_in_transit_under_it():
    """docs/barrier.md, "the planner's hold": ``hop`` (0.4 m) over a drone in transit under it for the
    layered rule; under ``barrier`` ``transit_hold`` × the filter's keep-out height (1.05 × 2.08 m),
    so that the drone under it is outside the tall keep-out and not pushed down into the ground."""
    lowest, last = _descend_over_a_climbing_follower(LayeredRule(3))
    assert lowest >= 0.4 - 1e-6 and last == pytest.approx(0.4, abs=0.01)
    rule = make_rule("barrier", 3, barrier={"assign_slots": False})
    hold = 1.05 * float(BarrierParams().radii()[2])
    assert rule.transit_hold_m == pytest.approx(hold)
    lowest, last = _descend_over_a_climbing_follower(rule)
    assert lowest >= 1.7 - 1e-6 and last == pytest.approx(hold, abs=0.01)  # never nearer than at its start


def test_climbing_follower_waits_under_a_hovering_leader_overhead():
    rule = LayeredRule(2)
    pos = np.array([[0.0, 0.0, 2.0], [0.3, 0.0, 0.0]])  # leader hovers 0.3 m off its column
    hist, phases, _ = fly_kinematic(rule, pos, _hover([0.0, 0.0, 2.0]), duration=6.0)
    under = np.linalg.norm(hist[:, 1, :2] - hist[:, 0, :2], axis=1) < 0.7
    assert under.any()
    assert (hist[under, 1, 2] <= 2.0 - 0.4 + 1e-6).all()  # hop below the leader while under it
    np.testing.assert_allclose(hist[-1, 1], [0.0, 1.0, 2.0], atol=0.02)  # and reaches its slot after


# --------------------------------------------------------------------------- random starts


def test_random_starts_are_seeded_spaced_and_within_the_radius():
    leader = np.array([0.5, -0.5, 0.0])
    rs = RandomStart(radius=3.0, min_spacing=0.6, seed=7)
    a = random_follower_starts(leader, 5, rs)
    np.testing.assert_array_equal(a, random_follower_starts(leader, 5, rs))  # same seed, same starts
    assert not np.allclose(a, random_follower_starts(leader, 5, RandomStart(3.0, 0.6, seed=8)))
    assert a.shape == (5, 3) and (a[:, 2] == 0.0).all()
    assert (np.linalg.norm(a[:, :2] - leader[:2], axis=1) <= 3.0 + 1e-12).all()
    pts = np.vstack([leader[:2], a[:, :2]])
    i, j = np.triu_indices(6, 1)
    # never closer than the rotors' span, whatever min_spacing asks (0.6 m lets rotors overlap)
    assert np.linalg.norm(pts[i] - pts[j], axis=1).min() >= max(0.6, START_CLEARANCE_M)
    wide = random_follower_starts(leader, 5, RandomStart(radius=4.0, min_spacing=1.5, seed=3))
    pts = np.vstack([leader[:2], wide[:, :2]])
    assert np.linalg.norm(pts[i] - pts[j], axis=1).min() >= 1.5


def test_start_clearance_covers_the_rotor_span():
    # docs/interpretations.md §1 geometry: rotor centres L = 0.25 m out, rotor radius 0.09 m
    assert START_CLEARANCE_M > 2 * (0.25 + 0.09)


@pytest.mark.parametrize(
    "n, radius, spacing", [(5, 1.0, 1.5), (30, 1.0, 0.8), (8, 1.0, 1.2), (3, 0.0, 0.6), (3, 2.0, -1.0)]
)
def test_impossible_random_start_is_refused(n, radius, spacing):
    with pytest.raises(UserError, match="followers.random_start"):
        check_random_start_feasible(n, RandomStart(radius=radius, min_spacing=spacing), "x.toml")


def test_tight_request_is_refused_after_max_tries_not_looping():
    rs = RandomStart(radius=1.5, min_spacing=0.75, seed=0, max_tries=200)
    check_random_start_feasible(12, rs)  # passes the packing bound...
    with pytest.raises(UserError, match="after 200 tries"):  # ...but cannot be drawn
        random_follower_starts(np.zeros(3), 12, rs)


def _random_scenario(count: int, radius: float, spacing: float) -> dict:
    return {
        "duration": 5.0,
        "leader": {"trajectory": "circle"},
        "followers": {"count": count, "random_start": {"radius": radius, "min_spacing": spacing, "seed": 1}},
    }


def test_random_start_request_is_refused_when_the_scenario_is_read():
    sc = parse_scenario(_random_scenario(5, 3.0, 0.6), "ok.toml")
    assert sc.follower_starts is None and sc.random_start == RandomStart(3.0, 0.6, 1)
    assert sc.initial_positions().shape == (6, 3)
    with pytest.raises(UserError) as ei:
        parse_scenario(_random_scenario(6, 1.0, 2.0), "bad.toml")
    msg = str(ei.value)
    assert "\n" not in msg and "bad.toml" in msg and "followers.random_start" in msg and "room" in msg


def test_crossing_brake_off_leaves_the_separation_to_a_filter():
    # with crossing_brake off (barrier's preset, docs/barrier.md "the planner's crossing brake") the
    # same crossing is never blocked and flies on through follower 1's place
    rule, _, x_final, blocked = _cross_past_a_hovering_follower(crossing_brake=False)
    assert not blocked and not any(e["action"] == "hold" for e in rule.events)
    assert x_final > 2.5  # nothing but a separation filter would stop it
    assert PRESETS["barrier"].crossing_brake is False and PRESETS["jet-aware"].crossing_brake is True
