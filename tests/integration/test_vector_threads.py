"""SwarmVectorEnv on threads (issue 30, "Every core for batches"): the blocks of copies are stepped on
``threads`` threads, and every output is the same bit for bit whatever the thread count
(docs/design.md, "The environment: one task over copies")."""

from __future__ import annotations

import gc
import threading
import time
from dataclasses import replace

import numpy as np
import pytest

pytest.importorskip("gymnasium", reason="the vector env needs the gym extra")
from gymnasium.vector import AutoresetMode

from swarm_mj.errors import UserError
from swarm_mj.physics.wind import ALWAYS_ON
from swarm_mj.scenario import load_scenario
from swarm_mj.wrappers import SwarmVectorEnv

POOL = "swarm-mj-env"


def pool_threads() -> list[threading.Thread]:
    return [t for t in threading.enumerate() if t.name.startswith(POOL)]


def touching(duration: float):
    """wind_swarm (turbulence seeded per copy) with the wind on from t = 0 and followers 0 and 1 starting
    0.4 m apart: their rotor planes (radius 0.25 m) touch from the first physics step."""
    sc = load_scenario("wind_swarm")
    starts = np.array(sc.follower_starts, float)
    starts[1] = starts[0] + [0.4, 0.0, 0.0]
    return sc.with_overrides(duration=duration, wind=replace(sc.wind, schedule=ALWAYS_ON), follower_starts=starts)


def actions(n: int, m: int, steps: int, params) -> np.ndarray:
    """(steps, m, 4n) U near hover, different per copy and step; copy 1 gets no thrust from step 5 (it falls
    and diverges below the floor), copy 4 strong random torques."""
    rng = np.random.default_rng(11)
    hover = np.tile([params.m * params.g, 0.0, 0.0, 0.0], n)
    scale = np.tile([1.0, 0.02, 0.02, 0.01], n)
    a = hover + 0.4 * scale * rng.standard_normal((steps, m, 4 * n))
    a[5:, 1] = 0.0
    a[:, 4] += 5 * scale * rng.standard_normal((steps, 4 * n)) * np.tile([0.0, 1.0, 1.0, 1.0], n)
    return a


def fly(threads: int, mode: AutoresetMode, steps: int = 90) -> tuple[list, dict]:
    """Every output of ``steps`` steps of 7 copies in 4 blocks (2, 2, 2, 1 copies), on ``threads`` threads."""
    before = set(pool_threads())  # (other tests' environments not yet collected)
    env = SwarmVectorEnv(
        touching(0.6), num_envs=7, block=2, threads=threads, terminate_on_contact=False, autoreset_mode=mode
    )
    assert env.threads == threads
    out = [env.reset(seed=3)]
    seen = {"contacts": 0, "diverged": 0, "truncated": 0}
    for a in actions(env.n, 7, steps, env.params):
        r = env.step(a)
        out.append(r)
        info = r[4]
        if "new_contacts" in info:
            seen["contacts"] += int(info["new_contacts"][info["_new_contacts"]].sum())
        seen["diverged"] += int(r[2].sum())  # terminated: diverged (contacts do not terminate here)
        seen["truncated"] += int(r[3].sum())
    ours = set(pool_threads()) - before
    assert len(ours) == threads - 1  # the steps did run on that many threads
    env.close()
    assert not ours & set(pool_threads())
    return out, seen


def same(x, y, where: str = "") -> None:
    """Equal bit for bit: arrays (NaN where NaN), dicts, object arrays of dicts or arrays, scalars."""
    if isinstance(x, dict):
        assert x.keys() == y.keys(), where
        for key in x:
            same(x[key], y[key], f"{where}/{key}")
    elif isinstance(x, (tuple, list)):
        assert len(x) == len(y), where
        for i, (a, b) in enumerate(zip(x, y)):
            same(a, b, f"{where}[{i}]")
    elif isinstance(x, np.ndarray) and x.dtype == object:
        for i, (a, b) in enumerate(zip(x, y)):
            same(a, b, f"{where}[{i}]")
    elif isinstance(x, np.ndarray):
        assert x.dtype == y.dtype and x.shape == y.shape, where
        assert x.tobytes() == y.tobytes(), where
    else:
        assert x == y, where


@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
def test_one_two_and_three_threads_give_the_same_bits(mode):
    """Contacts in every copy (flown on), a copy diverging, truncations and auto-resets, wind turbulence
    per copy: observations, rewards, flags and infos (final_obs included) equal bit for bit."""
    one, seen = fly(1, mode)
    assert seen["contacts"] > 0 and seen["diverged"] >= 1 and seen["truncated"] >= 6, seen
    for threads in (2, 3):
        many, _ = fly(threads, mode)
        same(one, many, f"threads={threads}")


def test_bad_threads_one_line():
    for bad in (0, -1, 1.5, True, "2"):
        with pytest.raises(UserError, match="threads must be an integer >= 1") as err:
            SwarmVectorEnv("circle", num_envs=2, threads=bad)
        assert "\n" not in str(err.value)


def test_default_threads_and_one_block_starts_no_pool():
    import os

    env = SwarmVectorEnv("circle", num_envs=16, block=2)  # 8 blocks
    assert env.threads == min(8, len(os.sched_getaffinity(0)))
    env.close()
    before = set(pool_threads())
    env = SwarmVectorEnv("circle", num_envs=4, threads=4)  # one block (4 x 6 drones <= 48)
    assert len(env.physics.blocks) == 1 and env.threads == 1
    env.reset(seed=0)
    env.step(np.tile(np.tile([env.params.m * env.params.g, 0, 0, 0], env.n), (4, 1)))
    assert set(pool_threads()) == before
    env.close()


def test_threads_end_when_the_env_is_garbage_collected():
    before = set(pool_threads())
    env = SwarmVectorEnv("circle", num_envs=4, block=2, threads=2)
    env.reset(seed=0)
    env.step(np.tile(np.tile([env.params.m * env.params.g, 0, 0, 0], env.n), (4, 1)))
    ours = set(pool_threads()) - before
    assert len(ours) == 1
    del env
    gc.collect()
    deadline = time.monotonic() + 10
    while ours & set(pool_threads()) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not ours & set(pool_threads())


def test_a_failing_group_is_raised_after_every_group_has_ended():
    """ThreadTeam (the tuner's and the vector env's threads): the first part's exception in part order, raised
    only once every part has returned."""
    from swarm_mj.experiments.parallel import ThreadTeam

    done: list[int] = []

    def work(i: int) -> None:
        if i == 1:
            raise ValueError("part 1")
        time.sleep(0.2 if i == 2 else 0.0)
        done.append(i)

    with ThreadTeam(3, "swarm-mj-test") as team:
        with pytest.raises(ValueError, match="part 1"):
            team.run(work, [0, 1, 2])
        assert sorted(done) == [0, 2]
        with pytest.raises(ValueError, match="parts"):
            team.run(work, [0, 2, 0, 2])
    assert not [t for t in threading.enumerate() if t.name.startswith("swarm-mj-test")]


def test_physics_with_a_solid_floor_on_threads_gives_one_model_per_block_and_the_same_bits():
    """A solid floor's gate writes the model as a block steps (Sim.floor_gate), so on threads each block
    gets its own model (SwarmPhysics; the vector env's default is one copy per model there). Copies 0 and 2
    stay on the floor (no thrust: the gate keeps it solid), copies 1 and 3 climb away (the gate turns it
    off): they fly the same bit for bit on 1 and 2 threads."""
    from swarm_mj.physics.aero.presets import with_aero
    from swarm_mj.pipeline.swarm import SwarmPhysics

    sc = with_aero(load_scenario("circle"), "realistic").with_overrides(duration=1.0)
    runs = []
    for threads in (1, 2):
        ph = SwarmPhysics(sc, 4, block=1, threads=threads)
        assert ph.blocks[0].sim.floor_gate
        models = {id(blk.sim.model) for blk in ph.blocks}
        assert len(models) == (1 if threads == 1 else 4)
        ph.begin(np.ones(4, bool), [5, 6, 7, 8])
        ph.reset()
        rng = np.random.default_rng(0)
        p, N = ph.params, 4 * ph.n
        out = []
        for _ in range(40):
            lift = np.repeat([0.0, 2.0, 0.0, 2.0], ph.n) * rng.uniform(0.9, 1.1, N)  # (N,) x hover thrust
            U = np.column_stack([p.m * p.g * lift, 0.002 * rng.standard_normal((N, 3))])
            health = ph.step(U).copy()
            state = [np.concatenate([blk.sim.qpos.ravel(), blk.sim.qvel.ravel()]) for blk in ph.blocks]
            out.append((health, ph.contacts.copy(), ph.k.copy(), *state))
        ph.close()
        runs.append(out)
    same(runs[0], runs[1])
    z = [o[3:] for o in runs[0][-1:]][0]  # the last step's state of each block: the leader's z
    assert z[0][2] > -0.05 and z[2][2] > -0.05  # held by the floor
    assert z[1][2] > 0.3 and z[3][2] > 0.3  # climbed away
