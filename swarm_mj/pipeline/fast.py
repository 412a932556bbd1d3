"""The chunk driver of a run: many control periods in one compiled call (docs/design.md, "The control
period, written once").

:func:`swarm_mj.pipeline.period.fly_chunk` flies the stages of :mod:`swarm_mj.pipeline.period` over the records of
:mod:`swarm_mj.pipeline.records`, the same functions the per-period path calls, so a run gives the same
numbers bit for bit either way (``tests/integration/test_fast_path.py``). This module decides
whether a run can use it and gathers the records from the run's objects:

* **Whether a run flies fast is one question** (:func:`why_not`): has every stage, monitor, the
  rule and its separation filter of this run a compiled step, and under a sensing model the sensing
  stage a compiled tick and the rule a compiled check (each drone's copy is asked before any steps)?
  Each has when its ``record()`` returns a record type the registry holds
  (:mod:`swarm_mj.pipeline.registry`: ``FORCE_KERNELS``, ``MONITOR_KERNELS``, ``RULE_KERNELS``,
  ``FILTER_KERNELS``, ``SENSING_KERNELS``, ``RULE_CHECKS``). Otherwise the run flies step by step and
  ``RunResult.extra["fast_path"]`` names what refused it (the run also says so on stderr).
* **Compiling.** The driver's signature comes from the records themselves (Numba types them), one
  per set of force stages and monitors. Compiling it takes Numba 10–20 s, more than a run saves,
  so ``runner.run(fused=None)`` uses it only when Numba's on-disk cache holds that signature for
  the current sources (:func:`compiled`), and otherwise flies step by step and starts one detached,
  low-priority process that compiles exactly that signature (:func:`compile_in_background`, the
  types pickled) for the runs after. ``fused=True`` compiles it first (:func:`compile_now`). The
  cache is checked against the sources of every module in :data:`swarm_mj._jit.KERNEL_MODULES`
  (Numba itself checks only the driver's own file).
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
import pickle
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from .. import _jit
from ..errors import UserError
from ..formation.barrier import barrier_off
from ..formation.layered import idle_record
from ..formation.own_view import OwnViewRule
from ..physics import _mjstep
from ..sensing.log import ViewLog
from . import registry
from .records import Feedforward, Obs, Viewing

#: Control periods per call: Ctrl-C and the progress bar are served between calls.
CHUNK = 100
#: Periods flown the ordinary way after Fig. 5 acted, before a chunk is tried again.
COOL_DOWN = 10


def _driver() -> Any:
    from .period import fly_chunk

    return fly_chunk


# --------------------------------------------------------------------------- the one question


def why_not(env, policy) -> str | None:  # noqa: ANN001 - SwarmEnv, BacksteppingPolicy
    """Why this run cannot fly the chunk driver (None: it can): every stage, monitor and the rule
    compilable, one swarm of the built-in policy, a compiled ``mj_step`` here."""
    sim = env.sim
    if not _mjstep.available():
        return "no compiled mj_step here (Numba, libmujoco or its ncon layout missing)"
    if env.action_mode != "thrust" or sim.n_copies != 1:
        return "not the built-in policy on one swarm"
    why = sim.not_compiled() or sim.monitors_not_compiled()
    if why is not None:
        return why
    sensing = getattr(env, "sensing", None)
    if sensing is not None:
        why = registry.why_not_compiled(sensing, registry.SENSING_KERNELS, "sensing stage", "step")
        if why is not None:
            return why
    if env.wind.relative_airspeed:
        return "the wind on the relative airspeed is computed in Python"
    ids = np.asarray(sim.world.body_ids)
    if len(ids) > 1 and not (np.diff(ids) == ids[1] - ids[0]).all():
        return "drone bodies not evenly spaced in the model"
    rule = policy.rule
    if env.n == 1:  # command() applies no rule to one drone
        return None
    if registry.why_not_compiled(rule, registry.RULE_KERNELS, "rule", "step") is not None:
        return f"the {rule.name!r} rule has no compiled step"
    if (sensing is not None) != isinstance(rule, OwnViewRule):
        return "the policy's rule and the environment disagree on the sensing model (one copy per drone or none)"
    if sensing is not None and registry.why_not_compiled(rule, registry.RULE_CHECKS, "rule", "check") is not None:
        return f"the {rule.name!r} rule has no compiled check (each drone's copy is asked before any steps)"
    filt = getattr(rule, "separation_filter", None)
    if filt is not None and registry.why_not_compiled(filt, registry.FILTER_KERNELS, "filter", "step") is not None:
        return f"the {rule.name!r} rule's separation filter has no compiled step"
    if filt is not None and not set(registry.FILTER_READS) <= set(type(rule.record())._fields):
        reads = ", ".join(registry.FILTER_READS)
        return f"the {rule.name!r} rule's record lacks what its separation filter reads ({reads})"
    return None


class FastLoop:
    """The chunk driver for one run of the built-in policy: :meth:`build`, then :meth:`run` per chunk.

    It shares every array with the environment, the simulator's stages and monitors, the policy
    and the log (nothing is copied per period), and leaves them as the per-period path would
    after the same periods. Build it after ``env.reset()``, for that episode."""

    def __init__(self, env, policy, log) -> None:  # noqa: ANN001 - SwarmEnv, BacksteppingPolicy, RunLog
        self.env, self.policy, self.log = env, policy, log
        n = env.n
        self.status = 0
        self.periods = 0  # control periods flown by the chunk driver so far
        self.seconds = 0.0  # wall-clock seconds spent in it (its share of a run's time)
        self._cool = 0
        self._obs = Obs.empty(n)
        self._handed: dict | None = None  # the observation the last chunk handed back (its buffers hold it)
        self._ruled = n > 1  # command() applies no rule to one drone (why_not: the rule has a compiled step)
        self._refs = env.refs
        self._log = log.rows
        # the stand-ins of a run of one drone or without a separation filter, built once: the driver
        # reads neither (``on`` False) and writes neither, so every chunk can pass the same ones
        self._filtered = self._ruled and getattr(policy.rule, "separation_filter", None) is not None
        self._idle_rule = idle_record(n)
        self._no_filter = barrier_off(n)
        self._copies = self._ruled and isinstance(policy.rule, OwnViewRule)  # one copy per drone: its own view
        self._view = self._viewing()

    @classmethod
    def build(cls, env, policy, log, *, compile: bool = False, announce=None) -> FastLoop | None:  # noqa: ANN001, A002
        """The chunk driver of this run, or None when it does not qualify (:func:`why_not`) or is not
        compiled yet: then ``compile`` True compiles it now, False starts :func:`compile_in_background`
        (``announce`` gets one line saying so) and the run flies step by step."""
        if why_not(env, policy) is not None:
            return None
        loop = cls(env, policy, log)
        sig = loop.signature(env.k)
        if not compiled(sig):
            if not compile:
                if compile_in_background(sig) and announce is not None:
                    announce("compiling the fast path in the background (later runs use it)")
                return None
            compile_now([sig])
        return loop

    # ------------------------------------------------------------------ the records
    def signature(self, k_end: int) -> tuple:
        """The driver's compile signature for this run (:func:`signature` of its arguments up to ``k_end``)."""
        return signature(self._args(0, k_end))

    def _args(self, k: int, k_end: int) -> tuple:
        """The driver's arguments for periods k .. k_end − 1 (the owners' records, read at each call: a
        ``reset`` or a period flown in Python may replace their arrays)."""
        env, policy = self.env, self.policy
        sim = env.sim
        # the rule's and its filter's own records (over their arrays; one per drone's copy under a sensing
        # model), or the run's stand-ins
        if self._copies:
            rules = policy.rule.records()
            filts = tuple(
                c.separation_filter.record() if self._filtered else self._no_filter for c in policy.rule.copies
            )
        else:
            rules = (policy.rule.record() if self._ruled else self._idle_rule,)
            filts = (policy.rule.separation_filter.record() if self._filtered else self._no_filter,)
        ff, pred = policy.feedforward_record(), policy.predictor_record()
        monitors = tuple(mon.record() for mon in sim.monitors)
        python_each = bool(sim.pairs_in_contact) or any(mon.holds_steps() for mon in sim.monitors)
        view = self._view
        if view is not None and env.sensing is not None:  # the stage's and the policy's records now (a reset)
            view = view._replace(sense=env.sensing.record(), rng=env.sensing.rng, pay=policy.payload_record())
        return (
            k, 0, k_end, python_each, sim.record(), self._refs, self._obs, rules, filts, view,
            policy.control_record(), ff, pred, self._log, sim.compiled_stages(), monitors,
        )  # fmt: skip

    def _viewing(self) -> Viewing | None:
        """The driver's :class:`~swarm_mj.pipeline.records.Viewing` under a sensing model (the run's sensing
        stage, its generator, the policy's payloads and the log's view rows; the stage's and the policy's
        records are read again at each call), None for the oracle."""
        env, n = self.env, self.env.n
        if env.sensing is None:
            return None
        views = self.log.views if self.log.views is not None else ViewLog.allocate(1, n)
        return Viewing(
            sense=env.sensing.record(), rng=env.sensing.rng, pay=self.policy.payload_record(),
            no_ff=Feedforward.off(n), feedforward=self.policy.downwash_ff is not None, log=self.log.views is not None,
            log_pos=views.pos, log_mask=views.mask, log_age=views.age, log_held_pos=views.held_pos,
            log_held_tick=views.held_tick,
        )  # fmt: skip

    def ready(self) -> bool:
        """The run is where a chunk can start: past its first period, every follower formed and every
        drone in the air, no contact pending, the controller's memories started, every monitor's
        compiled step all it would do, the rule's too, and Fig. 5 idle for a while."""
        if self._cool > 0:
            self._cool -= 1
            return False
        env, policy = self.env, self.policy
        if env.k < 1 or not policy.started() or env.sim.pairs_in_contact:
            return False
        if not all(mon.compiled_ready() for mon in env.sim.monitors):
            return False
        return not self._ruled or policy.rule.compiled_ready()

    # ------------------------------------------------------------------ one chunk
    def run(self, k_end: int) -> int:
        """Fly from the environment's period to ``k_end`` (or to where the driver hands back); returns the
        period reached, with the environment, policy and log as the per-period path leaves them (where
        it stopped on an error, the period that failed: then :meth:`raise_if_stopped` raises it)."""
        t0 = time.perf_counter()
        try:
            return self._run(k_end)
        finally:
            self.seconds += time.perf_counter() - t0

    def _run(self, k_end: int) -> int:
        from .period import BAD_ACTION, CONTACT, REACT, UNHEALTHY

        env, policy, sim = self.env, self.policy, self.env.sim
        fly = _driver()
        obs = env.observation
        if obs is not self._handed:  # periods flown in Python since the last chunk: their observation in
            for buf, key in zip(self._obs, _OBS_KEYS, strict=True):
                buf[...] = obs[key] if key != "dist" else env.obs_record.dist
        ctl = policy.controller
        args = list(self._args(env.k, k_end))
        k0 = env.k
        with _mjstep.profiler_paused():  # MuJoCo's profiling clock off, as in Sim.step
            while True:
                status, k, s = fly(*args)
                self._take_filter_events()
                if status == CONTACT:
                    sim.after_physics_step()  # contacts and monitors, as Sim.step after that physics step
                    args[0], args[1] = k, s
                    args[3] = bool(sim.pairs_in_contact) or any(mon.holds_steps() for mon in sim.monitors)
                    continue
                break
        self.status = status
        self.periods += k - k0
        ctl.U = policy.U_last.copy()  # the last command (command() kept it in U_last, as in Python)
        if status == REACT:
            self._cool = COOL_DOWN
        if status in (UNHEALTHY, BAD_ACTION):  # UNHEALTHY: env.k past the failed period, as SwarmEnv.step leaves it
            env.after_chunk(k, sim.contact_events)
            return k - 1 if status == UNHEALTHY else k
        self._handed = env.after_chunk(
            k, sim.contact_events, Obs(**{k: b.copy() for k, b in self._obs._asdict().items()})
        )
        return k

    def _take_filter_events(self) -> None:
        """The barrier filter's relax events of the periods flown, into the rule's ``events`` (as its
        Python call and the rule's ``references`` do: :meth:`~swarm_mj.formation.rules.Rule.take_separation_events`)."""
        rule = self.policy.rule
        if isinstance(rule, OwnViewRule):  # each copy's filter's, drone i's of copy i
            rule.take_separation_events()
            return
        f = rule.separation_filter if self._ruled else None
        if f is not None:
            f.take_events()
            rule.take_separation_events()

    def raise_if_stopped(self) -> None:
        """Raise what the per-period path raises where the last :meth:`run` stopped: the simulator's
        :class:`~swarm_mj.errors.SimulationDiverged` (naming why), or the environment's error for a
        non-finite command."""
        from .period import BAD_ACTION, UNHEALTHY

        if self.status == UNHEALTHY:
            self.env.sim.check()  # raises SimulationDiverged, naming why
            raise AssertionError("internal: the fast path found a state the simulator calls healthy")
        if self.status == BAD_ACTION:
            raise UserError("action contains NaN or inf")


_OBS_KEYS = (
    "pos", "vel", "quat", "body_rates", "rpy", "rpy_rate", "neighbours", "neighbour_mask", "dist",
    "setpoint", "setpoint_vel", "setpoint_acc", "setpoint_yaw", "wind_force",
)  # fmt: skip


# --------------------------------------------------------------------------- compiling


def signature(args: tuple) -> tuple:
    """The driver's compile signature for these arguments: the Numba types of the records themselves."""
    from numba import typeof

    return tuple(typeof(a) for a in args)


def _period(sig: tuple) -> tuple[Any, tuple]:
    """:func:`swarm_mj.physics.sim.period_physics` (what ``Sim.step`` flies a control period with) and its
    signature for the simulator of the driver's signature ``sig``: its Physics record, force stages and
    monitors, U (N, 4) C-ordered float64, the physics step and the bool ``Sim.step`` passes. Compiled with
    the driver, so that a first run's ``Sim.step`` never waits for it (swarm_mj/physics/sim.py, ``_Calls``)."""
    import inspect

    from numba import types

    from ..physics.sim import period_physics

    names = list(inspect.signature(_driver().py_func).parameters)  # the driver's arguments, by name
    phys, stages, monitors = (sig[names.index(k)] for k in ("phys", "stages", "monitors"))
    return period_physics, (phys, stages, monitors, types.Array(types.float64, 2, "C"), types.int64, types.boolean)


def _sources_hash() -> str:
    """A hash of the sources the driver is compiled from: every module of ``_jit.KERNEL_MODULES``, the
    records, the registry and the compiler switch itself."""
    h = hashlib.sha1(usedforsecurity=False)
    for name in sorted(
        {
            *_jit.KERNEL_MODULES,
            "swarm_mj._jit",
            "swarm_mj.physics._mjstep",
            "swarm_mj.pipeline.records",
            "swarm_mj.pipeline.registry",
        }
    ):
        spec = importlib.util.find_spec(name)
        if spec is not None and spec.origin:
            h.update(Path(spec.origin).read_bytes())
    return h.hexdigest()


def _stamp() -> Path | None:
    """Where the hash of the sources the cached driver came from is kept (beside Numba's index)."""
    try:
        path = _jit.cache_dir(_driver())
    except ImportError:
        return None
    return None if path is None else Path(path) / "period.fly_chunk.sources"  # None: no numba


def _cached_signatures() -> list[tuple]:
    """The signatures Numba's on-disk cache index holds for the driver ([] on surprise:
    :func:`swarm_mj._jit.cached_signatures`)."""
    return _jit.cached_signatures(_driver())


def compiled(sig: tuple) -> bool:
    """The driver is in Numba's on-disk cache for ``sig``, compiled from the current sources."""
    stamp = _stamp()
    if stamp is None or not _mjstep.available():
        return False
    try:
        fresh = stamp.read_text() == _sources_hash()
    except OSError:
        return False
    return fresh and (sig in _driver().overloads or sig in _cached_signatures()) and _jit.has_overload(*_period(sig))


def compile_now(signatures: list[tuple]) -> float:
    """Compile the driver for ``signatures`` into the cache
    (e.g. :func:`swarm_mj.experiments.runner.preset_signatures`),
    dropping a stale cache first; returns the seconds spent."""
    t0 = time.perf_counter()
    stamp = _stamp()
    if stamp is None or not _mjstep.available():
        return 0.0
    fly = _driver()
    try:
        fresh = stamp.read_text() == _sources_hash()
    except OSError:
        fresh = False
    if not fresh:
        _jit.flush_cache(fly)  # Numba would load a stale one
    for sig in signatures:
        fly.compile(sig)
        period, period_sig = _period(sig)
        period.compile(period_sig)
    try:
        tmp = stamp.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(_sources_hash())
        tmp.replace(stamp)
    except OSError:
        pass
    return time.perf_counter() - t0


def _lock_path() -> Path:
    key = hashlib.sha1(str(_stamp()).encode(), usedforsecurity=False).hexdigest()[:12]
    return Path(tempfile.gettempdir()) / f"swarm_mj-fast-{key}.lock"


def compile_in_background(sig: tuple, spawn: Callable[..., Any] = subprocess.Popen) -> bool:
    """Start one detached, low-priority process compiling the driver for ``sig`` (pickled) into the
    cache (unless one is already at it, or started less than 10 minutes ago); True if one was started."""
    if _stamp() is None or not _mjstep.available():
        return False
    lock = _lock_path()
    for _ in range(2):
        try:
            fd = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
            break
        except FileExistsError:
            try:
                if time.time() - lock.stat().st_mtime < 600:
                    return False
                lock.unlink()
            except OSError:
                return False
        except OSError:
            return False
    else:
        return False
    try:
        os.write(fd, pickle.dumps(sig))
    except Exception:  # noqa: BLE001 - a type that does not pickle (a stage defined in __main__)
        os.close(fd)
        lock.unlink(missing_ok=True)
        return False
    os.close(fd)
    try:
        spawn(
            [sys.executable, "-m", "swarm_mj.pipeline.fast", str(lock)],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            start_new_session=True,
            close_fds=True,
        )
    except OSError:
        lock.unlink(missing_ok=True)
        return False
    return True


def background_main(argv: list[str]) -> None:
    """The process :func:`compile_in_background` starts: compile the pickled signature in the lock
    file ``argv[0]``, then drop the lock file."""
    lock = Path(argv[0]) if argv else None
    try:
        if hasattr(os, "nice"):
            os.nice(10)
        if lock is not None:
            compile_now([pickle.loads(lock.read_bytes())])  # noqa: S301 - our own file
    finally:
        if lock is not None:
            lock.unlink(missing_ok=True)


if __name__ == "__main__":  # python -m swarm_mj.pipeline.fast LOCK: through the imported module, the one runs use
    import importlib

    importlib.import_module("swarm_mj.pipeline.fast").background_main(sys.argv[1:])
