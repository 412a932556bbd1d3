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


@pytest.mark.parametrize(
    "extra, field, problem",
    [
        ("[formation]\nmax_hops_down = inf", "formation.max_hops_down", "finite"),  # an integer field
        ("[formation]\nmax_hops_up = nan", "formation.max_hops_up", "finite"),
        ("control_period = 100000000000000000000", "control_period", "longer than the duration"),  # > int64
        ("[formation]\nhop = 1" + "0" * 400, "formation.hop", "finite"),  # beyond a float's range
        ("steady_after = 1" + "0" * 400, "steady_after", "finite"),
        ('[aero]\nmodel = ["realistic"]', "aero.model", "unknown aero model"),  # not a string: unhashable
        ('[aero]\nmodel = "realistic"\nmotor_tau = 1' + "0" * 400, "aero.motor_tau", "time constant"),
        ("[formation]\nsensing_range = 1e200", "formation.sensing_range", "<= 1000 m"),  # squared: overflow
        ("[sensing]\nrange_m = 1e200", "sensing.range_m", "<= 1000 m, or inf"),
        ("[sensing]\nrange_m = 1" + "0" * 400, "sensing.range_m", "finite"),  # float() overflows
    ],
)
def test_non_finite_and_huge_numbers_in_a_file(tmp_path, monkeypatch, capsys, no_flight, extra, field, problem):
    """TOML reads nan, inf and integers of any size: an integer field given nan or inf, and an integer
    beyond int64 (which ``np.isfinite`` cannot take), are each the field's one line."""
    monkeypatch.chdir(tmp_path)
    f = tmp_path / "s.toml"
    f.write_text(f'duration = 1.0\n{extra}\n[leader]\ntrajectory = "hover"\n')
    line = cli_error(capsys, ["run", f, "--no-record"])
    assert f"{f}: {field}" in line and problem in line, line


def test_more_seeds_than_there_are_is_one_line(tmp_path, monkeypatch, capsys, no_flight):
    """``sweep --seeds N`` flies seeds 0..N-1, each at most MAX_SEED: a larger N is refused, not an
    OverflowError from range()."""
    monkeypatch.chdir(tmp_path)
    line = cli_error(capsys, ["sweep", "step", "--seeds", 10**23, "--workers", "1"])
    assert "--seeds" in line and "<= 4294967296" in line, line


def test_a_sensing_range_beyond_the_world_is_one_line(tmp_path, monkeypatch, capsys, no_flight):
    """``stress --sensing-range`` is limited as a scenario's ``sensing_range`` is (the 1-km world,
    ``starts.MAX_RANGE_M``): 1e308 is refused, not an OverflowError from squaring it in flight."""
    monkeypatch.chdir(tmp_path)
    line = cli_error(capsys, ["stress", "--sensing-range", "1e308", "--starts", "1", "--workers", "1"])
    assert "--sensing-range" in line and "<= 1000 m" in line, line


@pytest.mark.parametrize("trajectory, key", [("step", "yaw_deg"), ("hover", "yaw_deg"), ("lemniscate", "altitude")])
def test_an_integer_trajectory_parameter_beyond_int64_is_read_as_its_float(tmp_path, trajectory, key):
    """TOML reads integers of any size and numpy keeps one beyond int64 as an object, which deg2rad and
    sqrt refuse (TypeError): the trajectory takes the integer as a float, as 1e30 written."""
    from swarm_mj.errors import UserError
    from swarm_mj.scenario import load_scenario

    refs = []
    for value in (10**30, 1e30):
        f = tmp_path / f"{type(value).__name__}.toml"
        f.write_text(f'duration = 1.0\n[leader]\ntrajectory = "{trajectory}"\n[leader.params]\n{key} = {value}\n')
        try:
            refs.append(load_scenario(f).make_trajectory()([0.0, 0.5]).yaw.tolist())
        except UserError as exc:  # the altitude: 1e30 m is beyond the 1-km world, one line for both
            refs.append(str(exc).split(": ", 1)[1])
    assert refs[0] == refs[1], refs


@pytest.mark.parametrize(
    "argv, says",
    [
        (["stress", "--starts", 10**14], "beyond the largest seed, 4294967295"),  # seed0 + starts - 1
        (["stress", "--seed0", 2**32 - 1, "--starts", 2], "beyond the largest seed"),
        (["stress", "--seed0", -1, "--starts", 1], "--seed0: must be >= 0"),
        (["stress", "--starts", 4 * 10**9], "--starts: 8e+09 runs would hold"),  # two rules' cases and rows
        (["sweep", "step", "--seeds", 4 * 10**9], "--seeds: 4e+09 runs would hold"),  # list(range(seeds))
    ],
)
def test_more_starts_or_seeds_than_fit_is_one_line(tmp_path, monkeypatch, capsys, no_flight, argv, says):
    """The stress starts' seeds are seed0 .. seed0 + starts - 1, each at most MAX_SEED; and a request's
    cases or tasks and result rows must fit in memory (16 GiB here): each is refused before the
    cases are built, not a MemoryError (or the machine's memory exhausted) minutes later."""
    from swarm_mj import scenario

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(scenario, "available_memory_bytes", lambda: 16 * 2**30)
    line = cli_error(capsys, [*argv, "--workers", "1"])
    assert says in line, line


@pytest.mark.parametrize(
    "key, value",
    [("mass", "1" + "0" * 400), ("inertia", "[1" + "0" * 400 + ", 1, 1]"), ("hub_area", "1" + "0" * 400)],
)
def test_a_vehicle_number_beyond_a_float_is_one_line(tmp_path, monkeypatch, capsys, no_flight, key, value):
    """A vehicle file's integer beyond a float's range is its key's one line (table_fields.finite), not
    math.isfinite's OverflowError."""
    from swarm_mj.vehicles import _HERE

    monkeypatch.chdir(tmp_path)
    lines = [ln for ln in (_HERE / "paper.toml").read_text().splitlines() if not ln.startswith(f"{key} =")]
    (tmp_path / "v.toml").write_text("\n".join([*lines, f"{key} = {value}", ""]))
    line = cli_error(capsys, ["run", "step", "--vehicle", "v.toml", "--no-record"])
    assert f"vehicle key {key!r} must be" in line, line


@pytest.mark.parametrize(
    "argv, says",
    [
        (["video", "step", "-o", "nope/x.mp4"], "-o/--output nope/x.mp4: folder nope does not exist"),
        (["video", "step", "--output", "x.avi"], "-o/--output x.avi: the file name must end in .mp4"),
        (["run", "step", "--video", "nope/x.mp4", "--no-record"], "--video nope/x.mp4: folder nope does not exist"),
    ],
)
def test_a_bad_video_path_names_the_commands_own_option(tmp_path, monkeypatch, capsys, no_flight, argv, says):
    """``video`` takes its path as ``-o/--output`` and ``run`` as ``--video``: the line names the one given."""
    monkeypatch.chdir(tmp_path)
    line = cli_error(capsys, argv)
    assert says in line, line


def test_a_sweeps_failed_run_is_named_by_its_value_and_seed(tmp_path, monkeypatch, capsys):
    """The closing line of a sweep with a failed flight names the run as its progress line does: the
    value swept and the seed (``seed 0`` alone is every value's first run)."""
    from swarm_mj.experiments import sweep

    real = sweep.run_task

    def second_value_fails(task):
        r = real(task)
        r["flight_failed"] = "flight failed: follower5 was lost" if task.value_index == 1 else None
        return r

    monkeypatch.setattr(sweep, "run_task", second_value_fails)
    monkeypatch.chdir(tmp_path)
    argv = ["sweep", "anti_collision", "--param", "formation.anti_collision=off,paper", "--seeds", "1"]
    rc = cli.main([*argv, "--duration", "0.2", "--workers", "1", "--quiet"])
    out = capsys.readouterr().out
    assert rc == 3, out
    assert "1 of 2 runs failed; formation.anti_collision='paper' seed 0: flight failed: follower5 was lost" in out, out
