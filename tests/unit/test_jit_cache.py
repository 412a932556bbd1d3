"""A Numba cache index that cannot be read back (written by an older layout of the package, whose
record types have moved) is a cache miss, not a crash (swarm_mj/_jit.py, ``_tolerate_stale_index``)."""

from __future__ import annotations

import importlib.util
import pickle
import sys
from pathlib import Path

import pytest

from swarm_mj import _jit

pytestmark = pytest.mark.skipif(not _jit.AVAILABLE, reason="Numba is off (SWARM_MJ_NO_JIT) or not installed")

KERNEL = '''
from swarm_mj._jit import jit


@jit
def twice(x):
    return 2.0 * x
'''


class Moved:
    """Stands for a record type whose module no longer exists."""


def _load(path: Path, name: str):  # noqa: ANN202
    spec = importlib.util.spec_from_file_location(name, path)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod
    spec.loader.exec_module(mod)
    return mod


def test_an_index_naming_a_module_that_moved_recompiles(tmp_path: Path) -> None:
    src = tmp_path / "kernel_mod.py"
    src.write_text(KERNEL)
    first = _load(src, "swarm_mj_test_kernel_a")
    assert first.twice(1.5) == 3.0  # compiled and saved: the index exists now
    (index,) = list((tmp_path / "__pycache__").glob("*.nbi"))
    with open(index, "rb") as f:
        version = pickle.load(f)
    # an index whose overloads name a class of a module that is gone
    payload = pickle.dumps(({"stamp": 0}, {"key": Moved()}))
    payload = payload.replace(b"test_jit_cache", b"no_such_mod_xy")  # same length: a valid pickle
    with pytest.raises(ModuleNotFoundError):
        pickle.loads(payload)
    with open(index, "wb") as f:
        pickle.dump(version, f)
        f.write(payload)
    fresh = _load(src, "swarm_mj_test_kernel_b")  # a new dispatcher reads the index from disk
    assert fresh.twice(2.0) == 4.0
    assert fresh.twice.stats.cache_misses, "the stale index is a miss: compiled afresh"
