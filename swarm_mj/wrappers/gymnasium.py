"""The swarm as a ``gymnasium.Env``: a thin face over :class:`~swarm_mj.env.SwarmEnv`.

    from swarm_mj.wrappers.gymnasium import SwarmGymEnv
    env = SwarmGymEnv("circle")
    # or, registered on import of this module:
    # gymnasium.make("swarm_mj.wrappers.gymnasium:swarm_mj/Swarm-v0", scenario="circle")
    obs, info = env.reset(seed=0)
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample())

Spaces (``n`` drones, leader = row 0; the keys, shapes and meanings are SwarmEnv's, see
``swarm_mj.env``):

* observation: ``spaces.Dict`` of float64 ``Box``, one per SwarmEnv observation key, same
  shapes (``time`` is a 0-d Box). Bounds: ``time`` [0, inf), ``rpy`` [-π, π],
  ``neighbour_mask`` [0, 1], everything else unbounded. ``flatten=True`` gives one float64
  ``Box`` instead (``gymnasium.spaces.flatten`` of that Dict: keys in sorted order).
  Under a sensing model (``sensing=``, any but ``perfect``) the Dict also holds each drone's own view
  (SwarmEnv's ``view_pos``, ``view_vel`` (n, n, 3), ``view_mask`` (n, n) in [0, 1], ``view_age`` (n, n) in
  [0, inf] (inf: nothing held), ``view_setpoint``, ``view_setpoint_vel`` (n, n, 3), ``own_pos``, ``own_vel``
  (n, 3); row i: what drone i believes), and ``neighbours``/``neighbour_mask`` are the view's.
* action: ``Box`` equal to ``SwarmEnv.action_spec()``: U1..U4 ``(n, 4)`` within what the
  rotors can deliver (``action="thrust"``), or a position setpoint ``(n, 3)`` in
  [-1000, 1000] m (``action="setpoint"``). Actions are NOT clipped here: out-of-bounds U is
  clipped per rotor by the saturation inside SwarmEnv; NaN or inf raises ``UserError``.

Reward, termination (contact, divergence) and truncation (the scenario's duration) are
SwarmEnv's: a dm_env LAST step with discount 0 is ``terminated``, with discount ≠ 0 it is
``truncated``.

Seeding: ``reset(seed=s)`` seeds the wind with ``s`` exactly (the same episode as
``SwarmEnv.reset(seed=s)``; ``seed=scenario.seed`` reproduces ``swarm-mj run``); a
``reset()`` without a seed draws the wind seed from ``self.np_random``, so a seeded reset
followed by unseeded ones is a reproducible sequence of episodes. ``options`` are accepted
for API compatibility; none are defined.
"""

from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np
from dm_env import specs
from gymnasium import spaces

from ..choices import VehicleLike
from ..env import SwarmEnv
from ..errors import SimulationDiverged, UserError
from ..scenario import Scenario
from ..sensing import SensingParams
from ..task import min_separation, observation_specs

ENV_ID = "swarm_mj/Swarm-v0"

# Observation keys with known bounds; the others are unbounded.
_BOUNDS = {"time": (0.0, np.inf), "rpy": (-np.pi, np.pi), "neighbour_mask": (0.0, 1.0)}


def _box(spec: specs.Array, low: Any = -np.inf, high: Any = np.inf) -> spaces.Box:
    if isinstance(spec, specs.BoundedArray):
        low, high = spec.minimum, spec.maximum
    low = np.broadcast_to(np.asarray(low, np.float64), spec.shape).copy()
    high = np.broadcast_to(np.asarray(high, np.float64), spec.shape).copy()
    return spaces.Box(low=low, high=high, shape=spec.shape, dtype=np.float64)


def observation_space(env: SwarmEnv) -> spaces.Dict:
    """The SwarmEnv observation spec as a ``spaces.Dict`` of float64 Box."""
    return space_of(env.observation_spec())


def space_of(spec: dict[str, specs.Array]) -> spaces.Dict:
    """dm_env observation specs (SwarmEnv's, :func:`swarm_mj.task.observation_specs`) as a ``spaces.Dict`` of
    float64 Box (a bounded spec's bounds, else :data:`_BOUNDS`' or none)."""
    return spaces.Dict({key: _box(s, *_BOUNDS.get(key, (-np.inf, np.inf))) for key, s in spec.items()})


def observation_space_for(n: int, sensing: bool) -> spaces.Dict:
    """The observation space of n drones without building an environment (the vector env's): with the view keys
    when ``sensing`` (the environment has a sensing stage)."""
    return space_of(observation_specs(n, sensing))


def action_space(env: SwarmEnv) -> spaces.Box:
    """The SwarmEnv action spec as a float64 Box (same shape and bounds)."""
    return _box(env.action_spec())


def as_swarm_env(
    scenario: Scenario | str | SwarmEnv,
    action: str,
    terminate_on_contact: bool,
    vehicle: VehicleLike | None = None,
    aero: str | None = None,
    sensing: str | SensingParams | None = None,
) -> SwarmEnv:
    """The wrapped :class:`SwarmEnv`: ``scenario`` itself when it is one (then ``vehicle``, ``aero`` and
    ``sensing`` are its own: giving them too is a :class:`UserError`), else one built with these settings."""
    if isinstance(scenario, SwarmEnv):
        if vehicle is not None or aero is not None or sensing is not None:
            raise UserError(
                "vehicle= and aero= go to the SwarmEnv itself when a ready SwarmEnv is wrapped, as does sensing="
            )
        return scenario
    return SwarmEnv(
        scenario,
        action=action,
        terminate_on_contact=terminate_on_contact,
        raise_on_divergence=False,
        vehicle=vehicle,
        aero=aero,
        sensing=sensing,
    )


def fresh_observation(obs: dict) -> dict[str, np.ndarray]:
    """A copy of a SwarmEnv observation as float64 arrays (``time`` a 0-d array)."""
    return {key: np.array(value, dtype=np.float64) for key, value in obs.items()}


def step_info(env: SwarmEnv, contacts_before: int, obs: dict, terminated: bool) -> dict[str, Any]:
    """The info dict of a step: time, contacts, separation (the task's :func:`swarm_mj.task.min_separation`
    of the observation's distances, as the vector env's) and why an episode terminated."""
    contacts = int(env.sim.contact_events)
    min_sep = float(min_separation(env.obs_record.dist))
    info: dict[str, Any] = {
        "time": float(obs["time"]),
        "contacts": contacts,
        "new_contacts": contacts - contacts_before,
        "min_separation": min_sep,
    }
    if terminated:
        try:
            env.sim.check()
            info["termination"] = "contact"
        except SimulationDiverged as exc:
            info["termination"] = "diverged"
            info["error"] = str(exc)
    return info


def seed_from(rng: np.random.Generator) -> int:
    return int(rng.integers(0, 2**31 - 1))


class SwarmGymEnv(gymnasium.Env):
    """A scenario as a ``gymnasium.Env`` (the whole swarm is one agent).

    ``scenario`` is a scenario name or path, a :class:`Scenario`, or a ready
    :class:`SwarmEnv` (then ``action`` and ``terminate_on_contact`` are its own). ``vehicle`` and ``aero``:
    the drones and the physics flown instead of the scenario's, ``sensing``: the sensing model (a preset's
    name, ``"perfect"``, ``"mocap"``, ``"uwb"``, or a :class:`~swarm_mj.sensing.SensingParams`; None: the
    scenario's) (:class:`SwarmEnv`'s).
    """

    metadata = {"render_modes": []}

    def __init__(
        self,
        scenario: Scenario | str | SwarmEnv = "circle",
        *,
        action: str = "thrust",
        flatten: bool = False,
        terminate_on_contact: bool = True,
        render_mode: str | None = None,
        vehicle: VehicleLike | None = None,
        aero: str | None = None,
        sensing: str | SensingParams | None = None,
    ) -> None:
        if render_mode is not None:
            raise UserError(f"render_mode {render_mode!r} is not supported (use swarm-mj run --video)")
        self.render_mode = None
        self.env = as_swarm_env(scenario, action, terminate_on_contact, vehicle, aero, sensing)
        self.flatten = bool(flatten)
        self.dict_observation_space = observation_space(self.env)
        self.observation_space = (
            spaces.flatten_space(self.dict_observation_space) if self.flatten else self.dict_observation_space
        )
        self.action_space = action_space(self.env)
        self.wind_seed: int | None = None
        self._done = True

    @property
    def scenario(self) -> Scenario:
        return self.env.scenario

    @property
    def agent_names(self) -> list[str]:
        return list(self.env.names)

    def _obs(self, obs: dict):
        o = fresh_observation(obs)
        return spaces.flatten(self.dict_observation_space, o) if self.flatten else o

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        self.wind_seed = int(seed) if seed is not None else seed_from(self.np_random)
        ts = self.env.reset(seed=self.wind_seed)
        self._contacts = 0
        self._done = False
        return self._obs(ts.observation), {"time": float(ts.observation["time"]), "wind_seed": self.wind_seed}

    def step(self, action):
        if self._done:
            raise gymnasium.error.ResetNeeded("call reset() before step() (the episode is over or not started)")
        a = np.asarray(action, dtype=np.float64)
        if a.shape != self.action_space.shape:
            raise UserError(f"action must have shape {self.action_space.shape}, got {a.shape}")
        ts = self.env.step(a)
        terminated = bool(ts.last() and ts.discount == 0.0)
        truncated = bool(ts.last() and not terminated)
        self._done = terminated or truncated
        info = step_info(self.env, self._contacts, ts.observation, terminated)
        self._contacts = info["contacts"]
        return self._obs(ts.observation), float(ts.reward), terminated, truncated, info

    def close(self) -> None:
        self._done = True


if ENV_ID not in gymnasium.registry:
    gymnasium.register(id=ENV_ID, entry_point=f"{__name__}:SwarmGymEnv")
