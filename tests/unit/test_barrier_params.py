"""The barrier filter's parameter record (swarm_mj/formation/barrier.py, ``BarrierParams``;
docs/barrier.md, "parameters"): every field with a unit, a reason and a range, validated from that
metadata, settable from a scenario's ``[formation.barrier]`` table and reaching the filter the run
flies; a bad value is one line naming the file and the key, before anything flies."""

from __future__ import annotations

from dataclasses import fields, replace
from pathlib import Path

import pytest

from swarm_mj.control.policy import BacksteppingPolicy
from swarm_mj.errors import UserError
from swarm_mj.formation.anticollision import make_rule
from swarm_mj.formation.barrier import BarrierParams, BarrierPlannerRule, keepout_radii
from swarm_mj.formation.rule_params import check_overrides
from swarm_mj.scenario import parse_scenario

ROOT = Path(__file__).resolve().parents[2]


def _scenario(rule: str = "barrier", planner_sensing: float | None = None, **barrier) -> dict:
    form: dict = {"anti_collision": rule}
    if planner_sensing is not None:
        form["sensing_range"] = planner_sensing
    if barrier:
        form["barrier"] = barrier
    return {
        "duration": 1.0,
        "leader": {"trajectory": "hover", "params": {"position": [0.0, 0.0, 2.0]}},
        "followers": {"start": [[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]]},
        "formation": form,
    }


def _other_value(f) -> object:
    """A valid value of field f that is not its default."""
    if f.type in ("bool", bool):
        return not f.default
    hi = f.metadata["hi"]
    v = f.default * 1.25 if f.default else 0.05
    return min(v, hi) if hi is not None and v > hi else v


def test_every_field_has_a_unit_a_reason_a_range_and_a_valid_default():
    for f in fields(BarrierParams):
        m = f.metadata
        assert {"unit", "why", "lo", "hi", "open_lo"} <= set(m), f.name
        assert m["why"] and len(m["why"]) <= 100, f.name  # one line; the long reasons are in docs/
        assert check_overrides({f.name: f.default}, record=BarrierParams) == {f.name: f.default}, f.name


def test_every_field_is_explained_in_the_docs():
    doc = (ROOT / "docs" / "barrier.md").read_text()
    assert not [f.name for f in fields(BarrierParams) if f"`{f.name}`" not in doc]


def test_every_field_is_settable_from_a_scenario_and_reaches_the_filter():
    for f in fields(BarrierParams):
        v = _other_value(f)
        sc = parse_scenario(_scenario("barrier", **{f.name: v}))
        assert sc.barrier_params == {f.name: v}
        r = BacksteppingPolicy(sc).rule
        assert isinstance(r, BarrierPlannerRule)
        bp = r.barrier_filter.barrier
        assert getattr(bp, f.name) == v, f.name
        # the other fields keep their defaults (the sensing range: the scenario's, 4 m)
        assert bp == replace(BarrierParams(), **{f.name: v}), f.name


def test_the_filter_record_has_the_guarded_nominal_and_the_vehicles_keep_out():
    """``barrier``'s filter record: its guarded nominal is ``guard_lanes``, ``guard_kp``, ``guard_kd``
    as set, and the keep-out is the run's vehicle's (not the paper drone's)."""
    from swarm_mj.vehicles import load_vehicle

    vehicle = load_vehicle("crazyflie21").params()
    r = make_rule("barrier", 3, vehicle=vehicle, barrier={"guard_lanes": True, "guard_kp": 9.0})
    rec = r.separation_filter.record()
    assert rec.lanes and rec.lane_gains[0] == 9.0 and rec.lane_gains[1] == BarrierParams().guard_kd
    expected = keepout_radii(vehicle, margin=BarrierParams().tracking_margin_m)
    assert rec.radii.tolist() == pytest.approx(expected.tolist())
    assert expected[0] < keepout_radii(margin=BarrierParams().tracking_margin_m)[0]  # not the paper drone's


def test_the_filter_senses_as_far_as_the_scenario_unless_its_table_says():
    r = BacksteppingPolicy(parse_scenario(_scenario(planner_sensing=2.5))).rule
    assert r.barrier_filter.barrier.sensing_range == 2.5 and r.params.sensing_range == 2.5
    own = _scenario(planner_sensing=2.5)
    own["formation"]["barrier"] = {"sensing_range": 3.0}
    r = BacksteppingPolicy(parse_scenario(own)).rule
    assert r.barrier_filter.barrier.sensing_range == 3.0 and r.params.sensing_range == 2.5


@pytest.mark.parametrize(
    ("key", "value", "needle"),
    [
        ("gain", -1.0, "positive"),
        ("gain", "3", "a number"),
        ("priority_share", 1.5, "<= 1"),
        ("max_tilt_deg", 95.0, "<= 89 deg"),
        ("accel_down", 9.9, "<= 9.8"),
        ("tracking_margin_m", -0.01, ">= 0 m"),
        ("guard_lanes", 1, "true or false"),
        ("leash_m", float("nan"), "finite"),
        ("lane_outer", 1.0, "must exceed lane_inner"),
        ("gian", 3.0, "unknown key 'gian'; did you mean 'gain'\\?$"),
        ("qqqq", 3.0, "unknown key 'qqqq'; the \\d+ allowed keys are listed in docs/barrier.md$"),
    ],
)
def test_bad_values_are_one_line_naming_the_key(key, value, needle):
    with pytest.raises(UserError, match=needle) as e:
        parse_scenario(_scenario(**{key: value}), path="x.toml")
    msg = str(e.value)
    assert "\n" not in msg and msg.startswith("x.toml: formation.barrier")
    assert key in ("gian", "qqqq") or f"formation.barrier.{key}:" in msg


def test_the_table_must_be_a_table_and_does_not_apply_to_a_rule_without_a_filter():
    """Issue 47 item 8: a scenario with the table flies ``--anti-collision jet-aware`` (and a sweep over
    the rules): the rule without a barrier filter has no use for the table and flies its own record."""
    with pytest.raises(UserError, match="x.toml: formation.barrier: must be a table"):
        parse_scenario({**_scenario(), "formation": {"anti_collision": "barrier", "barrier": 3}}, path="x.toml")
    sc = parse_scenario(_scenario("jet-aware", gain=2.0))
    assert sc.barrier_params == {"gain": 2.0}
    plain = BacksteppingPolicy(parse_scenario(_scenario("jet-aware"))).rule
    rule = BacksteppingPolicy(sc).rule
    assert type(rule) is type(plain) and not isinstance(rule, BarrierPlannerRule)
    assert rule.params == plain.params
    barrier_sc = parse_scenario(_scenario("barrier", gain=2.0))
    flown = BacksteppingPolicy(barrier_sc, anti_collision="jet-aware").rule  # what --anti-collision jet-aware flies
    assert type(flown) is type(plain) and flown.params == plain.params
    built = make_rule("barrier", 3, barrier={"gain": 2.0})
    assert isinstance(built, BarrierPlannerRule) and built.barrier_filter.barrier.gain == 2.0


def test_a_record_built_in_code_is_checked_the_same_way():
    with pytest.raises(UserError, match="formation.barrier.relax_weight: must be positive"):
        BarrierParams(relax_weight=0.0)


def test_the_barrier_planner_is_jet_awares_with_slower_descents_and_a_scenario_still_sets_them():
    """docs/barrier.md, "the planner's descent" and "the planner's crossing brake": the `barrier`
    preset is `jet-aware`'s record but for `descent_speed` (0.75 m/s against 1.5), `crossing_brake` (off)
    and the leader's start (docs/barrier.md, "the leader's start"), and a scenario's ``[formation]`` keys
    override them."""
    jet = BacksteppingPolicy(parse_scenario(_scenario("jet-aware"))).rule.params
    bar = BacksteppingPolicy(parse_scenario(_scenario())).rule.params
    assert bar.descent_speed == 0.75 and jet.descent_speed == 1.5
    assert not bar.crossing_brake and jet.crossing_brake
    assert bar.leader_join_s == 4.0 and bar.leader_climb_s == 2.5 and jet.leader_join_s == jet.leader_climb_s == 0.0
    assert (
        replace(bar, descent_speed=jet.descent_speed, crossing_brake=True, leader_join_s=0.0, leader_climb_s=0.0) == jet
    )
    own = _scenario()
    own["formation"]["descent_speed"] = 1.5
    own["formation"]["crossing_brake"] = True
    own["formation"]["leader_join_s"] = own["formation"]["leader_climb_s"] = 0.0
    assert BacksteppingPolicy(parse_scenario(own)).rule.params == jet
