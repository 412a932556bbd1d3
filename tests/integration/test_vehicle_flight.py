"""The Crazyflie 2.1 flown (docs/vehicles.md): the vehicle's tune, its shipped gains and its scenarios."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

from swarm_mj.cli import main as cli_main
from swarm_mj.commands.tune import LAG_SETTLING_FACTOR, lagged_bars
from swarm_mj.control.backstepping import TABLE4_GAINS, load_gains
from swarm_mj.errors import UserError
from swarm_mj.experiments.runner import run
from swarm_mj.physics.aero.presets import parse_aero
from swarm_mj.scenario import load_scenario
from swarm_mj.tuning import StepBars, StepCostSettings, step_check, step_ise
from swarm_mj.vehicles import load_vehicle

REPO = Path(__file__).resolve().parents[2]
CF_GAINS = REPO / "scenarios" / "gains" / "crazyflie21_fpa_seed0.toml"
CF = load_vehicle("crazyflie21")


def _ise_by_hand(log, K: int) -> float:  # noqa: ANN001
    """Eq. (25) over the step x = y = z = 1 m, ψ = 25° from a run's log, written out here."""
    e = np.empty((K, 6))
    e[:, 0:3] = np.array([1.0, 1.0, 1.0]) - log.pos[:K, 0]
    e[:, 3:5] = log.att_d[:K, 0, 0:2] - log.rpy[:K, 0, 0:2]
    dpsi = np.deg2rad(25.0) - log.rpy[:K, 0, 2]
    e[:, 5] = np.arctan2(np.sin(dpsi), np.cos(dpsi))
    return 0.01 * float(np.sum(e**2 @ np.array([3.0, 3.0, 1.0, 2.0, 2.0, 1.0])))


def test_lagged_tune_cost_is_eq25_on_the_runner_loop() -> None:
    """The tune under the vehicle's lag flies what `swarm-mj run` flies: the Crazyflie step with 15-ms
    rotors (no ground), the vehicle's yaw-last mixing and lag compensation, ISE to 1e-9."""
    sc = load_scenario("crazyflie_step").with_overrides(
        aero=parse_aero({"model": "paper", "motor_tau": 0.015}), duration=3.0, gains=TABLE4_GAINS
    )
    assert sc.mixer_flown == CF.mixer == "yaw_last" and sc.lag_horizons == (0.025, 0.015)
    res = run(sc, progress=False)
    assert res.error is None
    settings = StepCostSettings(t_sim=3.0, params=CF.params(), motor_tau=0.015, mixer=CF.mixer)
    assert step_ise(TABLE4_GAINS, settings) == pytest.approx(_ise_by_hand(res.log, settings.n_samples), rel=1e-9)
    # and the lag matters: the same gains without it have another cost
    ideal = StepCostSettings(t_sim=3.0, params=CF.params())
    assert abs(step_ise(TABLE4_GAINS, ideal) - step_ise(TABLE4_GAINS, settings)) > 1e-6


def test_lagged_bars() -> None:
    assert lagged_bars(0.0) == StepBars()  # the paper's tune is unchanged
    b, p = lagged_bars(0.05), StepBars()
    assert b.settling_z_s == pytest.approx(p.settling_z_s + LAG_SETTLING_FACTOR * 0.05)
    assert (b.overshoot_pct, b.max_tilt_deg, b.steady_state_error) == (p.overshoot_pct, p.max_tilt_deg, 1e-3)


@pytest.mark.parametrize("tau", [-0.01, 0.001, float("nan")])
def test_bad_motor_tau_is_a_user_error(tau: float) -> None:
    with pytest.raises(UserError, match="motor-tau"):
        StepCostSettings(motor_tau=tau)


def test_tiny_vehicle_tune_records_vehicle_and_lag(tmp_path, capsys) -> None:  # noqa: ANN001
    out = tmp_path / "g.toml"
    rc = cli_main(
        ["tune", "--vehicle", "crazyflie21", "--population", "4", "--iterations", "1", "--t-sim", "3",
         "--workers", "1", "--seed", "1", "-o", str(out), "--quiet"]
    )  # fmt: skip
    assert rc == 0
    data = tomllib.loads(out.read_text())
    assert data["settings"]["vehicle"] == "crazyflie21" and data["settings"]["motor_tau"] == CF.motor_tau
    assert data["settings"]["mixer"] == CF.mixer  # the vehicle's mixer, as swarm-mj run flies it
    assert data["bars"]["settling_z_s"] == pytest.approx(1.5 + LAG_SETTLING_FACTOR * CF.motor_tau)
    s = StepCostSettings(
        t_sim=3.0, params=CF.params(), motor_tau=CF.motor_tau, bars=lagged_bars(CF.motor_tau), mixer=CF.mixer
    )
    assert step_ise(load_gains(out), s) == pytest.approx(data["ise"], rel=1e-12)


def test_tune_unknown_vehicle_is_one_line(tmp_path, capsys) -> None:  # noqa: ANN001
    out = tmp_path / "g.toml"
    rc = cli_main(["tune", "--vehicle", "no_such_drone", "-o", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "unknown vehicle" in err[0] and not out.exists()


def test_shipped_crazyflie_gains_are_what_the_code_computes() -> None:
    """scenarios/gains/crazyflie21_fpa_seed0.toml was written by `swarm-mj tune --vehicle crazyflie21`;
    its ISEs must be the current cost of its gains, and they meet the lag-scaled bars."""
    data = tomllib.loads(CF_GAINS.read_text())
    s = data["settings"]
    assert (s["vehicle"], s["population"], s["iterations"], s["t_sim"]) == ("crazyflie21", 50, 100, 10.0)
    assert s["motor_tau"] == CF.motor_tau and s["mixer"] == CF.mixer  # tuned under the vehicle's lag and mixer
    settings = StepCostSettings(
        params=CF.params(), motor_tau=s["motor_tau"], bars=lagged_bars(s["motor_tau"]), mixer=s["mixer"]
    )
    gains = load_gains(CF_GAINS)
    assert step_ise(gains, settings) == pytest.approx(data["ise"], rel=1e-9)
    assert step_ise(TABLE4_GAINS, settings) == pytest.approx(data["table4_ise"], rel=1e-9)
    assert step_check(gains, settings).meets_bars and data["meets_bars"] is True


def _flown(name: str) -> dict:
    res = run(name, aero="realistic", progress=False)
    assert res.error is None
    return res.summary


@pytest.mark.parametrize("name", ["crazyflie_hover", "crazyflie_step"])
def test_single_crazyflie_scenarios_fly_clean_under_realistic(name: str) -> None:
    s = _flown(name)
    assert s["aero"]["motor_tau"] == CF.motor_tau  # the vehicle's lag, not the preset's 15 ms
    assert (s["contacts"], s["ground_contacts"], s["crashes"]) == (0, 0, 0)
    lead = s["drones"]["leader"]
    assert lead["rmse_steady"]["z"] < 1e-3  # settled at the set-point
    assert lead["max_rotor_thrust_n"] <= CF.extra["max_thrust"] + 1e-12


@pytest.mark.slow
@pytest.mark.parametrize("name", ["crazyflie_circle", "crazyflie_anti_collision"])
def test_crazyflie_swarms_fly_clean_under_realistic(name: str) -> None:
    s = _flown(name)
    assert (s["contacts"], s["ground_contacts"], s["crashes"]) == (0, 0, 0)
    assert s["min_separation_m"] > 2 * (CF.arm_length + CF.rotor_radius)
    f = s["formation"]
    assert all(t is not None and np.isfinite(t) for t in f["settling_s"]) and f["final_distance_error_m"] < 0.05
