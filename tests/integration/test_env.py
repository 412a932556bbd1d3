"""The swarm as an environment (issue 8): SwarmEnv (dm_env) and its Gymnasium / PettingZoo faces.

Short scenarios only (≤ 2 s simulated); every comparison of trajectories is bit-for-bit.
"""

from __future__ import annotations

import warnings
from dataclasses import replace

import dm_env
import numpy as np
import pytest

from swarm_mj.control.policy import BacksteppingPolicy
from swarm_mj.env import SwarmEnv
from swarm_mj.errors import UserError
from swarm_mj.experiments.runner import run
from swarm_mj.metrics import min_separation, rmse
from swarm_mj.physics.mixing import saturate
from swarm_mj.physics.wind import ALWAYS_ON
from swarm_mj.scenario import load_scenario

SHORT = 1.0  # s


def short(name: str, duration: float = SHORT, **kw):
    return load_scenario(name).with_overrides(duration=duration, **kw)


def windy(duration: float = SHORT):
    """wind_swarm, short, with the wind force on from t = 0 (the paper's schedule starts it at 20 s)."""
    sc = load_scenario("wind_swarm")
    assert sc.wind.enabled
    return sc.with_overrides(duration=duration, wind=replace(sc.wind, schedule=ALWAYS_ON))


def rollout(env: SwarmEnv, actions=None, policy=None, seed=None):
    """Positions (k+1, n, 3) and the time steps of one episode, open loop (actions) or closed loop (policy)."""
    ts = env.reset(seed=seed)
    steps = [ts]
    k = 0
    while not ts.last():
        a = policy(ts.observation) if policy is not None else actions[k]
        ts = env.step(a)
        steps.append(ts)
        k += 1
    return np.stack([s.observation["pos"] for s in steps]), steps


def hover_actions(env: SwarmEnv, seed: int = 0) -> np.ndarray:
    """An open-loop action sequence (K, n, 4): a little above hover, with small random torques."""
    rng = np.random.default_rng(seed)
    p = env.params
    U = np.zeros((env.n_steps, env.n, 4))
    U[..., 0] = 1.1 * p.hover_thrust
    U[..., 1:] = rng.normal(0.0, 0.002, (env.n_steps, env.n, 3))
    return U


# ----------------------------------------------------------------------------- dm_env specs
@pytest.mark.parametrize("mode", ["thrust", "setpoint"])
def test_specs_match_the_arrays(mode):
    sc = windy(0.05)
    env = SwarmEnv(sc, action=mode)
    n = sc.n_drones
    spec = env.observation_spec()
    aspec = env.action_spec()
    assert aspec.shape == ((n, 4) if mode == "thrust" else (n, 3)) and aspec.dtype == np.float64
    assert env.reward_spec().shape == () and env.reward_spec().dtype == np.float64

    ts = env.reset()
    assert ts.step_type == dm_env.StepType.FIRST and ts.reward is None
    policy = BacksteppingPolicy(sc, env.params)
    while True:
        obs = ts.observation
        assert set(obs) == set(spec)
        for key, s in spec.items():
            v = np.asarray(obs[key])
            assert v.shape == s.shape, key
            assert v.dtype == s.dtype, key
            s.validate(obs[key])
        if ts.reward is not None:
            env.reward_spec().validate(ts.reward)
            assert np.isfinite(ts.reward)
        if ts.last():
            break
        a = policy(obs) if mode == "thrust" else obs["setpoint"]
        # shape and dtype only: backstepping may command beyond the bounds, the saturation clips it
        assert a.shape == aspec.shape and a.dtype == aspec.dtype
        ts = env.step(a)
    # the applied U always lies within the thrust action bounds
    f = env.params.f_max
    assert np.all(env.sim.ctrl >= np.array([0, -f, -f, -2 * f]) - 1e-12)
    assert np.all(env.sim.ctrl <= np.array([4 * f, f, f, 2 * f]) + 1e-12)


# ----------------------------------------------------------------------------- same loop as `swarm-mj run`
@pytest.mark.parametrize("name, seed", [("circle", 0), ("windy", 7)])
def test_backstepping_through_env_reproduces_run(name, seed):
    sc = windy() if name == "windy" else load_scenario(name).with_overrides(duration=SHORT)
    res = run(name if name == "circle" else sc, duration=SHORT, seed=seed, progress=False)
    assert res.error is None
    env = SwarmEnv(sc, terminate_on_contact=False, raise_on_divergence=True)
    policy = BacksteppingPolicy(sc, env.params)
    pos, steps = rollout(env, policy=policy, seed=seed)
    slot = np.stack([s.observation["setpoint"] for s in steps])

    assert pos.shape == res.log.pos.shape
    np.testing.assert_array_equal(pos, res.log.pos)  # every step, bit for bit
    np.testing.assert_array_equal(pos[-1], res.log.pos[-1])
    np.testing.assert_array_equal(slot, res.log.slot)
    s = res.summary
    assert s["seed"] == seed and s["sim_time_s"] == steps[-1].observation["time"]
    assert s["contacts"] == env.sim.contact_events
    assert s["min_separation_m"] == min_separation(pos)[0]
    for i, drone in enumerate(env.names[1:], start=1):
        r = rmse(slot[:, i] - pos[:, i])
        assert [s["drones"][drone]["rmse"][ax] for ax in "xyz"] == [float(x) for x in r]


# ----------------------------------------------------------------------------- seeding
def test_reset_with_seed_is_deterministic_and_seeds_differ():
    sc = windy()
    env = SwarmEnv(sc, terminate_on_contact=False)
    U = hover_actions(env)
    a, steps_a = rollout(env, U, seed=3)
    b, steps_b = rollout(env, U, seed=3)  # same instance, reset again
    c, _ = rollout(SwarmEnv(sc, terminate_on_contact=False), U, seed=3)  # fresh instance
    d, _ = rollout(env, U, seed=4)
    assert a[-1, :, 2].min() > 0.1  # airborne: the wind acts on them
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(a, c)
    np.testing.assert_array_equal([s.reward for s in steps_a[1:]], [s.reward for s in steps_b[1:]])
    wind3 = [s.observation["wind_force"] for s in steps_a]
    env.reset(seed=4)
    assert np.abs(env.wind.force - SwarmEnv(sc, seed=3).wind.force).max() > 1e-3  # another wind
    assert np.abs(np.asarray(wind3)).max() > 0.01  # and it is on
    assert np.abs(a - d).max() > 1e-6  # another flight


# ----------------------------------------------------------------------------- actions
def test_out_of_bounds_action_is_saturated_not_nan():
    sc = short("circle", 0.2)
    env = SwarmEnv(sc, terminate_on_contact=False)
    spec = env.action_spec()
    n, K = env.n, env.n_steps
    huge = np.zeros((K, n, 4))
    huge[..., 0] = 1e6  # every rotor asks for far more than f_max
    top = np.zeros((K, n, 4))
    top[..., 0] = spec.maximum[:, 0]  # exactly all rotors at f_max
    a, _ = rollout(env, huge)
    b, _ = rollout(env, top)
    np.testing.assert_array_equal(a, b)  # the saturation clipped 1e6 to 4 f_max

    rng = np.random.default_rng(1)
    ts = env.reset()
    for _ in range(K):
        U = rng.normal(0.0, 1e6, (n, 4))
        ts = env.step(U)
        np.testing.assert_array_equal(env.sim.ctrl, saturate(U, env.params.f_min, env.params.f_max)[0])
        assert np.all(env.sim.ctrl >= spec.minimum - 1e-9) and np.all(env.sim.ctrl <= spec.maximum + 1e-9)
        assert all(np.isfinite(v).all() for v in ts.observation.values())
        if ts.last():
            break


@pytest.mark.parametrize("mode, width", [("thrust", 4), ("setpoint", 3)])
@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_non_finite_action_raises(mode, width, bad):
    env = SwarmEnv(short("circle", 0.1), action=mode)
    a = np.zeros((env.n, width))
    a[2, 1] = bad
    with pytest.raises(UserError, match="NaN or inf"):
        env.step(a)
    with pytest.raises(UserError, match="shape"):
        env.step(np.zeros((env.n, width + 1)))


# ----------------------------------------------------------------------------- episode ends
def test_contact_terminates_the_episode():
    sc = short("anti_collision", 2.0, anti_collision="off")
    env = SwarmEnv(sc, terminate_on_contact=True)
    _, steps = rollout(env, policy=BacksteppingPolicy(sc, env.params))
    last = steps[-1]
    assert last.last() and last.discount == 0.0  # dm_env.termination
    assert len(steps) - 1 < env.n_steps  # before the end
    assert env.sim.contact_events >= 1
    assert last.reward <= -100.0


def test_duration_truncates_the_episode():
    sc = short("anti_collision", 2.0)  # layers rule: no contact
    env = SwarmEnv(sc, terminate_on_contact=True)
    _, steps = rollout(env, policy=BacksteppingPolicy(sc, env.params))
    last = steps[-1]
    assert last.step_type == dm_env.StepType.LAST and last.discount == 1.0  # dm_env.truncation
    assert len(steps) - 1 == env.n_steps
    assert last.observation["time"] == pytest.approx(sc.duration)
    assert all(s.mid() and s.discount == 1.0 for s in steps[1:-1])
    assert env.step(np.zeros((env.n, 4))).first()  # dm_env: a step after LAST restarts


# ----------------------------------------------------------------------------- Gymnasium
def _only_unbounded_box_warnings(caught) -> None:
    """check_env's only complaints may be about the ±inf Box bounds (chosen on purpose)."""
    other = [str(w.message) for w in caught if "infinity" not in str(w.message)]
    assert not other, other


@pytest.mark.parametrize("kw", [{}, {"flatten": True}, {"action": "setpoint"}])
def test_gymnasium_check_env(kw):
    pytest.importorskip("gymnasium", reason="Gymnasium wrapper needs the gym extra")
    from gymnasium.utils.env_checker import check_env

    from swarm_mj.wrappers.gymnasium import SwarmGymEnv

    env = SwarmGymEnv(windy(0.3), **kw)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env, skip_render_check=True)
    _only_unbounded_box_warnings(caught)


def test_gymnasium_wrapper_is_swarm_env():
    gymnasium = pytest.importorskip("gymnasium", reason="Gymnasium wrapper needs the gym extra")
    from swarm_mj.wrappers import SwarmGymEnv as lazy
    from swarm_mj.wrappers.gymnasium import SwarmGymEnv

    assert lazy is SwarmGymEnv
    sc = windy()
    ref_env = SwarmEnv(sc, terminate_on_contact=True)
    ref, _ = rollout(ref_env, policy=BacksteppingPolicy(sc, ref_env.params), seed=5)

    env = gymnasium.make("swarm_mj/Swarm-v0", scenario=sc)
    policy = BacksteppingPolicy(sc, env.unwrapped.env.params)
    obs, info = env.reset(seed=5)
    assert info["wind_seed"] == 5
    pos = [obs["pos"]]
    terminated = truncated = False
    while not (terminated or truncated):
        obs, reward, terminated, truncated, info = env.step(policy(obs))
        pos.append(obs["pos"])
    assert truncated and not terminated and info["time"] == pytest.approx(sc.duration)
    np.testing.assert_array_equal(np.stack(pos), ref)
    with pytest.raises(gymnasium.error.ResetNeeded):
        env.step(env.action_space.sample())


def test_gymnasium_terminates_on_contact():
    pytest.importorskip("gymnasium", reason="Gymnasium wrapper needs the gym extra")
    from swarm_mj.wrappers.gymnasium import SwarmGymEnv

    sc = short("anti_collision", 2.0, anti_collision="off")
    env = SwarmGymEnv(sc)
    policy = BacksteppingPolicy(sc, env.env.params)
    obs, _ = env.reset(seed=0)
    for _ in range(env.env.n_steps):
        obs, reward, terminated, truncated, info = env.step(policy(obs))
        if terminated or truncated:
            break
    assert terminated and not truncated
    assert info["termination"] == "contact" and info["new_contacts"] >= 1
    assert info["time"] < sc.duration


# ----------------------------------------------------------------------------- PettingZoo
@pytest.mark.parametrize("mode", ["thrust", "setpoint"])
def test_pettingzoo_parallel_api(mode):
    pytest.importorskip("pettingzoo", reason="PettingZoo wrapper needs the gym extra")
    from pettingzoo.test import parallel_api_test

    from swarm_mj.wrappers.pettingzoo import SwarmParallelEnv

    env = SwarmParallelEnv(windy(0.3), action=mode)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        parallel_api_test(env, num_cycles=100)
    assert not [str(w.message) for w in caught]


@pytest.mark.filterwarnings("error")
def test_pettingzoo_agents_see_their_own_rows():
    pytest.importorskip("pettingzoo", reason="PettingZoo wrapper needs the gym extra")
    from swarm_mj.wrappers.pettingzoo import SwarmParallelEnv

    sc = windy(0.3)
    env = SwarmParallelEnv(sc)
    ref = SwarmEnv(sc)
    assert env.possible_agents == ["leader"] + [f"follower{k}" for k in range(1, 6)]
    U = hover_actions(ref)
    obs, infos = env.reset(seed=2)
    ts = ref.reset(seed=2)
    for k in range(ref.n_steps):
        for i, agent in enumerate(env.possible_agents):
            assert obs[agent] in env.observation_space(agent)
            full = ts.observation
            for key, value in obs[agent].items():
                assert isinstance(value, np.ndarray) and value.dtype == np.float64, key
                expected = full[key] if key in ("time", "leader_pos") else full[key][i]
                np.testing.assert_array_equal(value, expected, err_msg=f"{agent}.{key}")
            assert set(obs[agent]["neighbours"].shape) == {sc.n_drones, 3}
        obs, rewards, terms, truncs, infos = env.step({a: U[k, i] for i, a in enumerate(env.possible_agents)})
        ts = ref.step(U[k])
        assert set(rewards.values()) == {ts.reward}  # one team reward
    assert all(truncs.values()) and not any(terms.values()) and env.agents == []
    assert env.state().shape == env.state_space.shape
    with pytest.raises(UserError):
        env.step({})
    env.reset(seed=2)
    with pytest.raises(UserError, match="missing"):
        env.step({"leader": np.zeros(4)})
