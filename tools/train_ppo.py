"""Train stable-baselines3 PPO on :class:`~swarm_mj.wrappers.SwarmVectorEnv` for a few thousand steps.

A demonstration that the vector environment works with a standard RL library's vectorised
training loop, not a tuned agent: m copies of a scenario's swarm in batched MuJoCo models,
SB3's ``VecEnv`` through :class:`~swarm_mj.wrappers.sb3.SB3VecEnv` (same-step auto-reset, flat
observation), a policy acting in [−1, 1] around hover (:func:`~swarm_mj.wrappers.sb3.hover_centred`).
Needs the ``rl`` extra (``pip install 'swarm-mj[rl]'``: stable-baselines3 and torch).

    python tools/train_ppo.py [--scenario circle] [--num-envs 8] [--timesteps 4096] [--episode 2.0]

``--episode`` shortens the scenario (seconds) so that episodes end and reset during the
demo. Prints the mean episode return and length of the first and last rollouts, and the
training throughput in environment steps per second.
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="circle")
    ap.add_argument("--num-envs", type=int, default=8)
    ap.add_argument("--timesteps", type=int, default=4096)
    ap.add_argument("--episode", type=float, default=2.0, help="episode length in seconds (scenario duration)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--n-steps", type=int, default=128, help="PPO rollout length per copy")
    args = ap.parse_args(argv)
    try:
        import torch
        from stable_baselines3 import PPO
        from stable_baselines3.common.callbacks import BaseCallback
    except ModuleNotFoundError as exc:
        print(f"train_ppo: error: needs {exc.name}: pip install 'swarm-mj[rl]'", file=sys.stderr)
        return 2
    from gymnasium.vector import AutoresetMode

    from swarm_mj.scenario import load_scenario
    from swarm_mj.wrappers.sb3 import SB3VecEnv, hover_centred
    from swarm_mj.wrappers.vector import SwarmVectorEnv

    torch.set_num_threads(1)
    sc = load_scenario(args.scenario).with_overrides(duration=args.episode)
    env = SwarmVectorEnv(sc, num_envs=args.num_envs, flatten=True, autoreset_mode=AutoresetMode.SAME_STEP)
    space, action_map = hover_centred(env)
    venv = SB3VecEnv(env, action_space=space, action_map=action_map)
    venv.seed(args.seed)

    class Returns(BaseCallback):
        """Episode returns and lengths per rollout."""

        def __init__(self) -> None:
            super().__init__()
            self.ret = np.zeros(args.num_envs)
            self.len = np.zeros(args.num_envs, dtype=int)
            self.rollouts: list[list[tuple[float, int]]] = [[]]

        def _on_step(self) -> bool:
            self.ret += self.locals["rewards"]
            self.len += 1
            for c in np.flatnonzero(self.locals["dones"]):
                self.rollouts[-1].append((float(self.ret[c]), int(self.len[c])))
                self.ret[c], self.len[c] = 0.0, 0
            return True

        def _on_rollout_end(self) -> None:
            self.rollouts.append([])

    cb = Returns()
    model = PPO(
        "MlpPolicy",
        venv,
        n_steps=args.n_steps,
        batch_size=256,
        n_epochs=4,
        learning_rate=3e-4,
        seed=args.seed,
        verbose=0,
        device="cpu",
    )
    t0 = time.perf_counter()
    model.learn(total_timesteps=args.timesteps, callback=cb)
    wall = time.perf_counter() - t0
    done = [r for r in cb.rollouts if r]
    print(
        f"PPO on {args.num_envs} x {sc.name} ({sc.n_drones} drones, {args.episode:g}-s episodes): "
        f"{model.num_timesteps} env steps in {wall:.1f} s ({model.num_timesteps / wall:,.0f} steps/s, "
        f"{model.num_timesteps * sc.n_drones / wall:,.0f} drone-steps/s, policy updates included)"
    )
    for name, r in (("first", done[0] if done else []), ("last", done[-1] if done else [])):
        if r:
            ret, ln = np.mean([x[0] for x in r]), np.mean([x[1] for x in r])
            print(
                f"  {name} rollout with finished episodes: {len(r)} episodes, mean return {ret:.1f}, "
                f"mean length {ln:.0f} steps"
            )
    venv.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
