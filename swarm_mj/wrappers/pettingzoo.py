"""The swarm as a PettingZoo ``ParallelEnv``: one agent per drone.

    from swarm_mj.wrappers.pettingzoo import SwarmParallelEnv
    env = SwarmParallelEnv("circle")
    obs, infos = env.reset(seed=0)
    while env.agents:
        actions = {a: env.action_space(a).sample() for a in env.agents}
        obs, rewards, terminations, truncations, infos = env.step(actions)

Agents are the scenario's drones: ``leader``, ``follower1``, … (``possible_agents`` in that
order; drone ``i`` is row ``i`` of SwarmEnv's arrays). All act at once, every control period.

Each agent observes only its own row(s) of SwarmEnv's observation, a ``spaces.Dict`` of
float64 Box:

==================  =====  ===========================================================
key                 shape  meaning
==================  =====  ===========================================================
time                ()     simulated time (s)
pos, vel            (3,)   own position (m) and velocity (m/s)
quat                (4,)   own attitude (w, x, y, z)
rpy, rpy_rate       (3,)   own Euler angles (rad) and their rates (rad/s)
body_rates          (3,)   own body angular velocity (rad/s)
setpoint            (3,)   own formation setpoint (leader: its trajectory; follower: its slot)
setpoint_vel/acc    (3,)   its velocity / acceleration reference
setpoint_yaw        ()     yaw reference (rad)
leader_pos          (3,)   the leader's position
neighbours          (n,3)  drone j's position relative to this one, zero outside sensing range
                           (and for itself)
neighbour_mask      (n,)   1 where drone j is within sensing range
wind_force          (3,)   wind force on this drone when the controller is given the wind, else 0
==================  =====  ===========================================================

**Under a sensing model** (``sensing=``, any but ``perfect``) an agent's observation is its own view
(docs/sensing.md): nothing in it is another drone's true state. Agent i holds its own attitude, rates, yaw
and acceleration references and wind force as above, and instead of ``pos``, ``vel``, ``setpoint``,
``setpoint_vel`` and ``leader_pos`` (the truth, or made from the leader's true position):

==================  =====  ===========================================================
key                 shape  meaning (row i of SwarmEnv's key: what drone i believes)
==================  =====  ===========================================================
own_pos, own_vel    (3,)   its own position and velocity as its estimator gives them
view_pos, view_vel  (n,3)  where it believes each drone is and how fast it flies
                           (its own row: own_pos; what it last held of a drone it no longer
                           holds: far away, see swarm_mj.sensing.stage.UNSEEN_M)
view_mask           (n,)   1 where it holds a message from drone j (itself: 0)
view_age            (n,)   s since drone j sent what it holds (inf: nothing)
view_setpoint       (n,3)  the formation setpoints it flies by, from where it believes the
                           leader is (its own: row i); view_setpoint_vel (n,3) their velocities
neighbours          (n,3)  drone j's position relative to this one as it believes it, zero
                           where it holds nothing of j or j is beyond sensing range
neighbour_mask      (n,)   1 where it holds j within sensing range
==================  =====  ===========================================================

Action: U1..U4 ``(4,)`` bounded like one row of ``SwarmEnv.action_spec()`` (or a position
setpoint ``(3,)`` with ``action="setpoint"``); out-of-bounds U is clipped per rotor by the
saturation, NaN raises ``UserError``. Every live agent must act.

Reward: the swarm's (SwarmEnv's) reward, the same for every agent (a cooperative team
reward). An episode ends for all agents at once: a contact or a divergence terminates it,
the scenario's duration truncates it; ``agents`` is then empty.

``state()`` is the whole SwarmEnv observation, flattened (``state_space``), for centralised
critics (the true states, and under a sensing model every drone's view).
Seeding is as in :class:`~swarm_mj.wrappers.gymnasium.SwarmGymEnv`: ``reset(seed=s)``
seeds the wind with ``s``; an unseeded reset draws the wind seed from the generator that
the last seeded reset created. ``options`` are accepted for API compatibility; none are defined.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv

from ..choices import VehicleLike
from ..env import SwarmEnv
from ..errors import UserError
from ..scenario import Scenario
from ..sensing import SensingParams
from .gymnasium import as_swarm_env, fresh_observation, observation_space, seed_from, step_info


def _one_drone(box: Any) -> spaces.Box:
    """The Box of one drone's row of a per-drone Box (n, ...)."""
    return spaces.Box(box.low[0], box.high[0], shape=box.shape[1:], dtype=np.float64)


# SwarmEnv observation keys with a drone axis first (sliced per agent); the rest are shared.
_PER_DRONE = (
    "pos",
    "vel",
    "quat",
    "rpy",
    "rpy_rate",
    "body_rates",
    "setpoint",
    "setpoint_vel",
    "setpoint_acc",
    "setpoint_yaw",
    "neighbours",
    "neighbour_mask",
    "wind_force",
)

# Under a sensing model: the keys of an agent's own view (row i of SwarmEnv's), and the keys it does not get
# (another drone's true state, or made from the leader's true position).
_VIEW_ROWS = (
    "view_pos",
    "view_vel",
    "view_mask",
    "view_age",
    "view_setpoint",
    "view_setpoint_vel",
    "own_pos",
    "own_vel",
)
_NOT_OWN = ("pos", "vel", "setpoint", "setpoint_vel", "leader_pos")


class SwarmParallelEnv(ParallelEnv):
    """A scenario as a PettingZoo ``ParallelEnv`` with one agent per drone.

    ``scenario`` is a scenario name or path, a :class:`Scenario`, or a ready :class:`SwarmEnv`.
    ``vehicle`` and ``aero``: the drones and the physics flown instead of the scenario's, ``sensing``: the sensing
    model (:class:`SwarmEnv`'s; under any but ``perfect`` each agent observes its own view, module docstring).
    """

    metadata = {"name": "swarm_mj_v0", "render_modes": [], "is_parallelizable": True}

    def __init__(
        self,
        scenario: Scenario | str | SwarmEnv = "circle",
        *,
        action: str = "thrust",
        terminate_on_contact: bool = True,
        render_mode: str | None = None,
        vehicle: VehicleLike | None = None,
        aero: str | None = None,
        sensing: str | SensingParams | None = None,
    ) -> None:
        if render_mode is not None:
            raise UserError(f"render_mode {render_mode!r} is not supported (use swarm-mj run --video)")
        self.render_mode = None
        self.env = env = as_swarm_env(scenario, action, terminate_on_contact, vehicle, aero, sensing)
        self.possible_agents = list(env.names)
        self.agents: list[str] = []
        self._index = {name: i for i, name in enumerate(self.possible_agents)}
        full = observation_space(env)
        self._full_space = full
        self.state_space = spaces.flatten_space(full)
        #: an agent's rows (its own row of each) and the keys it does not get (module docstring)
        self._rows = _PER_DRONE + _VIEW_ROWS if env.sensing is not None else _PER_DRONE
        self._hidden = _NOT_OWN if env.sensing is not None else ()
        self._obs_space = spaces.Dict(
            {
                key: _one_drone(box) if key in self._rows else box
                for key, box in full.spaces.items()
                if key not in self._hidden
            }
        )
        spec = env.action_spec()
        lo = np.broadcast_to(spec.minimum, spec.shape)
        hi = np.broadcast_to(spec.maximum, spec.shape)
        self._act_spaces = {
            name: spaces.Box(lo[i].astype(np.float64), hi[i].astype(np.float64), dtype=np.float64)
            for name, i in self._index.items()
        }
        self._width = spec.shape[1]
        self._rng: np.random.Generator | None = None
        self.wind_seed: int | None = None
        self._last: dict | None = None

    # ------------------------------------------------------------------ spaces
    def observation_space(self, agent: str) -> spaces.Dict:
        """The same space object for every call (PettingZoo's requirement)."""
        self._check_agent(agent)
        return self._obs_space

    def action_space(self, agent: str) -> spaces.Box:
        self._check_agent(agent)
        return self._act_spaces[agent]

    def _check_agent(self, agent: str) -> None:
        if agent not in self._index:
            raise UserError(f"unknown agent {agent!r}; agents are {', '.join(self.possible_agents)}")

    # ------------------------------------------------------------------ API
    def reset(self, seed: int | None = None, options: dict | None = None):
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        elif self._rng is None:
            self._rng = np.random.default_rng()
        self.wind_seed = int(seed) if seed is not None else seed_from(self._rng)
        ts = self.env.reset(seed=self.wind_seed)
        self.agents = list(self.possible_agents)
        self._contacts = 0
        self._last = ts.observation
        info = {"time": float(ts.observation["time"]), "wind_seed": self.wind_seed}
        return self._split(ts.observation), {a: dict(info) for a in self.agents}

    def step(self, actions: dict):
        if not self.agents:
            raise UserError("the episode is over (or not started): call reset() before step()")
        missing = [a for a in self.agents if a not in actions]
        extra = [a for a in actions if a not in self._index]
        if missing or extra:
            raise UserError(f"actions needed for every live agent: missing {missing}, unknown {extra}")
        width = self._width
        U = np.empty((self.env.n, width))
        for name, i in self._index.items():
            a = np.asarray(actions[name], dtype=np.float64)
            if a.shape != (width,):
                raise UserError(f"action of {name} must have shape ({width},), got {a.shape}")
            U[i] = a
        ts = self.env.step(U)
        terminated = bool(ts.last() and ts.discount == 0.0)
        truncated = bool(ts.last() and not terminated)
        info = step_info(self.env, self._contacts, ts.observation, terminated)
        self._contacts = info["contacts"]
        self._last = ts.observation
        agents = self.agents
        reward = float(ts.reward)
        out = (
            self._split(ts.observation),
            {a: reward for a in agents},
            {a: terminated for a in agents},
            {a: truncated for a in agents},
            {a: dict(info) for a in agents},
        )
        if terminated or truncated:
            self.agents = []
        return out

    def state(self) -> np.ndarray:
        if self._last is None:
            raise UserError("call reset() before state()")
        return np.asarray(spaces.flatten(self._full_space, fresh_observation(self._last)))

    def close(self) -> None:
        self.agents = []

    # ------------------------------------------------------------------ internals
    def _split(self, obs: dict) -> dict[str, dict[str, np.ndarray]]:
        """Agent i gets row i of a fresh copy of each per-drone array (its own memory, new every
        step) and its own copy of the shared entries; under a sensing model its own view, not the
        keys of :data:`_NOT_OWN`."""
        rows = {key: np.array(obs[key], dtype=np.float64) for key in self._rows if key not in self._hidden}
        shared = {key: value for key, value in obs.items() if key not in self._rows and key not in self._hidden}
        out = {}
        for name in self.agents:
            i = self._index[name]
            o = {key: np.array(value, dtype=np.float64) for key, value in shared.items()}
            o.update({key: value[i, ...] for key, value in rows.items()})  # [i, ...]: 0-d arrays, not scalars
            out[name] = o
        return out
