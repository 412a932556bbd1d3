"""m independent swarms as one ``gymnasium.vector.VectorEnv``: :class:`SwarmVectorEnv`.

    from swarm_mj.wrappers import SwarmVectorEnv
    envs = SwarmVectorEnv("circle", num_envs=64, flatten=True)
    obs, info = envs.reset(seed=0)              # copy i seeded with 0 + i
    obs, reward, terminated, truncated, info = envs.step(envs.action_space.sample())

**One physics and one task over copies, SwarmEnv's.** The m swarms of n drones are the copies of
:class:`~swarm_mj.pipeline.swarm.SwarmPhysics` (``self.physics``; SwarmEnv is its one-copy case):
blocks of MuJoCo models of the simulator's copies axis (:class:`~swarm_mj.physics.sim.Sim` with
``n_copies``: the same saturation, drag and wind stages, ``mj_step``, contact bookkeeping and
per-copy health mask as every run and as the tuner), each copy's seed, starts, wind and leader
estimate, and the task's observation over copies (:func:`swarm_mj.task.observe_copies`). This
class adds Gymnasium's ``VectorEnv`` API: spaces, auto-reset, the info layout. It flies any physics a
run flies (``aero="realistic"``: the solid floor, the rotors' lag, downwash, ground effect): a copy's
auto-reset puts it where a fresh environment's reset puts it, every stage included
(:meth:`~swarm_mj.physics.sim.Sim.reset_copies`: its drones' state, inputs and rotor lag states, then each
force stage's and monitor's ``reset_rows`` for its drones, e.g. the ground monitor's take-off and contact
memory; its wind series and leader estimate are begun anew).

Copies never interact: drones touch only drones of their own
copy (``build_world(contact_groups=...)``: explicit contact pairs within a copy), and a free
body's dynamics depend only on its own state and inputs, so a copy flies the same whether it
is alone or among others (tested: copy 5 of 64 == the same copy alone, bit for bit, when no
drones touch; with drones touching in every copy at once, to 1e-12, as MuJoCo's constraint
solver works on all of a model's contacts together).

**Blocks.** The copies are spread over blocks of at most ``block`` copies per MuJoCo model
(default: as many as fit in :data:`BLOCK_DRONES` drones; one copy per model with a solid floor, below):
MuJoCo's site motor (U1, see
``build_world(torque_motors=...)``) costs O(drones²) per model (measured: mj_step per drone
25 µs at 48 drones in one model, 182 µs at 384), like the tuner's blocks
(:data:`swarm_mj.tuning.evaluator.DEFAULT_BLOCK`). Blocks of the same size share one model.
``block=num_envs`` puts every copy in one model. With a solid floor (``[aero] ground``) the default is
one copy per model: MuJoCo's constraint solver works on a whole model at once, so a drone pressing on
the floor in one copy changes the last bits of the other copies of its model (measured: 1e-20 to 1e-17
in their positions, velocities and attitudes after a few periods, with ``block`` > 1).

**Threads.** ``threads`` (default: the CPUs this process may use, ``os.sched_getaffinity``) steps
the blocks on that many threads, in contiguous groups of blocks (at most one thread per block; one
block: no thread is started): MuJoCo's ``mj_step`` releases the GIL, so the blocks' physics runs on
as many cores. Each thread steps only its own blocks' models; the contacts, health codes and
periods gathered over blocks are gathered after, in block order, and the blocks themselves do not
depend on the thread count, so every observation, reward, flag and info is the same **bit for bit**
with 1 thread or many (tested: 1, 2 and 3 threads, with contacts and auto-resets). The pool of
threads is started at the first step and ended by :meth:`close` (or when the environment is
garbage-collected).

**Spaces.** ``single_action_space``: a flat float64 ``Box`` (4n,), U1..U4 of drone 0, then
drone 1, ... (``SwarmEnv.action_spec()`` reshaped: the same bounds); out-of-bound values are
clipped per rotor by the saturation, a non-finite action raises ``UserError``.
``single_observation_space``: :class:`~swarm_mj.wrappers.gymnasium.SwarmGymEnv`'s, a
``spaces.Dict`` of SwarmEnv's observation keys, or with ``flatten=True`` its
``gymnasium.spaces.flatten`` (one float64 Box, keys in sorted order). The batched spaces are
``gymnasium.vector.utils.batch_space`` of these (leading axis m).

**Episodes** are SwarmEnv's, per copy: the task of :mod:`swarm_mj.task` (written once over the
copies axis; SwarmEnv is its one-copy case): the same observation, reward (formation keeping),
termination on a drone–drone contact within the copy (``terminate_on_contact``) or on
divergence (the copy's health code, reward −1000; after a non-finite state the observation
is the last finite one), truncation at the scenario's duration. A MuJoCo divergence warning
(MuJoCo then resets a whole model) terminates every copy of that block.

**Auto-reset** (``metadata["autoreset_mode"]``): ``NEXT_STEP`` (Gymnasium's default): the
step after a copy's episode ended resets it, ignoring its action, and returns its first
observation with reward 0 and both flags False. ``SAME_STEP``: the step that ends an episode
resets the copy at once; ``info["final_obs"]`` and ``info["final_info"]`` hold what ended.
(The copy's physics runs with the others; a copy being reset gets zero input for that step
and is put back at its start afterwards.)

**Seeds.** ``reset(seed=s)`` seeds copy i with s + i (or ``seed=[s0, s1, ...]``): its wind
turbulence and its random follower starts (scenarios with ``random_start``, drawn as
``Scenario.initial_positions(seed)`` draws them; SwarmGymEnv keeps the scenario's own starts).
Each copy also gets a generator seeded with s + i (``gymnasium.utils.seeding.np_random``)
from which an auto-reset or unseeded reset draws the
copy's next seed, as ``SwarmGymEnv.reset()`` does; so for a scenario with fixed starts the
vector env gives, bit for bit, what ``gymnasium.vector.SyncVectorEnv`` over m
``SwarmGymEnv`` gives (tested).

**Sensing.** ``sensing=`` (SwarmEnv's: a preset's name or a :class:`~swarm_mj.sensing.SensingParams`): under
any model but ``perfect`` each copy has its own :class:`~swarm_mj.sensing.stage.SensingStage`, reset at every
reset and auto-reset of the copy from its starts with the copy's episode seed (the copy's seed s + i, or the one
drawn from its generator: the same sensing stream as ``SwarmEnv.reset(seed)`` of that seed, so copies with
different seeds get different noise and the vector env equals ``SyncVectorEnv`` over ``SwarmGymEnv(...,
sensing=...)``, tested), and observed after each period from the copy's observed states: the view keys
(SwarmEnv's ``view_*``, ``own_pos``, ``own_vel``, and ``neighbours``/``neighbour_mask`` from the view) are in
the copy's observation (its slots of the flat buffer, where the Dict space puts them).

**Info** (Gymnasium's vector format: ``info[key]`` (m,) with a bool mask ``info["_key"]``):
``time``, ``contacts``, ``new_contacts``, ``min_separation`` for copies that stepped,
``wind_seed`` for copies that were reset, ``termination`` ("contact" / "diverged") and
``error`` (why) for copies that terminated.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from .._jit import warm_module
from ..choices import VehicleLike
from ..env import all_finite
from ..errors import UserError
from ..experiments.parallel import check_count, default_workers
from ..physics.sim import HEALTH_NAMES, HEALTHY
from ..pipeline.stepper import GivenPeriod
from ..pipeline.swarm import BLOCK_DRONES, Block, SwarmPhysics
from ..scenario import Scenario, flown
from ..sensing import SensingParams
from ..sensing.stage import SensingStage, sensing_stage, view_keys
from ..task import OBS_KEYS, outcomes
from .gymnasium import observation_space_for, seed_from

__all__ = ["BLOCK_DRONES", "OBS_KEYS", "SwarmVectorEnv"]


def _info_add(info: dict[str, Any], key: str, values: np.ndarray, mask: np.ndarray) -> None:
    """Gymnasium's vector info layout: info[key] (m,), info["_key"] (m,) bool."""
    info[key] = values
    info["_" + key] = mask


def _prune(info: dict[str, Any]) -> dict[str, Any]:
    """Without the keys no copy has (as Gymnasium's vector envs leave them out)."""
    return {
        key: v for key, v in info.items() if (key.removeprefix("_")) not in info or info["_" + key.lstrip("_")].any()
    }


class SwarmVectorEnv(VectorEnv):
    """``num_envs`` independent copies of a scenario's swarm as one Gymnasium ``VectorEnv`` (module docstring).

    ``scenario``: a name, path or :class:`Scenario`. ``flatten``: one float64 Box observation
    per copy instead of the Dict. ``block``: copies per MuJoCo model (default: ``BLOCK_DRONES``
    drones' worth). ``autoreset_mode``: ``AutoresetMode.NEXT_STEP`` (default) or ``SAME_STEP``.
    ``threads``: the threads that step the blocks (default: the usable CPUs; results do not depend on it).
    ``vehicle``: the drones flown instead of the scenario's, ``aero``: the physics preset (``"paper"`` or
    ``"realistic"``), ``sensing``: the sensing model (module docstring, "Sensing") (:class:`~swarm_mj.env.SwarmEnv`'s).
    """

    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": []}  # noqa: RUF012 (Gymnasium's)

    def __init__(
        self,
        scenario: Scenario | str = "circle",
        num_envs: int = 8,
        *,
        flatten: bool = False,
        terminate_on_contact: bool = True,
        block: int | None = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        render_mode: str | None = None,
        threads: int | None = None,
        vehicle: VehicleLike | None = None,
        aero: str | None = None,
        sensing: str | SensingParams | None = None,
    ) -> None:
        threads = default_workers() if threads is None else check_count("threads", threads)
        if render_mode is not None:
            raise UserError(f"render_mode {render_mode!r} is not supported (use swarm-mj run --video)")
        if not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
            raise UserError(f"num_envs must be an integer >= 1, got {num_envs!r}")
        try:
            mode = autoreset_mode if isinstance(autoreset_mode, AutoresetMode) else AutoresetMode(autoreset_mode)
        except ValueError:
            raise UserError(f"autoreset_mode must be next-step or same-step, got {autoreset_mode!r}") from None
        if mode not in (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP):
            raise UserError(f"autoreset_mode must be next-step or same-step, got {mode.value!r}")
        self.metadata = {**type(self).metadata, "autoreset_mode": mode}
        self.autoreset_mode = mode
        self.render_mode = None
        sc = flown(scenario, vehicle=vehicle, aero=aero)
        self.scenario = sc = sc if sensing is None else sc.with_overrides(sensing=sensing)  # as SwarmEnv's
        warm_module("swarm_mj.task")  # the copies' observation kernel (_jit.jit's on_demand), compiled once
        self.num_envs = m = int(num_envs)
        self.n = n = sc.n_drones
        self.flatten = bool(flatten)
        self.terminate_on_contact = bool(terminate_on_contact)
        # the physics side: the copies in blocks of MuJoCo models, their seeds, starts, wind, contacts, health
        if block is None and sc.aero.ground:
            block = 1  # the solver takes a model's floor contacts together (module docstring, "Blocks")
        self.physics = ph = SwarmPhysics(sc, m, block=block, contact_pairs=True, seeded_starts=True, threads=threads)
        self.threads = ph.threads  # at most one per block
        self._blocks: list[Block] = ph.blocks
        self.params = ph.params
        self.T = ph.T
        self.n_steps = ph.n_steps
        self.times = ph.times  # (K+1,)

        #: each copy's own sensing stage (module docstring, "Sensing"; empty: the ``perfect`` oracle)
        stages = [sensing_stage(sc.sensing, self.T, n) for _ in range(m)]
        self.sensing: list[SensingStage] = [st for st in stages if st is not None]
        self._plan = ph.refs()  # the leader's plan and D(t), shared by the copies (the stages read them)
        self._block_of = np.repeat(np.arange(len(ph.blocks)), [blk.b for blk in ph.blocks])  # (m,) copy -> block

        # spaces: SwarmGymEnv's, per copy
        self.single_dict_observation_space = observation_space_for(n, bool(self.sensing))
        self.single_observation_space = (
            spaces.flatten_space(self.single_dict_observation_space)
            if self.flatten
            else self.single_dict_observation_space
        )
        self.observation_space = batch_space(self.single_observation_space, m)

        # the flat layout (the Dict's key order, as spaces.flatten writes it)
        self._slots: dict[str, tuple[int, int, tuple[int, ...]]] = {}  # key: offset, size, shape
        off = 0
        for key, space in self.single_dict_observation_space.spaces.items():
            assert space.shape is not None  # every observation entry is a Box
            size = int(np.prod(space.shape, dtype=np.int64))
            self._slots[key] = (off, size, space.shape)
            off += size
        self._dim = off
        self._offs = np.array([self._slots[key][0] for key in OBS_KEYS], dtype=np.int64)

        f = self.params.f_max
        low = np.tile([0.0, -f, -f, -2 * f], n)
        high = np.tile([4 * f, f, f, 2 * f], n)
        self.single_action_space = spaces.Box(low=low, high=high, shape=(4 * n,), dtype=np.float64)
        self.action_space = batch_space(self.single_action_space, m)

        # per-copy state (the rest is the physics')
        self._rngs: list[np.random.Generator | None] = [None] * m
        self._obs = np.zeros((m, self._dim))
        self._reward = np.zeros(m)
        self._min_sep = np.zeros(m)
        self._autoreset = np.zeros(m, dtype=bool)
        self._started = False
        self._all = np.arange(m, dtype=np.int64)
        # step's period, the actions given (swarm_mj.pipeline.stepper): its physics and observation are these
        self._restart: np.ndarray | None = None  # the copies the coming period restarts
        self._health = np.zeros(m, dtype=np.int8)  # each copy's health code after it
        self._period = GivenPeriod(m * n, self.T, self._fly_copies, lambda: self._observe(self._all))

    def _fly_copies(self, U: np.ndarray, refs: None) -> bool:  # noqa: ARG002
        """The period's physics: every copy's (:meth:`SwarmPhysics.step`, the copies of ``_restart`` from their
        starts with zero input). Each copy's health is its own (the task's), never the whole batch's: True."""
        ph = self.physics
        self._health = ph.step(U, self._restart).copy()
        ph.forget_warnings()  # a block MuJoCo reset: its copies all terminate now, then fly on
        return True

    # ------------------------------------------------------------------ episodes
    def _copy_seed(self, c: int) -> int:
        rng = self._rngs[c]
        if rng is None:
            rng = self._rngs[c] = np.random.default_rng()
        return seed_from(rng)

    def _begin(self, mask: np.ndarray, seeds: Sequence[int] | None) -> None:
        """New episodes for the copies of mask (m,) (:meth:`SwarmPhysics.begin`): seeds per copy, or drawn
        from each copy's generator."""
        chosen = np.zeros(self.num_envs, dtype=np.int64)
        for c in np.flatnonzero(mask):
            chosen[c] = int(seeds[int(c)]) if seeds is not None else self._copy_seed(int(c))
        ph = self.physics
        ph.begin(mask, chosen)
        n = self.n
        for c in np.flatnonzero(mask) if self.sensing else ():
            self.sensing[c].reset(ph.starts[c * n : (c + 1) * n], int(ph.seeds[c]))  # as SwarmEnv.reset's

    def _observe(self, copies: np.ndarray) -> None:
        """The task's observation, reward (before divergence) and minimum separation of the given copies
        (:meth:`SwarmPhysics.observe_copies`, :func:`swarm_mj.task.observe_copies`), and each copy's own view."""
        self.physics.observe_copies(copies, self._offs, self._obs, self._reward, self._min_sep)
        if self.sensing:
            self._sense(copies)

    def _sense(self, copies: np.ndarray) -> None:
        """Each given copy's sensing stage observes its period k from the states its observation holds (as
        SwarmEnv's does from its record) and writes the view keys into its slots of the flat buffer. A copy with
        a non-finite state is skipped, as :func:`swarm_mj.task.observe_copies` skips it (its view not advanced)."""
        n, ph, r = self.n, self.physics, self._plan
        rng = self.scenario.sensing_range
        for c in copies:
            blk = self._blocks[int(self._block_of[c])]
            rows = slice((int(c) - blk.c0) * n, (int(c) - blk.c0 + 1) * n)
            if not (all_finite(blk.sim.qpos[rows]) and all_finite(blk.sim.qvel[rows])):
                continue
            o = self._obs[c]
            pos, vel = (
                o[off : off + size].reshape(shape).copy()
                for off, size, shape in (self._slots[key] for key in ("pos", "vel"))
            )
            k = int(ph.k[c])
            view = self.sensing[c].observe(k, pos, vel, (r.pos[k], r.vel[k], r.acc[k]), float(r.D[k]), r.unit_offsets)
            for key, value in view_keys(view, rng).items():
                off, size, _ = self._slots[key]
                o[off : off + size] = np.asarray(value, dtype=np.float64).reshape(-1)

    @property
    def k(self) -> np.ndarray:
        """(m,) the control periods each copy has flown this episode."""
        return self.physics.k

    @property
    def wind_seed(self) -> np.ndarray:
        """(m,) each copy's episode seed (its wind turbulence and random starts)."""
        return self.physics.seeds

    def _observation(self, flat: np.ndarray):
        """The batched observation of a fresh copy of the flat buffer (m, dim)."""
        if self.flatten:
            return flat
        m = flat.shape[0]
        return {key: flat[:, off : off + size].reshape((m, *shape)) for key, (off, size, shape) in self._slots.items()}

    # ------------------------------------------------------------------ VectorEnv API
    def reset(self, *, seed: int | Sequence[int] | None = None, options: dict | None = None):
        """Reset every copy (``seed``: an int s gives copy i the seed s + i; a list, one per copy)."""
        m = self.num_envs
        seeds: list[int] | None = None
        if seed is not None:
            if isinstance(seed, (int, np.integer)):
                super().reset(seed=int(seed))
                seeds = [int(seed) + i for i in range(m)]
            else:
                seeds = [int(s) for s in seed]
                if len(seeds) != m:
                    raise UserError(f"reset needs one seed per copy ({m}), got {len(seeds)}")
            for c in range(m):
                self._rngs[c] = seeding.np_random(seeds[c])[0]
        everyone = np.ones(m, dtype=bool)
        self._begin(everyone, seeds)
        self.physics.reset()
        self._observe(self._all)
        self._autoreset[:] = False
        self._started = True
        info: dict[str, Any] = {}
        _info_add(info, "time", np.zeros(m), everyone.copy())
        _info_add(info, "wind_seed", self.wind_seed.copy(), everyone.copy())
        return self._observation(self._obs.copy()), info

    def step(self, actions):
        if not self._started:
            raise gymnasium.error.ResetNeeded("call reset() before step()")
        m, n = self.num_envs, self.n
        a = np.asarray(actions, dtype=np.float64)
        if a.shape != (m, 4 * n):
            raise UserError(f"actions must have shape ({m}, {4 * n}), got {a.shape}")
        if not all_finite(a):
            raise UserError("action contains NaN or inf")
        U = a.reshape(m * n, 4)
        resetting = self._autoreset.copy() if self.autoreset_mode == AutoresetMode.NEXT_STEP else np.zeros(m, bool)
        restart = None
        if resetting.any():
            self._begin(resetting, None)
            restart = resetting
        # the period with the actions given (swarm_mj.pipeline.stepper.GivenPeriod): the physics of every copy
        # (the copies being reset fly from their starts with zero input), then the observation of every copy
        ph = self.physics
        self._restart = restart
        self._period.fly(U)
        health = self._health
        diverged = health != HEALTHY
        # the task's reward and termination (swarm_mj/task.py), as SwarmEnv's
        rewards, terminated, truncated = outcomes(
            self._reward, diverged, ph.new_contacts, ph.k, self.n_steps, self.terminate_on_contact
        )
        rewards[resetting] = 0.0
        terminated[resetting] = False
        truncated[resetting] = False
        info = self._step_info(~resetting, terminated, diverged, health)
        if resetting.any():
            info["_time"][:] = True  # a reset copy's info is its reset info: time 0, its seed
            _info_add(info, "wind_seed", self.wind_seed.copy(), resetting)
        done = terminated | truncated
        obs_flat = self._obs.copy()
        if self.autoreset_mode == AutoresetMode.NEXT_STEP:
            self._autoreset = done
        elif done.any():
            final_obs = np.full(m, None, dtype=object)
            final = self._observation(obs_flat.copy())
            for c in np.flatnonzero(done):
                final_obs[c] = final[c] if self.flatten else {key: v[c] for key, v in final.items()}
            final_info = _prune({key: (v & done if key.startswith("_") else v) for key, v in info.items()})
            self._begin(done, None)
            ph.put_back(done)
            ph.new_contacts[done] = 0
            self._observe(np.flatnonzero(done).astype(np.int64))
            obs_flat = self._obs.copy()
            # the ended copies' info is their reset info (time 0, their seed); what ended is in final_info
            for key in ("contacts", "new_contacts", "min_separation"):
                info["_" + key] = info["_" + key] & ~done
            info.pop("termination", None), info.pop("_termination", None)
            info.pop("error", None), info.pop("_error", None)
            info["time"] = np.where(done, 0.0, info["time"])
            _info_add(info, "final_obs", final_obs, done.copy())
            _info_add(info, "final_info", final_info, done.copy())
            _info_add(info, "wind_seed", self.wind_seed.copy(), done | resetting)
        return self._observation(obs_flat), rewards, terminated, truncated, _prune(info)

    def _step_info(
        self, stepped: np.ndarray, terminated: np.ndarray, diverged: np.ndarray, health: np.ndarray
    ) -> dict[str, Any]:
        info: dict[str, Any] = {}
        _info_add(info, "time", self.k * self.T, stepped.copy())
        _info_add(info, "contacts", self.physics.contacts.copy(), stepped.copy())
        _info_add(info, "new_contacts", self.physics.new_contacts.copy(), stepped.copy())
        _info_add(info, "min_separation", self._min_sep.copy(), stepped.copy())
        if terminated.any():
            why = np.full(self.num_envs, None, dtype=object)
            error = np.full(self.num_envs, None, dtype=object)
            for c in np.flatnonzero(terminated):
                why[c] = "diverged" if diverged[c] else "contact"
                if diverged[c]:
                    error[c] = HEALTH_NAMES[int(health[c])]
            _info_add(info, "termination", why, terminated.copy())
            if diverged.any():
                _info_add(info, "error", error, diverged.copy())
        return info

    def close(self, **kwargs: Any) -> None:
        self.physics.close()  # the blocks' threads end
        self._started = False
        self.closed = True
