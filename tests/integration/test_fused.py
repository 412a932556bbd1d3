"""The fused built-in path (issue 18, ``swarm_mj/fused.py``, docs/design.md "The fused path"): whole runs
give the same numbers bit for bit as the ordinary step-by-step path, through everything the kernel
hands back to Python (Fig. 5 acting, contacts, a divergence), and it does fly most of a formed run.
"""

from __future__ import annotations

import numpy as np
import pytest

from swarm_mj import _jit, _mjstep, fused
from swarm_mj.runner import RunLog, run
from swarm_mj.scenario import load_scenario

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(not (_jit.AVAILABLE and _mjstep.available()), reason="no compiled mj_step here"),
]

LOG_FIELDS = [f for f in RunLog.__dataclass_fields__ if f != "names"]


def _both(sc, **kw):
    a = run(sc, progress=False, fused=False, **kw)
    b = run(sc, progress=False, fused=True, **kw)
    return a, b


def _assert_same(a, b) -> None:
    for f in LOG_FIELDS:
        x, y = getattr(a.log, f), getattr(b.log, f)
        assert np.array_equal(x, y, equal_nan=True), f"log.{f} differs"
    sa, sb = dict(a.summary), dict(b.summary)
    for s in (sa, sb):
        s.pop("wall_time_s"), s.pop("real_time_factor")
    assert sa == sb
    assert a.events == b.events
    assert a.contact_log == b.contact_log
    assert repr(a.error) == repr(b.error)


@pytest.mark.parametrize("name", ["circle", "scenario1", "anti_collision"])
def test_bit_identical_to_the_ordinary_path(name):
    a, b = _both(name)
    _assert_same(a, b)
    K = len(a.log.t) - 1
    assert a.extra["fused_periods"] == 0
    # most of the run is formed flight, flown fused (the rest: form-up, and periods where Fig. 5 acts)
    assert b.extra["fused_periods"] > (0.9 if name == "circle" else 0.5) * K, b.extra


def test_one_drone_flies_fused_from_its_second_period():
    a, b = _both("lemniscate_single", duration=20.0)
    _assert_same(a, b)
    assert b.extra["fused_periods"] == len(a.log.t) - 2  # all but the first (and the last sample's command)


def test_contacts_inside_fused_chunks_are_counted_as_on_the_ordinary_path():
    # no rule, slots 0.6 m from the leader: neighbours' rotors touch in formation, again and again
    sc = load_scenario("circle").with_overrides(diameter=0.6, anti_collision="off", duration=8.0)
    a, b = _both(sc)
    late = [c for c in a.contact_log if c[0] > 3.0]
    assert len(late) > 10  # the check can fail: contacts during formed flight
    assert b.extra["fused_periods"] > 100
    _assert_same(a, b)


def test_a_divergence_stops_at_the_same_period_with_the_same_error():
    sc = load_scenario("circle").with_overrides(diameter=0.65, anti_collision="off", duration=5.0)
    a, b = _both(sc)
    assert a.error is not None and "diverged" in str(a.error)
    assert b.extra["fused_periods"] > 0
    _assert_same(a, b)


def test_realistic_physics_and_its_controller_bit_identical():
    # downwash and ground-effect stages, rotor lag, the ground monitor; the jet-aware rule, the
    # downwash feedforward, the lag prediction and the attitude-priority mixer (docs/aero.md)
    a, b = _both("circle", aero="realistic", duration=30.0)
    _assert_same(a, b)
    assert np.abs(b.log.downwash).max() > 0.01  # the jets are there
    assert b.extra["fused_periods"] > 0.8 * (len(a.log.t) - 1)


def test_a_touchdown_inside_a_fused_chunk_is_counted_as_on_the_ordinary_path(touchdown_scenario):
    sc = touchdown_scenario
    a, b = _both(sc)
    assert a.summary["ground_contacts"] == 1  # takes off, then descends onto the floor
    assert b.extra["fused_periods"] > 250  # every period after the first few, the touchdown among them
    _assert_same(a, b)


def test_compiled_is_tied_to_the_sources(tmp_path, monkeypatch):
    fused.compile_now()
    assert fused.compiled()
    monkeypatch.setattr(fused, "_sources_hash", lambda: "another source")
    assert not fused.compiled()  # a callee changed: Numba's own check (this file's stamp) would not see it


def test_warm_up_command_leaves_the_fused_path_compiled():
    import subprocess
    import sys

    out = subprocess.run(
        [sys.executable, "-m", "swarm_mj.cli", "warm-up"], capture_output=True, text=True, timeout=600, check=False
    )
    assert out.returncode == 0, out.stderr
    assert "fused path ready" in out.stderr, out.stderr
    assert fused.compiled()


def test_one_compiled_signature_for_every_run_it_flies():
    # a second signature would be a second 10-20 s compile in the middle of a user's run
    for name, aero in (("lemniscate_single", None), ("circle", None), ("circle", "realistic"), ("step", "realistic")):
        run(name, aero=aero, duration=2.0, progress=False, fused=True)
    assert len(fused.fused_steps.signatures) == 1, fused.fused_steps.signatures
