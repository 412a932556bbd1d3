"""The swarm as a ``dm_env.Environment`` (docs/design.md, "env").

One :meth:`SwarmEnv.step` is one control period T of the step pipeline (:class:`~swarm_mj.physics.sim.Sim`:
saturation, force stages, ``mj_step``, contacts, health). ``swarm-mj run``, the
Gymnasium/PettingZoo wrappers and user code step this class; they differ only in the policy
they plug in and in what they observe. The tuner flies the same :class:`~swarm_mj.physics.sim.Sim`
pipeline over many copies of one drone (:mod:`swarm_mj.tuning.evaluator`).

As dm_control's environment is a ``Physics`` and a ``Task``, this class is the one-copy case (m = 1)
of both halves written over a copies axis: the physics side
(:class:`~swarm_mj.pipeline.swarm.SwarmPhysics`, :attr:`SwarmEnv.physics`: the simulator with the
scenario's aero, the episode's wind and starts, the references and the leader-velocity estimate,
the wind held over each period, contact counting, health, the observation) and the task
(:mod:`swarm_mj.task`: observation keys, reward, termination).
:class:`swarm_mj.wrappers.vector.SwarmVectorEnv` drives the same two for m copies. What is this
class's own: the dm_env API, the action modes (U, a :class:`Command`, a setpoint), the
:class:`StepRecord`, ``raise_on_divergence`` and the exception naming why, and the attributes the
runner and the chunk driver read (``sim``, ``k``, ``wind``, ``refs``, ``observation``, ``obs_record``) and
what the chunk driver hands back (:meth:`SwarmEnv.after_chunk`).

What a step applied is in :attr:`SwarmEnv.last_applied`, a :class:`StepRecord`: the U1..U4
after saturation and the rotor thrusts, the wind force, and, when the action was a
:class:`Command` (what :class:`~swarm_mj.control.policy.BacksteppingPolicy.command` returns) or a
setpoint, the references and the commanded attitude that produced it. The runner's log and
the recording are built from these records.

Observation (a dict of arrays, drone axis first; ``n`` drones, leader = row 0):

=================  ============  ==========================================================
key                shape         meaning
=================  ============  ==========================================================
time               ()            simulated time (s)
pos, vel           (n, 3)        world position (m) and velocity (m/s) of the centre of mass
quat               (n, 4)        attitude quaternion (w, x, y, z), body → world
rpy, rpy_rate      (n, 3)        Z-Y-X Euler angles (φ, θ, ψ) (rad) and their rates (rad/s)
body_rates         (n, 3)        angular velocity in the body frame (rad/s)
setpoint           (n, 3)        formation setpoint: leader = its trajectory, followers = slot
setpoint_vel/acc   (n, 3)        its velocity / acceleration reference
setpoint_yaw       (n,)          yaw reference (rad)
leader_pos         (3,)          the leader's position (the only swarm-wide information)
neighbours         (n, n, 3)     position of drone j relative to drone i, zero outside sensing range
neighbour_mask     (n, n)        1 where drone j is within ``sensing_range`` of drone i (i ≠ j)
wind_force         (n, 3)        the wind force on each drone when the scenario gives the
                                 controller the wind (feedforward), else zeros
=================  ============  ==========================================================

Under a sensing model (``sensing=`` anything but ``perfect``; docs/sensing.md), each drone's own view
is added (:func:`swarm_mj.sensing.stage.view_keys`; row i: what drone i holds): ``view_pos``,
``view_vel`` (n, n, 3), ``view_mask``, ``view_age`` (n, n), ``view_setpoint``, ``view_setpoint_vel``
(n, n, 3), ``own_pos``, ``own_vel`` (n, 3), and ``neighbours``/``neighbour_mask`` are made from the
view. ``pos``, ``vel`` and ``setpoint`` stay the true ones (the reward's); the built-in policy reads
only the view and the drone's own state.

Actions (``action="thrust"``, default): U1..U4 per drone, shape (n, 4), bounded by what
the rotors can deliver; values outside ``action_spec()`` are clipped by the per-rotor
saturation (documented, never NaN physics); a non-finite action raises ``UserError``.
With ``action="setpoint"`` the action is a position setpoint (n, 3) handed to the
backstepping controller (velocity and acceleration references zero).

Observation, reward and termination are the task's (:mod:`swarm_mj.task`, written once over a
copies axis: this class is its one-copy case, :class:`swarm_mj.wrappers.vector.SwarmVectorEnv` its
m-copy case). Reward (formation keeping), per step:
``−mean_i ‖p_i − slot_i‖ − 10·(number of pairs closer than 0.5 m) − 100·(new contacts)``
(−1000 on divergence). Termination on a drone–drone contact (``terminate_on_contact``) or divergence
(``last_termination`` says which; after a non-finite divergence the observation is the
last finite one); truncation at the scenario's duration. ``reset(seed)`` seeds the wind
turbulence; random follower starts keep the scenario's own seed. ``reset()`` without a
seed replays the last one. The backstepping policy often asks for more than
``action_spec()`` allows (e.g. U1 up to ~27 N at take-off): the rotors' saturation clips it.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import dm_env
import numpy as np
from dm_env import specs

from ._jit import bind
from .choices import VehicleLike
from .control.backstepping import Backstepping
from .errors import SimulationDiverged, UserError
from .physics.sim import HEALTHY, ForceStage
from .physics.wind import WindSeries
from .pipeline.period import UNHEALTHY, all_finite
from .pipeline.records import Obs, Refs
from .pipeline.stepper import GivenPeriod
from .pipeline.swarm import SwarmPhysics
from .scenario import Scenario, flown
from .sensing import SensingParams
from .sensing.stage import SensingStage, sensing_stage, view_keys
from .task import copy_outcome, copy_reward, observation_specs


@dataclass(slots=True)
class Command:
    """An action with its provenance: the U1..U4 (n, 4) a controller computed from the references
    pos_d, vel_d, acc_d (n, 3) and the commanded attitude att_d (n, 3) = (φ_d, θ_d, ψ_d).
    :meth:`SwarmEnv.step` applies ``U`` and records the rest in :class:`StepRecord`."""

    U: np.ndarray  # (n, 4)
    pos_d: np.ndarray  # (n, 3) commanded position (after anti-collision)
    vel_d: np.ndarray  # (n, 3)
    acc_d: np.ndarray  # (n, 3)
    att_d: np.ndarray  # (n, 3) commanded (φ_d, θ_d, ψ_d)


@dataclass(slots=True)
class StepRecord:
    """What one :meth:`SwarmEnv.step` applied over the control period starting at ``time``.

    The references and commanded attitude are None when the action was a plain U array."""

    time: float  # s, start of the period
    U: np.ndarray  # (n, 4) U1..U4 after the rotors' saturation, held over the period
    rotor_thrust: np.ndarray  # (n, 4) F1..F4 produced
    wind_force: np.ndarray  # (n, 3) world-frame wind force applied (N)
    pos_d: np.ndarray | None  # (n, 3) references of the controller
    vel_d: np.ndarray | None  # (n, 3)
    acc_d: np.ndarray | None  # (n, 3)
    att_d: np.ndarray | None  # (n, 3) commanded (φ_d, θ_d, ψ_d)
    aero_forces: dict[str, np.ndarray] | None = None  # name -> (n, 3) force of each extra stage (N),
    #                                                    over the period's last physics step (docs/aero.md)


class Observation(dict):
    """SwarmEnv's observation: a dict of the module docstring's keys, and ``record``, the
    :class:`~swarm_mj.pipeline.records.Obs` whose arrays its values are (C-ordered float64 arrays of the
    observation's shapes, new each period). What the built-in policy reads without checking every array
    again, where the dict's arrays are still the record's (:meth:`BacksteppingPolicy.command
    <swarm_mj.control.policy.BacksteppingPolicy.command>`)."""

    __slots__ = ("record",)
    record: Obs


#: The one copy of SwarmEnv's physics (SwarmPhysics.begin's mask).
_ONE = np.ones(1, dtype=bool)


class SwarmEnv(dm_env.Environment):
    """A scenario as a dm_env environment. ``SwarmEnv("circle")`` or ``SwarmEnv(scenario)``.

    ``vehicle``: the drones flown instead of the scenario's (a bundled vehicle's name, a vehicle file or a
    :class:`~swarm_mj.vehicles.Vehicle`; with its own gains unless the scenario names some), ``aero``: the
    physics preset (``"paper"`` or ``"realistic"``, docs/aero.md); None: the scenario's
    (:func:`swarm_mj.scenario.flown`).

    ``force_stages``: extra :class:`~swarm_mj.physics.sim.ForceStage` s of the simulator, applied after
    drag and wind (e.g. aerodynamic effects between drones)."""

    _applied: tuple | None = None  # (time, references) of the last period flown (last_applied)
    _applied_record: StepRecord | None = None

    def __init__(
        self,
        scenario: Scenario | str,
        *,
        action: str = "thrust",
        terminate_on_contact: bool = True,
        raise_on_divergence: bool = False,
        seed: int | None = None,
        force_stages: Sequence[ForceStage] = (),
        vehicle: VehicleLike | None = None,
        aero: str | None = None,
        sensing: str | SensingParams | None = None,
    ) -> None:
        sc = flown(scenario, vehicle=vehicle, aero=aero)
        self.scenario = sc = sc if sensing is None else sc.with_overrides(sensing=sensing)
        if action not in ("thrust", "setpoint"):
            raise UserError(f"action must be 'thrust' or 'setpoint', got {action!r}")
        self.action_mode = action
        self.terminate_on_contact = terminate_on_contact
        self.raise_on_divergence = raise_on_divergence
        self.seed = sc.seed if seed is None else int(seed)
        self.n = n = sc.n_drones
        self.names = sc.names
        #: the physics side: one copy of the swarm (its Sim, aero, wind, references, contacts, health)
        self.physics = ph = SwarmPhysics(sc, force_stages=force_stages)
        self.T = ph.T
        self.n_steps = ph.n_steps
        self.sim = ph.blocks[0].sim
        self.world = self.sim.world
        self.params = self.world.params
        # Leader reference, precomputed at every control instant (analytic, docs/interpretations.md §3).
        self.times = ph.times  # (K+1,)
        self.reference = ph.reference
        self.D = ph.D  # (K+1,)
        self.unit_offsets = ph.unit_offsets  # (n-1, 3)
        #: each drone's own view (swarm_mj.sensing.stage; None: the ``perfect`` oracle, the true state)
        self.sensing: SensingStage | None = sensing_stage(sc.sensing, self.T, n)
        self._setpoint_ctl: Backstepping | None = None
        self._period = GivenPeriod(n, self.T, self.fly, self.observe_next)  # step's: the period with the action given
        self._reward_call: Callable[..., float] | None = None  # copy_reward bound (_reward)
        if action == "setpoint":
            self._setpoint_ctl = Backstepping(
                n,
                sc.gains,
                params=self.params,
                control_period=self.T,
                wind_feedforward=sc.wind_feedforward,
                attitude_map=sc.attitude_map,
            )
        f = self.params.f_max
        self._u_low = np.tile([0.0, -f, -f, -2 * f], (n, 1))
        self._u_high = np.tile([4 * f, f, f, 2 * f], (n, 1))
        self.reset()

    # ------------------------------------------------------------------ dm_env API
    def reset(self, seed: int | None = None) -> dm_env.TimeStep:
        if seed is not None:
            self.seed = int(seed)
        ph = self.physics
        ph.begin(_ONE, (self.seed,))  # k = 0, the wind of this seed, the leader estimate zeroed
        ph.reset()
        self._refs = ph.refs()  # the references as a record, shared with the chunk driver
        if self.sensing is not None:
            self.sensing.reset(ph.starts[: self.n], self.seed)
        self._applied = self._applied_record = None  # nothing flown yet this episode (last_applied)
        if self._setpoint_ctl is not None:
            self._setpoint_ctl.reset()
        self._done = False
        self.last_termination: str | None = None  # "contact" or "diverged" once an episode terminates
        self.last_error: Exception | None = None
        self._obs = self._observe()
        return dm_env.restart(self._obs)

    def step(self, action: np.ndarray | Command) -> dm_env.TimeStep:
        if self._done:
            return self.reset()
        refs = None
        if isinstance(action, Command):
            refs = (action.pos_d, action.vel_d, action.acc_d, action.att_d)
            action = action.U
        a = np.asarray(action, dtype=float)
        if self.action_mode == "setpoint":
            if a.shape != (self.n, 3):
                raise UserError(f"setpoint action must have shape ({self.n}, 3), got {a.shape}")
            if not all_finite(a):
                raise UserError("action contains NaN or inf")
            o = self._obs
            z = np.zeros((self.n, 3))
            ctl = self._setpoint_ctl
            assert ctl is not None
            U = ctl.compute(
                o["rpy"],
                o["rpy_rate"],
                o["pos"],
                o["vel"],
                a,
                z,
                z,
                o["setpoint_yaw"],
                wind_force=o["wind_force"],
                omega_body=o["body_rates"],
            )
            refs = (a, z, z, ctl.att_d.copy())
        else:
            if a.shape != (self.n, 4):
                raise UserError(f"thrust action must have shape ({self.n}, 4), got {a.shape}")
            U = a  # (a non-finite one is refused by the period, before anything flies)
        k = self.k  # the period flown now (swarm_mj.pipeline.stepper.GivenPeriod: the period with U given)
        diverged = None
        if self._period.fly(U, refs) == UNHEALTHY:
            try:
                self.sim.check()  # raises SimulationDiverged, naming why
            except SimulationDiverged as exc:
                if self.raise_on_divergence:
                    raise
                diverged = exc
            if diverged is None or np.isfinite(self.sim.qpos).all():
                self.observe_next()
        obs = self._obs  # after a non-finite divergence: the last finite observation
        new_contacts = int(self.physics.new_contacts[0])
        # the task's reward and termination (swarm_mj/task.py), as for every copy of the vector env
        reward, terminated, truncated = copy_outcome(
            self._reward(obs, new_contacts), diverged is not None, new_contacts, k + 1, self.n_steps,
            self.terminate_on_contact,
        )  # fmt: skip
        if terminated:
            self._done = True
            self.last_termination = "diverged" if diverged is not None else "contact"
            self.last_error = diverged
            return dm_env.termination(reward=float(reward), observation=obs)
        if truncated:
            self._done = True
            return dm_env.truncation(reward=float(reward), observation=obs)
        return dm_env.transition(reward=float(reward), observation=obs)

    def observation_spec(self):
        """The task's observation as dm_env specs, float64 (:func:`swarm_mj.task.observation_specs`): with a
        sensing stage also each drone's own view (``view_*``, ``own_pos``, ``own_vel``)."""
        return observation_specs(self.n, self.sensing is not None)

    def action_spec(self):
        if self.action_mode == "setpoint":
            return specs.BoundedArray((self.n, 3), np.float64, -1e3, 1e3, "setpoint")
        return specs.BoundedArray((self.n, 4), np.float64, self._u_low, self._u_high, "U")

    def reward_spec(self):
        return specs.Array((), np.float64, "reward")

    # ------------------------------------------------------------------ the period's physics and observation
    def fly(self, U: np.ndarray, refs: tuple | None = None) -> bool:
        """The physics of the period ``self.k`` with U (n, 4) (the step-by-step period's physics stage,
        swarm_mj.pipeline.stepper): the wind force of the period held over it (zero-order hold), the
        simulator's period (:meth:`swarm_mj.pipeline.swarm.SwarmPhysics.step`: contacts counted, k + 1);
        ``refs`` (pos_d, vel_d, acc_d, att_d) what :attr:`last_applied` names. Returns whether the
        simulator is healthy after it."""
        t = self.k * self.T
        healthy = self.physics.step(U)[0] == HEALTHY
        self._applied, self._applied_record = (t, refs), None  # last_applied, built when asked
        return bool(healthy)

    def observe_next(self) -> dict:
        """The observation of period ``self.k`` after a period flown by :meth:`fly` (its sensing stage ticked)."""
        self._obs = self._observe()
        return self._obs

    # ------------------------------------------------------------------ internals
    @property
    def time(self) -> float:
        return self.k * self.T

    @property
    def last_applied(self) -> StepRecord | None:
        """What the last period flown applied (None before the first of an episode): copies of the simulator's
        held inputs, produced rotor thrusts, wind force and stage forces, which stay as that period left them
        until the next (built at the first read after it), and the references of the :class:`Command` it was
        given (None for a plain U array or a period flown by the chunk driver)."""
        if self._applied is None:
            return None
        if self._applied_record is None:
            t, refs = self._applied
            sim = self.sim
            pos_d, vel_d, acc_d, att_d = refs if refs is not None else (None, None, None, None)
            self._applied_record = StepRecord(
                time=t,
                U=sim.ctrl.copy(),
                rotor_thrust=sim.rotor_thrust.copy(),
                wind_force=sim.wind.force.copy(),
                pos_d=pos_d,
                vel_d=vel_d,
                acc_d=acc_d,
                att_d=att_d,
                aero_forces=sim.stage_forces(),
            )
        return self._applied_record

    @property
    def last_wind_force(self) -> np.ndarray:
        """(n, 3) the wind force applied over the last control period (zeros before the first)."""
        rec = self.last_applied
        return rec.wind_force if rec is not None else np.zeros((self.n, 3))

    @property
    def k(self) -> int:
        """The control periods flown this episode (the physics' copy 0)."""
        return int(self.physics.k[0])

    @k.setter
    def k(self, k: int) -> None:  # the chunk driver hands back (swarm_mj/pipeline/fast.py)
        self.physics.k[0] = k

    @property
    def refs(self) -> Refs:
        """This episode's references as a record (the chunk driver's, over the same arrays; replaced by
        :meth:`reset`)."""
        return self._refs

    @property
    def observation(self) -> dict:
        """The observation the last :meth:`reset` or :meth:`step` returned (after a non-finite divergence: the
        last finite one)."""
        return self._obs

    def after_chunk(self, k: int, contacts_seen: int, obs: Obs | None = None) -> dict | None:
        """Take back the episode from a driver that stepped the simulator itself (the chunk driver,
        swarm_mj/pipeline/fast.py): ``k`` control periods flown, the simulator's ``contacts_seen`` drone–drone
        contacts counted into the rewards, and, where it stopped at the end of a period, that period's
        observation record ``obs`` (the observation is built from it and returned, and the episode is done at
        ``n_steps``, as :meth:`step` leaves it)."""
        self.k = k
        self.physics.count_until(contacts_seen)
        if obs is None:
            return None
        self._obs = self._observation(obs, sensed=True)
        if k > 0:  # the last period the driver flew: what it applied (last_applied), with no references
            self._applied, self._applied_record = ((k - 1) * self.T, None), None
        if k >= self.n_steps:
            self._done = True
        return self._obs

    @property
    def wind(self) -> WindSeries:
        """This episode's wind (:class:`~swarm_mj.physics.wind.WindSeries`, seeded with ``seed``)."""
        return self.physics.series[0]

    def _observe(self) -> dict:
        """The observation of period ``self.k``: :meth:`swarm_mj.pipeline.swarm.SwarmPhysics.observe`, the chunk
        driver's stage :func:`swarm_mj.pipeline.period.observe` (the known wind on the relative airspeed
        from the field)."""
        return self._observation(self.physics.observe(self._refs))

    def _observation(self, o: Obs, sensed: bool = False) -> Observation:
        """The observation dict of period ``self.k`` from its record ``o`` (see :meth:`observation_spec`);
        ``dist`` (n, n) is kept for the reward. Also what the chunk driver (:mod:`swarm_mj.pipeline.fast`)
        hands back after a chunk (``sensed``: the sensing stage already ticked period k there)."""
        self._dist = o.dist
        self.obs_record = o  #: the same arrays as a record (what the compiled stages read, e.g. the run log's row)
        obs = Observation(
            time=np.float64(self.k * self.T),
            pos=o.pos,
            vel=o.vel,
            quat=o.quat,
            rpy=o.rpy,
            rpy_rate=o.rpy_rate,
            body_rates=o.omega,
            setpoint=o.sp,
            setpoint_vel=o.spv,
            setpoint_acc=o.spa,
            setpoint_yaw=o.yaw,
            leader_pos=o.pos[0].copy(),
            neighbours=o.rel,
            neighbour_mask=o.mask,
            wind_force=o.wf,
        )
        obs.record = o
        if self.sensing is not None:
            k, r = self.k, self._refs
            if sensed:
                view = self.sensing.view()
            else:
                plan = (r.pos[k], r.vel[k], r.acc[k])
                view = self.sensing.observe(k, o.pos, o.vel, plan, float(r.D[k]), r.unit_offsets)
            obs.update(view_keys(view, self.scenario.sensing_range))
        return obs

    def _reward(self, obs: dict, new_contacts: int) -> float:
        """The task's reward of this step (:func:`swarm_mj.task.copy_reward`)."""
        pos, sp, dist, rec = obs["pos"], obs["setpoint"], self._dist, self.obs_record
        if pos is not rec.pos or sp is not rec.sp:  # the dict's arrays replaced: the dispatcher types them
            return copy_reward(pos, sp, dist, new_contacts)
        call = self._reward_call  # bound once (_jit.bind): the record's arrays are (n, 3), (n, n) float64, C order
        if call is None:
            call = self._reward_call = bind(copy_reward, pos, sp, dist, new_contacts)
        return call(pos, sp, dist, new_contacts)
