"""The first run's compile notice (issue 18): ``warm_up`` announces BEFORE compiling, only when a
kernel is missing from Numba's on-disk cache."""

from __future__ import annotations

import importlib
import sys
import textwrap

import pytest

from swarm_mj import _jit

pytestmark = pytest.mark.skipif(not _jit.AVAILABLE, reason="Numba not installed or SWARM_MJ_NO_JIT set")


def test_announces_before_compiling_then_cached(tmp_path, monkeypatch):
    (tmp_path / "_speed_probe_kernels.py").write_text(
        textwrap.dedent("""
        import numpy as np
        from swarm_mj._jit import jit

        @jit(samples=lambda: [(np.ones(3),)])
        def probe_kernel(x):
            return 2.0 * x
    """)
    )
    monkeypatch.syspath_prepend(str(tmp_path))  # a fresh module: its cache (tmp_path/__pycache__) is empty
    mod = importlib.import_module("_speed_probe_kernels")
    name = "_speed_probe_kernels.probe_kernel"
    try:
        assert name in _jit.uncached()
        seen = []

        def announce(msg):
            seen.append((msg, list(mod.probe_kernel.signatures)))

        _jit.warm_up(announce=announce)
        assert len(seen) == 1
        msg, compiled_then = seen[0]
        assert msg.startswith("compiling the control kernels (first run only, ~") and msg.endswith(" s)…")
        assert compiled_then == []  # said before compiling
        assert mod.probe_kernel.signatures  # and compiled after
        assert name not in _jit.uncached()  # now in the on-disk cache
        seen.clear()
        _jit.warm_up(announce=announce)
        assert seen == []  # nothing to compile: no notice
    finally:
        _jit.REGISTRY.pop(name, None)
        sys.modules.pop("_speed_probe_kernels", None)
