"""SwarmVectorEnv (issue 18): m independent swarms in batched MuJoCo models as a Gymnasium VectorEnv.

The reference for every episode is Gymnasium's own ``SyncVectorEnv`` over m ``SwarmGymEnv`` (one
model per swarm): the vector env must give the same observations, rewards, flags and infos,
bit for bit, including auto-resets (next-step and same-step) and per-copy termination.
Gymnasium 1.x ships no checker for vector envs; the API checks below follow its contract
(batched spaces, ``autoreset_mode`` metadata, info masks, seeding determinism).
"""

from __future__ import annotations

import types
from dataclasses import replace

import numpy as np
import pytest

gymnasium = pytest.importorskip("gymnasium", reason="the vector env needs the gym extra")
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, SyncVectorEnv
from gymnasium.vector.utils import batch_space

from swarm_mj.env import SwarmEnv
from swarm_mj.errors import UserError
from swarm_mj.physics.wind import ALWAYS_ON
from swarm_mj.scenario import RandomStart, load_scenario, random_follower_starts
from swarm_mj.wrappers import SwarmGymEnv, SwarmVectorEnv


def windy(duration: float):
    """wind_swarm (six drones, fixed starts, turbulence seeded per episode) with the wind on from t = 0."""
    sc = load_scenario("wind_swarm")
    return sc.with_overrides(duration=duration, wind=replace(sc.wind, schedule=ALWAYS_ON))


class FlatAction(gymnasium.ActionWrapper):
    """SwarmGymEnv's (n, 4) action as the vector env's flat (4n,)."""

    def __init__(self, env):
        super().__init__(env)
        box = env.action_space
        self.action_space = spaces.Box(box.low.reshape(-1), box.high.reshape(-1), dtype=np.float64)

    def action(self, action):
        return np.asarray(action).reshape(self.env.action_space.shape)


def hover_actions(env, steps: int, rng: np.random.Generator, sd: float = 0.3) -> np.ndarray:
    """(steps, m, 4n) U near hover, different for every copy and step."""
    p = env.params
    hover = np.tile([p.m * p.g, 0.0, 0.0, 0.0], env.n)
    scale = np.tile([1.0, 0.02, 0.02, 0.01], env.n)
    return hover + sd * scale * rng.standard_normal((steps, env.num_envs, 4 * env.n))


def same_info(a: dict, b: dict, keys) -> None:
    for key in keys:
        assert (key in a) == (key in b), key
        if key not in a:
            continue
        np.testing.assert_array_equal(a["_" + key], b["_" + key], err_msg=key)
        mask = a["_" + key]
        np.testing.assert_array_equal(a[key][mask], b[key][mask], err_msg=key)


def compare_with_sync(
    sc,
    m: int,
    steps: int,
    mode: AutoresetMode,
    actions=None,
    seed: int = 7,
    atol: float = 0.0,
    block: int | None = 2,
    aero: str | None = None,
    sensing: str | None = None,
) -> dict:
    """Step SwarmVectorEnv and SyncVectorEnv(SwarmGymEnv) side by side; everything must agree, bit for bit
    (atol = 0) or, where drones touch, to ``atol``: the vector env's contacts come from explicit pairs, the
    single env's from MuJoCo's broad phase, in another order, so the solver sums them in another order.
    ``aero`` and ``sensing`` go to both (None: the scenario's); ``block`` to the vector env (None: its default).
    Returns the counts of terminations, truncations and resets, and ``resets`` (m,): each copy's."""
    ours = SwarmVectorEnv(sc, num_envs=m, flatten=True, autoreset_mode=mode, block=block, aero=aero, sensing=sensing)
    ref = SyncVectorEnv(
        [lambda: FlatAction(SwarmGymEnv(sc, flatten=True, aero=aero, sensing=sensing)) for _ in range(m)],
        autoreset_mode=mode,
    )
    assert ours.single_observation_space == ref.single_observation_space
    assert ours.single_action_space == ref.single_action_space
    o1, i1 = ours.reset(seed=seed)
    o2, i2 = ref.reset(seed=seed)
    np.testing.assert_array_equal(o1, o2)
    np.testing.assert_array_equal(i1["wind_seed"], i2["wind_seed"])
    if actions is None:
        actions = hover_actions(ours, steps, np.random.default_rng(1))
    seen = {"terminated": 0, "truncated": 0, "reset": 0, "resets": np.zeros(m, dtype=np.int64)}
    for k in range(steps):
        r1 = ours.step(actions[k])
        r2 = ref.step(actions[k])
        np.testing.assert_allclose(r1[0], r2[0], rtol=0, atol=atol, err_msg=f"observation, step {k}")
        np.testing.assert_allclose(r1[1], r2[1], rtol=0, atol=atol, err_msg=f"reward, step {k}")
        for j in (2, 3):
            np.testing.assert_array_equal(r1[j], r2[j], err_msg=f"step {k} output {j}")
        same_info(r1[4], r2[4], ("time", "contacts", "new_contacts", "termination", "wind_seed"))
        if "min_separation" in r2[4]:
            mask = r2[4]["_min_separation"]
            np.testing.assert_allclose(r1[4]["min_separation"][mask], r2[4]["min_separation"][mask], rtol=0, atol=atol)
        if mode == AutoresetMode.SAME_STEP and "final_obs" in r2[4]:
            np.testing.assert_array_equal(r1[4]["_final_obs"], r2[4]["_final_obs"])
            for c in np.flatnonzero(r2[4]["_final_obs"]):
                np.testing.assert_array_equal(r1[4]["final_obs"][c], r2[4]["final_obs"][c])
        seen["terminated"] += int(r1[2].sum())
        seen["truncated"] += int(r1[3].sum())
        seen["reset"] += int(r1[4].get("_wind_seed", np.zeros(m, bool)).sum())
        seen["resets"] += r1[4].get("_wind_seed", np.zeros(m, bool))
    ours.close()
    ref.close()
    return seen


# --------------------------------------------------------------------------- the Gymnasium contract


def test_spaces_and_metadata():
    env = SwarmVectorEnv("circle", num_envs=3)
    assert env.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    assert env.observation_space == batch_space(env.single_observation_space, 3)
    assert env.action_space == batch_space(env.single_action_space, 3)
    spec = SwarmEnv("circle").action_spec()
    np.testing.assert_array_equal(env.single_action_space.low, spec.minimum.reshape(-1))
    np.testing.assert_array_equal(env.single_action_space.high, spec.maximum.reshape(-1))
    assert env.single_observation_space == SwarmGymEnv("circle").observation_space
    obs, info = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    assert info["_time"].all() and info["wind_seed"].tolist() == [0, 1, 2]
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
    assert env.observation_space.contains(obs)
    assert reward.shape == (3,) and reward.dtype == np.float64
    assert terminated.dtype == np.bool_ and truncated.dtype == np.bool_ and terminated.shape == (3,)
    flat = SwarmVectorEnv("circle", num_envs=3, flatten=True)
    fobs, _ = flat.reset(seed=0)
    np.testing.assert_array_equal(
        fobs[1], spaces.flatten(env.single_observation_space, {k: v[1] for k, v in env.reset(seed=0)[0].items()})
    )


def test_bad_input():
    env = SwarmVectorEnv("circle", num_envs=2)
    with pytest.raises(gymnasium.error.ResetNeeded):
        env.step(env.action_space.sample())
    env.reset(seed=0)
    with pytest.raises(UserError, match="shape"):
        env.step(np.zeros((3, 24)))
    a = env.action_space.sample()
    a[1, 0] = np.nan
    with pytest.raises(UserError, match="NaN"):
        env.step(a)
    with pytest.raises(UserError):
        SwarmVectorEnv("circle", num_envs=0)
    with pytest.raises(UserError):
        SwarmVectorEnv("circle", num_envs=2, autoreset_mode=AutoresetMode.DISABLED)


def test_returned_data_not_reused_and_deterministic():
    env = SwarmVectorEnv(windy(0.1), num_envs=2)
    a = hover_actions(env, 3, np.random.default_rng(0))
    o1, _ = env.reset(seed=5)
    s1 = [env.step(a[k]) for k in range(3)]
    o2, _ = env.reset(seed=5)
    assert o1["pos"] is not o2["pos"]
    s2 = [env.step(a[k]) for k in range(3)]
    for x, y in zip(s1, s2):
        for key in x[0]:
            np.testing.assert_array_equal(x[0][key], y[0][key])
        np.testing.assert_array_equal(x[1], y[1])
    assert s1[0][0]["pos"] is not s1[1][0]["pos"]
    # copies seeded s + i differ (wind turbulence)
    assert not np.array_equal(s1[-1][0]["wind_force"][0], s1[-1][0]["wind_force"][1])


# --------------------------------------------------------------------------- == SyncVectorEnv(SwarmGymEnv)


@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
def test_equals_sync_vector_env_with_resets(mode):
    """Wind turbulence per copy, 5-step episodes: truncations and auto-resets (seeds drawn per copy)."""
    seen = compare_with_sync(windy(0.05), m=3, steps=13, mode=mode)
    assert seen["truncated"] == 6 and seen["reset"] >= 3


def realistic_actions(env, steps: int, lift=(1.5, 0.9, 1.25, 0.7)) -> np.ndarray:
    """(steps, m, 4n) U of each copy near lift[c] × hover (with noise): copies 0 and 2 climb off the floor,
    1 and 3 press on it."""
    a = hover_actions(env, steps, np.random.default_rng(4), sd=0.3)
    a[:, :, 0::4] *= np.asarray(lift)[None, : env.num_envs, None]
    return a


@pytest.mark.slow
@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
def test_realistic_physics_equals_sync_vector_env_with_resets(mode):
    """Issue 48: SwarmVectorEnv("anti_collision", num_envs=4, aero="realistic") == SyncVectorEnv over
    SwarmGymEnv("anti_collision", aero="realistic"), bit for bit, through three auto-resets of every copy (0.2-s
    episodes): the rotors' lag, the solid floor and its ground monitor, downwash and ground effect reset per
    copy as a fresh environment's reset does (each copy its own model by default: the solver takes a model's
    floor contacts together)."""
    sc = load_scenario("anti_collision").with_overrides(duration=0.2)
    probe = SwarmVectorEnv(sc, num_envs=4, aero="realistic", threads=1)
    assert [blk.b for blk in probe.physics.blocks] == [1, 1, 1, 1]
    assert probe.physics.blocks[0].sim.motor_lag and probe.physics.blocks[0].sim.monitors
    steps = 3 * probe.n_steps + 8
    seen = compare_with_sync(
        sc, m=4, steps=steps, mode=mode, actions=realistic_actions(probe, steps), block=None, aero="realistic"
    )
    assert (seen["resets"] >= 3).all() and seen["truncated"] == 12


@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
def test_mocap_sensing_equals_sync_vector_env_with_resets(mode):
    """Issue 49: SwarmVectorEnv(..., sensing="mocap") == SyncVectorEnv over SwarmGymEnv(..., sensing="mocap"),
    bit for bit, view keys included (each copy's own sensing stage, seeded with the copy's episode seed and reset
    with it at every auto-reset): six drones in turbulence, 0.2-s episodes, at least two auto-resets of every
    copy."""
    sc = windy(0.2)
    probe = SwarmVectorEnv(sc, num_envs=3, sensing="mocap", threads=1)
    assert len(probe.sensing) == 3 and "view_pos" in probe.single_observation_space.spaces
    steps = 2 * probe.n_steps + 6
    seen = compare_with_sync(sc, m=3, steps=steps, mode=mode, sensing="mocap")
    assert (seen["resets"] >= 2).all() and seen["truncated"] == 6


def test_reset_copies_leaves_a_copy_as_a_fresh_reset_every_stage_included():
    """Sim.reset_copies under realistic physics (4 copies in one model): the reset copies' rows of the MuJoCo
    state (rotor lag included), of every force stage and of the ground monitor equal a freshly reset Sim's,
    and the other copies' rows are what they were. Copies 0 and 2 have climbed off the floor, 1 and 3 not."""
    from swarm_mj.pipeline.swarm import SwarmPhysics
    from swarm_mj.scenario import flown

    sc = flown(load_scenario("anti_collision").with_overrides(duration=1.0), aero="realistic")

    def rows_of(sim) -> dict:
        N, d = sim.n_total, sim.data
        out = {
            "qpos": sim.qpos, "qvel": sim.qvel, "act": d.act.reshape(N, 4), "ctrl": sim.ctrl,
            "warmstart": d.qacc_warmstart.reshape(N, 6), "thrust": sim.rotor_thrust, "command": sim.rotor_command,
            "xfrc": d.xfrc_applied[sim.world.body_ids],
        }  # fmt: skip
        for obj in (*sim.stages, *sim.monitors):
            for key, v in vars(obj).items():
                if isinstance(v, np.ndarray) and v.ndim and v.shape[0] == N:
                    out[f"{obj.name}.{key}"] = v
        return {key: np.array(v) for key, v in out.items()}

    def physics():
        ph = SwarmPhysics(sc, 4, block=4, contact_pairs=True)
        ph.begin(np.ones(4, bool), [3, 3, 3, 3])
        ph.reset()
        return ph

    fresh = rows_of(physics().blocks[0].sim)
    ph = physics()
    sim = ph.blocks[0].sim
    assert {s.name for s in sim.stages} >= {"downwash", "ground_effect"} and sim.motor_lag
    probe = types.SimpleNamespace(params=ph.params, n=ph.n, num_envs=4)
    for a in realistic_actions(probe, 40):
        ph.step(a.reshape(-1, 4))
    ground = sim.monitors[0]
    assert ground.airborne.reshape(4, ph.n)[[0, 2]].all() and not ground.airborne.reshape(4, ph.n)[[1, 3]].any()
    before = rows_of(sim)
    mask = np.array([True, False, True, False])
    rows = np.repeat(mask, ph.n)
    ph.put_back(mask)
    after = rows_of(sim)
    assert len(after) == len(fresh) > 14  # the stages' and the monitor's arrays are there
    for key in after:
        np.testing.assert_array_equal(after[key][rows], fresh[key][rows], err_msg=key)
        np.testing.assert_array_equal(after[key][~rows], before[key][~rows], err_msg=key)
    changed = [key for key in after if not np.array_equal(before[key][rows], fresh[key][rows])]
    assert {"act", "ground.airborne", "downwash.force"} <= set(changed)  # what the reset had to undo
    assert not ground.compiled_ready() or not ground.airborne.all()


def test_per_copy_termination_on_divergence_equals_sync():
    """Copy 1 gets no thrust and falls through the floor; the others hover on."""
    sc = windy(1.0)
    probe = SwarmVectorEnv(sc, num_envs=3)
    actions = hover_actions(probe, 45, np.random.default_rng(2), sd=0.1)
    actions[:, 1, :] = 0.0
    seen = compare_with_sync(sc, m=3, steps=45, mode=AutoresetMode.NEXT_STEP, actions=actions)
    assert seen["terminated"] == 1
    env = SwarmVectorEnv(sc, num_envs=3)
    env.reset(seed=0)
    for k in range(45):
        obs, reward, terminated, _, info = env.step(actions[k])
        if terminated.any():
            assert terminated.tolist() == [False, True, False]
            assert info["termination"][1] == "diverged" and info["error"][1] == "below the floor"
            assert reward[1] == -1000.0
            obs, reward, terminated, _, info = env.step(actions[k + 1])
            assert obs["time"].tolist() == [(k + 2) * sc.control_period, 0.0, (k + 2) * sc.control_period]
            assert reward[1] == 0.0 and not terminated.any()
            break
    else:
        pytest.fail("copy 1 never terminated")


def test_termination_on_contact_within_a_copy_only():
    """Two followers 0.4 m apart (rotor planes of radius 0.25 m) touch from the first physics step: every
    copy terminates on contact, as SwarmGymEnv does; a copy's drones never touch another copy's although
    all copies fill the same space."""
    sc = load_scenario("circle").with_overrides(duration=1.0)
    starts = np.array(sc.follower_starts, float)
    starts[1] = starts[0] + [0.4, 0.0, 0.0]
    close = sc.with_overrides(follower_starts=starts)
    seen = compare_with_sync(close, m=2, steps=3, mode=AutoresetMode.NEXT_STEP, atol=1e-12)
    assert seen["terminated"] == 4  # steps 1 and 3 (step 2 resets both copies)
    env = SwarmVectorEnv(close, num_envs=2)
    env.reset(seed=0)
    _, _, terminated, _, info = env.step(hover_actions(env, 1, np.random.default_rng(0), sd=0)[0])
    assert terminated.all() and list(info["termination"]) == ["contact", "contact"]
    assert info["new_contacts"].tolist() == [1, 1]
    # the circle's own starts: 4 copies in the same place, no contact anywhere
    env = SwarmVectorEnv(sc, num_envs=4, block=4)
    env.reset(seed=0)
    for a in hover_actions(env, 20, np.random.default_rng(0)):
        _, _, terminated, _, info = env.step(a)
        assert not terminated.any() and info["contacts"].sum() == 0


def test_random_starts_seeded_per_copy():
    sc = load_scenario("circle").with_overrides(follower_starts=None, random_start=RandomStart(radius=4.0, seed=0))
    env = SwarmVectorEnv(sc, num_envs=3)
    obs, _ = env.reset(seed=10)
    for c in range(3):
        want = random_follower_starts(sc.leader_start, sc.n_followers, replace(sc.random_start, seed=10 + c))
        np.testing.assert_array_equal(obs["pos"][c, 1:], want)
    assert not np.array_equal(obs["pos"][0], obs["pos"][1])


# --------------------------------------------------------------------------- copies do not interact


def test_copy_alone_equals_copy_among_63_others():
    """Copy 5 of 64 (blocks of 8 and of 16 copies per model) flies bit for bit as the same copy alone,
    and as SwarmEnv with the same seed and actions."""
    sc = windy(0.3)
    steps = 30
    big = SwarmVectorEnv(sc, num_envs=64)
    actions = hover_actions(big, steps, np.random.default_rng(3))
    alone = SwarmVectorEnv(sc, num_envs=1)
    single = SwarmEnv(sc)
    runs = []
    for env, rows in (
        (big, slice(5, 6)),
        (SwarmVectorEnv(sc, num_envs=64, block=16), slice(5, 6)),
        (alone, slice(0, 1)),
    ):
        obs, _ = env.reset(seed=[100 + i for i in range(env.num_envs)] if env.num_envs > 1 else 105)
        traj = [obs["pos"][rows].copy()]
        out = []
        for k in range(steps):
            a = actions[k].copy()
            if env.num_envs == 1:
                a = a[5:6]
            obs, reward, terminated, _, _ = env.step(a)
            traj.append(np.concatenate([obs[key][rows].reshape(-1) for key in sorted(obs)]))
            out.append((reward[rows].copy(), terminated[rows].copy()))
        runs.append((traj, out))
    for other in runs[1:]:
        for x, y in zip(runs[0][0], other[0]):
            np.testing.assert_array_equal(x, y)
        for x, y in zip(runs[0][1], other[1]):
            np.testing.assert_array_equal(x[0], y[0])
    ts = single.reset(seed=105)
    for k in range(steps):
        ts = single.step(actions[k][5].reshape(single.n, 4))
    obs = runs[2][0][-1]
    want = np.concatenate([np.asarray(ts.observation[key], float).reshape(-1) for key in sorted(ts.observation)])
    np.testing.assert_array_equal(obs, want)


def test_one_drone_copies_equal_swarm_env_bit_for_bit():
    """One drone (lemniscate_single): every copy's observation, reward and flags equal SwarmEnv's with the
    same seed and actions, bit for bit, the step that truncates included (the task of swarm_mj/task.py is
    the one both call; before it, SwarmEnv's one-drone reward was a BLAS dot product and the vector
    env's a sum, which differ in the last bit for about a fifth of positions)."""
    sc = load_scenario("lemniscate_single").with_overrides(duration=0.2)
    m = 3
    vec = SwarmVectorEnv(sc, num_envs=m)
    singles = [SwarmEnv(sc) for _ in range(m)]
    actions = hover_actions(vec, vec.n_steps, np.random.default_rng(11))
    obs, _ = vec.reset(seed=40)
    for c, env in enumerate(singles):
        first = env.reset(seed=40 + c).observation
        for key in obs:
            np.testing.assert_array_equal(obs[key][c], first[key], err_msg=key)
    for k in range(vec.n_steps):
        obs, reward, terminated, truncated, _ = vec.step(actions[k])
        for c, env in enumerate(singles):
            ts = env.step(actions[k][c].reshape(1, 4))
            for key in obs:
                np.testing.assert_array_equal(obs[key][c], ts.observation[key], err_msg=key)
            assert reward[c] == ts.reward
            assert bool(terminated[c]) == (ts.last() and ts.discount == 0.0)
            assert bool(truncated[c]) == (ts.last() and ts.discount != 0.0)
    assert truncated.all() and not terminated.any()


# --------------------------------------------------------------------------- a standard RL library's loop


def test_sb3_ppo_trains_briefly():
    sb3 = pytest.importorskip("stable_baselines3", reason="stable-baselines3 not installed (the rl extra)")
    from stable_baselines3.common.env_util import is_wrapped  # noqa: F401  (SB3 importable end to end)

    from swarm_mj.wrappers.sb3 import SB3VecEnv, hover_centred

    sc = load_scenario("circle").with_overrides(duration=0.2)
    env = SwarmVectorEnv(sc, num_envs=4, flatten=True, autoreset_mode=AutoresetMode.SAME_STEP)
    space, action_map = hover_centred(env)
    venv = SB3VecEnv(env, action_space=space, action_map=action_map)
    venv.seed(0)
    model = sb3.PPO("MlpPolicy", venv, n_steps=32, batch_size=64, n_epochs=1, seed=0, device="cpu")
    model.learn(total_timesteps=256)
    assert model.num_timesteps == 256
    obs = venv.reset()
    assert obs.shape == (4, env.single_observation_space.shape[0])
    act, _ = model.predict(obs, deterministic=True)
    _, reward, dones, _ = venv.step(act)
    assert reward.shape == (4,) and dones.shape == (4,)
    with pytest.raises(UserError):
        SB3VecEnv(SwarmVectorEnv(sc, num_envs=2, flatten=True))


def test_kernel_samples_fit_the_kernel():
    """warm_up calls the kernel with its samples, compiled (no bounds checks): run them as plain
    Python, where an index out of bounds raises instead of corrupting memory."""
    from swarm_mj.task import _observe_samples, observe_copies

    fn = getattr(observe_copies, "py_func", observe_copies)
    for args in _observe_samples():
        fn(*args)
        out = args[-4]
        assert out.shape[1] == args[-5][-1] + 3 * args[2]  # the wind force is the last key


def test_copies_in_contact_agree_with_a_copy_alone_to_1e_12():
    """With drones touching in EVERY copy at once (two followers 0.4 m apart, 60 steps), copy 3 of 8 in
    one model flies as the same copy alone to 1e-12 (not bit for bit: MuJoCo's constraint solver
    works on all the model's contacts together), and each copy counts only its own contact."""
    sc = load_scenario("circle").with_overrides(duration=1.0)
    starts = np.array(sc.follower_starts, float)
    starts[1] = starts[0] + [0.4, 0.0, 0.0]
    close = sc.with_overrides(follower_starts=starts)
    big = SwarmVectorEnv(close, num_envs=8, block=8, terminate_on_contact=False)
    one = SwarmVectorEnv(close, num_envs=1, terminate_on_contact=False)
    actions = hover_actions(big, 60, np.random.default_rng(0), sd=0.2)
    ob, _ = big.reset(seed=list(range(8)))
    oo, _ = one.reset(seed=3)
    for a in actions:
        ob, _, _, _, ib = big.step(a)
        oo, _, _, _, io = one.step(a[3:4])
        for key in ob:
            np.testing.assert_allclose(ob[key][3], oo[key][0], rtol=0, atol=1e-12, err_msg=key)
    assert ib["contacts"].tolist() == [1] * 8 and io["contacts"].tolist() == [1]
