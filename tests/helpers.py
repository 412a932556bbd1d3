"""What tests/unit and tests/integration share (importable from both: pytest puts tests/ on sys.path
for tests/conftest.py).

The Neural-Swarm logs (docs/validation.md): looked for at ``../shared/neural-swarm`` from the
repository root (or at ``$NEURAL_SWARM_DATA``); the tests that read them are skipped, saying so,
where they are absent.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
DATA = Path(os.environ.get("NEURAL_SWARM_DATA", REPO.parent / "shared" / "neural-swarm"))
needs_data = pytest.mark.skipif(not DATA.is_dir(), reason=f"the Neural-Swarm logs are not at {DATA}")
#: The smallest flight of the dataset: three drones, 18 s (~190 kB a log).
SMALL = "datacollection20_12_20_2019/swap_sss"


class UnitRuleError(RuntimeError):
    """Raised inside tests/unit by what the folder does not do (tests/unit/conftest.py): start a process,
    fly a whole scenario, run a flying command or validate a whole data set. Not a
    :class:`swarm_mj.errors.SwarmError`, so that the command line does not turn it into an exit code."""


def start_until_progress(args: list[str], cwd: Path, stdout: int | None, poll: float) -> tuple:
    """Start ``args`` with a terminal on stderr (so the progress bar shows) and SIGINT at its default in the
    child (a shell's background job starts with it ignored); return (the process, the terminal's master fd,
    the stderr read so far) once the progress bar is up: the simulation loop is running. The caller
    closes the master fd and kills the process if it is still running."""
    import select
    import signal
    import subprocess
    import time

    pty = pytest.importorskip("pty")
    master, slave = pty.openpty()
    proc = subprocess.Popen(
        args,
        cwd=cwd,
        stdin=subprocess.DEVNULL,
        stdout=stdout,
        stderr=slave,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    os.close(slave)
    err = b""
    try:
        deadline = time.monotonic() + 120
        while b"%" not in err:  # the progress bar: the simulation loop is running
            assert time.monotonic() < deadline, err
            assert proc.poll() is None, err
            r, _, _ = select.select([master], [], [], poll)
            if r:
                err += os.read(master, 4096)
    except BaseException:
        proc.kill()
        proc.wait()
        os.close(master)
        raise
    return proc, master, err


def assert_same_runs(a, b) -> None:  # noqa: ANN001 - two swarm_mj.experiments.runner.RunResult
    """Two runs of the same scenario gave the same numbers bit for bit (the drivers' parity): every log
    series, the force rows, the summary but its timing, the events, the contacts and the error."""
    import numpy as np

    from swarm_mj.experiments.runner import _SERIES

    for f in (*_SERIES, "stage_rows"):
        x, y = getattr(a.log, f), getattr(b.log, f)
        assert np.array_equal(x, y, equal_nan=True), f"log.{f} differs"
    assert list(a.log.forces) == list(b.log.forces)
    sa, sb = dict(a.summary), dict(b.summary)
    for s in (sa, sb):
        s.pop("wall_time_s"), s.pop("real_time_factor")
    assert sa == sb
    assert a.events == b.events
    assert a.contact_log == b.contact_log
    assert repr(a.error) == repr(b.error)
