"""Extreme values found by fuzzing the CLI: each is one ``swarm-mj: error:`` line and exit status 2,
before anything flies, never a traceback. The CLI's ``main()`` runs in this process; "before anything
flies" is checked by replacing the runner's entry point with a function that fails the test."""

from __future__ import annotations

import pytest

from swarm_mj import cli


@pytest.fixture
def no_flight(monkeypatch):
    """Fail the test if anything is flown."""
    from swarm_mj.experiments import runner

    def boom(*a, **k):
        raise AssertionError("a simulation started before the bad input was refused")

    monkeypatch.setattr(runner, "run", boom)


def cli_error(capsys, argv: list) -> str:
    """``swarm-mj ARGV`` in this process: exit status 2 and one ``swarm-mj: error:`` line."""
    rc = cli.main([str(a) for a in argv])
    err = capsys.readouterr().err
    assert "Traceback" not in err, err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert rc == 2 and len(lines) == 1 and lines[0].startswith("swarm-mj: error: "), (rc, err)
    return lines[0]


@pytest.mark.parametrize(
    "argv",
    [
        ["run", "step", "--duration", "1e308", "--no-record"],
        ["stress", "--duration", "1e308", "--starts", "1", "--workers", "1"],
        ["sweep", "step", "--seeds", "1", "--workers", "1", "--param", "duration=1e308"],
    ],
)
def test_a_duration_near_the_largest_float_is_too_long(tmp_path, monkeypatch, capsys, no_flight, argv):
    """1e308 s over a 0.01-s control period overflows to inf steps: refused as too many steps, not an
    OverflowError from round()."""
    monkeypatch.chdir(tmp_path)
    line = cli_error(capsys, argv)
    assert "duration" in line and "too many steps" in line, line
