"""Vehicle files (docs/vehicles.md): the bundled ones load, bad files give one clear error."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from swarm_mj.errors import UserError
from swarm_mj.physics.params import DEFAULT_PARAMS
from swarm_mj.vehicles import _HERE, KEYS, MIN_THRUST_TO_WEIGHT, bundled, load_vehicle

ROOT = Path(__file__).resolve().parents[2]


def test_bundled_vehicles_load() -> None:
    assert {"paper", "crazyflie21"} <= set(bundled())
    for name in bundled():
        v = load_vehicle(name)
        assert v.mass > 0 and v.arm_length > 0 and v.rotor_radius > 0


def test_paper_vehicle_is_table1() -> None:
    v = load_vehicle("paper")
    assert v.mass == DEFAULT_PARAMS.m and v.arm_length == DEFAULT_PARAMS.L
    assert v.rotor_span == pytest.approx(0.34)


def test_vehicle_file_by_path(tmp_path) -> None:  # noqa: ANN001
    p = tmp_path / "mine.toml"
    p.write_text("mass = 1.2\narm_length = 0.2\nrotor_radius = 0.1\nmotor_tau = 0.03\n")
    v = load_vehicle(p)
    assert (v.name, v.mass, v.extra, v.motor_tau) == ("mine", 1.2, {"motor_tau": 0.03}, 0.03)


def _one_line(e: pytest.ExceptionInfo, path: Path) -> str:
    """The message of a refused vehicle file: one line naming the file once; returns it without the file."""
    msg = str(e.value)
    assert "\n" not in msg and msg.count(str(path)) == 1 and msg.startswith(f"{path}: "), msg
    return msg[len(f"{path}: ") :]


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("arm_length = 0.2\nrotor_radius = 0.1\n", "missing key 'mass' (kg): take-off mass"),
        ("mass = 1\nrotor_radius = 0.1\n", "missing key 'arm_length' (m): "),
        ("mass = 1\narm_length = 0.2\n", "missing key 'rotor_radius' (m): propeller radius"),
        (
            "mass = -1\narm_length = 0.2\nrotor_radius = 0.1\n",
            "vehicle key 'mass' must be a positive number (kg), got -1",
        ),
        ("mass = 1\narm_length = 'x'\nrotor_radius = 0.1\n", "vehicle key 'arm_length' must be a positive number (m)"),
        ("mass = 1\narm_length = 0.2\nrotor_radius = 0.1\ndrag = [0, -1, 0]\n", "'drag' must be 3 numbers >= 0"),
        ("mass = 1\narm_length = 0.2\nrotor_radius = 0.1\ninertia = [1, 1]\n", "'inertia' must be 3 positive numbers"),
        ("mass = 1\narm_length = 0.2\nrotor_radius = 0.1\nhub_area = -1\n", "'hub_area' must be a number >= 0 (m²)"),
        ("mass = 1\narm_length = 0.2\nrotor_radius = 0.1\nname = 3\n", "'name' must be a non-empty string, got 3"),
        ("mass = 1\narm_length = 0.2\nrotor_radius = 0.1\nlayout = 'h'\n", "'layout' must be one of '+', 'x'"),
        ("mass = 1\narm_length = 0.2\nrotor_radius = 0.1\nmax_thrust = 6\nmin_thrust = 6\n", "below max_thrust"),
        (
            "mass = 1\narm_length = 0.2\nrotor_radius = 0.1\nmotor_ta = 0.05\n",
            "unknown key 'motor_ta'; did you mean 'motor_tau'?",
        ),
        (
            "mass = 1\narm_length = 0.2\nrotor_radius = 0.1\nkf = 3.0\n",
            "unknown key 'kf'; the {n} allowed keys are listed in docs/vehicles.md",
        ),
        ("mass = [", "cannot read the vehicle file"),
    ],
)
def test_bad_vehicle_file(tmp_path, text: str, expected: str) -> None:  # noqa: ANN001
    """Issue 47 item 4: an unknown key refused with a "did you mean", a missing key called missing, and
    (item 9) every message one line naming the file once."""
    p = tmp_path / "bad.toml"
    p.write_text(text)
    with pytest.raises(UserError) as e:
        load_vehicle(p)
    msg = _one_line(e, p)
    expected = expected.replace("{n}", str(len(KEYS)))
    assert msg.startswith(expected) or expected in msg, msg
    assert len(msg) < 200, msg


def test_every_key_is_in_the_docs_table() -> None:
    """docs/vehicles.md's table ("The vehicle file") lists every key of KEYS, with its unit and need."""
    doc = (ROOT / "docs" / "vehicles.md").read_text()
    section = doc[doc.index("## The vehicle file") : doc.index("### Gains")]
    rows = {m[0]: (m[1].strip(), m[2].strip()) for m in re.findall(r"^\| `(\w+)` \|([^|]*)\|([^|]*)\|", section, re.M)}
    assert set(rows) == set(KEYS), set(rows) ^ set(KEYS)
    for key, spec in KEYS.items():
        assert rows[key] == (spec.unit, spec.need), key


def _crazyflie_text() -> str:
    return (_HERE / "crazyflie21.toml").read_text()


def _with_mass(text: str, mass: float) -> str:
    return re.sub(r"^mass = [0-9.]+", f"mass = {mass!r}", text, count=1, flags=re.M)


def test_a_vehicle_that_cannot_hover_with_margin_is_refused(tmp_path) -> None:  # noqa: ANN001
    """Issue 47 item 3: the Crazyflie's file with mass = 0.067 kg (its rotors give less than its weight) is
    refused in one line naming the figure 4·f_max / (m·g), computed here from the file's own numbers."""
    text = _crazyflie_text()
    f_max = float(re.search(r"^max_thrust = ([0-9.]+)", text, re.M)[1])
    p = tmp_path / "cf_heavy.toml"
    p.write_text(_with_mass(text, 0.067))
    with pytest.raises(UserError) as e:
        load_vehicle(p)
    msg = _one_line(e, p)
    tw = 4 * f_max / (0.067 * 9.81)
    assert tw < 1.0  # it cannot even lift off
    assert msg.startswith(f"thrust-to-weight {tw:.2f} ") and "below the minimum 1.4" in msg, msg
    # either side of the minimum: the mass that gives exactly 1.4, 1 % heavier and 1 % lighter
    m14 = 4 * f_max / (1.4 * 9.81)
    p.write_text(_with_mass(text, m14 * 1.01))
    with pytest.raises(UserError, match="thrust-to-weight 1.39 .* is below the minimum 1.4"):
        load_vehicle(p)
    p.write_text(_with_mass(text, m14 * 0.99))
    assert load_vehicle(p).mass == pytest.approx(m14 * 0.99)
    assert MIN_THRUST_TO_WEIGHT == 1.4  # the figure docs/vehicles.md reasons ("Thrust to weight")


@pytest.mark.parametrize("name", ["paper", "crazyflie21"])
def test_the_bundled_vehicles_have_the_margin(name: str) -> None:
    """The figures of docs/vehicles.md, "Thrust to weight": 4·f_max / (m·g) from each file, typed-in g."""
    text = (_HERE / f"{name}.toml").read_text()
    m = float(re.search(r"^mass = ([0-9.]+)", text, re.M)[1])
    f_max = float(re.search(r"^max_thrust = ([0-9.]+)", text, re.M)[1])
    tw = 4 * f_max / (m * 9.81)
    assert tw >= 1.4
    assert load_vehicle(name).mass == m
    doc = (ROOT / "docs" / "vehicles.md").read_text()
    assert f"= {tw:.2f}" in doc[doc.index("### Thrust to weight") :], (name, tw)


def test_gains_by_bundled_name_or_by_path_relative_to_the_vehicle_file(tmp_path, monkeypatch) -> None:  # noqa: ANN001
    """A bundled gains name is the package's file; a relative path is read from the vehicle file's own
    folder, whatever the working directory; a missing one is one line naming the path looked at."""
    bundled_gains = ROOT / "scenarios" / "gains" / "crazyflie21_fpa_seed0.toml"
    # the bundled Crazyflie's file copied elsewhere and changed still finds its gains
    copy = tmp_path / "copied" / "my_cf.toml"
    copy.parent.mkdir()
    copy.write_text(_with_mass(_crazyflie_text(), 0.030))
    assert load_vehicle(copy).gains_file == bundled_gains.resolve()
    # a relative path: from the vehicle file's folder, not the working directory
    base = "mass = 1\narm_length = 0.2\nrotor_radius = 0.1\n"
    (tmp_path / "v" / "g").mkdir(parents=True)
    (tmp_path / "v" / "g" / "mine.toml").write_text(bundled_gains.read_text())
    v = tmp_path / "v" / "quad.toml"
    v.write_text(base + 'gains = "g/mine.toml"\n')
    monkeypatch.chdir(tmp_path)
    assert load_vehicle(v).gains_file == (tmp_path / "v" / "g" / "mine.toml").resolve()
    v.write_text(base + f'gains = "{bundled_gains}"\n')  # absolute
    assert load_vehicle(v).gains_file == bundled_gains.resolve()
    # absent: the path looked at, resolved
    v.write_text(base + 'gains = "../scenarios/gains/crazyflie21_fpa_seed0.toml"\n')
    with pytest.raises(UserError) as e:
        load_vehicle(v)
    looked = (tmp_path / "scenarios" / "gains" / "crazyflie21_fpa_seed0.toml").resolve()
    assert f"vehicle key 'gains': no gains file at {looked} " in _one_line(e, v)
    v.write_text(base + 'gains = "crazyflie21_fpa_seed9"\n')
    with pytest.raises(UserError) as e:
        load_vehicle(v)
    assert "no bundled gains named 'crazyflie21_fpa_seed9' (bundled: crazyflie21_fpa_seed0" in _one_line(e, v)


def test_unknown_vehicle() -> None:
    with pytest.raises(UserError, match="unknown vehicle"):
        load_vehicle("no_such_vehicle")


# ----------------------------------------------------------------------------- vehicle -> QuadParams
# The physics checks below compute the expected values here (rigid-body equations, the rotor
# torques written out); swarm_mj's mixing is what is under test.
import mujoco  # noqa: E402
import numpy as np  # noqa: E402

from swarm_mj.physics.aero.ground import REST_HEIGHT, SKID_HALF  # noqa: E402
from swarm_mj.physics.mixing import MIX_T, UNMIX_T  # noqa: E402
from swarm_mj.physics.sim import Sim  # noqa: E402
from swarm_mj.physics.world import build_world  # noqa: E402
from swarm_mj.scenario import START_CLEARANCE_M, load_scenario, parse_scenario  # noqa: E402

CF = load_vehicle("crazyflie21")
CFP = CF.params()


def test_paper_vehicle_file_gives_table1_params_exactly() -> None:
    """paper.toml flies the same QuadParams as a scenario without [vehicle] (Table 1, typed in here)."""
    p = load_vehicle("paper").params()
    assert p == DEFAULT_PARAMS
    assert (p.m, p.Ix, p.Iy, p.Iz, p.L) == (0.486, 0.0038, 0.0038, 0.0071, 0.25)
    assert (p.Kx, p.Ky, p.Kz, p.f_max, p.rotor_radius) == (0.0056, 0.0056, 0.0064, 4.5, 0.09)
    assert p.yaw_coefficient is None and p.mix_t is MIX_T and p.unmix_t is UNMIX_T  # yaw torque L·U4
    assert p.size_scale == 1.0 and p.contact_radius == 0.25


def test_crazyflie_params_follow_its_file() -> None:
    assert (CFP.m, CFP.L, CFP.rotor_radius) == (CF.mass, CF.arm_length, CF.rotor_radius)
    assert [CFP.Ix, CFP.Iy, CFP.Iz] == CF.extra["inertia"]
    assert CFP.f_max == CF.extra["max_thrust"] and CFP.yaw_coefficient == CF.extra["yaw_torque_coefficient"]
    # the contact disc reaches the rotor tips
    assert CFP.contact_radius == pytest.approx(CF.arm_length + CF.rotor_radius, abs=1e-12)
    # can it fly? 4·f_max above its weight
    assert 4 * CFP.f_max > CFP.m * CFP.g


# The Crazyflie's mixing, rotor torques and airframe values: tests/unit/test_crazyflie_airframe.py.


def _geom(world, name: str) -> int:  # noqa: ANN001
    return mujoco.mj_name2id(world.model, mujoco.mjtObj.mjOBJ_GEOM, name)


def _site(world, name: str) -> int:  # noqa: ANN001
    return mujoco.mj_name2id(world.model, mujoco.mjtObj.mjOBJ_SITE, name)


@pytest.mark.parametrize("vehicle", ["paper", "crazyflie21"])
def test_geometry_scales_with_the_arm(vehicle: str) -> None:
    v = load_vehicle(vehicle)
    p = v.params()
    s = v.arm_length / 0.25
    w = build_world(1, params=p, ground=True)
    m = w.model
    c = 0.5**0.5  # the rotor centres / L of each layout, typed in (docs/vehicles.md, "Rotor layout")
    dirs = {"+": [(0, -1), (1, 0), (0, 1), (-1, 0)], "x": [(c, -c), (-c, -c), (-c, c), (c, c)]}
    for k, (x, y) in enumerate(dirs[v.extra.get("layout", "+")], start=1):
        sid = _site(w, f"leader/rotor{k}")
        np.testing.assert_allclose(m.site_pos[sid][:2], [x * v.arm_length, y * v.arm_length], atol=1e-15)
        assert m.site_size[sid][0] == pytest.approx(v.rotor_radius)
    disc = _geom(w, "leader/rotor_plane")
    assert m.geom_size[disc][0] == pytest.approx(v.extra.get("collision_radius", v.arm_length))
    assert m.geom_size[_geom(w, "leader/arm_x")][0] == pytest.approx(v.arm_length)
    assert m.geom_size[_geom(w, "leader/skid")][0] == pytest.approx(SKID_HALF * s)


def test_crazyflie_rests_on_its_scaled_landing_gear() -> None:
    """On a solid floor a Crazyflie placed at the scaled rest height stays there (its skid carries it)."""
    h = REST_HEIGHT * CFP.size_scale
    sim = Sim(build_world(1, positions=[[0.0, 0.0, h]], params=CFP, ground=True))
    U = np.array([[0.5 * CFP.m * 9.81, 0.0, 0.0, 0.0]])  # half its weight: it must sit on the gear
    for _ in range(50):
        sim.step(U)
    assert sim.pos[0, 2] == pytest.approx(h, abs=1e-3)
    assert h < 0.02  # a 9-cm drone's gear, not the paper drone's 6.6 cm


@pytest.mark.parametrize(("gap", "touch"), [(-0.003, True), (0.003, False)])
def test_two_crazyflies_touch_at_two_rotor_spans(gap: float, touch: bool) -> None:
    d = 2 * (0.046 + 0.0231) + gap
    sim = Sim(build_world(2, positions=[[0.0, 0.0, 1.0], [d, 0.0, 1.0]], params=CFP))
    sim.step(np.tile([CFP.m * 9.81, 0.0, 0.0, 0.0], (2, 1)))
    assert (sim.data.ncon > 0) == touch


# ----------------------------------------------------------------------------- [vehicle] in scenarios
BASE = {"duration": 2.0, "leader": {"trajectory": "hover", "params": {"position": [0.0, 0.0, 1.0]}}}


def test_scenario_without_vehicle_is_the_paper() -> None:
    sc = parse_scenario(dict(BASE))
    assert sc.params is DEFAULT_PARAMS and sc.vehicle == "paper" and sc.start_clearance == START_CLEARANCE_M


def test_scenario_names_a_vehicle_by_name_or_file(tmp_path) -> None:  # noqa: ANN001
    sc = parse_scenario({**BASE, "vehicle": {"model": "crazyflie21"}})
    assert sc.params == CFP
    f = tmp_path / "v.toml"
    f.write_text(
        "mass = 1\narm_length = 0.2\nrotor_radius = 0.1\ninertia = [0.01, 0.01, 0.02]\n"
        "drag = [0, 0, 0]\nmax_thrust = 6\nyaw_torque_coefficient = 0.015\n"
    )
    sc = parse_scenario({**BASE, "vehicle": {"model": "v.toml"}}, str(tmp_path / "s.toml"))
    assert (sc.params.m, sc.params.L, sc.params.yaw_coefficient) == (1.0, 0.2, 0.015)


@pytest.mark.parametrize(
    ("table", "needle"),
    [
        ({"model": "no_such"}, "vehicle.model: unknown vehicle 'no_such'"),
        ({"model": 3}, "vehicle.model"),
        ({"modle": "paper"}, "unknown key"),
        ("crazyflie21", "vehicle: must be a table"),
    ],
)
def test_bad_vehicle_table(table, needle: str) -> None:  # noqa: ANN001
    with pytest.raises(UserError, match=needle):
        parse_scenario({**BASE, "vehicle": table}, "s.toml")


@pytest.mark.parametrize(
    ("extra", "needle"),
    [
        ("drag = [0, 0, 0]\nmax_thrust = 6\n", "missing key 'inertia' \\(kg·m²\\): needed to fly it"),
        ("inertia = [0.01, 0, 0.02]\ndrag = [0, 0, 0]\nmax_thrust = 6\n", "'inertia' must be 3 positive"),
        ("inertia = [0.01, 0.01, 0.02]\nmax_thrust = 6\n", "missing key 'drag' \\(N·s/m\\): needed to fly it"),
        ("inertia = [0.01, 0.01, 0.02]\ndrag = [0, 0, 0]\n", "missing key 'max_thrust' \\(N\\): needed to fly it"),
        (
            "inertia = [0.01, 0.01, 0.02]\ndrag = [0, 0, 0]\nmax_thrust = 6\nyaw_torque_coefficient = -1\n",
            "'yaw_torque_coefficient'",
        ),
    ],
)
def test_vehicle_file_missing_what_flying_needs(tmp_path, extra: str, needle: str) -> None:  # noqa: ANN001
    f = tmp_path / "v.toml"
    f.write_text("mass = 1\narm_length = 0.2\nrotor_radius = 0.1\n" + extra)
    with pytest.raises(UserError, match=needle) as e:
        parse_scenario({**BASE, "vehicle": {"model": str(f)}}, "s.toml")
    assert str(e.value).count(str(f)) == 1 and "\n" not in str(e.value)  # the vehicle file, named once


def test_start_spacing_scales_with_the_vehicle() -> None:
    """Two starts 0.3 m apart: fine for Crazyflies (rotor spans 6.9 cm), refused for the paper's drone."""
    starts = {"followers": {"start": [[0.3, 0.0, 0.0]]}}
    parse_scenario({**BASE, **starts, "vehicle": {"model": "crazyflie21"}})
    with pytest.raises(UserError, match="start 0.3 m apart"):
        parse_scenario({**BASE, **starts})


def test_bundled_crazyflie_scenarios_fly_a_crazyflie() -> None:
    from swarm_mj.scenario import bundled_scenarios

    names = [n for n in bundled_scenarios() if n.startswith("crazyflie_")]
    assert len(names) >= 2
    for n in names:
        assert load_scenario(n).params == CFP


def test_the_vehicles_rotor_lag_is_the_lag_of_a_preset_with_lag() -> None:
    from swarm_mj.physics.aero.presets import REALISTIC_MOTOR_TAU, with_aero

    cf = {**BASE, "vehicle": {"model": "crazyflie21"}}
    assert parse_scenario({**cf, "aero": {"model": "realistic"}}).aero.motor_tau == CF.motor_tau
    assert parse_scenario({**cf, "aero": {"model": "realistic", "motor_tau": 0.02}}).aero.motor_tau == 0.02
    assert parse_scenario(cf).aero.motor_tau == 0.0  # the paper's physics: ideal rotors whatever the vehicle
    assert with_aero(parse_scenario(cf), "realistic").aero.motor_tau == CF.motor_tau  # --aero realistic
    assert with_aero(parse_scenario(dict(BASE)), "realistic").aero.motor_tau == REALISTIC_MOTOR_TAU


def test_vehicle_gains_file() -> None:
    g = CF.gains_file
    assert g is not None and g.is_file() and g.name == "crazyflie21_fpa_seed0.toml"
    assert load_vehicle("paper").gains_file is None


def test_stress_flies_the_vehicle_and_its_gains() -> None:
    from swarm_mj.experiments.stress import StressCase, stress_data, stress_scenario

    case = StressCase("layers", 3, 2, 3.0, 0.6, 1.0, vehicle="crazyflie21", gains=str(CF.gains_file))
    d = stress_data(case)
    assert d["vehicle"] == {"model": "crazyflie21"} and d["controller"] == {"gains": str(CF.gains_file)}
    sc = stress_scenario(case)
    assert sc.params == CFP and sc.gains_source == str(CF.gains_file)
    plain = stress_data(StressCase("layers", 3, 2, 3.0, 0.6, 1.0))
    assert "vehicle" not in plain and "controller" not in plain  # the paper's stress scenario as before


def test_auto_mixer_is_the_vehicles_where_its_file_names_one(tmp_path) -> None:  # noqa: ANN001
    """docs/vehicles.md, "Crazyflie scenarios": ``mixer = "auto"`` is the vehicle file's ``mixer`` (the
    Crazyflie's gives up yaw first, "Mixer") under either physics; without one, attitude priority where the
    rotors lag and the paper's clipping otherwise; a scenario's own mixer wins."""
    assert CF.mixer == "yaw_last" and load_vehicle("paper").mixer is None
    cf = parse_scenario({**BASE, "vehicle": {"model": "crazyflie21"}})
    assert cf.mixer == "auto" and cf.aero.motor_tau == 0 and cf.attitude_priority_on and cf.mixer_flown == "yaw_last"
    assert not parse_scenario(
        {**BASE, "vehicle": {"model": "crazyflie21"}, "controller": {"mixer": "clip"}}
    ).attitude_priority_on
    paper = parse_scenario(dict(BASE))
    assert not paper.attitude_priority_on and paper.mixer_flown == "clip"
    assert parse_scenario({**BASE, "aero": {"model": "realistic"}}).mixer_flown == "attitude_priority"
    f = tmp_path / "v.toml"
    f.write_text('mass = 1\narm_length = 0.2\nrotor_radius = 0.1\nmixer = "fancy"\n')
    with pytest.raises(UserError, match="vehicle key 'mixer' must be one of 'clip', 'attitude_priority'"):
        _ = load_vehicle(f).mixer
