"""The physics side of the swarm environments, over a copies axis (docs/design.md, "The environment: one
task over copies").

As dm_control's ``Physics`` stands apart from its ``Task``, :class:`SwarmPhysics` holds what flies
an episode of m copies of a scenario's swarm (n drones each, copy-major: drone i of copy c is row
c·n + i of the (m·n, ...) arrays), apart from what the episode means (:mod:`swarm_mj.task`). Both
environments drive it: :class:`swarm_mj.env.SwarmEnv` is its one-copy case (m = 1, plus the dm_env
API) and :class:`swarm_mj.wrappers.vector.SwarmVectorEnv` its m-copy case (plus Gymnasium's
``VectorEnv`` API). Written once here, per copy:

================  ==================================================================================
part              what
================  ==================================================================================
models            blocks of at most ``block`` copies per MuJoCo model, each a
                  :class:`~swarm_mj.physics.sim.Sim` with ``n_copies``; the scenario's aero
                  (:func:`~swarm_mj.physics.aero.presets.install`) and extra force stages
episode           :meth:`begin`: the copy's seed, its starts (the scenario's, or with
                  ``seeded_starts`` drawn with the seed; at rest on a solid floor), its wind
                  series (:class:`~swarm_mj.physics.wind.WindField` seeded with the seed), k = 0,
                  its contact count and leader-velocity estimate back to zero;
                  :meth:`reset` / :meth:`put_back` put every copy / some copies at their starts
references        the leader trajectory and D(t) at every control instant, shared
                  (:attr:`reference`, :attr:`D`); :meth:`refs` a copy's
                  :class:`~swarm_mj.pipeline.records.Refs` (its wind, its leader estimate)
step              :meth:`step`: the wind force of each copy's period k (for the physics), the
                  control period of every block (on ``threads`` threads: contiguous groups of
                  blocks, :class:`~swarm_mj.experiments.parallel.ThreadTeam`), each copy's health
                  code and new drone–drone contacts, k + 1; copies being restarted fly it with
                  zero input and are put back
wind              :func:`copy_winds` (uniform wind) or each copy's
                  :meth:`~swarm_mj.physics.wind.WindSeries.drone_forces` (relative airspeed),
                  for the physics and for the observation's known wind
observation       :meth:`observe` (one copy: :func:`swarm_mj.pipeline.period.observe_into`, the chunk
                  driver's stage) and :meth:`observe_copies` (m copies into a flat buffer:
                  :func:`swarm_mj.task.observe_copies`, the same function per copy)
================  ==================================================================================
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from .._jit import Bound, bind, jit
from ..errors import UserError
from ..experiments.parallel import ThreadTeam, check_count
from ..formation.planner import leader_start
from ..formation.rule_params import LayersParams
from ..formation.slots import DiameterSchedule, polygon_offsets
from ..physics._mjstep import profiler_paused
from ..physics.aero.ground import REST_HEIGHT, rest_positions
from ..physics.aero.presets import install as install_aero
from ..physics.sim import MUJOCO_WARNING, ForceStage, Sim
from ..physics.wind import WindConfig, WindField, WindSeries
from ..physics.world import World, build_world
from ..scenario import Scenario
from ..task import CopyRefs, observe_copies
from ..trajectories import Reference
from .period import observe_into
from .records import Obs, Refs

__all__ = ["BLOCK_DRONES", "Block", "SwarmPhysics", "copy_winds"]

#: Drones per MuJoCo model at most (the default block is this many drones' worth of copies): MuJoCo's
#: site motor (U1) costs O(drones²) per model (swarm_mj/wrappers/vector.py).
BLOCK_DRONES = 48


@jit(samples=lambda: [(np.zeros((2, 3, 3)), np.zeros(2, np.int64), 2, 2, np.zeros((4, 3)))])
def copy_winds(wind: np.ndarray, k: np.ndarray, n_steps: int, n: int, out: np.ndarray) -> None:
    """out (m·n, 3): each copy's uniform wind force wind[c, min(k[c], n_steps)] (wind (m, K+1, 3), eq. 37)
    on each of its n drones."""
    for c in range(k.shape[0]):
        kk = min(k[c], n_steps)
        for i in range(c * n, c * n + n):
            for j in range(3):
                out[i, j] = wind[c, kk, j]


class Block:
    """Copies c0 .. c0 + b − 1 in one model: their Sim and rows."""

    def __init__(self, sim: Sim, c0: int, b: int, n: int) -> None:
        self.sim, self.c0, self.b = sim, c0, b
        self.copies = slice(c0, c0 + b)  # in (m, ...) arrays
        self.rows = slice(c0 * n, (c0 + b) * n)  # in (m·n, ...) arrays
        self.n_log = 0  # contact_log entries already counted
        # set by SwarmPhysics once its arrays exist: the only block (its rows every row), and its views of
        # SwarmPhysics.wind_now and .health
        self.whole = False
        self.wind_rows: np.ndarray
        self.health_rows: np.ndarray


def leader_reference(sc: Scenario) -> Callable[[np.ndarray], Reference]:
    """The reference the leader of ``sc`` flies: its trajectory, its start planned by the rule's planner
    (:func:`~swarm_mj.formation.planner.leader_start`) where it has followers to plan it for and its
    rule's record is a planner's (docs/barrier.md, "the leader's start")."""
    record, trajectory = sc.rule_params, sc.make_trajectory()
    if sc.n_followers == 0 or not isinstance(record, LayersParams):
        return trajectory
    return leader_start(record, trajectory, sc.leader_start)


class SwarmPhysics:
    """m copies of a scenario's swarm, stepped and observed per copy (module docstring).

    ``block``: copies per MuJoCo model (default: :data:`BLOCK_DRONES` drones' worth). ``contact_pairs``:
    drones touch only drones of their own copy, through explicit pairs (``build_world(contact_groups=
    ...)``, a vector env's blocks); False: the scenario's own model. ``seeded_starts``: an episode's
    seed also draws the copy's random follower starts (Gymnasium's ``reset(seed)``); False: the
    scenario's own starts (dm_env's, where the seed is the wind's). ``force_stages``: extra
    :class:`~swarm_mj.physics.sim.ForceStage` s after drag and wind (one block only: a stage is one
    simulator's).

    ``threads``: the blocks are stepped in that many contiguous groups (at most one per block), each
    on its own thread (:class:`~swarm_mj.experiments.parallel.ThreadTeam`: the first on the calling
    thread, the others on a pool started at the first such step and ended by :meth:`close`). A
    group's threads touch only its blocks' simulators and their slices of :attr:`health`; what is
    gathered over blocks (contacts, k) is done after, in block order, and the blocks are the same
    whatever the thread count, so every result is the same bit for bit with 1 thread or many."""

    def __init__(
        self,
        scenario: Scenario,
        m: int = 1,
        *,
        block: int | None = None,
        contact_pairs: bool = False,
        seeded_starts: bool = False,
        force_stages: Sequence[ForceStage] = (),
        threads: int = 1,
    ) -> None:
        threads = check_count("threads", threads)
        self.scenario = sc = scenario
        self.m = m = int(m)
        self.n = n = sc.n_drones
        self.T = T = sc.control_period
        self.n_steps = K = int(round(sc.duration / T))
        self.seeded_starts = bool(seeded_starts) and sc.n_followers > 0 and sc.follower_starts is None
        # the leader's reference and D at every control instant (analytic, docs/interpretations.md §3)
        self.times = np.arange(K + 1) * T  # (K+1,)
        self.reference = ref = leader_reference(sc)(self.times)  # its start planned where the rule plans it
        c = np.ascontiguousarray  # C-ordered float64: the records' types (swarm_mj/pipeline/records.py)
        self.D = c(DiameterSchedule(sc.diameter)(self.times), dtype=float)  # (K+1,)
        self.unit_offsets = c(polygon_offsets(n - 1, 1.0), dtype=float).reshape(n - 1, 3)  # (n-1, 3)
        self._ref = (c(ref.pos, dtype=float), c(ref.vel, dtype=float), c(ref.acc, dtype=float), c(ref.yaw, dtype=float))
        self.relative_wind = bool(sc.wind.enabled and sc.wind.relative_airspeed)
        self.wind_known = bool(sc.wind.enabled and sc.wind_feedforward)
        # bound to the simulator's arrays and the references: no re-typing per call (_jit.py)
        self._observe = Bound(observe_into, records=4)
        self._copy_refs = self._shared_refs(float(sc.sensing_range))
        self._yaws = np.r_[np.deg2rad(sc.leader_yaw_deg), np.zeros(n - 1)]  # (n,)
        aero = sc.aero
        start = self._starts(None)  # (n, 3)

        # the models: blocks of copies (blocks of the same size share one model)
        per = block if block is not None else max(1, BLOCK_DRONES // n)
        if not isinstance(per, (int, np.integer)) or per < 1:
            raise UserError(f"block must be an integer >= 1, got {block!r}")
        per = int(min(per, m))
        if force_stages and per < m:
            raise UserError("extra force stages need every copy in one model (block = the number of copies)")
        # Blocks of the same size share one model, unless threads step them and a block writes its model as it
        # steps (a solid floor's gate sets the floor's contype each period, Sim.floor_gate): then one model each.
        own = threads > 1 and bool(aero.ground)
        worlds: dict[tuple[int, int], World] = {}
        self.blocks: list[Block] = []
        for c0 in range(0, m, per):
            b = min(per, m - c0)
            key = (b, c0 if own else 0)
            if key not in worlds:
                worlds[key] = build_world(
                    b * n,
                    positions=np.tile(start, (b, 1)),
                    names=[f"c{i}_{name}" for i in range(b) for name in sc.names] if contact_pairs else sc.names,
                    yaws=np.tile(self._yaws, b),
                    timestep=sc.timestep,
                    integrator=sc.integrator,
                    ground=aero.ground,
                    motor_tau=aero.motor_tau,
                    contact_groups=b if contact_pairs else None,
                    params=sc.params,
                )
            sim = Sim(worlds[key], T, n_copies=b, force_stages=force_stages)
            if not aero.is_paper:
                install_aero(sim, aero)  # downwash, ground effect, ground contacts (docs/aero.md)
            self.blocks.append(Block(sim, c0, b, n))
        self.params = self.blocks[0].sim.params
        # the blocks' threads: contiguous groups of blocks, one per thread
        cuts = np.array_split(np.arange(len(self.blocks)), min(threads, len(self.blocks)))
        self.groups: list[list[Block]] = [[self.blocks[int(j)] for j in cut] for cut in cuts]
        self.threads = len(self.groups)
        self.team = ThreadTeam(self.threads, "swarm-mj-env")

        # per-copy state
        N = m * n
        self.k = np.zeros(m, dtype=np.int64)  # control periods flown this episode
        self.seeds = np.zeros(m, dtype=np.int64)  # each copy's episode seed (its wind, its starts)
        self.starts = np.tile(start, (m, 1))  # (N, 3)
        self.yaws = np.tile(self._yaws, m)  # (N,)
        self.prev_leader = np.zeros((m, 3))  # the leader-velocity estimate (paper §4), per copy
        self.leader_vel = np.zeros((m, 3))
        self.contacts = np.zeros(m, dtype=np.int64)  # drone–drone contacts this episode
        self.new_contacts = np.zeros(m, dtype=np.int64)  # ... over the last step
        self.health = np.zeros(m, dtype=np.int8)  # the last step's health codes (physics.sim.HEALTH_NAMES)
        # each copy's wind (begin); calm until then
        self.series: list[WindSeries] = [WindField(config=WindConfig.none(), dt=T).sample(self.times)] * m
        self.wind = np.zeros((m, K + 1, 3))  # (m, K+1, 3) each copy's uniform wind force series
        self.wind_now = np.zeros((N, 3))  # the wind force held over the current period (the physics)
        self.wind_obs = np.zeros((m, n, 3))  # the known wind force on the relative airspeed (the observation)
        # bound once (no re-typing per step, _jit.bind): these arrays are this object's, written only in place
        self._copy_winds = bind(copy_winds, self.wind, self.k, K, n, self.wind_now)
        for blk in self.blocks:  # each block's views of them (the arrays are written only in place)
            blk.whole = len(self.blocks) == 1
            blk.wind_rows, blk.health_rows = self.wind_now[blk.rows], self.health[blk.copies]

    def _shared_refs(self, sensing_range: float) -> CopyRefs:
        """The references every copy shares (the task's record): the leader trajectory, D(t), the wind's roles."""
        pos, vel, acc, yaw = self._ref
        return CopyRefs(
            T=float(self.T),
            sensing_range=sensing_range,
            pos=pos,
            vel=vel,
            acc=acc,
            yaw=yaw,
            D=self.D,
            unit_offsets=self.unit_offsets,
            wind_known=self.wind_known,
            relative=self.relative_wind,
        )

    # ------------------------------------------------------------------ episodes
    def _starts(self, seed: int | None) -> np.ndarray:
        """A copy's starts (n, 3): the scenario's, or its random follower starts drawn with ``seed``; raised to
        rest on a solid floor (docs/aero.md)."""
        sc = self.scenario
        pos = sc.initial_positions(seed)
        return pos if not sc.aero.ground else rest_positions(pos, REST_HEIGHT * sc.params.size_scale)

    def begin(self, mask: np.ndarray, seeds: Sequence[int] | np.ndarray) -> None:
        """New episodes for the copies of ``mask`` (m,) bool, copy c seeded with ``seeds[c]``: its wind (and,
        with ``seeded_starts``, its starts), k = 0, its contacts and leader-velocity estimate zeroed. Put
        the copies at their starts with :meth:`reset` or :meth:`put_back` (or a :meth:`step`'s ``restart``)."""
        n, sc = self.n, self.scenario
        for c in np.flatnonzero(mask):
            seed = int(seeds[int(c)])
            self.seeds[c] = seed
            if self.seeded_starts:
                self.starts[c * n : (c + 1) * n] = self._starts(seed)
            series = WindField(config=sc.wind, dt=self.T, seed=seed).sample(self.times)
            self.series[c] = series
            self.wind[c] = series.force
        self.k[mask] = 0
        self.contacts[mask] = 0
        self.prev_leader[mask] = self.starts[::n][mask]
        self.leader_vel[mask] = 0.0

    def reset(self) -> None:
        """Every copy at its start (:meth:`~swarm_mj.physics.sim.Sim.reset` of every block)."""
        for blk in self.blocks:
            blk.sim.reset(self.starts[blk.rows], self.yaws[blk.rows])
            blk.n_log = 0
        self.new_contacts[:] = 0

    def put_back(self, mask: np.ndarray) -> None:
        """The copies of ``mask`` (m,) back at their starts in their models, the others untouched
        (:meth:`~swarm_mj.physics.sim.Sim.reset_copies`)."""
        for blk in self.blocks:
            sub = mask[blk.copies]
            if sub.any():
                blk.sim.reset_copies(sub, self.starts[blk.rows], self.yaws[blk.rows])

    def refs(self, c: int = 0) -> Refs:
        """Copy c's references as a record (:class:`~swarm_mj.pipeline.records.Refs`: its wind this episode;
        its leader-velocity estimate, views updated in place by :func:`~swarm_mj.pipeline.period.observe`)."""
        pos, vel, acc, yaw = self._ref
        return Refs(
            pos=pos,
            vel=vel,
            acc=acc,
            yaw=yaw,
            D=self.D,
            unit_offsets=self.unit_offsets,
            prev_leader=self.prev_leader[c],
            leader_vel=self.leader_vel[c],
            sensing_range=float(self.scenario.sensing_range),
            wind_force=self.wind[c],
            wind_speed=np.ascontiguousarray(self.series[c].speed, dtype=float),
            wind_known=self.wind_known,
        )

    # ------------------------------------------------------------------ wind
    def drone_wind(self, c: int, vel: np.ndarray) -> np.ndarray:
        """Copy c's wind force on its drones (n, 3) at its period k, from their velocities vel (n, 3) (a fresh
        array; :meth:`~swarm_mj.physics.wind.WindSeries.drone_forces`)."""
        return self.series[c].drone_forces(min(int(self.k[c]), self.n_steps), vel)

    def _relative(self, out: np.ndarray) -> None:
        """:meth:`drone_wind` of every copy into out (m·n, 3) or (m, n, 3), from its drones' velocities."""
        n = self.n
        rows = out.reshape(self.m * n, 3)
        for blk in self.blocks:
            vel = blk.sim.vel
            for c in range(blk.c0, blk.c0 + blk.b):
                r = (c - blk.c0) * n
                rows[c * n : (c + 1) * n] = self.drone_wind(c, vel[r : r + n])

    # ------------------------------------------------------------------ step
    def step(self, U: np.ndarray, restart: np.ndarray | None = None) -> np.ndarray:
        """One control period of every copy with U (m·n, 4): the wind force of each copy's period k held over
        it, each block's :meth:`~swarm_mj.physics.sim.Sim.step`, then each copy's health code
        (:attr:`health`, (m,)), its new drone–drone contacts (:attr:`new_contacts`, added to
        :attr:`contacts`), k + 1. The copies of ``restart`` (m,) bool (begun, see :meth:`begin`) fly it from
        their starts with zero input and are put back after it: k 0, no contacts, healthy. Returns
        :attr:`health`."""
        n, new = self.n, self.new_contacts
        if restart is not None:
            self.put_back(restart)
            U = U.copy()
            U[np.repeat(restart, n)] = 0.0
        if self.relative_wind:
            self._relative(self.wind_now)
        else:
            self._copy_winds(self.wind, self.k, self.n_steps, n, self.wind_now)
        new.fill(0)
        if self.threads == 1:  # on this thread, where each Sim.step pauses MuJoCo's profiling clock itself
            self._fly(self.blocks, U)
        else:  # the clock is one global: paused here, once, rather than by each thread's Sim.step
            with profiler_paused():
                self.team.run(lambda group: self._fly(group, U), self.groups)
        for blk in self.blocks:  # then the contacts, in block order
            log = blk.sim.contact_log
            if len(log) > blk.n_log:
                for _, i, _ in log[blk.n_log :]:
                    new[blk.c0 + i // n] += 1
                    self.contacts[blk.c0 + i // n] += 1
                blk.n_log = len(log)
        self.k += 1
        if restart is not None:
            self.put_back(restart)
            self.k[restart] = 0
            new[restart] = 0
            self.contacts[restart] = 0  # begun: none before this step, and this step's are not theirs
            self.health[restart] = 0
        return self.health

    def _fly(self, group: list[Block], U: np.ndarray) -> None:
        """One thread's blocks through the period: their simulators and their rows of :attr:`health` only."""
        for blk in group:
            blk.sim.step(U if blk.whole else U[blk.rows], blk.wind_rows)
            blk.sim.health(blk.health_rows)

    def close(self) -> None:
        """End the threads of :attr:`team` (a later :meth:`step` starts them again)."""
        self.team.close()

    def forget_warnings(self) -> None:
        """Clear MuJoCo's divergence warnings of the blocks whose copies the last :meth:`step` reported
        with them (MuJoCo reset that whole model: every copy of it terminates once, then flies on)."""
        for blk in self.blocks:
            if (self.health[blk.copies] == MUJOCO_WARNING).any():
                blk.sim.data.warning.number[:] = 0

    def counted(self, c: int = 0) -> int:
        """The drone–drone contacts of copy c's block counted so far (its ``contact_log`` entries)."""
        return self.blocks[self._block_of(c)].n_log

    def count_until(self, seen: int, c: int = 0) -> None:
        """Copy c's block's contacts up to ``seen`` log entries counted (a driver that stepped its
        :class:`~swarm_mj.physics.sim.Sim` itself, e.g. the chunk driver, hands back)."""
        blk = self.blocks[self._block_of(c)]
        self.contacts[c] += seen - blk.n_log
        blk.n_log = seen

    def _block_of(self, c: int) -> int:
        return next(j for j, blk in enumerate(self.blocks) if blk.c0 <= c < blk.c0 + blk.b)

    # ------------------------------------------------------------------ observation
    def observe(self, refs: Refs) -> Obs:
        """The observation of copy 0 of a one-copy physics at its period k (fresh arrays):
        :func:`~swarm_mj.pipeline.period.observe_into` (the chunk driver's stage) on its simulator's state and
        ``refs`` (:meth:`refs`, kept by the caller: the chunk driver shares it), with the known wind on the
        relative airspeed from :meth:`drone_wind`."""
        o = Obs.empty(self.n, fill=False)  # new buffers (observe_into writes each): the environments hand them out
        rec = self.blocks[0].sim.record()
        self._observe(rec.qpos, rec.qvel, rec.T, refs, o, int(self.k[0]))
        if self.wind_known and self.relative_wind:
            o = o._replace(wf=self.drone_wind(0, o.vel))
        return o

    def observe_copies(
        self, copies: np.ndarray, offs: np.ndarray, out: np.ndarray, reward: np.ndarray, min_sep: np.ndarray
    ) -> None:
        """The task of the given copies (indices (c,) int64) at their periods k: observation into out[c]
        (m, dim) (key i of :data:`swarm_mj.task.OBS_KEYS` at offs[i]), reward (with :attr:`new_contacts`)
        into reward[c], minimum separation into min_sep[c] (:func:`swarm_mj.task.observe_copies`). A copy
        with a non-finite state keeps its last observation."""
        if self.wind_known and self.relative_wind:
            self._relative(self.wind_obs)
        for blk in self.blocks:
            cs = copies[(copies >= blk.c0) & (copies < blk.c0 + blk.b)]
            if len(cs):
                observe_copies(
                    blk.sim.qpos,
                    blk.sim.qvel,
                    self.n,
                    self._copy_refs,
                    cs,
                    blk.c0,
                    self.k,
                    self.prev_leader,
                    self.leader_vel,
                    self.wind,
                    self.wind_obs,
                    offs,
                    out,
                    self.new_contacts,
                    reward,
                    min_sep,
                )
