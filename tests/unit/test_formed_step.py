"""The layered rule's formed step, written once (swarm_mj/formation/layered.py ``formed_update``,
docs/anticollision.md "The formed step, written once"): the per-period rule (LayeredRule.update) and
the chunk driver's stage (the layered record's registered step, swarm_mj/formation/layered.py
``formed_step``, on the record swarm_mj/pipeline/fast.py hands it) call the same compiled function,
and a tunable of the paths set by a scenario reaches it on both."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from swarm_mj.control.policy import BacksteppingPolicy
from swarm_mj.formation.anticollision import FORMED, JetAwareRule, LayeredRule
from swarm_mj.formation.layered import PathLimits, formed_update
from swarm_mj.formation.rule_params import PARAM_KEYS, LayersParams
from swarm_mj.pipeline import registry
from swarm_mj.pipeline.records import Obs
from swarm_mj.scenario import parse_scenario

LAYERED = Path(__file__).resolve().parents[2] / "swarm_mj" / "formation" / "layered.py"
ALT = 2.0  # m, the formation (and leader's) altitude
T = 0.01  # s, the control period


def _slots(n: int) -> np.ndarray:
    """(n, 3) the leader at (0, 0, ALT) and its followers 1.2 m around it (neighbours > D̄ apart)."""
    ang = np.pi / 2 + 2 * np.pi * np.arange(n - 1) / (n - 1)
    s = np.zeros((n, 3))
    s[1:, 0], s[1:, 1] = 1.2 * np.cos(ang), 1.2 * np.sin(ang)
    s[:, 2] = ALT
    return s


def _formed(rule: LayeredRule, slots: np.ndarray) -> LayeredRule:
    """``rule`` reset at the slots with every follower formed; follower 1's horizontal path 1.5 m off
    its slot (its altitude path on target), follower 2's altitude path 1 m under it (its horizontal
    path on target): every limit of the paths has something to shape."""
    rule.reset(slots)
    rule.phase[:] = FORMED
    rule._all_formed = True
    rule.path_p[1] += [1.5, 0.0]
    rule.zp[2] -= 1.0
    return rule


def _fly_per_period(rule: LayeredRule, slots: np.ndarray, k: int) -> list[tuple[np.ndarray, ...]]:
    """k periods of the per-period driver: the rule's own references (the drones hold at the slots)."""
    zero = np.zeros_like(slots)
    return [rule.references(i * T, slots, slots, zero, zero, ALT) for i in range(k)]


def _fly_chunk_stage(rule: LayeredRule, slots: np.ndarray, k: int) -> list[tuple[np.ndarray, ...]]:
    """k periods of the chunk driver's stage on the record the chunk driver builds for this rule."""
    n = len(slots)
    record = rule.record()  # what the chunk driver passes for a layered rule (FastLoop._args)
    obs = Obs.empty(n)
    obs.pos[:] = slots
    obs.sp[:] = slots
    out = []
    for i in range(k):
        react, pos_d, vel_d, acc_d = registry.RULE_KERNELS[type(record)](record, obs, i * T)
        assert not react
        out.append((pos_d.copy(), vel_d.copy(), acc_d.copy()))
    return out


def _same(a: list, b: list) -> bool:
    return all(np.array_equal(x, y) for ra, rb in zip(a, b, strict=True) for x, y in zip(ra, rb, strict=True))


def _scenario(**formation) -> dict:
    return {
        "duration": 1.0,
        "leader": {"trajectory": "hover", "params": {"position": [0.0, 0.0, ALT]}},
        "followers": {"start": [[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]},
        "formation": {"anti_collision": "layers", **formation},
    }


def test_every_path_limit_is_read_by_a_kernel_and_the_tunables_come_from_the_record():
    # a PathLimits field no kernel reads would be a tunable accepted and dropped
    src = LAYERED.read_text()
    unread = [k for k in PathLimits._fields if not re.search(rf"\blim\.{k}\b", src)]
    assert not unread, unread
    # the fields named as the record's are the record's (a scenario's value), the others derived
    rule = LayeredRule(3, braking_share=0.6, thrust_floor=2.5, path_approach_gain=2.0)
    lim = rule.record().limits
    for k in set(PathLimits._fields) & set(PARAM_KEYS):
        assert getattr(lim, k) == getattr(rule.params, k), k
    assert (lim.v_max, lim.v_up, lim.a_down_formed) == (rule.v_max, rule.z_up[0], rule.z_down_formed[1])


@pytest.mark.parametrize(
    ("key", "value"),
    [("braking_share", 0.5), ("path_approach_gain", 1.0), ("altitude_approach_gain", 1.0), ("thrust_floor", 12.0)],
)
def test_a_path_tunable_set_by_a_scenario_reaches_the_formed_step_on_both_drivers(key, value):
    assert getattr(LayersParams(), key) != value
    slots = _slots(4)

    def rule(**formation) -> LayeredRule:
        r = BacksteppingPolicy(parse_scenario(_scenario(**formation))).rule
        assert isinstance(r, LayeredRule)
        return _formed(r, slots)

    default = _fly_per_period(rule(), slots, 60)
    per_period = _fly_per_period(rule(**{key: value}), slots, 60)
    chunk = _fly_chunk_stage(rule(**{key: value}), slots, 60)
    assert _same(per_period, chunk)  # one function on both drivers: bit for bit
    assert not _same(per_period, default)  # and the scenario's value is what it flew


@pytest.mark.parametrize("cls", [LayeredRule, JetAwareRule])
def test_both_drivers_fly_the_same_formed_step(cls):
    slots = _slots(6)
    a = _fly_per_period(_formed(cls(6), slots), slots, 40)
    b = _fly_chunk_stage(_formed(cls(6), slots), slots, 40)
    assert _same(a, b)
    assert np.abs(a[-1][2][1:]).max() > 0.0  # the paths did move


def test_when_fig5_has_work_the_compiled_step_writes_nothing_and_the_rule_reacts():
    slots = _slots(4)
    rule = _formed(LayeredRule(4), slots)
    rule.references(0.0, slots, slots, np.zeros_like(slots), np.zeros_like(slots), ALT)
    pos = slots.copy()
    pos[3, :2] = pos[2, :2] + [0.3, 0.0]  # follower 3 within D̄ of follower 2, and level with it
    record = rule.record()
    before = [x.copy() for x in (record.prev_pos, record.vel, record.prev_t, record.path_p, record.zp, record.offset)]
    busy, _ = formed_update(record, pos, slots, T, ALT)
    assert busy
    after = (record.prev_pos, record.vel, record.prev_t, record.path_p, record.zp, record.offset)
    assert all(np.array_equal(x, y, equal_nan=True) for x, y in zip(before, after, strict=True))
    assert not rule.events
    rule.update(T, pos, slots, ALT)  # the Python reaction flies this period: Fig. 5, the higher index yields
    assert [(e["drone"], e["other"], e["action"]) for e in rule.events] == [(3, 2, "up")]
    assert rule.offset[3] == rule.hop and record.prev_t[0] == T
