"""A :class:`SwarmVectorEnv` as a stable-baselines3 ``VecEnv`` (the ``rl`` extra: ``pip install 'swarm-mj[rl]'``).

    from swarm_mj.wrappers.sb3 import SB3VecEnv
    venv = SB3VecEnv(SwarmVectorEnv("circle", num_envs=8, flatten=True, autoreset_mode="SameStep"))
    model = stable_baselines3.PPO("MlpPolicy", venv).learn(4096)

Stable-baselines3 has its own vector API: ``reset()`` returns the observations only, ``step``
returns ``dones = terminated | truncated`` and, for a copy whose episode ended, the FIRST
observation of its next episode, with the last one in ``infos[i]["terminal_observation"]`` and
``infos[i]["TimeLimit.truncated"]`` True when it was cut by the time limit. That is Gymnasium's
same-step auto-reset, so the wrapped env must use ``autoreset_mode=AutoresetMode.SAME_STEP``
and a flat observation (``flatten=True``; SB3's ``MultiInputPolicy`` would take the Dict too,
but the flat Box is the common case).

``action_map`` (optional): a function applied to the policy's actions (m, 4n) before the
environment gets them, e.g. :func:`hover_centred` for a policy acting in [−1, 1].
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode
from stable_baselines3.common.vec_env.base_vec_env import (
    VecEnv,
    VecEnvIndices,
    VecEnvObs,
    VecEnvStepReturn,
)

from ..errors import UserError
from .vector import SwarmVectorEnv

__all__ = ["SB3VecEnv", "hover_centred"]


def hover_centred(env: SwarmVectorEnv, span: float = 0.5) -> tuple[spaces.Box, Callable[[np.ndarray], np.ndarray]]:
    """A [−1, 1] action space and its map to U1..U4: 0 is hover (U1 = m·g, no torque), ±1 is
    ``span`` times the distance from hover to the bound, per component. Returns (space, map)."""
    p = env.params
    space = env.single_action_space
    assert isinstance(space, spaces.Box)  # SwarmVectorEnv's action space is a flat Box (4n,)
    low, high = space.low, space.high
    hover = np.tile([p.m * p.g, 0.0, 0.0, 0.0], env.n)
    up, down = span * (high - hover), span * (hover - low)

    def action_map(a: np.ndarray) -> np.ndarray:
        a = np.clip(np.asarray(a, dtype=np.float64), -1.0, 1.0)
        return hover + np.where(a >= 0.0, a * up, a * down)

    n = space.shape[0]
    return spaces.Box(-1.0, 1.0, shape=(n,), dtype=np.float32), action_map


class SB3VecEnv(VecEnv):
    """stable-baselines3's ``VecEnv`` over a :class:`SwarmVectorEnv` (same-step auto-reset, flat observation)."""

    def __init__(
        self,
        env: SwarmVectorEnv,
        action_space: spaces.Box | None = None,
        action_map: Callable[[np.ndarray], np.ndarray] | None = None,
    ) -> None:
        if env.autoreset_mode != AutoresetMode.SAME_STEP:
            raise UserError("SB3VecEnv needs SwarmVectorEnv(..., autoreset_mode=AutoresetMode.SAME_STEP)")
        if not env.flatten:
            raise UserError("SB3VecEnv needs SwarmVectorEnv(..., flatten=True)")
        self.env = env
        self.action_map = action_map
        super().__init__(
            env.num_envs,
            env.single_observation_space,
            action_space if action_space is not None else env.single_action_space,
        )
        self._actions: np.ndarray | None = None

    def reset(self) -> VecEnvObs:
        seeds: Sequence[int] | None = None
        if any(s is not None for s in self._seeds):
            rng = np.random.default_rng()
            seeds = [int(s) if s is not None else int(rng.integers(0, 2**31 - 1)) for s in self._seeds]
        obs, _ = self.env.reset(seed=seeds)
        self._reset_seeds()
        self._reset_options()
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions)

    def step_wait(self) -> VecEnvStepReturn:
        actions = self._actions
        assert actions is not None, "step_async comes first"
        a = actions if self.action_map is None else self.action_map(actions)
        obs, reward, terminated, truncated, info = self.env.step(a)
        dones = terminated | truncated
        infos: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        for c in np.flatnonzero(dones):
            infos[c]["terminal_observation"] = info["final_obs"][c]
            infos[c]["TimeLimit.truncated"] = bool(truncated[c] and not terminated[c])
        return obs, reward.astype(np.float32), dones, infos

    def close(self) -> None:
        self.env.close()

    def _indices(self, indices: VecEnvIndices) -> list[int]:
        if indices is None:
            return list(range(self.num_envs))
        if isinstance(indices, int):
            return [indices]
        return list(indices)

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        value = getattr(self.env, attr_name)
        return [value for _ in self._indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        setattr(self.env, attr_name, value)

    def env_method(self, method_name: str, *method_args, indices: VecEnvIndices = None, **method_kwargs) -> list[Any]:
        result = getattr(self.env, method_name)(*method_args, **method_kwargs)
        return [result for _ in self._indices(indices)]

    def env_is_wrapped(self, wrapper_class: type, indices: VecEnvIndices = None) -> list[bool]:
        return [False for _ in self._indices(indices)]
