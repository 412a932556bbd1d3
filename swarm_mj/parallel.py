"""What the parallel backends share: worker count, the optional Ray, the machine description.

Used by the tuner (``tuning.cost``), the sweeps and the report (``sweep``, ``report``) and the
benchmarks, so that each backend does not carry its own copy.
"""

from __future__ import annotations

import os
import platform
from pathlib import Path
from typing import Any

import numpy as np

from .errors import UserError

RAY_INSTALL_HINT = "pip install 'swarm-mj[ray]'"


def default_workers() -> int:
    """Local worker processes by default: the CPUs this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def import_ray():
    """The ``ray`` module, or one clear UserError naming the extra to install."""
    try:
        import ray  # noqa: PLC0415 - optional extra, imported only when asked for
    except ImportError:
        raise UserError(f"--ray needs Ray, which is not installed: {RAY_INSTALL_HINT}") from None
    return ray


def init_ray(ray, address: str, workers: int | None = None) -> bool:
    """Start a local Ray (``address == "local"``) or connect to a cluster, unless one is up.

    Returns True when this call started it (the caller then shuts it down).
    """
    if ray.is_initialized():
        return False
    try:
        if address == "local":
            ray.init(num_cpus=workers or default_workers(), include_dashboard=False,
                     log_to_driver=False, configure_logging=False)
        else:
            ray.init(address=address, log_to_driver=False, configure_logging=False)
    except Exception as exc:  # noqa: BLE001 - connection refused, bad address, ...
        raise UserError(f"cannot start or reach the Ray cluster at {address!r}: {exc}") from None
    return True


def machine_description() -> dict[str, Any]:
    """CPU model, cores, Python / MuJoCo / NumPy versions and platform of this machine."""
    import mujoco

    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {"cpu": cpu, "cores": os.cpu_count(), "usable_cores": default_workers(),
            "python": platform.python_version(), "mujoco": mujoco.__version__, "numpy": np.__version__,
            "platform": platform.platform()}
