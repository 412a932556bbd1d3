"""Optional ahead-of-use compilation of the per-step kernels with Numba.

The Python control layer runs every 10 ms for every drone; with plain numpy each of its
~200 small array operations costs about a microsecond of interpreter overhead, several
times the cost of the physics itself. The kernels are therefore written as plain numpy
functions on (n_drones, ...) arrays that Numba can compile unchanged. Numba is a
dependency, but the code stays correct without it: set ``SWARM_MJ_NO_JIT=1`` (or uninstall
numba) and the same functions run as ordinary numpy (tests check that both agree).
Compiled code is cached next to the sources, so only the first run pays for compilation.
"""

from __future__ import annotations

import os

ENABLED = os.environ.get("SWARM_MJ_NO_JIT", "") in ("", "0")

try:  # pragma: no cover - exercised by the environment, not by a branch of ours
    if not ENABLED:
        raise ImportError
    import numba as _numba

    def jit(fn):
        """Compile ``fn`` with numba.njit (cached, no fastmath: results match numpy)."""
        return _numba.njit(cache=True, fastmath=False, nogil=True)(fn)

    AVAILABLE = True
except ImportError:  # pragma: no cover
    def jit(fn):
        return fn

    AVAILABLE = False
