"""The two drivers of the control period (docs/design.md, "The control period, written once"): the chunk
driver (swarm_mj/pipeline/fast.py, swarm_mj/pipeline/period.py) gives the same numbers bit for bit as the per-period
path over whole runs, through everything it hands back to Python (Fig. 5 acting, contacts, a
touchdown, a divergence), and it does fly most of a formed run.

These tests FAIL where the chunk driver does not exist (no compiled ``mj_step``): a run that
silently flew step by step would otherwise pass every parity check. Only an explicit
``SWARM_MJ_NO_JIT=1`` (Numba switched off on purpose) skips them.
"""

from __future__ import annotations

import pickle

import numpy as np
import pytest
from helpers import assert_same_runs

from swarm_mj import _jit
from swarm_mj.env import SwarmEnv
from swarm_mj.experiments.runner import preset_signatures, run
from swarm_mj.experiments.stress import StressCase, stress_scenario
from swarm_mj.physics import _mjstep
from swarm_mj.physics.aero.updraft import UpdraftStage
from swarm_mj.pipeline import fast, registry
from swarm_mj.scenario import load_scenario

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(not _jit.ENABLED, reason="SWARM_MJ_NO_JIT set: Numba switched off on purpose"),
]


def test_the_fast_path_exists_here():
    assert _jit.AVAILABLE, "Numba is a dependency: the chunk driver needs it"
    assert _mjstep.available(), "no compiled mj_step: every run would fly step by step"


def _both(sc, **kw):
    a = run(sc, progress=False, fused=False, **kw)
    b = run(sc, progress=False, fused=True, **kw)
    assert b.extra["fast_path"] == "on", b.extra  # the run qualified: the comparison is not vacuous
    return a, b


_assert_same = assert_same_runs


@pytest.mark.parametrize("name", ["circle", "scenario1", "anti_collision"])
def test_bit_identical_to_the_per_period_path(name):
    a, b = _both(name)
    _assert_same(a, b)
    K = len(a.log.t) - 1
    assert a.extra["fused_periods"] == 0
    # most of the run is formed flight, flown in chunks (the rest: form-up, and periods where Fig. 5 acts)
    assert b.extra["fused_periods"] > (0.9 if name == "circle" else 0.5) * K, b.extra


def test_one_drone_flies_fast_from_its_second_period():
    a, b = _both("lemniscate_single", duration=20.0)
    _assert_same(a, b)
    assert b.extra["fused_periods"] == len(a.log.t) - 2  # all but the first (and the last sample's command)


def test_contacts_inside_chunks_are_counted_as_on_the_per_period_path():
    # no rule, slots 0.6 m from the leader: neighbours' rotors touch in formation
    sc = load_scenario("circle").with_overrides(diameter=0.6, anti_collision="off", duration=8.0)
    a, b = _both(sc)
    # the check can fail: physics steps in contact after 3 s (formed flight, in chunks), at least 0.5 s
    # of them. Steps, not rising edges: since MuJoCo 4.0.1 (its fix of cylinder-edge multicontact) two
    # rotors that touch stay in contact instead of flickering, and the rising edges after 3 s went
    # from 86 to 0 on this run while the steps in contact stayed 1330 of 1600 (docs/libraries.md)
    late_steps = a.summary["contact_steps"] - round(3.0 / sc.timestep)
    assert late_steps > round(0.5 / sc.timestep)
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
    assert list(b.log.forces) == ["downwash", "ground_effect"]
    assert np.abs(b.log.forces["downwash"]).max() > 0.01  # the jets are there
    assert b.extra["fused_periods"] > 0.8 * (len(a.log.t) - 1)


def test_a_touchdown_inside_a_chunk_is_counted_as_on_the_per_period_path(touchdown_scenario):
    sc = touchdown_scenario
    a, b = _both(sc)
    assert a.summary["ground_contacts"] == 1  # takes off, then descends onto the floor
    assert b.extra["fused_periods"] > 250  # every period after the first few, the touchdown among them
    _assert_same(a, b)


@pytest.mark.parametrize(
    ("rule", "key", "value"), [("layers", "path_approach_gain", 1.0), ("jet-aware", "braking_share", 0.5)]
)
def test_a_path_tunable_set_by_a_scenario_flies_on_both_drivers(rule, key, value):
    # a [formation] key read by the compiled path kernels (docs/anticollision.md, "The formed step,
    # written once"): the chunk driver flies it as the per-period path does, and it changes the flight
    base = load_scenario("circle").with_overrides(duration=12.0, anti_collision=rule)
    sc = base.with_overrides(anti_collision_params={**base.anti_collision_params, key: value})
    a, b = _both(sc)
    _assert_same(a, b)
    assert b.extra["fused_periods"] > 0.5 * (len(a.log.t) - 1), b.extra
    default = run(base, progress=False, fused=True)
    assert default.extra["fused_periods"] > 0
    assert not np.array_equal(default.log.pos_d, b.log.pos_d)


@pytest.mark.parametrize("aero", ["paper", "realistic"])
def test_the_barrier_filter_flies_fast_bit_identical(aero, monkeypatch):
    # the barrier separation filter (swarm_mj/formation/barrier.py, barrier_step) after the planner's
    # formed step in the chunk driver; a start whose followers are still guarded (flown on the
    # filter's own references) when the chunks begin, so that its state crosses the two drivers; its
    # followers fly to assigned slots (docs/barrier.md, "slot assignment"), not their own
    guarded, slot_of = [], []
    run_chunk = fast.FastLoop.run

    def counting(self, k_end):
        f = self.policy.rule.separation_filter
        before = f.guarded_periods
        out = run_chunk(self, k_end)
        guarded.append(f.guarded_periods - before)
        slot_of.append(self.policy.rule.slot_of.copy())
        return out

    monkeypatch.setattr(fast.FastLoop, "run", counting)
    a, b = _both(stress_scenario(StressCase("barrier", 100032, 5, 3.0, 0.6, 15.0, aero=aero)))
    _assert_same(a, b)
    assert b.extra["fused_periods"] > 0.3 * (len(a.log.t) - 1), b.extra
    assert sum(guarded) > 0  # the filter flew guarded drones inside the chunks
    assert (slot_of[0] != np.arange(6)).any()  # the chunks flew permuted slots


# --------------------------------------------------------------------------- a new force stage


def _updraft_over_the_circle() -> UpdraftStage:
    """A disc of 1 m around where the leader is at t = 60 s, pushing up 0.4 N."""
    env = SwarmEnv(load_scenario("circle").with_overrides(duration=61.0))
    return UpdraftStage(centre=tuple(env.reference.pos[6000, :2]), radius=1.0, lift=0.4)


def test_a_new_force_stage_flies_fast_is_logged_and_applied():
    a = run("circle", progress=False, fused=False, force_stages=[_updraft_over_the_circle()])
    b = run("circle", progress=False, fused=True, force_stages=[_updraft_over_the_circle()])
    assert b.extra["fast_path"] == "on"
    K = len(b.log.t) - 1
    assert b.extra["fused_periods"] > 0.9 * K, b.extra
    _assert_same(a, b)
    f = b.log.forces["updraft"]  # logged by its name, with no edit of the runner
    assert set(np.unique(f[:, :, 2])) == {0.0, 0.4} and not f[:, :, :2].any()
    # independent check: the force is on exactly when the drone is over the disc (at the start of the
    # period's last physics step, between two logged positions: allow the periods at the disc's edge)
    stage = _updraft_over_the_circle()
    inside = np.hypot(*(b.log.pos[:, :, :2] - stage.centre).transpose(2, 0, 1)) <= stage.radius
    on = f[:, :, 2] > 0
    assert on.sum() > 100  # the swarm passes through it
    edge = np.zeros_like(inside)
    edge[1:] |= inside[1:] != inside[:-1]
    edge[:-1] |= inside[1:] != inside[:-1]
    assert np.array_equal(on[~edge], inside[~edge])
    # and it changes the flight (MuJoCo received it): the runs without it differ only after it acts
    c = run("circle", progress=False, fused=True)
    first = int(np.argmax(on.any(axis=1)))
    assert np.array_equal(c.log.pos[: first + 1], b.log.pos[: first + 1])
    assert not np.array_equal(c.log.pos[first + 2 :], b.log.pos[first + 2 :])


def test_the_updraft_accelerates_a_drone_by_lift_over_mass():
    # MuJoCo's own step: a drone at rest over the disc, rotors off, one physics step
    from swarm_mj.physics.sim import Sim
    from swarm_mj.physics.world import build_world

    world = build_world(1, positions=np.array([[0.3, 0.0, 5.0]]))
    sim = Sim(world, 0.01, force_stages=[UpdraftStage(radius=0.5, lift=1.0)])
    v0 = sim.vel[0, 2]
    sim.step(np.zeros((1, 4)))
    m = float(world.model.body_subtreemass[world.body_ids[0]])
    g = -float(world.model.opt.gravity[2])
    dt = 0.01
    # over one control period from rest, with the lift and gravity only (drag −Kz·v is small: checked loosely)
    assert sim.vel[0, 2] - v0 == pytest.approx((1.0 / m - g) * dt, rel=2e-2)


def test_a_stage_without_a_compiled_kernel_flies_step_by_step_and_says_so(capsys):
    class PythonOnly:
        name = "python-only"

        def reset(self, sim):
            pass

        def apply(self, sim, force, torque):
            pass

    res = run("circle", duration=1.0, progress=None, fused=True, force_stages=[PythonOnly()])
    assert res.extra["fused_periods"] == 0
    assert res.extra["fast_path"] == "the force stage 'python-only' has no compiled kernel"
    assert "flying step by step: the force stage 'python-only'" in capsys.readouterr().err


# --------------------------------------------------------------------------- compiling


def _sig(name="circle", aero=None):
    from swarm_mj.control.policy import BacksteppingPolicy
    from swarm_mj.experiments.runner import RunLog
    from swarm_mj.physics.aero.presets import with_aero

    sc = with_aero(load_scenario(name).with_overrides(duration=0.1), aero)
    env = SwarmEnv(sc, terminate_on_contact=False, raise_on_divergence=True)
    log = RunLog.allocate(env.names, env.n_steps + 1, [s.name for s in env.sim.force_stages])
    return fast.FastLoop(env, BacksteppingPolicy(sc, env.params), log).signature(0)


def test_compiled_is_tied_to_the_sources(monkeypatch):
    sig = _sig()
    fast.compile_now([sig])
    assert fast.compiled(sig)
    monkeypatch.setattr(fast, "_sources_hash", lambda: "another source")
    assert not fast.compiled(sig)  # a callee changed: Numba's own check (the driver's file) would not see it


def test_the_background_compile_builds_the_signature_it_is_handed(tmp_path):
    sig = _sig("circle", "realistic")
    lock = tmp_path / "lock"
    lock.write_bytes(pickle.dumps(sig))  # what compile_in_background writes
    fast.background_main([str(lock)])
    assert not lock.exists()
    assert fast.compiled(sig)


def test_compile_in_background_hands_over_the_signature(monkeypatch, tmp_path):
    monkeypatch.setattr(fast, "_lock_path", lambda: tmp_path / "lock")
    seen = []
    assert fast.compile_in_background(_sig(), spawn=lambda argv, **kw: seen.append(argv))
    assert seen and seen[0][-1] == str(tmp_path / "lock")
    assert pickle.loads((tmp_path / "lock").read_bytes()) == _sig()


def test_warm_up_command_leaves_the_fast_path_compiled():
    import subprocess
    import sys

    out = subprocess.run(
        [sys.executable, "-m", "swarm_mj.cli", "warm-up"], capture_output=True, text=True, timeout=600, check=False
    )
    assert out.returncode == 0, out.stderr
    assert "fast path ready" in out.stderr, out.stderr
    assert all(fast.compiled(sig) for sig in preset_signatures())


def test_one_signature_per_set_of_stages_and_monitors():
    # a new signature is a 10-20 s compile in the middle of a user's run: one per physics preset,
    # whatever the drone count, the rule, the feedforward or the lag prediction
    cases = (("lemniscate_single", None), ("circle", None), ("circle", "realistic"), ("step", "realistic"))
    assert len({_sig(name, aero) for name, aero in cases}) == 2
    for name, aero in cases:
        res = run(name, aero=aero, duration=2.0, progress=False, fused=True)
        assert res.extra["fast_path"] == "on", (name, aero, res.extra)


def test_the_design_docs_force_stage_runs_as_written(tmp_path, monkeypatch):
    # the code block of docs/design.md, "A new force stage", as a module of its own
    import importlib
    import re
    from pathlib import Path

    doc = (Path(__file__).resolve().parents[2] / "docs" / "design.md").read_text()
    section = doc[doc.index("### A new force stage") :]
    block = re.search(r"```python\n(.*?)```", section, re.S).group(1)
    (tmp_path / "doc_updraft.py").write_text(block)
    monkeypatch.syspath_prepend(str(tmp_path))
    mod = importlib.import_module("doc_updraft")
    res = run("circle", duration=2.0, progress=False, fused=True, force_stages=[mod.UpdraftStage(lift=0.3)])
    # its kernel not registered: refused by name, flown step by step, still applied and logged
    assert res.extra["fast_path"] == "the force stage 'updraft' has no compiled kernel", res.extra
    assert res.extra["fused_periods"] == 0
    f = res.log.forces["updraft"][:, :, 2]
    inside = np.hypot(res.log.pos[:, :, 0], res.log.pos[:, :, 1]) <= 1.0
    assert (f[inside[:, :]] == 0.3).mean() > 0.9 and (f[~inside] == 0.0).mean() > 0.9
    # the registration line (swarm_mj/pipeline/registry.py), still refused while its module is not in KERNEL_MODULES
    monkeypatch.setitem(registry.FORCE_KERNELS, mod.UpdraftRecord, mod.updraft_apply)
    why = SwarmEnv("circle", force_stages=[mod.UpdraftStage()]).sim.not_compiled()
    assert why is not None and "doc_updraft is not in _jit.KERNEL_MODULES" in why, why
    monkeypatch.setattr(_jit, "KERNEL_MODULES", (*_jit.KERNEL_MODULES, "doc_updraft"))
    env = SwarmEnv("circle", force_stages=[mod.UpdraftStage()])
    assert env.sim.not_compiled() is None  # with both lines, it is compilable
