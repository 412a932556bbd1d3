"""The built-in policy's command is the chunk driver's command stage (docs/design.md, "The control period,
written once"): ``BacksteppingPolicy.command`` calls ``period.command``'s Python body
(``_jit.python_body``) on the policy's records. Checked here against the stages composed by hand, as the
policy composed them before (the downwash feedforward from m·g then the last U1, the lag prediction,
``Backstepping.compute``, ``attitude_priority`` or the vehicle's ``yaw_last``), bit for bit from the first
period on; the log's input row (``RunLog.observe``) against the observation. Whole runs through both
drivers: tests/integration/test_fast_path.py."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import pytest

from swarm_mj import _jit
from swarm_mj.control.backstepping import Backstepping
from swarm_mj.control.lag import AttitudePredictor
from swarm_mj.control.policy import BacksteppingPolicy, DownwashFeedforward
from swarm_mj.env import Command, Observation, SwarmEnv
from swarm_mj.experiments.runner import RunLog
from swarm_mj.physics.aero.presets import with_aero
from swarm_mj.physics.mixing import attitude_priority, yaw_last
from swarm_mj.pipeline.stepper import StepPeriod
from swarm_mj.scenario import load_scenario

needs_numba = pytest.mark.skipif(not _jit.AVAILABLE, reason="Numba is off (SWARM_MJ_NO_JIT) or not installed")


class ByHand:
    """The command composed stage by stage from the public pieces (the policy's orchestration before it
    called ``period.command``), with its own memories."""

    def __init__(self, policy: BacksteppingPolicy, sc) -> None:
        c = policy.controller
        self.ctl = Backstepping(
            policy.n, c.gains, params=c.params, control_period=c.T, wind_feedforward=c.wind_feedforward,
            attitude_map=c.attitude_map,
        )  # fmt: skip
        lag = sc.lag_horizons
        self.pred = None if policy.predictor is None else AttitudePredictor(policy.n, lag[0], lag[1], sc.control_period)
        self.ff = None if policy.downwash_ff is None else DownwashFeedforward(policy.n, c.params)
        self.priority = policy.attitude_priority
        self.mixer = yaw_last if policy.mixer == "yaw_last" else attitude_priority
        self.last_U1: np.ndarray | None = None

    def __call__(self, obs: dict, cmd: Command) -> np.ndarray:
        p = self.ctl.params
        ext = obs["wind_force"]
        if self.ff is not None:
            thrust = np.full(len(ext), p.m * p.g) if self.last_U1 is None else self.last_U1
            ext = ext + self.ff(obs["pos"], obs["quat"], thrust)
        rpy, rate, body = obs["rpy"], obs["rpy_rate"], obs["body_rates"]
        if self.pred is not None:
            rpy, rate, body = self.pred(rpy, rate, body)
        U = self.ctl.compute(
            rpy, rate, obs["pos"], obs["vel"], cmd.pos_d, cmd.vel_d, cmd.acc_d, obs["setpoint_yaw"],
            wind_force=ext, omega_body=body,
        )  # fmt: skip
        if self.priority:
            U = self.mixer(U, p.f_min, p.f_max, p.unmix_t, p.mix_t)
        self.last_U1 = U[:, 0].copy()
        return U


def _fly(name: str, aero: str | None, periods: int, plain: bool = False):
    sc = with_aero(load_scenario(name).with_overrides(duration=periods * 0.01 + 0.1), aero)
    env = SwarmEnv(sc, terminate_on_contact=False)
    policy = BacksteppingPolicy(sc, env.params)
    hand = ByHand(policy, sc)
    ts = env.reset()
    for k in range(periods):
        obs = ts.observation
        assert isinstance(obs, Observation) and obs.record is env.obs_record
        if plain:  # a dict of the user's: other layouts, read-only; the policy makes its own copies
            obs = {key: (np.array(v, order="F") if isinstance(v, np.ndarray) else v) for key, v in obs.items()}
            for v in obs.values():
                if isinstance(v, np.ndarray):
                    v.flags.writeable = False
        cmd = policy.command(obs)
        U = hand(obs, cmd)
        np.testing.assert_array_equal(cmd.U, U, err_msg=f"period {k}")
        np.testing.assert_array_equal(cmd.att_d, hand.ctl.att_d, err_msg=f"period {k}")
        assert policy.started()
        ts = env.step(cmd)
    return policy


@pytest.mark.parametrize(
    ("name", "aero"),
    [
        ("circle", None),
        ("wind_circle", None),
        ("lemniscate_single", None),
        ("circle", "realistic"),
        ("crazyflie_circle", "realistic"),
    ],
)
def test_the_policy_command_equals_the_stages_composed_by_hand(name, aero):
    policy = _fly(name, aero, 40)
    if aero == "realistic":  # every stage of the command was on: the comparison is not vacuous
        assert policy.downwash_ff is not None and policy.predictor is not None and policy.attitude_priority
        assert policy.mixer == ("yaw_last" if name.startswith("crazyflie") else "attitude_priority")


def test_a_plain_dict_observation_gives_the_same_command():
    _fly("circle", "realistic", 25, plain=True)


def test_reset_starts_the_memories_again():
    sc = with_aero(load_scenario("circle").with_overrides(duration=1.0), "realistic")
    env = SwarmEnv(sc, terminate_on_contact=False)
    policy = BacksteppingPolicy(sc, env.params)
    first = []
    for _ in range(2):
        policy.reset()
        ts = env.reset()
        assert not policy.started()
        cmds = []
        for _ in range(5):
            cmd = policy.command(ts.observation)
            cmds.append(cmd.U)
            ts = env.step(cmd)
        first.append(np.array(cmds))
    np.testing.assert_array_equal(first[0], first[1])  # the same episode twice: the first command from m·g again


class _Rec(NamedTuple):
    a: np.ndarray


@_jit.jit(deferred=True)
def _scale(rec, x):
    return rec.a * x


@_jit.jit(deferred=True)
def _outer(rec, x):
    y = _scale(rec, x)
    return y + 1.0


@needs_numba
def test_python_body_runs_the_orchestration_in_python_and_its_callees_compiled():
    body = _jit.python_body(_outer)
    assert body is not _outer and not hasattr(body, "overloads")  # a plain Python function
    rec = _Rec(np.arange(3.0))
    np.testing.assert_array_equal(body(rec, 2.0), _outer(rec, 2.0))
    callee = body.__globals__["_scale"]
    assert callee is not _scale and not hasattr(callee, "overloads")  # bound at its first call
    np.testing.assert_array_equal(body(_Rec(np.ones(3)), 3.0), np.full(3, 4.0))
    other = _jit.python_body(_outer)
    assert other.__globals__["_scale"] is not callee  # each caller its own bindings


def test_python_body_without_numba_is_the_function(monkeypatch):
    monkeypatch.setattr(_jit, "AVAILABLE", False)
    assert _jit.python_body(_outer) is _outer


def test_the_logs_input_row_is_the_observation_and_the_command():
    """The step-by-step period's last sample (nothing flown) writes the log's input row: the observation,
    the command computed from it, the wind speed and D of that instant."""
    sc = load_scenario("wind_circle").with_overrides(duration=0.2)
    env = SwarmEnv(sc, terminate_on_contact=False)
    policy = BacksteppingPolicy(sc, env.params)
    log = RunLog.allocate(env.names, env.n_steps + 1)
    env.reset()
    o = env.obs_record
    StepPeriod(env, policy, log).sample()
    cmd = BacksteppingPolicy(sc, env.params).command(env.observation)  # another policy, on the same observation
    for series, want in [
        (log.pos, o.pos), (log.vel, o.vel), (log.quat, o.quat), (log.rpy, o.rpy), (log.slot, o.sp),
        (log.pos_d, cmd.pos_d), (log.att_d, cmd.att_d),
    ]:  # fmt: skip
        np.testing.assert_array_equal(series[0], want)
    assert log.t[0] == 0.0 and log.D[0] == env.D[0]
    np.testing.assert_array_equal(log.wind_speed[0], env.wind.speed[0])
    assert np.abs(log.wind_speed[0]).sum() > 0  # (a wind scenario: the row's wind is not a zero by chance)
    assert env.k == 0 and np.isnan(log.U[0]).all()  # nothing flown, no output row
    assert np.isnan(log.pos[1]).all()  # one row written
