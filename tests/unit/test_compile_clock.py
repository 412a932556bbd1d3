"""A run's speed figure leaves out compiling (swarm_mj/_jit.py, ``CompileClock``; swarm_mj/experiments/runner.py):
the clock counts Numba's compiles (cache misses), nested ones once, and nothing for a call already compiled."""

from __future__ import annotations

import numba
import pytest

from swarm_mj import _jit

pytestmark = pytest.mark.skipif(not _jit.AVAILABLE, reason="Numba is off (SWARM_MJ_NO_JIT) or not installed")


def test_the_clock_counts_a_compile_and_not_a_compiled_call():
    @numba.njit(cache=False)
    def inner(x):
        return x + 1.0

    @numba.njit(cache=False)
    def outer(x):
        return inner(x) * 2.0  # compiling outer compiles inner inside it: one interval, not two

    clock = _jit.CompileClock().start()
    assert outer(1.0) == 4.0
    compiled = clock.stop()
    assert compiled > 0.0
    again = _jit.CompileClock().start()
    assert outer(2.0) == 6.0  # compiled already: no compile event
    assert again.stop() == 0.0
    assert clock.seconds == compiled  # stopped: a later compile is not counted

    @numba.njit(cache=False)
    def later(x):
        return x

    later(1.0)
    assert clock.seconds == compiled


def test_nested_compiles_are_counted_once():
    clock = _jit.CompileClock().start()
    listener = clock._listener
    listener.on_start(None)
    listener.on_start(None)  # a callee compiled inside
    listener.on_end(None)
    assert clock.seconds == 0.0  # still inside the outer compile
    listener.on_end(None)
    assert clock.seconds > 0.0
    clock.stop()
