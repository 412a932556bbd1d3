"""Whole runs over kept models (swarm_mj/physics/world.py, build_world's cache): runs that differ in
their starts, flown one after another in one process, give what each gives from a freshly composed
and compiled model, bit for bit (log, summary, events, contacts)."""

from __future__ import annotations

import numpy as np

from swarm_mj.experiments.runner import run
from swarm_mj.physics.world import clear_world_cache
from swarm_mj.scenario import load_scenario


def _same(a, b) -> None:
    for f in ("t", "pos", "vel", "quat", "pos_d", "U", "rotor", "wind_force"):
        assert np.array_equal(getattr(a.log, f), getattr(b.log, f), equal_nan=True), f
    sa, sb = dict(a.summary), dict(b.summary)
    for s in (sa, sb):
        s.pop("wall_time_s"), s.pop("real_time_factor")
    assert sa == sb
    assert a.events == b.events and a.contact_log == b.contact_log


def test_runs_with_other_starts_equal_runs_on_fresh_models():
    base = load_scenario("circle").with_overrides(duration=3.0)
    moved = base.with_overrides(follower_starts=base.follower_starts + np.array([0.0, 0.5, 0.0]))
    clear_world_cache()
    fresh_base = run(base, progress=False, fused=False)
    clear_world_cache()
    fresh_moved = run(moved, progress=False, fused=False)
    # now one after another in one process: the second and third runs find their models kept
    clear_world_cache()
    kept = [run(sc, progress=False, fused=False) for sc in (base, moved, base, moved)]
    assert not np.array_equal(fresh_base.log.pos[0], fresh_moved.log.pos[0])  # the starts differ
    for got, expected in zip(kept, (fresh_base, fresh_moved, fresh_base, fresh_moved), strict=True):
        _same(got, expected)
