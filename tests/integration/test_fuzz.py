"""Property-based fuzz of the CLI (issue 16): scenario tables and argument lists, valid and not.

Hypothesis generates scenario tables with valid and invalid values for every field (top level,
``[leader]`` and its trajectory parameters, ``[followers]`` with explicit or random starts,
``[formation]``, ``[wind]``, ``[controller]`` and its gains) and ``swarm-mj run`` argument lists.
Each goes through the CLI's ``main()`` in this process (a few through a subprocess, as a user
runs them). The properties:

* the exit status is 0, 1 or 2 and nothing escapes ``main()`` (no traceback);
* a failure is one ``swarm-mj: error:`` line;
* a successful run's summary holds no NaN (before the strict-JSON writer sees it) and its
  file is strict JSON.

Simulated durations stay at or below 0.5 s. Profiles (``HYPOTHESIS_PROFILE``): ``ci`` (default:
a bounded number of examples, derandomized, so CI is reproducible) and ``long`` (2,000
scenario tables plus 500 argument lists, for a developer's machine).
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import os
import subprocess
import sys
from pathlib import Path

import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from swarm_mj import cli

_COMMON = {
    "deadline": None,
    "print_blob": True,
    "suppress_health_check": [
        HealthCheck.too_slow,
        HealthCheck.function_scoped_fixture,
        HealthCheck.data_too_large,
        HealthCheck.filter_too_much,
    ],
}
settings.register_profile("ci", max_examples=40, derandomize=True, **_COMMON)
settings.register_profile("long", max_examples=2000, **_COMMON)
PROFILE = os.environ.get("HYPOTHESIS_PROFILE", "ci")
if PROFILE not in ("ci", "long"):
    PROFILE = "ci"
SCENARIO_SETTINGS = settings(settings.get_profile(PROFILE))
ARGS_SETTINGS = settings(
    settings.get_profile(PROFILE), max_examples=max(10, settings.get_profile(PROFILE).max_examples // 4)
)
SUBPROCESS_SETTINGS = settings(settings.get_profile("ci"), max_examples=4)

MAX_DURATION = 0.5


# --------------------------------------------------------------------------- TOML text of anything


def _toml_key(k: str) -> str:
    return k if k and all(c.isalnum() or c in "_-" for c in k) else json.dumps(k)


def toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{_toml_key(k)} = {toml_value(x)}" for k, x in v.items()) + " }"
    raise TypeError(type(v))


def toml_text(data: dict) -> str:
    top = [f"{_toml_key(k)} = {toml_value(v)}" for k, v in data.items() if not isinstance(v, dict)]
    out = top + [""]
    for k, v in data.items():
        if isinstance(v, dict):
            out.append(f"[{_toml_key(k)}]")
            out += [f"{_toml_key(kk)} = {toml_value(vv)}" for kk, vv in v.items()]
            out.append("")
    return "\n".join(out)


# --------------------------------------------------------------------------- strategies

# TOML integers are 64-bit; strings, booleans, lists, tables and non-finite floats: every wrong type.
WEIRD = st.one_of(
    st.sampled_from(
        [
            float("nan"),
            float("inf"),
            float("-inf"),
            0,
            -1,
            0.0,
            -0.0,
            1e300,
            -1e300,
            2**63 - 1,
            -(2**63),
            1e-300,
            "",
            "x",
            "big",
            "origin",
            "up",
            True,
            False,
            [],
            [1],
            [1, 2],
            [[1, 2, 3]],
            {},
            {"a": 1},
        ]
    ),
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(min_value=-(2**63), max_value=2**63 - 1),
    st.text(max_size=6),
    st.lists(st.floats(allow_nan=True, allow_infinity=True), max_size=4),
)


def num(lo: float, hi: float):
    return st.floats(min_value=lo, max_value=hi, allow_nan=False, allow_infinity=False)


def point(n: int, lo: float, hi: float):
    return st.lists(num(lo, hi), min_size=n, max_size=n)


@st.composite
def maybe(draw, valid, bad_rate: float):
    """A valid value, or (with probability ``bad_rate``) a weird one."""
    if bad_rate and draw(st.floats(0, 1)) < bad_rate:
        return draw(WEIRD)
    return draw(valid)


TRAJ_PARAMS = {
    "step": {"target": point(3, 0.0, 2.0), "yaw_deg": num(-180, 180)},
    "hover": {"position": point(3, 0.0, 2.5), "yaw_deg": num(-180, 180)},
    "lemniscate": {"amplitude": num(-4, 4), "omega": num(-1, 1), "altitude": num(0.2, 3), "center": point(2, -2, 2)},
    "circle": {
        "radius": num(-4, 4),
        "omega": num(-1, 1),
        "altitude": num(0.2, 3),
        "climb_rate": num(0, 0.5),
        "center": point(2, -2, 2),
    },
    "ascending_orbit": {
        "radius": num(-4, 4),
        "omega": num(-1, 1),
        "altitude": num(0.2, 3),
        "climb_rate": num(0, 0.5),
        "center": point(2, -2, 2),
    },
}
TIMING = [(0.01, 0.005), (0.01, 0.01), (0.02, 0.005), (0.01, 0.0025), (0.02, 0.01)]


@st.composite
def scenario_tables(draw, gains_file: str, gains_dir: str) -> dict:
    """A scenario table: every field present or absent, valid or (at a drawn rate) not."""
    bad = draw(st.sampled_from([0.0, 0.0, 0.0, 0.02, 0.08, 0.3]))
    m = lambda valid: draw(maybe(valid, bad))
    opt = lambda: draw(st.integers(0, 3)) > 0
    T, dt = draw(st.sampled_from(TIMING))
    data: dict = {}
    if opt():
        data["name"] = m(st.text(alphabet="abcxyz_-", min_size=1, max_size=8))
    data["duration"] = m(num(T, MAX_DURATION))
    if opt():
        data["control_period"] = m(st.just(T))
    if opt():
        data["timestep"] = m(st.just(dt) if "control_period" in data else st.just(0.005))
    if opt():
        data["integrator"] = m(st.sampled_from(["RK4", "Euler", "implicitfast"]))
    if opt():
        data["seed"] = m(st.integers(0, 2**32 - 1))
    if opt():
        data["steady_after"] = m(num(0, 1))
    if bad and draw(st.floats(0, 1)) < bad:
        data[draw(st.sampled_from(["sped", "followerz", "wind_speed"]))] = 1

    traj = m(st.sampled_from(sorted(TRAJ_PARAMS)))
    leader: dict = {"trajectory": traj}
    if isinstance(traj, str) and traj in TRAJ_PARAMS and opt():
        keys = draw(st.lists(st.sampled_from(sorted(TRAJ_PARAMS[traj])), unique=True, max_size=3))
        leader["params"] = {k: m(TRAJ_PARAMS[traj][k]) for k in keys}
        if bad and draw(st.floats(0, 1)) < bad:
            leader["params"] = m(st.just(leader["params"]))
    if opt():
        leader["start"] = m(st.tuples(num(-0.3, 0.3), num(-0.3, 0.3), num(0, 0.5)).map(list))
    if opt():
        leader["yaw_deg"] = m(num(-90, 90))
    data["leader"] = leader if not (bad and draw(st.floats(0, 1)) < bad / 3) else m(st.just(leader))

    n = draw(st.integers(0, 5))
    fol: dict = {}
    kind = draw(st.sampled_from(["none", "explicit", "random"]))
    if kind == "explicit" and n:
        # on a ring 1.5-3 m out (valid spacing), then maybe jittered into a clash
        base = [
            [r * math.cos(2 * math.pi * k / n), r * math.sin(2 * math.pi * k / n), 0.0]
            for k, r in zip(range(n), draw(st.lists(num(1.5, 3.0), min_size=n, max_size=n)))
        ]
        if draw(st.integers(0, 5)) == 0 and n >= 2:
            base[1] = [base[0][0] + draw(num(-0.3, 0.3)), base[0][1], base[0][2]]
        fol["start"] = m(st.just(base))
        if opt():
            fol["count"] = m(st.just(n))
    elif kind == "random" and n:
        rs: dict = {}
        if opt():
            rs["radius"] = m(num(2.0, 4.0))
        if opt():
            rs["min_spacing"] = m(num(0.1, 1.0))
        if opt():
            rs["seed"] = m(st.integers(0, 2**32 - 1))
        if draw(st.integers(0, 4)) == 0:
            rs["max_tries"] = m(st.integers(1, 50000))
        fol = {"count": m(st.just(n)), "random_start": m(st.just(rs))}
    elif opt():
        fol = {"count": m(st.just(0))}
    if fol or opt():
        data["followers"] = fol

    if opt():
        form: dict = {}
        if opt():
            form["diameter"] = m(
                st.one_of(
                    num(0.5, 2.0), st.tuples(num(0.5, 2.0), num(0.5, 2.0)).map(lambda d: [[0.0, d[0]], [0.2, d[1]]])
                )
            )
        if opt():
            form["anti_collision"] = m(st.sampled_from(["layers", "paper", "off"]))
        for k, lo, hi in (
            ("safety_distance", 0.3, 1.5),
            ("hop", 0.1, 0.8),
            ("hysteresis", 0.01, 0.2),
            ("arrive", 0.05, 0.5),
            ("sensing_range", 1.0, 8.0),
        ):
            if draw(st.integers(0, 3)) == 0:
                form[k] = m(num(lo, hi))
        data["formation"] = form

    if opt():
        ctl: dict = {}
        if opt():
            ctl["gains"] = m(
                st.one_of(
                    st.just("table4"),
                    st.just(gains_file),
                    st.just(gains_dir),
                    st.just("missing_gains.toml"),
                    st.lists(num(0.5, 12.0), min_size=12, max_size=12),
                )
            )
        if opt():
            ctl["wind_feedforward"] = m(st.booleans())
        if opt():
            ctl["attitude_map"] = m(st.sampled_from(["exact", "paper"]))
        data["controller"] = ctl

    if opt():
        wind: dict = {"enabled": m(st.booleans())}
        if opt():
            wind["mean"] = m(point(2, -6, 6))
        if opt():
            wind["sigma"] = m(st.one_of(num(0, 1.5), point(2, 0, 1.5)))
        if opt():
            wind["tau"] = m(st.one_of(num(0.1, 5), point(2, 0.1, 5)))
        if draw(st.integers(0, 3)) == 0:
            wind["sinusoids_x"] = m(st.lists(point(3, -2, 2), max_size=2))
        if draw(st.integers(0, 3)) == 0:
            wind["schedule"] = m(
                st.lists(st.tuples(num(0, 0.2), num(0.3, 1.0), st.sampled_from(["x", "y", "xy"])).map(list), max_size=2)
            )
        for k in ("rho", "cd", "area"):
            if draw(st.integers(0, 5)) == 0:
                wind[k] = m(num(0, 2))
        if draw(st.integers(0, 5)) == 0:
            wind["relative_airspeed"] = m(st.booleans())
        data["wind"] = wind
    return data


# --------------------------------------------------------------------------- the property


class Outcome:
    def __init__(self, rc: int, err: str, summary: dict | None):
        self.rc, self.err, self.summary = rc, err, summary


def _non_finite_paths(o, path="") -> list[str]:
    if isinstance(o, dict):
        return [p for k, v in o.items() for p in _non_finite_paths(v, f"{path}.{k}")]
    if isinstance(o, (list, tuple)):
        return [p for i, v in enumerate(o) for p in _non_finite_paths(v, f"{path}[{i}]")]
    if isinstance(o, float) and math.isnan(o):
        return [path]
    return []


def call_cli(argv: list[str]) -> Outcome:
    """``swarm-mj ARGV`` in this process; the raw summary handed to the JSON writer is kept."""
    from swarm_mj.output import atomic

    seen: dict = {}
    real = atomic.write_json_atomic

    def spy(path, data):
        seen["summary"] = data
        real(path, data)

    out, err = io.StringIO(), io.StringIO()
    with pytest.MonkeyPatch.context() as mp, contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        mp.setattr(atomic, "write_json_atomic", spy)  # undone after each example
        try:
            rc = cli.main(argv)
        except SystemExit as exc:  # argparse: usage errors exit 2, --help 0
            rc = exc.code if isinstance(exc.code, int) else 2
    return Outcome(rc, err.getvalue(), seen.get("summary"))


def check(o: Outcome, summary_path: Path | None) -> None:
    event(f"exit {o.rc}")
    assert o.rc in (0, 1, 2), (o.rc, o.err)
    assert "Traceback" not in o.err, o.err
    if o.rc == 2 or (o.rc == 1 and o.summary is None):
        lines = [
            ln
            for ln in o.err.splitlines()
            if ln.startswith(("swarm-mj: error:", "swarm-mj run: error:")) or "usage:" in ln
        ]
        assert lines, o.err
    if o.rc == 0 and summary_path is not None:
        assert o.summary is not None
        assert not _non_finite_paths(o.summary), _non_finite_paths(o.summary)
        json.loads(summary_path.read_text(), parse_constant=lambda c: pytest.fail(f"{c} in the summary file"))


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("fuzz")
    (d / "gains.toml").write_text("gains = [" + ", ".join(["2.0"] * 12) + "]\n")
    (d / "gainsdir").mkdir()
    return d


@SCENARIO_SETTINGS
@given(data=st.data())
def test_fuzz_scenario_tables(files, data):
    table = data.draw(scenario_tables(str(files / "gains.toml"), str(files / "gainsdir")))
    if data.draw(st.integers(0, 40)) == 0:  # now and then a file that is not TOML at all
        text = data.draw(st.sampled_from(["[leader", "duration = ", "x = 1\nx = 2", "\x00\xff", "= 3"]))
    else:
        text = toml_text(table)
    scen = files / "fuzz.toml"
    scen.write_text(text)
    out = files / "summary.json"
    out.unlink(missing_ok=True)
    extra = data.draw(st.sampled_from([[], [], ["--anti-collision", "off"], ["--seed", "5"], ["--duration", "0.1"]]))
    o = call_cli(["run", str(scen), "--no-record", "--quiet", "--summary", str(out), *extra])
    check(o, out)


OPTION_VALUES = {
    "--duration": ["0.2", "0.05", "inf", "nan", "-1", "0", "1e9", "1e400", "0.001", "abc", ""],
    "--seed": ["0", "7", "-1", str(2**32), "4294967295", "1.5", "abc"],
    "--gains": ["GAINS", "GAINSDIR", "missing.toml", "/"],
    "--anti-collision": ["layers", "paper", "off", "bogus"],
    "--summary": ["s.json", "nodir/s.json", "GAINSDIR", "-", "/dev/null"],
    "-o": ["r.rrd", "nodir/r.rrd", "GAINSDIR"],
    "--snapshot": ["x.jpg", "nodir/x.png"],
    "--video": ["x.avi", "nodir/x.mp4"],
    "--snapshot-time": ["5", "-1", "nan"],
    "--fps": ["0", "-3", "30"],
    "--size": ["1x1", "axb", "1280x720"],
}
FLAGS = ["--no-record", "--quiet", "--spawn-not-an-option", "--help"]


@st.composite
def arg_lists(draw) -> list[str]:
    scen = draw(
        st.sampled_from(
            [
                "circle",
                "step",
                "hover_missing",
                "circle_single",
                "anti_collision",
                "wind_lemniscate",
                "nodir/x.toml",
                "GAINSDIR",
                "",
            ]
        )
    )
    args = ["run", scen]
    for opt in draw(st.lists(st.sampled_from(sorted(OPTION_VALUES)), max_size=4, unique=True)):
        args += [opt, draw(st.sampled_from(OPTION_VALUES[opt]))]
    for flag in draw(st.lists(st.sampled_from(FLAGS), max_size=2, unique=True)):
        if flag in ("--spawn-not-an-option", "--help") and draw(st.integers(0, 4)):
            continue
        args.append(flag)
    if "--duration" not in args:
        args += ["--duration", "0.2"]
    if "--spawn-not-an-option" not in args and "--video" not in args and "--snapshot" not in args:
        args.append("--no-record") if draw(st.booleans()) and "--no-record" not in args else None
    return args


@ARGS_SETTINGS
@given(argv=arg_lists())
def test_fuzz_cli_arguments(files, monkeypatch, argv):
    monkeypatch.chdir(files)
    for name in ("s.json", "r.rrd"):
        (files / name).unlink(missing_ok=True)
    argv = [a.replace("GAINSDIR", str(files / "gainsdir")).replace("GAINS", str(files / "gains.toml")) for a in argv]
    o = call_cli(argv)
    check(o, files / "s.json" if "s.json" in argv and "--help" not in argv else None)


@SUBPROCESS_SETTINGS
@given(table=scenario_tables("gains.toml", "gainsdir"))
def test_fuzz_scenarios_in_a_subprocess(files, table):
    scen = files / "sub.toml"
    scen.write_text(toml_text(table))
    out = files / "sub.json"
    out.unlink(missing_ok=True)
    root = str(Path(__file__).resolve().parents[2])
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([root, os.environ.get("PYTHONPATH", "")])}
    p = subprocess.run(
        [sys.executable, "-m", "swarm_mj.cli", "run", str(scen), "--no-record", "--quiet", "--summary", str(out)],
        cwd=files,
        capture_output=True,
        text=True,
        env=env,
        timeout=600,
        stdin=subprocess.DEVNULL,
        check=False,
    )
    assert p.returncode in (0, 1, 2), p.stderr
    assert "Traceback" not in p.stderr, p.stderr
    if p.returncode == 0:
        json.loads(out.read_text(), parse_constant=lambda c: pytest.fail(f"{c} in the summary file"))
