"""The background compile of the chunk driver (swarm_mj/pipeline/fast.py, ``compile_in_background``) in a
fresh interpreter, as a first run starts it: ``python -m swarm_mj.pipeline.fast LOCK`` imports nothing but
that module and the record types of the pickled signature, so every compiled step it needs must be found
through the registry (swarm_mj/pipeline/registry.py), never through an import a run happened to make."""

from __future__ import annotations

import os
import pickle
import subprocess
import sys
from pathlib import Path

import pytest

from swarm_mj import _jit
from swarm_mj.control.policy import BacksteppingPolicy
from swarm_mj.env import SwarmEnv
from swarm_mj.experiments.runner import RunLog
from swarm_mj.physics import _mjstep
from swarm_mj.physics.aero.presets import with_aero
from swarm_mj.pipeline import fast
from swarm_mj.scenario import load_scenario

pytestmark = pytest.mark.skipif(
    not (_jit.AVAILABLE and _mjstep.available()), reason="no chunk driver here (Numba or compiled mj_step missing)"
)

REPO = Path(__file__).resolve().parents[2]


def _realistic_signature(path: Path) -> Path:
    """The chunk driver's signature of a realistic circle (force stages and the ground monitor), pickled
    as compile_in_background writes it."""
    sc = with_aero(load_scenario("circle").with_overrides(duration=0.1), "realistic")
    env = SwarmEnv(sc, terminate_on_contact=False, raise_on_divergence=True)
    log = RunLog.allocate(env.names, env.n_steps + 1, [s.name for s in env.sim.force_stages])
    assert env.sim.monitors, "the realistic physics has the ground monitor"
    sig = fast.FastLoop(env, BacksteppingPolicy(sc, env.params), log).signature(0)
    path.write_bytes(pickle.dumps(sig))
    return path


def _python(code: str, *args: str, env: dict | None = None, timeout: float = 120) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-c", code, *args], capture_output=True, text=True, cwd=REPO, env=env, timeout=timeout,
        check=False,
    )  # fmt: skip


LOOKUP = """
import inspect, pickle, sys
from swarm_mj.pipeline import fast
sig = pickle.loads(open(sys.argv[1], "rb").read())
names = list(inspect.signature(fast._driver().py_func).parameters)
stages, monitors = sig[names.index("stages")], sig[names.index("monitors")]
from swarm_mj.physics import compiled
compiled._apply_stages_compiled(stages, None, None, None)  # what Numba calls to unroll the tuples: a lookup each
compiled._track_monitors_compiled(monitors, None)
print(len(stages.types), len(monitors.types))
"""


def test_a_fresh_interpreter_importing_the_fast_module_finds_every_kernel(tmp_path):
    # the first-run bug: the ground monitor's step was registered only by importing its module
    lock = _realistic_signature(tmp_path / "sig")
    out = _python(LOOKUP, str(lock))
    assert out.returncode == 0, out.stderr[-2000:]
    n_stages, n_monitors = map(int, out.stdout.split())
    assert n_stages >= 1 and n_monitors >= 1  # the lookups ran over the realistic stages and the monitor


@pytest.mark.slow
def test_the_background_process_compiles_a_realistic_signature_on_an_empty_cache(tmp_path):
    lock = _realistic_signature(tmp_path / "lock")
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba")}  # Numba's cache, empty
    run = subprocess.run(
        [sys.executable, "-m", "swarm_mj.pipeline.fast", str(lock)], capture_output=True, text=True, cwd=REPO,
        env=env, timeout=900, check=False,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr[-3000:]
    assert not lock.exists()  # it drops its lock when done
    sig = tmp_path / "sig"
    _realistic_signature(sig)
    check = _python(
        "import pickle, sys; from swarm_mj.pipeline import fast; "
        "print(fast.compiled(pickle.loads(open(sys.argv[1], 'rb').read())))",
        str(sig),
        env=env,
    )
    assert check.returncode == 0, check.stderr[-2000:]
    assert check.stdout.strip() == "True"  # a later run in that cache finds the driver compiled
