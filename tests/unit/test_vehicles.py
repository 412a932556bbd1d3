"""Vehicle files (docs/vehicles.md): the bundled ones load, bad files give one clear error."""

from __future__ import annotations

import pytest

from swarm_mj.errors import UserError
from swarm_mj.physics.params import DEFAULT_PARAMS
from swarm_mj.vehicles import bundled, load_vehicle


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
    p.write_text("mass = 1.2\narm_length = 0.2\nrotor_radius = 0.1\nkf = 3.0\n")
    v = load_vehicle(p)
    assert (v.name, v.mass, v.extra) == ("mine", 1.2, {"kf": 3.0})


@pytest.mark.parametrize(
    ("text", "needle"),
    [
        ("arm_length = 0.2\nrotor_radius = 0.1\n", "'mass'"),
        ("mass = -1\narm_length = 0.2\nrotor_radius = 0.1\n", "'mass'"),
        ("mass = 1\narm_length = 'x'\nrotor_radius = 0.1\n", "'arm_length'"),
        ("mass = [", "cannot read"),
    ],
)
def test_bad_vehicle_file(tmp_path, text: str, needle: str) -> None:  # noqa: ANN001
    p = tmp_path / "bad.toml"
    p.write_text(text)
    with pytest.raises(UserError, match=needle):
        load_vehicle(p)


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
        ("drag = [0, 0, 0]\nmax_thrust = 6\n", "'inertia' is needed"),
        ("inertia = [0.01, 0, 0.02]\ndrag = [0, 0, 0]\nmax_thrust = 6\n", "'inertia' must be 3 positive"),
        ("inertia = [0.01, 0.01, 0.02]\nmax_thrust = 6\n", "'drag' is needed"),
        ("inertia = [0.01, 0.01, 0.02]\ndrag = [0, 0, 0]\n", "'max_thrust' is needed"),
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
    assert str(f) in str(e.value)


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
    Crazyflie's firmware desaturates with attitude priority) under either physics; without one, attitude
    priority where the rotors lag and the paper's clipping otherwise; a scenario's own mixer wins."""
    assert CF.mixer == "attitude_priority" and load_vehicle("paper").mixer is None
    cf = parse_scenario({**BASE, "vehicle": {"model": "crazyflie21"}})
    assert cf.mixer == "auto" and cf.aero.motor_tau == 0 and cf.attitude_priority_on
    assert not parse_scenario(
        {**BASE, "vehicle": {"model": "crazyflie21"}, "controller": {"mixer": "clip"}}
    ).attitude_priority_on
    paper = parse_scenario(dict(BASE))
    assert not paper.attitude_priority_on
    assert parse_scenario({**BASE, "aero": {"model": "realistic"}}).attitude_priority_on
    f = tmp_path / "v.toml"
    f.write_text('mass = 1\narm_length = 0.2\nrotor_radius = 0.1\nmixer = "fancy"\n')
    with pytest.raises(UserError, match="vehicle key 'mixer' must be one of clip, attitude_priority"):
        _ = load_vehicle(f).mixer
