"""The run's vehicle gives every size (docs/vehicles.md, "What comes from the vehicle"): the
anti-collision rule's keep-out and size fields (docs/anticollision.md, "The vehicle's sizes"), the
downwash dip's jet, the simulator's downwash gain (docs/validation.md), the drawn drones."""

from __future__ import annotations

import math
import tomllib

import numpy as np
import pytest

from swarm_mj.control.policy import BacksteppingPolicy, DownwashFeedforward
from swarm_mj.formation.anticollision import make_rule
from swarm_mj.formation.rule_params import SIZE_KEYS, JetAwareParams, LayersParams
from swarm_mj.metrics import in_jet, jet_geometry
from swarm_mj.physics.aero.downwash import S0, SPREAD, DownwashStage, downwash_kernel
from swarm_mj.physics.params import DEFAULT_PARAMS
from swarm_mj.scenario import load_scenario
from swarm_mj.vehicles import _HERE, load_vehicle

CF = load_vehicle("crazyflie21")
CFP = CF.params()
PAPER_SPAN = 0.25 + 0.09  # the paper drone's arm + rotor radius (docs/interpretations.md §1), typed in


# --------------------------------------------------------------------------- the rule's geometry
def test_paper_rule_keeps_its_keep_out_bit_for_bit() -> None:
    """The paper's drone: keep-out 0.34 + 0.01 m, overlap 2·0.35 + 0.02 m, the size fields as written."""
    for name in ("layers", "jet-aware"):
        r = make_rule(name, 6)
        assert r.footprint == 0.25 + 0.09 + 0.01 and r.overlap == 2.0 * (0.25 + 0.09 + 0.01) + 0.02
        assert r.vehicle is DEFAULT_PARAMS
    assert LayersParams().for_vehicle(DEFAULT_PARAMS) == LayersParams()
    assert load_vehicle("paper").params() == DEFAULT_PARAMS  # so paper.toml's runs are the same


def test_crazyflie_rule_keep_out_is_its_rotor_span() -> None:
    """The keep-out radius is the Crazyflie's arm + rotor radius + the margin scaled by its span."""
    k = (CF.arm_length + CF.rotor_radius) / PAPER_SPAN
    for name in ("layers", "jet-aware"):
        r = make_rule(name, 6, vehicle=CFP)
        assert r.footprint == pytest.approx(CF.arm_length + CF.rotor_radius + 0.01 * k, rel=1e-12)
        assert r.overlap == pytest.approx(2.0 * r.footprint + 0.02 * k, rel=1e-12)
        assert r.overlap < 0.15  # under half the paper drone's 0.72 m
    p = make_rule("layers", 6, vehicle=CFP).params
    for key in SIZE_KEYS:
        assert getattr(p, key) == pytest.approx(getattr(LayersParams(), key) * k, rel=1e-12)


def test_size_fields_are_the_lateral_margins_only() -> None:
    """The scaled fields are the outline's margins and the pass-by margin of a hovering drone; D̄,
    the layers, altitudes, braking margins and the step aside (beyond D̄ + approach_margin from a
    moving leader; more than ``at_start``) are not vehicle sizes (docs/anticollision.md)."""
    assert set(SIZE_KEYS) == {"outline_margin", "overlap_spare", "hover_pass_margin"}
    p = make_rule("jet-aware", 6, vehicle=CFP).params
    keys = ("safety_distance", "hop", "clearance", "floor_clearance", "approach_margin", "arrive", "aside_margin")
    for key in keys:
        assert getattr(p, key) == getattr(JetAwareParams(), key)


def test_a_scenario_override_is_in_metres_as_written() -> None:
    r = make_rule("layers", 6, vehicle=CFP, outline_margin=0.05)
    assert r.footprint == pytest.approx(CF.arm_length + CF.rotor_radius + 0.05, rel=1e-12)


def test_the_policy_builds_the_rule_for_the_scenarios_vehicle() -> None:
    sc = load_scenario("crazyflie_circle")
    pol = BacksteppingPolicy(sc, sc.params)
    assert pol.rule.vehicle == CFP
    assert pol.rule.params == sc.rule_params  # the record the scenario says its rule flies
    assert pol.rule.footprint == pytest.approx(make_rule("layers", 6, vehicle=CFP).footprint, rel=1e-15)


# --------------------------------------------------------------------------- the downwash gain
def _jet_on_lower(gain: float) -> np.ndarray:
    """Force (3,) of an upper Crazyflie's jet on one 0.3 m below and 3 cm aside (the stage's kernel)."""
    st = DownwashStage(rotor_radius=CFP.rotor_radius, gain=gain)
    pos = np.array([[0.0, 0.0, 1.0], [0.03, 0.0, 0.7]])
    quat = np.array([[1.0, 0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]])
    thrust = np.full((2, 4), CFP.m * CFP.g / 4)
    f, tq, af, at = (np.zeros((2, 3)) for _ in range(4))
    downwash_kernel(
        pos, quat, thrust, 2, CFP.L, CFP.rotor_dirs, st.rho, st.rotor_radius, st.half_cda, st.half_cda_body,
        st.rotor_radius, f, tq, af, at,
    )  # fmt: skip
    return f[1]


def test_stage_force_with_gain_is_gain_times_the_force() -> None:
    f1 = _jet_on_lower(1.0)
    assert f1[2] < -1e-4  # pushed down, a measurable force
    for g in (0.5, CFP.downwash_gain, 2.0):
        np.testing.assert_allclose(_jet_on_lower(g), g * f1, rtol=1e-12)


def test_the_gain_in_the_vehicle_file_is_the_simulators_and_the_validations() -> None:
    """crazyflie21.toml's downwash_gain (read here as TOML) is the vehicle's (what ``validate
    downwash`` multiplies the jet by), the QuadParams', the simulator's stage's and the feedforward's."""
    g = tomllib.loads((_HERE / "crazyflie21.toml").read_text())["downwash_gain"]
    assert CF.downwash_gain == g and CFP.downwash_gain == g
    assert DownwashStage.for_vehicle(CFP).gain == g
    ff = DownwashFeedforward(2, CFP)
    plain = DownwashStage(rotor_radius=CFP.rotor_radius)
    assert ff.record().half_cda == pytest.approx(g * plain.half_cda, rel=1e-12)
    assert DEFAULT_PARAMS.downwash_gain == 1.0 and load_vehicle("paper").downwash_gain == 1.0


def test_realistic_crazyflie_sim_flies_the_gain() -> None:
    from swarm_mj.env import SwarmEnv
    from swarm_mj.physics.aero.presets import with_aero

    sim = SwarmEnv(with_aero(load_scenario("crazyflie_circle"), "realistic")).sim
    stage = next(s for s in sim.stages if getattr(s, "name", "") == "downwash")
    assert stage.gain == CF.downwash_gain


# --------------------------------------------------------------------------- the dip metric's jet
def test_dip_jet_geometry_is_the_vehicles() -> None:
    """r0 = 2·l·S·(−s0*) with l = 2L, reach = 12·l, radius = the rotor span (metrics module comment)."""
    for p in (DEFAULT_PARAMS, CFP):
        l = 2.0 * p.L
        jet = jet_geometry(p)
        assert jet["r0"] == pytest.approx(2.0 * l * SPREAD * -S0, rel=1e-12)
        assert jet["reach"] == pytest.approx(12.0 * l, rel=1e-12)
        assert jet["radius"] == pytest.approx(p.L + p.rotor_radius, rel=1e-12)
    assert jet_geometry(DEFAULT_PARAMS)["reach"] == 6.0


def test_a_crazyflie_beside_anothers_jet_is_not_in_it() -> None:
    """0.4 m aside and 0.5 m below: inside the paper drone's jet edge (0.45 + 0.08 + 0.34 m), outside
    the Crazyflie's (0.08 + 0.08 + 0.07 m)."""
    pos = np.array([[[0.0, 0.0, 1.0], [0.4, 0.0, 0.5]]])
    quat = np.tile([1.0, 0.0, 0.0, 0.0], (1, 2, 1))
    assert in_jet(pos, quat, **jet_geometry(DEFAULT_PARAMS))[0, 0, 1]
    assert not in_jet(pos, quat, **jet_geometry(CFP))[0, 0, 1]
    edge = jet_geometry(CFP)
    r_edge = edge["r0"] + edge["spread"] * 0.5 + edge["radius"]
    assert math.isclose(r_edge, 2 * 2 * CF.arm_length * SPREAD * -S0 + 2 * SPREAD * 0.5 + CF.rotor_span)


# --------------------------------------------------------------------------- the recording and the video
def test_the_video_replays_a_crazyflie_run_into_crazyflies() -> None:
    """A Crazyflie run is replayed into drones with its rotor radius (the rotor sites' radius)."""
    import types

    import mujoco

    from swarm_mj.video.encode import _world_of

    log = types.SimpleNamespace(pos=np.array([[[0.0, 0.0, 0.5], [1.0, 0.0, 0.5]]]), names=["leader", "f1"])
    w = _world_of(types.SimpleNamespace(scenario=load_scenario("crazyflie_circle"), log=log), None)
    m = w.model
    radii = [
        m.site_size[i][0]
        for i in range(m.nsite)
        if (mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_SITE, i) or "").split("/")[-1].startswith("rotor")
    ]
    assert len(radii) == 8 and all(r == pytest.approx(CF.rotor_radius, rel=1e-12) for r in radii)


def test_the_recording_draws_the_runs_vehicle() -> None:
    """The drawn rotors sit at the vehicle's arm with its rotor radius; the drawn jet at the rotor
    plane is the jet model's half-width for its motor distance, l·S·(−s0*)."""
    from swarm_mj.output.recording import _drone_shape, _jet_frustum

    _, rotors = _drone_shape(CFP, [0, 0, 0])
    centres = np.asarray(rotors.centers.as_arrow_array().to_pylist())
    halves = np.asarray(rotors.half_sizes.as_arrow_array().to_pylist())
    np.testing.assert_allclose(np.linalg.norm(centres[:, :2], axis=1), CF.arm_length, rtol=1e-6)
    np.testing.assert_allclose(halves[:, :2], CF.rotor_radius, rtol=1e-6)
    top = _jet_frustum(CFP)[0]
    r0 = float(np.linalg.norm(top[0, :2]))
    assert r0 == pytest.approx(2 * CF.arm_length * SPREAD * -S0, rel=1e-9)
