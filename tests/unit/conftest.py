"""tests/unit runs no whole scenario and starts no process (docs/design.md, "Tests").

Every test here runs with the doors below shut, its fixtures' set-up and tear-down included (a
module-scoped fixture that flies is refused too): each raises :class:`helpers.UnitRuleError`, whose
message says to put the test in tests/integration. The doors are shut by this folder's runtest hooks,
which pytest calls for the items under tests/unit only, and open again after each phase.

* a process: ``subprocess.Popen`` (and so ``subprocess.run``, ``os.popen``), ``os.fork``,
  ``os.forkpty``, ``os.system``, ``os.posix_spawn(p)`` and ``_posixsubprocess.fork_exec`` (what
  multiprocessing's spawn and forkserver use);
* a whole scenario: :func:`swarm_mj.experiments.runner.run`, under every name a test module bound it to
  (``from swarm_mj import run`` included);
* the flying commands' ``main`` (``swarm-mj run``, ``video``, ``stress``, ``sweep``, ``tune``,
  ``report``); ``swarm-mj validate downwash`` past its input checks (the analysis of the flights of a
  data set), so that its bad input stays a unit test.
"""

from __future__ import annotations

import _posixsubprocess
import importlib
import os
import subprocess
from collections.abc import Callable, Generator
from types import ModuleType

import pytest
from helpers import UnitRuleError

import swarm_mj
from swarm_mj.experiments import runner

FLYING_COMMANDS = ("run", "video", "stress", "sweep", "tune", "report")
PROCESS_STARTERS = ("fork", "forkpty", "system", "posix_spawn", "posix_spawnp")


def _shut(what: str) -> Callable[..., object]:
    def refuse(*_args: object, **_kwargs: object) -> object:
        raise UnitRuleError(
            f"{what} inside tests/unit: tests/unit runs no whole scenario and starts no process; "
            'put this test in tests/integration (docs/design.md, "Tests")'
        )

    return refuse


def _shut_doors(mp: pytest.MonkeyPatch, module: ModuleType | None) -> None:
    """Shut the doors of the module docstring on ``mp`` (undone by ``mp.undo()``)."""
    mp.setattr(subprocess.Popen, "__init__", _shut("starting a process (subprocess.Popen)"))
    mp.setattr(_posixsubprocess, "fork_exec", _shut("starting a process (_posixsubprocess.fork_exec)"))
    for name in PROCESS_STARTERS:
        if hasattr(os, name):
            mp.setattr(os, name, _shut(f"starting a process (os.{name})"))
    real_run = runner.run
    guard = _shut("a whole scenario (swarm_mj.experiments.runner.run)")
    mp.setattr(runner, "run", guard)
    mp.setattr(swarm_mj, "run", guard, raising=False)
    for name, value in list(vars(module or ModuleType("none")).items()):
        if value is real_run:  # bound at import: `from swarm_mj.experiments.runner import run`
            mp.setattr(module, name, guard)
    for command in FLYING_COMMANDS:
        mp.setattr(
            importlib.import_module(f"swarm_mj.commands.{command}"),
            "main",
            _shut(f"a flying command (swarm-mj {command})"),
        )
    report = importlib.import_module("swarm_mj.validation.report")
    mp.setattr(report, "analyse_flight", _shut("validating a whole data set (swarm-mj validate downwash)"))


def _phase(item: pytest.Item) -> Generator[None, object, object]:
    with pytest.MonkeyPatch.context() as mp:
        _shut_doors(mp, getattr(item, "module", None))
        return (yield)


@pytest.hookimpl(wrapper=True)
def pytest_runtest_setup(item: pytest.Item) -> Generator[None, object, object]:
    return (yield from _phase(item))


@pytest.hookimpl(wrapper=True)
def pytest_runtest_call(item: pytest.Item) -> Generator[None, object, object]:
    return (yield from _phase(item))


@pytest.hookimpl(wrapper=True)
def pytest_runtest_teardown(item: pytest.Item) -> Generator[None, object, object]:
    return (yield from _phase(item))
