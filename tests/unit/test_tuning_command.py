"""The tuner's command is the command of every run (docs/design.md, "The control period, written once"):
``BatchEvaluator`` flies its copies with ``period.command``'s Python body on records of its m copies. Checked
here against the stages composed by hand as the evaluator composed them before (the lag prediction,
``Backstepping.compute`` with the copies' gains (m, 12), ``attitude_priority`` where the rotors lag, the
vehicle's ``yaw_last`` where its file names it), bit for bit from the first period, on the paper's drone and on
a vehicle with rotor lag."""

from __future__ import annotations

import numpy as np
import pytest

from swarm_mj.control.backstepping import Backstepping
from swarm_mj.control.lag import AttitudePredictor
from swarm_mj.paper import TABLE4_GAINS
from swarm_mj.physics.mixing import attitude_priority, yaw_last
from swarm_mj.physics.observation import attitude_kernel
from swarm_mj.tuning import BatchEvaluator, StepCostSettings
from swarm_mj.vehicles import load_vehicle

SCALES = (0.8, 1.0, 1.25)  # one gain set per copy: the copies' commands differ from the first period


def _settings(vehicle: str) -> StepCostSettings:
    v = load_vehicle(vehicle)
    return StepCostSettings(
        t_sim=0.6, bars=None, params=v.params(), motor_tau=float(v.motor_tau or 0.0), mixer=v.mixer or "auto"
    )


def _flown(settings: StepCostSettings, gains: np.ndarray) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """(qpos, qvel, U) of every period the evaluator flies: the state its command read and the command."""
    ev = BatchEvaluator(len(gains), settings)
    (sim,) = ev.sims
    seen = []
    step = sim.step

    def recording_step(U: np.ndarray, *args: object) -> None:
        seen.append((sim.qpos.copy(), sim.qvel.copy(), np.array(U)))
        step(U, *args)

    sim.step = recording_step  # type: ignore[method-assign]
    cost = ev.evaluate(gains)
    assert np.isfinite(cost).all() and len(seen) == settings.n_samples
    return seen


@pytest.mark.parametrize("vehicle", ["paper", "crazyflie21"])
def test_the_evaluators_command_equals_the_stages_composed_by_hand(vehicle):
    s = _settings(vehicle)
    p, T, tau = s.params, s.control_period, s.motor_tau
    assert (tau > 0) == (vehicle == "crazyflie21")
    mixer = yaw_last if s.mixer_flown == "yaw_last" else attitude_priority
    assert (s.mixer_flown == "yaw_last") == (vehicle == "crazyflie21")
    gains = np.array([TABLE4_GAINS * c for c in SCALES])  # (m, 12)
    m = len(gains)
    ctl = Backstepping(m, gains, params=p, control_period=T, attitude_map=s.attitude_map)
    pred = AttitudePredictor(m, tau + T, tau, T) if tau > 0 else None
    pos_d, zero3 = np.tile(s.target, (m, 1)), np.zeros((m, 3))
    yaw_d = np.full(m, np.deg2rad(s.yaw_deg))
    mixed = 0
    for k, (qpos, qvel, U) in enumerate(_flown(s, gains)):
        rpy, rate = attitude_kernel(qpos, qvel)
        pos, vel, omega = qpos[:, 0:3], qvel[:, 0:3], qvel[:, 3:6]
        if pred is not None:
            rpy, rate, omega = pred(rpy, rate, omega)
        want = ctl.compute(rpy, rate, pos, vel, pos_d, zero3, zero3, yaw_d, omega_body=omega)
        if pred is not None:
            raw, want = want, mixer(want, p.f_min, p.f_max, p.unmix_t, p.mix_t)
            mixed += not np.array_equal(raw, want)
        np.testing.assert_array_equal(U, want, err_msg=f"{vehicle}, period {k}")
        assert len({tuple(u) for u in U}) == m  # each copy flies its own gains
    if tau > 0:  # the mixer moved U1 in some periods: the comparison covers it
        assert mixed > 0
