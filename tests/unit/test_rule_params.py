"""Each anti-collision rule's parameter record (swarm_mj/formation/rule_params.py, docs/anticollision.md):
every field documented, validated from its metadata, settable from a scenario with today's keys and
read by its rule (each record holds exactly the fields its rule reads); the named rules' presets are
their own record types; the keep-out geometry comes from the vehicle; and the reference-level
separation filter interface (swarm_mj/formation/separation.py)."""

from __future__ import annotations

import ast
import inspect
import re
import sys
import textwrap
from dataclasses import fields, replace
from pathlib import Path

import numpy as np
import pytest

from swarm_mj.control.policy import BacksteppingPolicy
from swarm_mj.errors import UserError
from swarm_mj.formation.anticollision import (
    ANTI_COLLISION_RULES,
    FORMED,
    JetAwareRule,
    LayeredRule,
    make_rule,
    rule_record,
)
from swarm_mj.formation.layered import PathLimits
from swarm_mj.formation.rule_params import (
    CONTROLLER_KEYS,
    CONTROLLER_PRESETS,
    PARAM_KEYS,
    PARAM_TABLE,
    PRESETS,
    RULE_RECORDS,
    BaseParams,
    ControllerParams,
    JetAwareParams,
    LayersParams,
    PaperParams,
    check_overrides,
    record_keys,
    vehicle_outline,
)
from swarm_mj.formation.stagger import StaggerParams
from swarm_mj.physics.aero.constants import ROTOR_RADIUS
from swarm_mj.physics.aero.presets import preset
from swarm_mj.physics.params import QuadParams
from swarm_mj.scenario import parse_scenario

ROOT = Path(__file__).resolve().parents[2]
#: the keys the rules' records hold (the controller's aside)
RULE_KEYS = set(PARAM_KEYS) - set(CONTROLLER_KEYS)


def _scenario(**keys) -> dict:
    """A scenario with each key in its table ([formation], or [controller] for what is asked of it)."""
    tables: dict[str, dict] = {"formation": {}, "controller": {}}
    for k, v in keys.items():
        tables[PARAM_TABLE.get(k, "formation")][k] = v
    return {
        "duration": 1.0,
        "leader": {"trajectory": "hover", "params": {"position": [0.0, 0.0, 2.0]}},
        "followers": {"start": [[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]]},
        **tables,
    }


def _other_value(f) -> object:
    """A valid value of field f that is not its default."""
    if f.type in ("bool", bool):
        return not f.default
    if f.type in ("int", int):
        return f.default + 1
    hi = f.metadata["hi"]
    v = f.default * 1.25 if f.default else 0.05
    return min(v, hi) if hi is not None and v > hi else v


def test_every_field_of_every_record_has_a_unit_a_reason_a_range_and_a_valid_default():
    for record in (*RULE_RECORDS, ControllerParams):
        for f in fields(record):
            m = f.metadata
            assert {"unit", "why", "lo", "hi", "open_lo", "table", "size"} <= set(m), (record, f.name)
            assert m["why"] and len(m["why"]) <= 100, f.name  # one line; the long reasons are in docs/
            assert check_overrides({f.name: f.default}, record=record) == {f.name: f.default}, f.name
            assert m["table"] == ("controller" if record is ControllerParams else "formation"), f.name
    # the records extend one another as the rules do, and the scenario's keys are their union
    assert all(issubclass(s, r) for r, s in zip(RULE_RECORDS, RULE_RECORDS[1:]))
    assert set(PARAM_KEYS) == {f.name for f in fields(JetAwareParams)} | {f.name for f in fields(ControllerParams)}


def test_every_field_is_explained_in_the_docs():
    doc = (ROOT / "docs" / "anticollision.md").read_text()
    missing = [k for k in PARAM_KEYS if f"`{k}`" not in doc]
    assert not missing, missing
    # and the docs say which record each rule has
    for record in (*RULE_RECORDS, ControllerParams, StaggerParams):
        assert re.search(rf"`{record.__name__}[`(]", doc), record.__name__


def _is_record(node: ast.expr) -> bool:
    """``node`` is a rule's parameter record as the rules name it: ``p``, ``params``, ``<x>.params``."""
    return (isinstance(node, ast.Name) and node.id in ("p", "params")) or (
        isinstance(node, ast.Attribute) and node.attr == "params"
    )


def _method_reads(name: str) -> set[str]:
    """The fields a record's method ``name`` (e.g. ``keep_out``) reads, ``self.<field>`` (and its methods')."""
    tree = ast.parse(textwrap.dedent(inspect.getsource(getattr(JetAwareParams, name))))
    out: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id == "self":
            if node.attr in RULE_KEYS:
                out.add(node.attr)
            elif callable(getattr(JetAwareParams, node.attr, None)):
                out |= _method_reads(node.attr)
    return out


def _reads(cls: type) -> set[str]:
    """The record fields rule class ``cls`` reads, by an AST scan of the source of it and of each class it
    inherits from in swarm_mj.formation, with the module-level functions of their modules: attribute reads
    on the record (``p.<field>``, ``self.params.<field>``, ``rec.params.<field>``), the fields of the record's
    methods called there (``p.keep_out(...)``), and where it calls ``path_limits(record, ...)`` the fields of
    ``layered.PathLimits`` named as the record's (the path kernels read those, ``lim.<field>``)."""
    trees = []
    for c in cls.__mro__:
        if not c.__module__.startswith("swarm_mj.formation"):
            continue
        trees.append(ast.parse(textwrap.dedent(inspect.getsource(c))))
        module = ast.parse(inspect.getsource(sys.modules[c.__module__]))
        trees += [node for node in module.body if isinstance(node, ast.FunctionDef)]
    out: set[str] = set()
    for tree in trees:
        for node in ast.walk(tree):
            if isinstance(node, ast.Attribute) and _is_record(node.value):
                out |= {node.attr} & RULE_KEYS
                if node.attr in ("keep_out", "overlap"):
                    out |= _method_reads(node.attr)
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "path_limits":
                out |= set(PathLimits._fields) & RULE_KEYS
    return out


@pytest.mark.parametrize("name", list(ANTI_COLLISION_RULES))
def test_each_rules_record_holds_exactly_the_fields_the_rule_reads(name):
    # a field a scenario may set but the rule does not read would be accepted and dropped; a field it reads
    # but a lower record holds would be the other rules' without their reading it (each in the lowest record)
    cls = ANTI_COLLISION_RULES[name]
    assert set(record_keys(rule_record(name))) == _reads(cls), name


def test_the_scan_of_the_rules_sees_what_they_read():
    # the scan above is not empty-handed: Fig. 5's three for paper, the jet-aware five only for jet-aware
    assert _reads(ANTI_COLLISION_RULES["paper"]) == {"safety_distance", "hop", "hysteresis"}
    only_jet = _reads(ANTI_COLLISION_RULES["jet-aware"]) - _reads(ANTI_COLLISION_RULES["layers"])
    assert only_jet == {"floor_clearance", "closing_min", "crossing_hold", "max_hops_up", "max_hops_down"}
    assert {"outline_margin", "overlap_spare", "thrust_floor"} <= _reads(ANTI_COLLISION_RULES["layers"])
    assert _reads(ANTI_COLLISION_RULES["off"]) == set()
    # what a rule asks of the controller: its own record, read by the rules' base
    src = inspect.getsource(sys.modules["swarm_mj.formation.rules"])
    assert all(f"controller_params.{k}" in src for k in CONTROLLER_KEYS)


@pytest.mark.parametrize("name", ["paper", "layers", "jet-aware", "barrier", "stagger"])
def test_every_field_is_settable_from_a_scenario_and_reaches_the_rule(name):
    base = rule_record(name)
    for key in record_keys(base):
        f = next(f for f in fields(JetAwareParams) if f.name == key)  # the same field in every record
        v = _other_value(f)
        sc = parse_scenario(_scenario(anti_collision=name, **{key: v}))
        assert getattr(sc.rule_params, key) == v, key
        rule = BacksteppingPolicy(sc).rule
        assert type(rule.params) is type(base) and getattr(rule.params, key) == v, key
        # the other fields keep the preset's values
        assert rule.params == (replace(base, **{key: v}) if isinstance(base, BaseParams) else base._replace(**{key: v}))


def test_a_key_only_another_rule_reads_is_accepted_and_left_out():
    # jet-aware's crossing_hold and the planner's max_speed in a scenario flying the paper's rule: accepted
    # (as before the records were split), its record Fig. 5's three fields as preset
    sc = parse_scenario(_scenario(anti_collision="paper", crossing_hold=0.3, max_speed=2.0, hop=0.3))
    assert sc.anti_collision_params == {"crossing_hold": 0.3, "max_speed": 2.0, "hop": 0.3}
    assert sc.rule_params == PaperParams(hop=0.3)
    rule = BacksteppingPolicy(sc).rule
    assert rule.params == PaperParams(hop=0.3) and rule.hop == 0.3
    # the same keys under --anti-collision jet-aware reach that rule
    jet = BacksteppingPolicy(sc, anti_collision="jet-aware").rule
    assert (jet.params.crossing_hold, jet.params.max_speed, jet.params.hop) == (0.3, 2.0, 0.3)
    # a key no rule has is still refused, and a rule built directly takes only its own record's keys
    with pytest.raises(UserError, match="unknown key 'crossing_hold'"):
        ANTI_COLLISION_RULES["paper"](3, crossing_hold=0.3)


def test_unknown_key_is_one_short_line_naming_it_with_a_did_you_mean():
    """Issue 47 item 9: not the 45 keys on one line, but the close one, or where the docs list them."""
    with pytest.raises(UserError) as e:
        parse_scenario(_scenario(crosing_hold=0.3), path="x.toml")
    msg = str(e.value)
    assert msg == "x.toml: formation: unknown key 'crosing_hold'; did you mean 'crossing_hold'?"
    with pytest.raises(UserError) as e:
        make_rule("layers", 3, qqq_limit=1.0)
    n = len(PARAM_KEYS)
    assert (
        str(e.value) == f"formation: unknown key 'qqq_limit'; the {n} allowed keys are listed in docs/anticollision.md"
    )
    doc = (Path(__file__).resolve().parents[2] / "docs" / "anticollision.md").read_text()
    assert all(f"`{k}`" in doc for k in PARAM_KEYS)  # where the message points, every key is


@pytest.mark.parametrize(
    ("key", "value", "needle"),
    [
        ("hop", -0.4, "positive"),
        ("hop", True, "a number"),
        ("hop", "0.4", "a number"),
        ("max_tilt_deg", 95.0, "<= 89 deg"),
        ("max_hops_up", 2.5, "an integer"),
        ("max_hops_up", 0, ">= 1"),
        ("downwash_feedforward", 1, "true or false"),
        ("horizon", float("inf"), "finite"),
    ],
)
def test_bad_values_are_refused_naming_the_field(key, value, needle):
    with pytest.raises(UserError, match=needle) as e:
        parse_scenario(_scenario(**{key: value}), path="x.toml")
    assert f"x.toml: {PARAM_TABLE[key]}.{key}:" in str(e.value)


def test_the_downwash_feedforward_is_a_controller_option_any_rule_may_take():
    # once the ``compensated`` rule: now ``layers`` (or any rule) with [controller] downwash_feedforward
    real = preset("realistic")
    layers = parse_scenario(_scenario(anti_collision="layers")).with_overrides(aero=real)
    assert BacksteppingPolicy(layers).downwash_ff is None
    on = parse_scenario(_scenario(anti_collision="layers", downwash_feedforward=True)).with_overrides(aero=real)
    assert BacksteppingPolicy(on).downwash_ff is not None and isinstance(BacksteppingPolicy(on).rule, LayeredRule)
    jet = parse_scenario(_scenario(anti_collision="jet-aware")).with_overrides(aero=real)
    assert BacksteppingPolicy(jet).downwash_ff is not None  # the jet-aware preset asks for it
    off = parse_scenario(_scenario(anti_collision="jet-aware", downwash_feedforward=False)).with_overrides(aero=real)
    assert BacksteppingPolicy(off).downwash_ff is None
    # it is not a [formation] key
    data = _scenario()
    data["formation"]["downwash_feedforward"] = True
    with pytest.raises(UserError, match="unknown key"):
        parse_scenario(data)


def test_each_preset_is_its_rules_own_record_and_the_default_is_written_once():
    for name, cls in ANTI_COLLISION_RULES.items():
        assert type(rule_record(name)) is cls.Params, name
        if name in PRESETS:
            assert type(PRESETS[name]) is cls.Params, name
    assert PRESETS["paper"] == PaperParams() and PRESETS["layers"] == LayersParams() and PRESETS["off"] == BaseParams()
    assert rule_record("stagger") == StaggerParams()  # a rule outside the presets: its class's own record
    jet = PRESETS["jet-aware"]
    changed = {k for k in record_keys(jet) if getattr(jet, k) != getattr(JetAwareParams(), k)}
    assert changed == {"max_speed", "max_accel", "formed_descent_accel"}
    bar = PRESETS["barrier"]
    assert {k for k in record_keys(bar) if getattr(bar, k) != getattr(jet, k)} == {
        "descent_speed",
        "crossing_brake",
        "leader_join_s",
        "leader_climb_s",
    }
    # what the rules ask of the controller: the downwash feedforward, by the jet-aware rules
    assert set(CONTROLLER_PRESETS) == {"jet-aware", "barrier"}
    assert all(c == ControllerParams(downwash_feedforward=True) for c in CONTROLLER_PRESETS.values())
    # a scenario that sets nothing holds no copy of a default
    assert parse_scenario(_scenario()).anti_collision_params == {}
    # the rules' attributes come from the record
    rule = make_rule("jet-aware", 3)
    assert (rule.safety, rule.hop, rule.v_max, rule.a_max) == (0.8, 0.4, 3.0, 4.0)
    assert rule.z_down_formed == (1.5, 3.0) and rule.downwash_feedforward
    assert not make_rule("layers", 3).downwash_feedforward
    assert make_rule("layers", 3, downwash_feedforward=True).downwash_feedforward
    assert not JetAwareRule(3, downwash_feedforward=False).downwash_feedforward


def test_keep_out_is_the_vehicles_arm_plus_rotor_radius_plus_the_margin():
    p = LayersParams()
    assert vehicle_outline() == pytest.approx(0.25 + ROTOR_RADIUS)
    big = QuadParams(L=0.4)
    assert p.keep_out(big) == pytest.approx(0.4 + ROTOR_RADIUS + p.outline_margin)
    assert p.overlap(big) == pytest.approx(2 * (0.4 + ROTOR_RADIUS + p.outline_margin) + p.overlap_spare)
    rule = LayeredRule(3, outline_margin=0.05)
    assert rule.footprint == pytest.approx(0.25 + ROTOR_RADIUS + 0.05)


def test_a_hovering_threshold_set_by_a_scenario_changes_who_counts_as_hovering():
    # hover_speed (one field, was 0.5 m/s written five times): a follower climbing under a drone
    # that drifts at 0.6 m/s keeps D̄ + approach_margin from it; call the drift hovering (0.7 m/s)
    # and it keeps only 2·keep-out + hover_pass_margin, so a drone 0.9 m aside no longer stops it
    def climb_target(hover_speed: float) -> float:
        rule = LayeredRule(3, hover_speed=hover_speed)
        p = np.array([[5.0, 5.0, 2.0], [0.0, 0.0, 0.5], [0.9, 0.0, 1.6]])
        rule.reset(p)
        rule.update(0.0, p, p.copy(), 2.0)
        q = p.copy()
        q[2, 1] += 0.006  # 0.6 m/s over 10 ms
        rule.update(0.01, q, p.copy(), 2.0)
        return rule.zp[1], rule.zv[1]

    _, v_default = climb_target(0.5)
    _, v_hover = climb_target(0.7)
    assert v_default <= 0.0 < v_hover  # held (or braking) under it vs free to climb


class _ZeroAcc:
    """A separation filter that asks every steered drone for zero acceleration (a test double)."""

    def reset(self, n: int) -> None:
        self.calls = 0
        self.events: list[dict] = []

    def __call__(self, sensed, pos_d, vel_d, acc_d, steer):
        self.calls += 1
        self.events.append({"t": sensed.t, "drone": 1, "other": -1, "action": "zero"})
        assert sensed.positions.shape == (3, 3) and sensed.seen.shape == (3, 3)
        assert sensed.keep_out == pytest.approx(vehicle_outline() + LayersParams().outline_margin)
        acc = acc_d.copy()
        acc[steer] = 0.0
        return pos_d.copy(), vel_d.copy(), acc


def test_a_separation_filter_sees_the_planners_references_and_changes_only_steered_rows():
    p = np.array([[0.0, 0.0, 2.0], [2.0, 0.0, 0.0], [-2.0, 0.0, 0.0]])
    slots = np.array([[0.0, 0.0, 2.0], [0.0, 1.0, 2.0], [0.0, -1.0, 2.0]])
    lead_vel, lead_acc = np.zeros((3, 3)), np.zeros((3, 3))
    lead_acc[0] = [0.5, 0.0, 0.0]
    plain, filt = JetAwareRule(3), JetAwareRule(3)
    f = _ZeroAcc()
    f.reset(3)
    filt.separation_filter = f
    for rule in (plain, filt):
        rule.reset(p)
    for k in range(20):
        a = plain.references(0.01 * k, p, slots, lead_vel, lead_acc, 2.0)
        b = filt.references(0.01 * k, p, slots, lead_vel, lead_acc, 2.0)
        np.testing.assert_array_equal(a[0], b[0])  # positions: the planner's
        np.testing.assert_array_equal(a[1], b[1])
        np.testing.assert_array_equal(b[2][0], a[2][0])  # the leader's row untouched
        assert (b[2][1:] == 0.0).all()
    assert f.calls == 20 and np.abs(a[2][1:]).max() > 0.0  # the planner did ask for accelerations
    # the filter's events become the rule's (a run's summary counts them), each once
    assert [e["t"] for e in filt.events if e["action"] == "zero"] == [0.01 * k for k in range(20)]
    assert f.events == [] and not any(e["action"] == "zero" for e in plain.events)
    assert (plain.phase != FORMED).any()
