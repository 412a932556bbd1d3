"""Each drone's copy of the barrier rule computing its own row only (``OwnViewRule.own_rows``,
swarm_mj/formation/own_view.py; every row under the joint fallback, counting its own) flies every
sensing run bit for bit as the copies computing every row: the log (the views included), the events
and the summary, under ``uwb`` step by step and ``mocap`` on the chunk driver, realistic air.
tests/unit/test_own_row.py checks the filter itself over random states."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from swarm_mj.control.policy import BacksteppingPolicy
from swarm_mj.experiments.runner import RunResult, run
from swarm_mj.formation.own_view import OwnViewRule
from swarm_mj.scenario import load_scenario

pytestmark = pytest.mark.slow

_TIMING = ("wall_time_s", "real_time_factor")


def _arrays(r: RunResult) -> dict[str, np.ndarray]:
    """Every array of the run's log, its views' included."""
    out: dict[str, np.ndarray] = {}
    for f in dataclasses.fields(r.log):
        v = getattr(r.log, f.name)
        if isinstance(v, np.ndarray):
            out[f.name] = v
        elif dataclasses.is_dataclass(v):
            out.update({f"{f.name}.{g.name}": getattr(v, g.name) for g in dataclasses.fields(v)})
    return out


@pytest.mark.parametrize(
    ("scenario", "duration", "sensing", "fused"),
    [("anti_collision", 6.0, "uwb", False), ("circle", 10.0, "mocap", True)],  # step by step; the chunk driver
)
def test_own_rows_fly_bit_for_bit_as_every_row(monkeypatch, scenario, duration, sensing, fused):
    sc = load_scenario(scenario).with_overrides(duration=duration, anti_collision="barrier", sensing=sensing)
    runs, policies = {}, {}
    for own_rows in (True, False):
        monkeypatch.setattr(OwnViewRule, "own_rows", own_rows)

        def make(*args, own_rows=own_rows):
            policies[own_rows] = BacksteppingPolicy(*args)
            return policies[own_rows]

        runs[own_rows] = run(sc, progress=False, aero="realistic", make_policy=make, fused=fused)
    copies = policies[True].rule.copies
    # the joint fallback (docs/barrier.md) is off where the robust margin is capped (uwb); with it a copy
    # computes every row and counts its own drone's
    joint = sensing == "mocap"
    assert all(c.separation_filter.barrier.joint_fallback is joint for c in copies)
    restricted = [-1] * len(copies) if joint else list(range(len(copies)))
    assert [c.separation_filter.own_row for c in copies] == restricted
    assert [c.separation_filter.tally_row for c in copies] == list(range(len(copies)))
    assert all(c.separation_filter.own_row == -1 for c in policies[False].rule.copies)
    # the filter changed drone i's command in copy i (QP solutions compared, not only untouched nominals)
    assert sum(c.separation_filter.active_periods for c in copies) > 0
    a, b = runs[True], runs[False]
    assert a.error is None and b.error is None and a.summary["sensing"]["own_view"] is True
    assert (a.extra["fused_periods"] > 0) is fused, a.extra  # the restricted records on the driver asked for
    arrays_a, arrays_b = _arrays(a), _arrays(b)
    assert arrays_a.keys() == arrays_b.keys()
    for name, x in arrays_a.items():
        assert np.array_equal(x, arrays_b[name], equal_nan=True), name
    assert a.events == b.events and a.contact_log == b.contact_log
    assert {k: v for k, v in a.summary.items() if k not in _TIMING} == {
        k: v for k, v in b.summary.items() if k not in _TIMING
    }
