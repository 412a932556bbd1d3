"""A new anti-collision rule is one module plus one registration, and it flies on the chunk driver (issue 48;
docs/design.md, "A new anti-collision rule"): the worked example, the stagger rule
(swarm_mj/formation/stagger.py), registered by one line in ``ANTI_COLLISION_RULES`` and one in
``RULE_KERNELS`` (swarm_mj/pipeline/registry.py), flies over 90 % of its periods in the chunk driver
(which finds its compiled step by its record's type), bit for bit as step by step, and keeps its
invariant; the block of docs/design.md runs as written.

Like tests/integration/test_fast_path.py, these FAIL where the chunk driver does not exist; only
``SWARM_MJ_NO_JIT=1`` skips them.
"""

from __future__ import annotations

import ast
import importlib
import pickle
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from swarm_mj import _jit
from swarm_mj.control.policy import BacksteppingPolicy
from swarm_mj.env import SwarmEnv
from swarm_mj.experiments.runner import RunLog, run
from swarm_mj.formation.anticollision import make_rule
from swarm_mj.formation.stagger import StaggerParams, StaggerRecord, StaggerRule
from swarm_mj.physics import _mjstep
from swarm_mj.pipeline import fast, registry
from swarm_mj.pipeline.records import Obs
from swarm_mj.scenario import parse_scenario

pytestmark = pytest.mark.skipif(not _jit.ENABLED, reason="SWARM_MJ_NO_JIT set: Numba switched off on purpose")

REPO = Path(__file__).resolve().parents[2]
HOP, SAFETY, HYST = 0.4, 0.8, 0.05  # the rule's defaults (StaggerParams' safety_distance, hop, hysteresis)
#: the slots of the pentagon at D = 1 m (scenarios/anti_collision.toml starts its followers opposite them)
SLOTS = -np.array([[0.0, -1.5], [1.4266, -0.4635], [0.8817, 1.2135], [-0.8817, 1.2135], [-1.4266, -0.4635]]) / 1.5


def _squeeze(rule: str = "stagger", duration: float = 10.0):
    """The anti_collision scenario's squeeze (D from 1 m to 0.75 m, inside D̄, and back), each follower
    starting under its own slot: the rule acts in formed flight, where the chunk driver flies."""
    return parse_scenario(
        {
            "duration": duration,
            "leader": {"trajectory": "hover", "start": [0.0, 0.0, 0.0], "params": {"position": [0.0, 0.0, 1.5]}},
            "followers": {"start": [[x, y, 0.0] for x, y in SLOTS]},
            "formation": {"diameter": [[0.0, 1.0], [5.0, 0.75], [7.5, 1.0]], "anti_collision": rule},
        }
    )


@pytest.fixture(scope="module")
def both():
    """The squeeze flown step by step and on the chunk driver."""
    return run(_squeeze(), progress=False, fused=False), run(_squeeze(), progress=False, fused=True)


@pytest.mark.slow
def test_the_new_rule_flies_on_the_chunk_driver_bit_identical_to_step_by_step(both):
    assert _mjstep.available(), "no compiled mj_step: every run would fly step by step"
    a, b = both
    assert b.extra["fast_path"] == "on", b.extra
    K = len(a.log.t) - 1
    assert a.extra["fused_periods"] == 0
    assert b.extra["fused_periods"] > 0.9 * K, (b.extra["fused_periods"], K)
    for f in ("pos", "U", "pos_d", "vel", "quat", "rotor"):
        assert np.array_equal(getattr(a.log, f), getattr(b.log, f)), f"log.{f} differs"
    assert a.summary["contacts"] == b.summary["contacts"] and a.error is None and b.error is None


@pytest.mark.slow
def test_the_new_rule_keeps_its_invariant_in_flight(both):
    # from the log, by hand: a follower with another drone closer than D̄ horizontally flies its slot raised
    # by its index times hop; one with every other drone beyond D̄ + hysteresis flies its slot
    _, b = both
    K = len(b.log.t) - 1  # rows 0 .. K - 1: the periods flown (row K: the last observation)
    pos, raise_ = b.log.pos[:K], b.log.pos_d[:K, :, 2] - b.log.slot[:K, :, 2]
    n = pos.shape[1]
    h = np.hypot(pos[:, None, :, 0] - pos[:, :, None, 0], pos[:, None, :, 1] - pos[:, :, None, 1])  # (K, n, n)
    h[:, np.arange(n), np.arange(n)] = np.inf
    near, clear = h.min(axis=2) < SAFETY, h.min(axis=2) > SAFETY + HYST
    index = np.broadcast_to(np.arange(n) * HOP, near.shape)  # the leader's is 0: it flies its own reference
    assert np.allclose(raise_[near], index[near]) and (raise_[clear] == 0.0).all()
    assert near[:, 1:].sum() > 100 and clear[:, 1:].sum() > 100  # the squeeze made it act, and let go
    # two drones within D̄ of each other: their setpoints |i - j|·hop further apart in altitude than their slots
    i, j = np.nonzero(np.triu(np.ones((n, n), dtype=bool), 1))
    close = h[:, i, j] < SAFETY
    apart = np.broadcast_to(np.abs(i - j) * HOP, close.shape)
    assert close.any() and np.allclose(np.abs(raise_[:, i] - raise_[:, j])[close], apart[close])


def test_the_raise_holds_within_the_hysteresis_and_its_keys_come_from_a_scenario():
    rule = make_rule("stagger", 3, safety_distance=SAFETY, hop=0.3, hysteresis=HYST)
    assert isinstance(rule, StaggerRule) and rule.params == StaggerParams(SAFETY, 0.3, HYST)
    slots = np.zeros((3, 3))
    rule.reset(slots)
    for x, raised in ((SAFETY - 0.01, True), (SAFETY + HYST / 2, True), (SAFETY + 2 * HYST, False)):
        pos = np.array([[0.0, 0.0, 1.0], [x, 0.0, 1.0], [0.0, 5.0, 1.0]])  # drone 2 far from both
        out, steer = rule.update(0.0, pos, slots, 1.0)
        assert out[1, 2] == (0.3 if raised else 0.0) and out[0, 2] == 0.0 and out[2, 2] == 0.0, (x, out)
        assert not steer.any()


def test_a_fresh_interpreter_finds_the_new_rules_step_from_the_pickled_signature(tmp_path):
    # what the background compile (python -m swarm_mj.pipeline.fast LOCK) does: the record types come
    # pickled by reference, the step from the registry, never through an import a run happened to make
    sc = _squeeze(duration=0.1)
    env = SwarmEnv(sc, terminate_on_contact=False, raise_on_divergence=True)
    log = RunLog.allocate(env.names, env.n_steps + 1, [s.name for s in env.sim.force_stages])
    assert fast.why_not(env, policy := BacksteppingPolicy(sc, env.params)) is None
    (tmp_path / "sig").write_bytes(pickle.dumps(fast.FastLoop(env, policy, log).signature(0)))
    code = (
        "import inspect, pickle, sys; from swarm_mj.pipeline import fast, period; "
        "sig = pickle.loads(open(sys.argv[1], 'rb').read()); "
        "names = list(inspect.signature(fast._driver().py_func).parameters); "
        "rule, filt = sig[names.index('rules')].dtype, sig[names.index('filts')].dtype; "
        "period._rule_period_compiled(rule, filt, None, None); print(rule.instance_class.__name__)"
    )
    out = subprocess.run(
        [sys.executable, "-c", code, str(tmp_path / "sig")], capture_output=True, text=True, cwd=REPO, timeout=300
    )
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip() == "StaggerRecord"


def _docs_block() -> str:
    doc = (REPO / "docs" / "design.md").read_text()
    section = doc[doc.index("### A new anti-collision rule") :]
    return re.search(r"```python\n(.*?)```", section, re.S).group(1)


def _without_docstrings(node: ast.AST) -> str:
    body = getattr(node, "body", [])
    if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
        node.body = body[1:]  # type: ignore[attr-defined]
    return ast.dump(node)


def test_the_design_docs_block_is_the_modules_code():
    module = {
        n.name: n for n in ast.parse((REPO / "swarm_mj/formation/stagger.py").read_text()).body if hasattr(n, "name")
    }
    shown = [n for n in ast.parse(_docs_block()).body]
    assert [n.name for n in shown] == ["stagger_update", "stagger_step"]  # the compiled step, as registered
    for node in shown:
        assert _without_docstrings(node) == _without_docstrings(module[node.name]), node.name


@pytest.mark.slow
def test_the_design_docs_block_runs_as_written_and_replays_the_flight(tmp_path, monkeypatch, both):
    # the block of docs/design.md as a module of its own, over the rule's record, fed each period's
    # observation from the chunk driver's log: the references the rule flew, bit for bit
    head = "import math\nimport numpy as np\nfrom swarm_mj._jit import jit\nfrom swarm_mj.pipeline.records import Obs\n"
    head += "from swarm_mj.formation.stagger import StaggerRecord, _samples\n"
    (tmp_path / "doc_stagger.py").write_text(head + _docs_block())
    monkeypatch.syspath_prepend(str(tmp_path))
    mod = importlib.import_module("doc_stagger")
    sys.modules.pop("doc_stagger")  # registered by importing it, with the kernels: not one of the package's
    _jit.REGISTRY.pop("doc_stagger.stagger_update")
    _jit.ON_DEMAND.discard("doc_stagger.stagger_update")
    _, b = both
    K, n = len(b.log.t) - 1, b.log.pos.shape[1]
    rec = StaggerRecord(params=StaggerParams(), raised=np.zeros(n, dtype=np.bool_))
    obs = Obs.empty(n)
    for k in range(K):
        obs.pos[:], obs.sp[:] = b.log.pos[k], b.log.slot[k]
        react, pos_d, _, _ = mod.stagger_step(rec, obs, float(b.log.t[k]))
        assert not react
        assert np.array_equal(pos_d, b.log.pos_d[k]), k


def test_its_registration_line_is_what_makes_it_fly_fast(monkeypatch):
    rule = make_rule("stagger", 3)
    assert registry.why_not_compiled(rule, registry.RULE_KERNELS, "rule", "step") is None
    monkeypatch.delitem(registry.RULE_KERNELS, StaggerRecord)
    assert registry.why_not_compiled(rule, registry.RULE_KERNELS, "rule", "step") == (
        "the rule 'stagger' has no compiled step"
    )


def test_a_rule_whose_record_lacks_what_a_separation_filter_reads_flies_step_by_step():
    # the chunk driver runs a filter only after a step whose record has registry.FILTER_READS: asked for
    # one without them, the run says why rather than fly the filter in Python alone
    sc = _squeeze(duration=0.1)
    env = SwarmEnv(sc, terminate_on_contact=False, raise_on_divergence=True)
    policy = BacksteppingPolicy(sc, env.params)
    assert fast.why_not(env, policy) is None
    policy.rule.separation_filter = make_rule("barrier", env.n).separation_filter
    assert fast.why_not(env, policy) == (
        "the 'stagger' rule's record lacks what its separation filter reads (vel, prev_t, steer)"
    )


@pytest.mark.slow
def test_the_command_line_flies_the_new_rule(tmp_path):
    out = subprocess.run(
        [sys.executable, "-m", "swarm_mj.cli", "run", "anti_collision", "--anti-collision", "stagger", "--duration",
         "0.5", "--no-record", "--quiet", "--summary", str(tmp_path / "s.json")],
        capture_output=True, text=True, cwd=tmp_path, timeout=600, stdin=subprocess.DEVNULL,
    )  # fmt: skip
    assert out.returncode == 0, out.stderr[-2000:]
    assert '"anti_collision_rule": "stagger"' in (tmp_path / "s.json").read_text()
