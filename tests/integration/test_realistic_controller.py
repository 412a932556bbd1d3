"""The controller under the realistic physics (issue 15, docs/interpretations.md §1–§2): the
rotor-lag compensation (:class:`swarm_mj.control.lag.AttitudePredictor`) and the attitude-priority
mixer are on by default wherever the rotors have lag, off under the paper's physics, and the
compensation is what damps the swarm's attitude ringing (measured in MuJoCo)."""

from __future__ import annotations

import numpy as np
import pytest

from swarm_mj.control.lag import AttitudePredictor
from swarm_mj.control.policy import BacksteppingPolicy
from swarm_mj.experiments.runner import run
from swarm_mj.physics.aero.presets import with_aero
from swarm_mj.scenario import load_scenario


def test_predictor_is_the_first_order_prediction_over_the_delays():
    pred = AttitudePredictor(2, attitude_horizon=0.025, rate_horizon=0.015, control_period=0.01)
    rpy = np.array([[0.1, -0.2, 0.3], [0.0, 0.0, 0.0]])
    rate0 = np.array([[1.0, 2.0, -1.0], [0.0, 0.5, 0.0]])
    body0 = rate0 * 0.9
    r, rr, bb = pred(rpy, rate0, body0)
    np.testing.assert_allclose(r, rpy + 0.025 * rate0)  # rates held on the first call
    np.testing.assert_allclose(rr, rate0)
    np.testing.assert_allclose(bb, body0)
    rate1, body1 = rate0 + 0.2, body0 - 0.1
    r, rr, bb = pred(rpy, rate1, body1)
    np.testing.assert_allclose(r, rpy + 0.025 * rate1)
    np.testing.assert_allclose(rr, rate1 + 0.015 * 0.2 / 0.01)  # η̇ + d_rate·Δη̇/T
    np.testing.assert_allclose(bb, body1 - 0.015 * 0.1 / 0.01)
    pred.reset()
    _, rr, _ = pred(rpy, rate0, body0)
    np.testing.assert_allclose(rr, rate0)


def test_the_controller_changes_only_where_the_rotors_lag():
    paper = load_scenario("circle")
    assert paper.lag_horizons is None and not paper.attitude_priority_on
    pol = BacksteppingPolicy(paper)
    assert pol.predictor is None and not pol.attitude_priority
    real = with_aero(paper, "realistic")
    assert real.lag_horizons == pytest.approx((0.015 + 0.01, 0.015))  # rotor τ + T, τ
    pol = BacksteppingPolicy(real)
    assert pol.predictor is not None and pol.attitude_priority
    assert real.with_overrides(lag_compensation="off").lag_horizons is None


def _tilt_std_after(sc, t0: float) -> tuple[float, dict]:
    res = run(sc, progress=False)
    assert res.error is None, res.summary.get("stopped")
    tilt = np.degrees(res.log.rpy[:, :, :2])
    return float(tilt[res.log.t > t0].std()), res.summary


@pytest.mark.slow
def test_lag_compensation_damps_the_swarms_attitude_ringing():
    # the six-drone circle under realistic physics, 10 s, with the layered rule's crossing figures
    # (``layers`` and the downwash feedforward): after the form-up (t > 6 s)
    # the drones fly their slots on the circle; without the compensation their roll and pitch ring
    # (std 4.6°, up to 43°, docs/interpretations.md §2), with it they hold (0.6°, at most 3.5°)
    sc = load_scenario("circle").with_overrides(
        duration=10.0, anti_collision="layers", anti_collision_params={"downwash_feedforward": True}
    )
    sc = with_aero(sc, "realistic")
    on, s_on = _tilt_std_after(sc, 6.0)
    off, _ = _tilt_std_after(sc.with_overrides(lag_compensation="off"), 6.0)
    assert on < 0.25 * off, (on, off)
    assert on < 2.0
    assert s_on["contacts"] == 0 and s_on["crashes"] == 0


def test_the_summary_says_what_the_physics_and_the_controller_were():
    from swarm_mj.experiments.report_table import format_summary

    sc = with_aero(load_scenario("circle").with_overrides(duration=0.5), "realistic")
    s = run(sc, progress=False).summary
    assert s["controller"] == {"mixer": "attitude_priority", "lag_compensation_s": [pytest.approx(0.025), 0.015]}
    text = format_summary(s, sc)
    assert "physics 'realistic'" in text and "attitude predicted 25 ms ahead" in text
    assert "ground contacts: 0, crashes: 0" in text
    paper = run(load_scenario("circle").with_overrides(duration=0.5), progress=False).summary
    assert paper["controller"] == {"mixer": "clip", "lag_compensation_s": None}
    assert "physics '" not in format_summary(paper, load_scenario("circle"))
