"""Compiled functions called on records without the dispatcher re-typing them (swarm_mj/_jit.py, ``bind`` and
``Bound``), and Sim.step's one compiled call per control period (swarm_mj/physics/sim.py, ``period_physics``)
against the Python loop over the physics steps with MuJoCo's own ``mujoco.mj_step`` (docs/design.md, "The
control period, written once")."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import pytest

from swarm_mj import _jit
from swarm_mj.physics import _mjstep
from swarm_mj.physics.aero.ground import GroundContacts
from swarm_mj.physics.aero.updraft import UpdraftStage
from swarm_mj.physics.sim import Sim
from swarm_mj.physics.world import build_world

needs_numba = pytest.mark.skipif(not _jit.AVAILABLE, reason="Numba is off (SWARM_MJ_NO_JIT) or not installed")


class Rec(NamedTuple):
    a: np.ndarray
    scale: float


def _total(rec: Rec, k: int):  # noqa: ANN202
    s = rec.a.sum() * rec.scale
    return s + k


total = _jit.jit(_total, deferred=True)


@needs_numba
def test_bind_returns_the_compiled_overload_for_the_arguments_types() -> None:
    rec = Rec(np.arange(5.0), 2.0)
    call = _jit.bind(total, rec, 1)
    assert call is not total  # not the dispatcher
    assert call(rec, 3) == total(rec, 3) == 2.0 * 10.0 + 3
    other = Rec(np.ones(3), 0.5)  # another record of the same types: the same overload
    assert _jit.bind(total, other, 0) is call
    assert call(other, 0) == 1.5


def test_without_numba_bind_returns_the_function_itself(monkeypatch: pytest.MonkeyPatch) -> None:
    assert _jit.bind(_total, Rec(np.ones(2), 1.0), 0) is _total  # a plain function
    monkeypatch.setattr(_jit, "AVAILABLE", False)
    assert _jit.bind(total, Rec(np.ones(2), 1.0), 0) is total


@needs_numba
def test_bound_rebinds_when_a_record_argument_is_another_object() -> None:
    bound = _jit.Bound(total, records=1)
    floats = Rec(np.arange(4.0), 1.0)
    assert bound(floats, 0) == 6.0
    assert bound(floats, 2) == 8.0  # the same record, another scalar: no rebind needed
    ints = Rec(np.arange(6, dtype=np.int64).reshape(2, 3), 3.0)  # another type: rebound, not misread
    assert bound(ints, 1) == 3.0 * 15 + 1
    assert bound(floats, 0) == 6.0  # and back


def _fly(sim: Sim, periods: int, U: np.ndarray) -> np.ndarray:
    out = []
    for k in range(periods):
        sim.step(U * (1.0 + 0.002 * np.sin(0.05 * k)), np.array([0.02, -0.01, 0.0]))
        sim.check()
        out.append(np.concatenate([sim.qpos.ravel(), sim.qvel.ravel(), sim.rotor_thrust.ravel()]))
    return np.array(out)


def _python_loop(monkeypatch: pytest.MonkeyPatch, make, fly):  # noqa: ANN001, ANN202
    """What ``fly(make())`` gives with the physics steps looped in Python (mujoco.mj_step from Python)."""
    with monkeypatch.context() as m:
        m.setattr(_mjstep, "available", lambda: False)
        sim = make()
        out = fly(sim)
        assert not sim._bound().compiled
    return out, sim


@needs_numba
def test_a_stage_added_after_flying_is_used_by_the_rebound_period(monkeypatch: pytest.MonkeyPatch) -> None:
    """Sim rebinds its compiled calls when its records are rebuilt (add_stage, reset): a stage added after
    some periods acts exactly as one given from the start."""
    if not _mjstep.available():
        pytest.fail("no compiled mj_step here: the compiled period cannot be checked")
    world = lambda: build_world(2, positions=[[0.0, 0.0, 2.0], [3.0, 0.0, 2.0]])  # noqa: E731
    U = np.tile([world().params.hover_thrust, 0.0, 0.0, 0.0], (2, 1))
    late = Sim(world())
    assert late.compile_period()
    _fly(late, 5, U)  # bound to the records without the stage
    assert late._bound().compiled
    late.add_stage(UpdraftStage((0.0, 0.0), 1.0, 0.3))  # over drone 0 only
    late.reset()
    early = Sim(world(), force_stages=[UpdraftStage((0.0, 0.0), 1.0, 0.3)])
    assert early.compile_period()  # the signature with the stage, now cached: late rebinds to it below
    none = Sim(world())
    a, b, c = _fly(late, 50, U), _fly(early, 50, U), _fly(none, 50, U)
    np.testing.assert_array_equal(a, b)
    assert a[-1, 2] > c[-1, 2] + 1e-3  # drone 0 lifted
    assert a[-1, 9] == c[-1, 9]  # drone 1 (z of its qpos) outside the disc: untouched
    looped, _ = _python_loop(monkeypatch, lambda: Sim(world(), force_stages=[UpdraftStage((0.0, 0.0), 1.0, 0.3)]),
                             lambda s: _fly(s, 50, U))  # fmt: skip
    np.testing.assert_array_equal(a, looped)


@needs_numba
def test_the_compiled_period_equals_the_python_loop_through_contacts_and_the_ground(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Two drones resting on a solid floor (the ground monitor's Python sees each step), taking off,
    rolling into each other (drone-drone contacts handed back at the step they happen) and falling: the
    state, the contacts and the ground monitor's counts bit for bit as the Python loop's."""
    if not _mjstep.available():
        pytest.fail("no compiled mj_step here: the compiled period cannot be checked")

    def make() -> Sim:
        w = build_world(2, positions=[[0.0, 0.0, 0.066], [0.55, 0.0, 0.066]], ground=True)
        return Sim(w, monitors=[GroundContacts()])

    def fly(sim: Sim) -> np.ndarray:
        hover = sim.params.hover_thrust
        up = np.tile([1.3 * hover, 0.0, 0.0, 0.0], (2, 1))
        roll = np.array([[hover, 0.0, 0.004, 0.0], [hover, 0.0, -0.004, 0.0]])  # towards each other
        fall = np.tile([0.2 * hover, 0.0, 0.0, 0.0], (2, 1))
        return np.concatenate([_fly(sim, 40, up), _fly(sim, 80, roll), _fly(sim, 120, fall)])

    compiled = make()
    assert compiled.compile_period()
    a = fly(compiled)
    assert compiled._bound().compiled  # flown by period_physics
    b, looped = _python_loop(monkeypatch, make, fly)
    np.testing.assert_array_equal(a, b)
    assert compiled.contact_events > 0 and compiled.contact_log == looped.contact_log
    mon_a, mon_b = compiled.monitors[0], looped.monitors[0]
    assert mon_a.ground_contacts > 0  # the fall was seen
    assert (mon_a.ground_contacts, mon_a.crashes, mon_a.log) == (mon_b.ground_contacts, mon_b.crashes, mon_b.log)
