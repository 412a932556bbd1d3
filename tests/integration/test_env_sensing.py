"""The environments under a sensing model (issue 49, "The environments"): ``sensing=`` on SwarmEnv, SwarmGymEnv,
SwarmParallelEnv and SwarmVectorEnv; the observation carries each drone's own view, and a PettingZoo agent's
observation is its own view, with no other drone's true state in it. ``perfect`` keeps today's observations.

(SwarmVectorEnv == SyncVectorEnv over SwarmGymEnv under ``mocap``, auto-resets included, is in
tests/integration/test_vector_env.py, beside the same check for the realistic physics.)
"""

from __future__ import annotations

import numpy as np
import pytest
from gymnasium import spaces

from swarm_mj.env import SwarmEnv
from swarm_mj.errors import UserError
from swarm_mj.wrappers import SwarmGymEnv, SwarmParallelEnv, SwarmVectorEnv

#: SwarmEnv's observation keys before issue 49 (its docstring's table), in their order.
TODAY_KEYS = (
    "time", "pos", "vel", "quat", "rpy", "rpy_rate", "body_rates", "setpoint", "setpoint_vel", "setpoint_acc",
    "setpoint_yaw", "leader_pos", "neighbours", "neighbour_mask", "wind_force",
)  # fmt: skip
#: A PettingZoo agent's keys before issue 49: the shared ones, then its rows (the module docstring's table).
TODAY_AGENT_KEYS = (
    "time", "leader_pos", "pos", "vel", "quat", "rpy", "rpy_rate", "body_rates", "setpoint", "setpoint_vel",
    "setpoint_acc", "setpoint_yaw", "neighbours", "neighbour_mask", "wind_force",
)  # fmt: skip
#: Keys an agent does not get under a sensing model: another drone's true state, or made from the leader's.
NOT_OWN = ("pos", "vel", "setpoint", "setpoint_vel", "leader_pos")
#: mocap's position noise σ (m, per axis; docs/sensing.md, DMPC's experiments).
MOCAP_SIGMA_M = 0.0023


def view_shapes(n: int) -> dict[str, tuple[int, ...]]:
    """The view keys and their shapes as issue 49 states them (row i: what drone i believes)."""
    return {
        "view_pos": (n, n, 3), "view_vel": (n, n, 3), "view_mask": (n, n), "view_age": (n, n),
        "view_setpoint": (n, n, 3), "view_setpoint_vel": (n, n, 3), "own_pos": (n, 3), "own_vel": (n, 3),
    }  # fmt: skip


def hover(env: SwarmEnv) -> np.ndarray:
    p = env.params
    return np.tile([p.m * p.g, 0.0, 0.0, 0.0], (env.n, 1))


def test_spec_and_gym_space_hold_the_view_under_mocap():
    env = SwarmEnv("circle", sensing="mocap")
    n = env.n
    spec = env.observation_spec()
    assert tuple(spec)[: len(TODAY_KEYS)] == TODAY_KEYS
    extra = {key: s.shape for key, s in spec.items() if key not in TODAY_KEYS}
    assert extra == view_shapes(n)
    assert spec["view_age"].minimum == 0.0 and spec["view_age"].maximum == np.inf
    assert spec["view_mask"].minimum == 0.0 and spec["view_mask"].maximum == 1.0
    ts = env.reset(seed=1)
    assert np.isinf(ts.observation["view_age"]).all()  # nothing held before the first delivery
    for _ in range(10):
        ts = env.step(hover(env))
    assert set(ts.observation) == set(spec)
    for key, s in spec.items():
        value = np.asarray(ts.observation[key])
        assert value.dtype == np.float64 and value.shape == s.shape, key
        s.validate(value)
    assert np.isfinite(ts.observation["view_age"]).any() and np.isinf(ts.observation["view_age"]).any()

    gym = SwarmGymEnv("circle", sensing="mocap")
    space = gym.observation_space
    assert set(space.spaces) == set(spec)
    assert (space["view_age"].low == 0).all() and (space["view_age"].high == np.inf).all()
    assert (space["view_mask"].low == 0).all() and (space["view_mask"].high == 1).all()
    obs, _ = gym.reset(seed=1)
    for _ in range(10):
        obs = gym.step(hover(env))[0]
    assert space.contains(obs)
    flat = SwarmGymEnv("circle", sensing="mocap", flatten=True)
    assert flat.observation_space.shape == (sum(int(np.prod(s.shape)) for s in spec.values()),)


def test_perfect_keeps_todays_spec_spaces_and_observations():
    plain, perfect = SwarmEnv("circle"), SwarmEnv("circle", sensing="perfect")
    assert perfect.sensing is None
    assert tuple(perfect.observation_spec()) == TODAY_KEYS
    assert {k: s.shape for k, s in perfect.observation_spec().items()} == {
        k: s.shape for k, s in plain.observation_spec().items()
    }
    assert SwarmGymEnv("circle", sensing="perfect").observation_space == SwarmGymEnv("circle").observation_space
    a, b = SwarmParallelEnv("circle", sensing="perfect"), SwarmParallelEnv("circle")
    assert a.observation_space("follower1") == b.observation_space("follower1")
    oa, _ = a.reset(seed=4)
    ob, _ = b.reset(seed=4)
    rng = np.random.default_rng(0)
    for k in range(12):
        u = hover(a.env) + 0.2 * rng.standard_normal((a.env.n, 4))
        for i, name in enumerate(a.possible_agents):
            assert tuple(oa[name]) == tuple(ob[name]) == TODAY_AGENT_KEYS
            full = a.env.observation
            for key in TODAY_AGENT_KEYS:
                np.testing.assert_array_equal(oa[name][key], ob[name][key], err_msg=f"{key} step {k}")
                want = full[key] if key in ("time", "leader_pos") else full[key][i]
                np.testing.assert_array_equal(oa[name][key], want, err_msg=f"{key} step {k}")
        np.testing.assert_array_equal(a.state(), b.state())
        oa = a.step({name: u[i] for i, name in enumerate(a.possible_agents)})[0]
        ob = b.step({name: u[i] for i, name in enumerate(b.possible_agents)})[0]


def test_pettingzoo_agent_observes_its_own_view_not_the_truth():
    """Under mocap, agent i's observation is row i of the view: no other drone's true position (nor its true
    position relative to i), the view's values where the truth differs by the channel's noise."""
    pz = SwarmParallelEnv("circle", sensing="mocap")
    env, n = pz.env, pz.env.n
    obs, _ = pz.reset(seed=2)
    for _ in range(40):  # hovering: at rest, so the latency adds nothing to the error
        obs = pz.step({name: row for name, row in zip(pz.possible_agents, hover(env), strict=True)})[0]
    full = env.observation  # SwarmEnv's: the truth and every drone's view
    truth = full["pos"]
    assert np.abs(full["vel"]).max() < 1e-9
    for i, name in enumerate(pz.possible_agents):
        o = obs[name]
        assert pz.observation_space(name).contains(o)
        assert not set(NOT_OWN) & set(o)
        for key in view_shapes(n):
            np.testing.assert_array_equal(o[key], full[key][i], err_msg=key)
        np.testing.assert_array_equal(o["own_pos"], o["view_pos"][i])
        others = [j for j in range(n) if j != i]
        held = o["view_mask"].astype(bool)
        assert held[others].all() and not held[i]  # all in range (range_m inf); 40 periods: every pair delivered
        err = o["view_pos"][others] - truth[others]
        assert (err != 0).all(), name  # the view's, not the truth
        assert np.abs(err).max() < 6 * MOCAP_SIGMA_M  # a view of the truth: within the fixes' noise
        near = o["neighbour_mask"].astype(bool)
        np.testing.assert_array_equal(o["neighbours"][near], o["view_pos"][near] - o["own_pos"])
        assert (o["neighbours"][~near] == 0).all()
        # no 3-vector in the observation is another drone's true position or its true offset from this one
        # (skipped where it is zero, e.g. the leader at the origin, or equal to the drone's own true position,
        # which mocap gives it without noise: those are in the observation for other reasons)
        vectors = np.concatenate([np.asarray(v).reshape(-1, 3) for v in o.values() if np.shape(v)[-1:] == (3,)])
        for j in others:
            for secret in (truth[j], truth[j] - truth[i]):
                if secret.any() and not (secret == truth[i]).all():
                    assert not (vectors == secret).all(axis=1).any(), (name, j, secret)


def test_vector_env_copies_draw_their_own_noise():
    """Each copy's sensing stage is seeded by its episode seed: two copies with the same seed see the same
    views, another seed other noise; the copy's view is in its observation."""
    envs = SwarmVectorEnv("circle", num_envs=3, sensing="mocap", threads=1)
    envs.reset(seed=[5, 5, 6])
    u = np.tile(hover(SwarmEnv("circle")).reshape(-1), (3, 1))
    for _ in range(10):
        obs = envs.step(u)[0]
    assert set(view_shapes(envs.n)) <= set(obs)
    np.testing.assert_array_equal(obs["view_pos"][0], obs["view_pos"][1])
    held = obs["view_mask"][0].astype(bool) & obs["view_mask"][2].astype(bool)
    assert held.any()
    assert (obs["view_pos"][0][held] != obs["view_pos"][2][held]).all()
    np.testing.assert_array_equal(obs["pos"][0], obs["pos"][2])  # the same flight, other noise
    envs.close()


def test_bad_sensing_is_one_user_error_line():
    for make in (SwarmEnv, SwarmGymEnv, SwarmParallelEnv, SwarmVectorEnv):
        with pytest.raises(UserError, match="bogus") as err:
            make("circle", sensing="bogus")
        assert "\n" not in str(err.value), make.__name__
    ready = SwarmEnv("circle")
    for wrap in (SwarmGymEnv, SwarmParallelEnv):
        with pytest.raises(UserError, match="sensing="):
            wrap(ready, sensing="mocap")
    assert isinstance(SwarmGymEnv(SwarmEnv("circle", sensing="mocap")).observation_space, spaces.Dict)
