"""Environment steps per second for the 6-drone swarm, next to raw mujoco.mj_step.

One SwarmEnv step is one control period T = control_period / timestep physics steps
(2 by default). Each row times the same number of env steps and is compared with raw
``mujoco.mj_step`` doing the same physics steps on the same model (ctrl at hover, a
constant xfrc_applied):

  * raw mj_step           the physics alone (T / dt mj_step calls per env step),
  * SwarmEnv, random U    ``SwarmEnv.step`` with pre-drawn random U near hover (uniform over
                          the whole action box flips the drones and ends the episode in 0.5 s;
                          an episode that still ends early is restarted, and counted),
  * SwarmEnv + backstep.  ``SwarmEnv.step`` + ``BacksteppingPolicy`` (the ``swarm-mj run`` loop
                          without its logging), with the env and policy shares split out,
  * Gymnasium / PettingZoo wrappers with the same random U (if installed).

Repeats are interleaved (every row sees the same machine state); the best is kept.

    .venv/bin/python tools/bench_env.py [--scenario circle] [--seconds 10] [--repeats 3]
"""

from __future__ import annotations

import argparse
import time

import mujoco
import numpy as np

from swarm_mj.control.policy import BacksteppingPolicy
from swarm_mj.env import SwarmEnv
from swarm_mj.physics._mjstep import profiler_paused
from swarm_mj.scenario import load_scenario


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenario", default="circle", help="scenario (default circle: 6 drones)")
    ap.add_argument("--seconds", type=float, default=10.0, help="simulated seconds per repeat (default 10)")
    ap.add_argument("--repeats", type=int, default=3, help="repeats, best taken (default 3)")
    args = ap.parse_args(argv)
    if args.seconds <= 0 or args.repeats < 1:
        ap.error("--seconds must be > 0 and --repeats >= 1")

    sc = load_scenario(args.scenario).with_overrides(duration=args.seconds)
    env = SwarmEnv(sc, terminate_on_contact=False)
    n, K = env.n, env.n_steps
    n_sub = env.sim.n_substeps
    p = env.params
    rng = np.random.default_rng(0)
    U_rand = np.empty((K, n, 4))
    U_rand[..., 0] = p.hover_thrust * rng.uniform(0.95, 1.10, (K, n))
    U_rand[..., 1:] = rng.uniform(-0.002, 0.002, (K, n, 3))
    restarts = dict.fromkeys(("random", "backstepping", "gym", "pz"), 0)  # episodes ended early

    model = env.world.model
    raw = mujoco.MjData(model)

    def run_raw() -> float:
        mujoco.mj_resetData(model, raw)
        raw.qpos[:] = env.sim.data.qpos
        raw.ctrl[:] = np.tile([p.hover_thrust, 0, 0, 0], n)
        raw.xfrc_applied[env.world.body_ids, 0:3] = [0.1, -0.05, 0.02]
        mujoco.mj_forward(model, raw)
        step = mujoco.mj_step
        with profiler_paused():  # as Sim.step steps (swarm_mj/physics/_mjstep.py)
            t0 = time.perf_counter()
            for _ in range(K * n_sub):
                step(model, raw)
            return time.perf_counter() - t0

    def run_random() -> float:
        env.reset(seed=0)
        step = env.step
        t0 = time.perf_counter()
        for k in range(K):
            ts = step(U_rand[k])  # dm_env: a step after an early LAST restarts
            restarts["random"] += ts.last() and k < K - 1
        return time.perf_counter() - t0

    policy = BacksteppingPolicy(sc, p)
    split = {"policy": np.inf}

    def run_policy() -> float:
        ts = env.reset(seed=0)
        policy.reset()
        step, clock = env.step, time.perf_counter
        t_pol = 0.0
        t0 = clock()
        for _ in range(K):
            t1 = clock()
            U = policy(ts.observation)
            t_pol += clock() - t1
            ts = step(U)
        dt = clock() - t0
        split["policy"] = min(split["policy"], t_pol)
        restarts["backstepping"] += env.k != K
        return dt

    rows = {"raw mj_step": run_raw, "SwarmEnv, random U": run_random, "SwarmEnv + backstepping": run_policy}

    try:
        from swarm_mj.wrappers.gymnasium import SwarmGymEnv
        from swarm_mj.wrappers.pettingzoo import SwarmParallelEnv
    except ModuleNotFoundError:
        print("(gymnasium / pettingzoo not installed: wrapper rows skipped)")
    else:
        gym_env = SwarmGymEnv(SwarmEnv(sc, terminate_on_contact=False))
        pz_env = SwarmParallelEnv(SwarmEnv(sc, terminate_on_contact=False))
        agents = pz_env.possible_agents
        pz_actions = [{a: U_rand[k, i] for i, a in enumerate(agents)} for k in range(K)]

        def run_gym() -> float:
            gym_env.reset(seed=0)
            step = gym_env.step
            t0 = time.perf_counter()
            for k in range(K):
                if any(step(U_rand[k])[2:4]) and k < K - 1:
                    restarts["gym"] += 1
                    gym_env.reset()
            return time.perf_counter() - t0

        def run_pz() -> float:
            pz_env.reset(seed=0)
            step = pz_env.step
            t0 = time.perf_counter()
            for k in range(K):
                step(pz_actions[k])
                if not pz_env.agents and k < K - 1:
                    restarts["pz"] += 1
                    pz_env.reset()
            return time.perf_counter() - t0

        rows["Gymnasium, random U"] = run_gym
        rows["PettingZoo, random U"] = run_pz

    for fn in rows.values():  # warm-up
        fn()
    best = {name: np.inf for name in rows}
    for _ in range(args.repeats):  # interleaved
        for name, fn in rows.items():
            best[name] = min(best[name], fn())

    raw_t = best["raw mj_step"]
    best = {(f"raw mj_step ×{n_sub}" if k == "raw mj_step" else k): v for k, v in best.items()}
    print(
        f"{sc.name}: {n} drones, {K} env steps = {K * n_sub} mj_step ({n_sub} per env step, "
        f"dt = {sc.timestep:g} s, T = {sc.control_period:g} s), best of {args.repeats}\n"
    )
    print(f"{'':26s}{'env steps/s':>12s}{'µs/env step':>13s}{'× raw':>8s}{'sim s / wall s':>16s}")
    for name, t in best.items():
        print(f"{name:26s}{K / t:12.0f}{1e6 * t / K:13.1f}{t / raw_t:8.2f}{args.seconds / t:16.0f}")
        if name == "SwarmEnv + backstepping":
            t_pol = split["policy"]
            print(f"{'  of which the policy':26s}{'':12s}{1e6 * t_pol / K:13.1f}{t_pol / raw_t:8.2f}")
            print(f"{'  of which SwarmEnv.step':26s}{'':12s}{1e6 * (t - t_pol) / K:13.1f}{(t - t_pol) / raw_t:8.2f}")
    if any(restarts.values()):
        print(f"\nnote: episodes that ended early and were restarted (reset time included): {restarts}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
