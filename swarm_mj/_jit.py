"""Optional ahead-of-use compilation of the per-step kernels with Numba, and their registry.

The Python control layer runs every 10 ms for every drone; with plain numpy each of its
~200 small array operations costs about a microsecond of interpreter overhead, several
times the cost of the physics itself. The kernels are therefore written as plain numpy
functions on (n_drones, ...) arrays that Numba can compile unchanged. Numba is a
dependency, but the code stays correct without it: set ``SWARM_MJ_NO_JIT=1`` (or uninstall
numba) and the same functions run as ordinary numpy (tests check that both agree).
Compiled code is cached next to the sources (or, for a read-only install, in the user's cache
directory; see :func:`warm_up`), so only the first run pays for compilation.

A kernel lives in the module of the concept it computes (mixing, sim, observation,
formation, the layered rule, the controller, the tuner's record). Each is declared with
``@jit(samples=...)``: ``samples`` is a callable returning a list of argument tuples of the
types the kernel is called with, so that :func:`warm_up` compiles (or loads from the cache)
every registered kernel. :func:`warm_up` imports the modules listed in
:data:`KERNEL_MODULES` by name — the domain modules, never their callers — so this module
imports nothing of the package and no import cycle can go through it.
"""

from __future__ import annotations

import importlib
import os
import pickle
import time
import types
from collections.abc import Callable, Iterable
from typing import Any

ENABLED = os.environ.get("SWARM_MJ_NO_JIT", "") in ("", "0")

#: The modules that define kernels (imported by :func:`warm_up`; each registers its kernels).
KERNEL_MODULES: tuple[str, ...] = (
    "swarm_mj.physics.state",
    "swarm_mj.physics.mixing",
    "swarm_mj.physics.observation",
    "swarm_mj.physics.kernels",
    "swarm_mj.physics.compiled",
    "swarm_mj.formation.slots",
    "swarm_mj.formation.anticollision",
    "swarm_mj.formation.layered",
    "swarm_mj.formation.keepout",
    "swarm_mj.formation.barrier_qp",
    "swarm_mj.formation.barrier_joint",
    "swarm_mj.formation.barrier_params",
    "swarm_mj.formation.barrier_kernels",
    "swarm_mj.formation.barrier_filter",
    "swarm_mj.formation.barrier",
    "swarm_mj.formation.stagger",
    "swarm_mj.sensing.channel",
    "swarm_mj.sensing.tracker",
    "swarm_mj.sensing.stage",
    "swarm_mj.sensing.payload",
    "swarm_mj.control.backstepping",
    "swarm_mj.control.lag",
    "swarm_mj.env",
    "swarm_mj.task",
    "swarm_mj.physics.aero.downwash",
    "swarm_mj.physics.aero.ground_effect",
    "swarm_mj.physics.aero.ground",
    "swarm_mj.physics.aero.updraft",
    "swarm_mj.pipeline.period",
    "swarm_mj.pipeline.swarm",
    "swarm_mj.metrics",
)

Samples = Callable[[], Iterable[tuple[Any, ...]]]

#: name -> (kernel, samples): every kernel declared with :func:`jit`.
REGISTRY: dict[str, tuple[Callable[..., Any], Samples | None]] = {}
#: the names in :data:`REGISTRY` of the ``on_demand`` kernels (:func:`jit`).
ON_DEMAND: set[str] = set()

try:  # pragma: no cover - exercised by the environment, not by a branch of ours
    if not ENABLED:
        raise ImportError
    import numba as _numba

    def _tolerate_stale_index(dispatcher: Any) -> Any:
        """A cache index Numba cannot read back is a cache miss, and is emptied.

        Numba unpickles a whole index before it checks the source's stamp, so an index written
        by an older layout of this package (a record type whose module has moved, e.g. after an
        upgrade or a ``git pull``) raises ``ModuleNotFoundError`` from the first call instead of
        recompiling. Here such an index is flushed and the kernel compiles as on an empty cache
        (tests/unit/test_jit_cache.py)."""
        cache = getattr(dispatcher, "_cache", None)
        if cache is None or not hasattr(cache, "load_overload"):
            return dispatcher
        load = cache.load_overload

        def load_overload(sig: Any, target_context: Any) -> Any:
            try:
                return load(sig, target_context)
            except (ImportError, AttributeError, EOFError, pickle.UnpicklingError):
                cache.flush()
                return None

        cache.load_overload = load_overload
        return dispatcher

    def _compile(fn, inline: bool = False):
        return _tolerate_stale_index(
            _numba.njit(cache=True, fastmath=False, nogil=True, inline="always" if inline else "never")(fn)
        )

    AVAILABLE = True
except ImportError:  # pragma: no cover

    def _compile(fn, inline: bool = False):  # noqa: ARG001
        return fn

    AVAILABLE = False


def jit(
    fn: Callable[..., Any] | None = None,
    *,
    samples: Samples | None = None,
    deferred: bool = False,
    inline: bool = False,
    on_demand: bool = False,
):
    """Compile ``fn`` with numba.njit (cached, no fastmath: results match numpy) and register it.

    ``@jit`` or ``@jit(samples=lambda: [(arg, ...), ...])``: the argument tuples :func:`warm_up`
    calls the kernel with (a kernel only called from another kernel needs none).
    ``deferred``: not registered, so :func:`warm_up` leaves it alone (a large kernel its caller
    compiles when it chooses, with :func:`compile_samples`).
    ``on_demand``: registered, but a run's :func:`warm_up` compiles it only when asked for everything
    (``swarm-mj warm-up``): a kernel only some runs need (the barrier filter's, the vector env's), which
    its owner compiles with :func:`warm_module` when it is built, before a run's clock starts.
    ``inline``: Numba inlines it into its compiled callers (a stage of the chunk driver: a call that
    passes a whole record costs ~0.2 µs, an inlined one reads the record's fields in place); it is
    still compiled on its own for Python callers.
    """

    def register(f: Callable[..., Any]) -> Callable[..., Any]:
        compiled = _compile(f, inline)
        if not deferred:
            name = f"{f.__module__}.{f.__qualname__}"
            REGISTRY[name] = (compiled, samples)
            if on_demand:
                ON_DEMAND.add(name)
        return compiled

    return register if fn is None else register(fn)


def bind(fn: Callable[..., Any], *args: Any) -> Callable[..., Any]:
    """``fn``'s compiled overload for the Numba types of ``args`` (compiled, or loaded from the cache, now
    if needed), as a callable that skips the dispatcher: the same machine code ``fn(*args)`` runs.

    Why: a call through Numba's dispatcher types every argument on every call, and a record
    (:mod:`swarm_mj.pipeline.records`) is typed field by field: ``apply_forces(phys, stages, kin, xf,
    xt)`` costs 4.3 µs through the dispatcher against 1.3 µs through the bound overload, ``unhealthy(phys)``
    3.5 against 1.2 µs (a six-drone ``mj_step``: 17.6 µs; docs/design.md, "The control period, written
    once").

    **Invariant**: call the result only with arguments of the types it was bound to (the same record
    objects, or arrays of the same dtype, dimensions and layout). It unboxes its arguments by that fixed
    signature and does not check them: an argument of another type is undefined behaviour, not an
    error. So an owner rebinds whenever it rebuilds a record it passes (``Sim`` after ``reset``,
    ``add_stage``, ``add_monitor``), and a caller passing arrays it does not own makes them of the bound
    type first (``np.ascontiguousarray(a, dtype=float)``) or calls ``fn`` itself.

    Without Numba (or for a plain Python function) ``fn`` itself is returned."""
    if not AVAILABLE or not hasattr(fn, "overloads"):
        return fn
    dispatcher: Any = fn
    return dispatcher.compile(tuple(_numba.typeof(a) for a in args))


def compiled(fn: Callable[..., Any], *args: Any) -> bool:
    """:func:`bind` would not compile: ``fn`` has an overload for the types of ``args`` in memory or in
    Numba's on-disk cache for its current source (True without Numba: nothing compiles). Reads Numba's
    cache index (an internal API: False on any surprise, and the caller then does without)."""
    if not AVAILABLE or not hasattr(fn, "overloads"):
        return True
    return has_overload(fn, tuple(_numba.typeof(a) for a in args))


def has_overload(fn: Callable[..., Any], sig: tuple) -> bool:
    """``fn`` (a Numba dispatcher) has an overload for ``sig`` (a tuple of Numba types) in memory or in
    its on-disk cache for its current source (False on any surprise of Numba's internals)."""
    dispatcher: Any = fn
    if sig in dispatcher.overloads:
        return True
    try:
        return any(key[0] == sig for key in _numba_cache(dispatcher)._cache_file._load_index())
    except Exception:  # noqa: BLE001 - numba internals changed
        return False


# --------------------------------------------------------------------------- Numba's on-disk cache
# Numba has no public API for its on-disk cache: where it lives, which signatures its index holds, and
# dropping it are a dispatcher's internals (``Dispatcher._cache``, a ``_CacheImpl`` with its
# ``_cache_file``). This module is the one of the package that knows Numba, so it is the one that reaches
# into them, through :func:`_numba_cache` alone; the chunk driver (swarm_mj/pipeline/fast.py) and the
# kernels' warm-up go through the functions below, each of which does without on a surprise.


def _numba_cache(fn: Callable[..., Any]) -> Any:
    """The on-disk cache object of the Numba dispatcher ``fn`` (AttributeError for a plain function)."""
    dispatcher: Any = fn
    return dispatcher._cache


def cache_dir(fn: Callable[..., Any]) -> str | None:
    """The directory of Numba's on-disk cache for ``fn``; None for a plain function (no Numba)."""
    try:
        return str(_numba_cache(fn).cache_path)
    except AttributeError:
        return None


def cached_signatures(fn: Callable[..., Any]) -> list[tuple]:
    """The signatures (tuples of Numba types) Numba's on-disk cache index holds for ``fn``'s current
    source ([] without Numba, or on any surprise of Numba's internals)."""
    try:
        return [key[0] for key in _numba_cache(fn)._cache_file._load_index()]
    except Exception:  # noqa: BLE001 - numba internals changed
        return []


def flush_cache(fn: Callable[..., Any]) -> None:
    """Empty Numba's on-disk cache of the dispatcher ``fn`` (its index and overloads): a stale one would load."""
    _numba_cache(fn).flush()


class CompileClock:
    """The seconds Numba spends compiling between :meth:`start` and :meth:`stop` (a cache miss; a load from
    the on-disk cache is not compiling), nested compiles counted once: what a run leaves out of its speed
    figure. Numba's compile events (``numba.core.event``, "numba:compile"); 0 without Numba."""

    def __init__(self) -> None:
        self.seconds = 0.0
        self._depth = 0
        self._t0 = 0.0
        self._listener: Any = None

    def start(self) -> CompileClock:
        if AVAILABLE and self._listener is None:
            from numba.core import event

            clock = self

            class _Listener(event.Listener):
                def on_start(self, ev: Any) -> None:  # noqa: ARG002
                    if clock._depth == 0:
                        clock._t0 = time.perf_counter()
                    clock._depth += 1

                def on_end(self, ev: Any) -> None:  # noqa: ARG002
                    clock._depth -= 1
                    if clock._depth == 0:
                        clock.seconds += time.perf_counter() - clock._t0

            self._listener = _Listener()
            event.register("numba:compile", self._listener)
        return self

    def stop(self) -> float:
        """Stop listening; returns :attr:`seconds`."""
        if self._listener is not None:
            from numba.core import event

            event.unregister("numba:compile", self._listener)
            self._listener = None
        return self.seconds


class Bound:
    """``fn`` called through :func:`bind`, for a caller that does not own the records it passes: rebound
    whenever one of the first ``records`` arguments is not the object it was bound with (compared by
    identity; the bound objects are kept, so an identity is never reused by another object). The other
    arguments must keep the types of the first call (the invariant of :func:`bind`): scalars, or arrays
    the caller makes."""

    __slots__ = ("_call", "_ids", "_keep", "fn", "records")

    def __init__(self, fn: Callable[..., Any], records: int = 1) -> None:
        self.fn, self.records = fn, records
        self._call: Callable[..., Any] = fn
        self._ids: tuple[int, ...] = ()
        self._keep: tuple[Any, ...] = ()

    def __deepcopy__(self, memo: dict) -> Bound:
        """A copy not bound yet (it binds at its first call): the dispatcher is shared, never copied (a copy
        would pickle it; e.g. each drone's copy of a rule under a sensing model, swarm_mj.formation.own_view)."""
        return Bound(self.fn, self.records)

    def __call__(self, *args: Any) -> Any:
        ids = tuple(map(id, args[: self.records]))
        if ids != self._ids:
            self._call = bind(self.fn, *args)
            self._ids, self._keep = ids, args[: self.records]
        return self._call(*args)


def python_body(fn: Callable[..., Any], stages: dict[str, Callable[..., Any]] | None = None) -> Callable[..., Any]:
    """``fn``'s Python body (a Numba dispatcher's ``py_func``) as a function of its own whose calls of
    compiled functions run compiled: the same orchestration as the compiled ``fn``, called from Python
    without compiling ``fn`` for Python callers (docs/design.md, "The control period, written once").
    Without Numba, ``fn`` itself (or, with ``stages``, its Python function with them).

    ``stages``: callees of ``fn`` by name, replaced in the new function by these Python callables (the
    step-by-step period's stages that have no compiled step, or whose owner runs them in Python); each
    name must be one ``fn`` calls.

    Each compiled callee is bound (:func:`bind`) at its first call, to that call's argument types, and
    called through the bound overload from then on (no dispatcher, no per-call check). **Invariant** (that
    of :func:`bind`): every later call of the new function hands each callee arguments of those types, so
    its caller passes records of fixed types (records it owns) and arrays of fixed dtype, dimensions and
    layout (C-ordered float64 it checked or made). Each call of ``python_body`` makes a new function with
    its own bindings, so each caller keeps its own. The module's other globals are those of ``fn``'s
    module when it is made."""
    py = getattr(fn, "py_func", fn)
    if not stages and (not AVAILABLE or py is fn):
        return fn
    unknown = set(stages or ()) - set(py.__code__.co_names)
    if unknown:
        raise ValueError(f"{py.__qualname__} calls no {', '.join(sorted(unknown))}")
    names = dict(py.__globals__)
    for name in py.__code__.co_names:
        callee: Any = names.get(name)
        if AVAILABLE and hasattr(callee, "overloads") and hasattr(callee, "py_func"):  # a Numba dispatcher
            names[name] = _BindAtFirstCall(names, name, callee)
    names.update(stages or {})
    body = types.FunctionType(py.__code__, names, py.__name__, py.__defaults__, py.__closure__)
    body.__doc__, body.__qualname__ = py.__doc__, py.__qualname__
    return body


class _BindAtFirstCall:
    """A callee of a :func:`python_body`: at its first call, bound to that call's types and put in the
    body's globals in its place (so later calls go straight to the compiled overload)."""

    __slots__ = ("fn", "name", "names")

    def __init__(self, names: dict[str, Any], name: str, fn: Callable[..., Any]) -> None:
        self.names, self.name, self.fn = names, name, fn

    def __call__(self, *args: Any) -> Any:
        call = bind(self.fn, *args)
        self.names[self.name] = call
        return call(*args)


def _cache_index(kernel: Callable[..., Any]) -> bool | None:
    """Whether Numba's on-disk cache index holds ``kernel`` for its current source; None when that
    cannot be told (no Numba, or Numba's internals surprise us: the index is an internal API)."""
    if not AVAILABLE:
        return None
    try:
        return bool(_numba_cache(kernel)._cache_file._load_index())
    except Exception:  # noqa: BLE001 - numba internals changed
        return None


def is_cached(kernel: Callable[..., Any]) -> bool:
    """Numba's on-disk cache holds ``kernel`` for its current source (False when that cannot be
    told: then the caller compiles)."""
    return bool(_cache_index(kernel))


def compile_samples(kernel: Callable[..., Any], samples: Samples | None) -> None:
    """Compile (or load from the cache) ``kernel`` for each of its sample argument tuples."""
    for args in samples() if samples is not None else ():
        kernel(*args)


#: Rough compile time per kernel on an unloaded development machine (s), for the first-run notice.
COMPILE_S_PER_KERNEL = 0.4


def uncached(everything: bool = False) -> list[str]:
    """The registered kernels (with samples) that Numba's on-disk cache does not hold for their
    current source, i.e. that :func:`warm_up` (with the same ``everything``) will compile. Uses Numba's
    cache index (an internal API: on any surprise a kernel counts as cached, and only the notice is lost)."""
    return [
        name
        for name, (kernel, samples) in list(REGISTRY.items())
        if samples is not None and (everything or name not in ON_DEMAND) and _cache_index(kernel) is False
    ]


def warm_module(module: str) -> None:
    """Compile (or load from the cache) the ``on_demand`` kernels of ``module`` (see :func:`jit`)."""
    for name in sorted(ON_DEMAND):
        if name.rsplit(".", 1)[0] == module or name.startswith(module + "."):
            compile_samples(*REGISTRY[name])


def warm_up(announce: Callable[[str], None] | None = None, everything: bool = False) -> float:
    """Compile (or load from the on-disk cache) every registered kernel but the ``on_demand`` ones
    (``everything``: those too); returns the seconds spent.

    Called before a run's clock starts so that the real-time factor measures simulation,
    not compilation (the first run on a machine compiles for several seconds). ``announce``
    gets one line BEFORE compiling when some kernel is not cached yet (the first run).

    The cache is Numba's: next to the sources (``__pycache__``) when that directory is
    writable, else (a read-only install) the user-wide cache directory,
    ``$XDG_CACHE_HOME/numba`` (default ``~/.cache/numba``), or ``NUMBA_CACHE_DIR`` when set
    (tested with a read-only copy of the package).
    """
    t0 = time.perf_counter()
    for name in KERNEL_MODULES:
        importlib.import_module(name)
    if announce is not None:
        missing = uncached(everything)
        if missing:
            announce(
                f"compiling the control kernels (first run only, ~{max(1, round(COMPILE_S_PER_KERNEL * len(missing)))}"
                f" s)…"
            )
    for name, (kernel, samples) in list(REGISTRY.items()):
        if everything or name not in ON_DEMAND:
            compile_samples(kernel, samples)
    return time.perf_counter() - t0
