"""The rule of tests/unit (tests/unit/conftest.py, docs/design.md "Tests"): starting a process, flying a
whole scenario, running a flying command or validating a whole data set raises UnitRuleError, whose
message sends the test to tests/integration, before anything starts or flies."""

from __future__ import annotations

import multiprocessing
import os
import subprocess
import sys

import pytest
from helpers import DATA, SMALL, UnitRuleError, needs_data

import swarm_mj
from swarm_mj.cli import main as cli_main
from swarm_mj.experiments.runner import run as run_bound_at_import

SENDS_TO_INTEGRATION = "put this test in tests/integration"


def test_subprocess_run_is_refused():
    with pytest.raises(UnitRuleError, match=SENDS_TO_INTEGRATION) as ei:
        subprocess.run([sys.executable, "-c", "pass"], check=False)
    assert "subprocess.Popen" in str(ei.value)
    with pytest.raises(UnitRuleError, match=SENDS_TO_INTEGRATION):
        subprocess.Popen([sys.executable, "-c", "pass"])
    with pytest.raises(UnitRuleError, match=SENDS_TO_INTEGRATION):
        os.popen("true")


def test_fork_and_system_are_refused():
    with pytest.raises(UnitRuleError, match=r"os\.fork"):
        pid = os.fork()
        if pid == 0:  # the guard failed: the child leaves at once, the parent fails below
            os._exit(0)
        os.waitpid(pid, 0)
    with pytest.raises(UnitRuleError, match=r"os\.system"):
        os.system("true")


@pytest.mark.parametrize("method", ["spawn", "forkserver", "fork"])
def test_multiprocessing_is_refused(method):
    ctx = multiprocessing.get_context(method)
    proc = ctx.Process(target=print)
    with pytest.raises(UnitRuleError, match=SENDS_TO_INTEGRATION):
        proc.start()
    assert proc.pid is None or proc.exitcode is not None or not proc.is_alive()


def test_a_whole_scenario_is_refused_under_every_name(capsys):
    from swarm_mj.experiments import runner

    for fly in (runner.run, swarm_mj.run, run_bound_at_import):
        with pytest.raises(UnitRuleError, match=r"whole scenario \(swarm_mj\.experiments\.runner\.run\)"):
            fly("step", progress=False, duration=0.05)
    assert capsys.readouterr().err == ""  # nothing compiled or announced: refused before anything


@pytest.mark.parametrize("command", ["run", "video", "stress", "sweep", "tune", "report"])
def test_a_flying_command_is_refused(command, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    argv = {
        "run": ["run", "step", "--no-record", "--quiet"],
        "video": ["video", "step"],
        "sweep": ["sweep", "step"],
    }.get(command, [command])
    with pytest.raises(UnitRuleError, match=rf"flying command \(swarm-mj {command}\)"):
        cli_main(argv)
    assert list(tmp_path.iterdir()) == []  # nothing written


def test_the_commands_bad_input_is_still_a_unit_test(capsys):
    with pytest.raises(SystemExit) as ei:  # argparse's refusal comes before the command's main
        cli_main(["run", "step", "--bogus-option"])
    assert ei.value.code == 2 and "unrecognized arguments" in capsys.readouterr().err
    assert cli_main(["validate", "downwash", "--data", "/nonexistent/folder", "--quiet"]) == 2
    assert "no such folder" in capsys.readouterr().err


@needs_data
def test_validating_a_whole_data_set_is_refused():
    with pytest.raises(UnitRuleError, match=r"whole data set \(swarm-mj validate downwash\)"):
        cli_main(["validate", "downwash", "--data", str(DATA / SMALL), "--quiet"])


@pytest.fixture(scope="module")
def flown_at_module_set_up():
    """A module-scoped fixture is set up before any function-scoped one: the doors are shut for it too."""
    from swarm_mj.experiments import runner

    try:
        runner.run("step", progress=False, duration=0.05)
    except UnitRuleError as exc:
        return exc
    return None


def test_a_module_scoped_fixture_cannot_fly(flown_at_module_set_up):
    assert isinstance(flown_at_module_set_up, UnitRuleError)
    assert SENDS_TO_INTEGRATION in str(flown_at_module_set_up)
