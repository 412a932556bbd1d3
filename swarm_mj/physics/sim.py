"""The simulation core: one control period of the step pipeline (docs/design.md, "the step pipeline").

:meth:`Sim.step` owns each control period T, in one compiled call where it can (:func:`period_physics`:
1. and 2. below, handing back to Python only the physics steps Python must see, as the chunk driver of
swarm_mj/pipeline/period.py does; else :func:`python_period`, handing back after every step), in one loop
over the steps (:meth:`Sim._fly_period`). The kernels are in :mod:`swarm_mj.physics.kernels`, the compiled
period in :mod:`swarm_mj.physics.compiled`, drag and wind in :mod:`swarm_mj.physics.stages`, the contact
pairs in :mod:`swarm_mj.physics.contacts` (their names re-exported here):

1. **saturation** — the commanded U1..U4 (N, 4) are mapped to rotor thrusts, clipped to
   [f_min, f_max] per rotor and mapped back (:func:`swarm_mj.physics.mixing.saturate_kernel`,
   docs/interpretations.md §1); the result is held in ``ctrl`` for the whole period (a
   zero-order hold, docs/interpretations.md §2); with a solid floor, the **floor gate**
   (:func:`floor_gate_kernel`) leaves the floor out of MuJoCo's collision tests for the period
   when no drone could reach it (the same run bit for bit, docs/aero.md);
2. per physics step (``model.opt.timestep``; two per 10-ms period at the 5-ms default):

   a. the **force stages** each ADD a world-frame force and torque at every drone's centre of
      mass (:class:`ForceStage`): first :class:`DragStage` (paper eq. 1, −(Kx·ẋ, Ky·ẏ, Kz·ż)
      from the velocity at the start of the physics step, held over its RK4 stages), then
      :class:`WindStage` (the wind force F^w of eq. 37, held over the control period), then any
      extra stage in the order given; the sum goes to ``xfrc_applied``;
   b. ``mujoco.mj_step``, with MuJoCo's profiling clock (``mjcb_time``, which feeds
      ``mjData.timer`` and nothing else) off while the period is stepped: its clock reads cost
      about a tenth of a step (:func:`swarm_mj.physics._mjstep.timer_pause`);
   c. **contacts** between drones (rising edges counted, :attr:`Sim.contact_log`), then the
      **monitors** (:class:`Monitor`, e.g. the ground contacts and crashes of
      :class:`swarm_mj.physics.aero.ground.GroundContacts`), each reading the state after the step;

3. the **health mask** (:meth:`Sim.health`): per copy, a non-finite state, a drone below
   ``floor_z`` or beyond ``max_distance`` (optionally tilted beyond ``max_tilt``), or a new
   MuJoCo divergence warning (a bad position, velocity, acceleration or control: MuJoCo then
   resets the whole ``MjData`` and goes on, so the state alone may look sane).

**Copies.** ``Sim(world, T, n_copies=m)`` steps m independent copies of an n-drone swarm held
in one model of N = m·n drones, copy-major (drone i of copy c is row c·n + i); the tuner flies
its candidates this way. :meth:`park` holds diverged copies at their start with zero input so
that a bad state never reaches MuJoCo.

State arrays are views into MjData with the drone axis first (N rows):
``pos (N, 3)``, ``quat (N, 4)`` (w, x, y, z), ``vel (N, 3)`` world frame,
``omega (N, 3)`` body frame, ``ctrl (N, 4)`` the U1..U4 applied, ``rotor_thrust (N, 4)``
the rotor thrusts F1..F4 actually produced.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Iterable, Sequence
from collections.abc import Set as AbstractSet
from typing import Protocol

import mujoco
import numpy as np

from .._jit import bind, compiled
from ..errors import SimulationDiverged, UserError
from ..pipeline import registry
from ..pipeline.records import Kinematics, Physics
from . import _mjstep
from ._mjstep import timer_pause, timer_resume
from .compiled import (
    apply_forces,
    drone_views,
    hold_inputs,
    log_stage_forces,
    period_physics,
    physics_steps,
    track_monitors,
    unhealthy,
)
from .contacts import touching_pairs
from .kernels import (
    BELOW_FLOOR,
    DIVERGENCE_WARNING_IDS,
    DIVERGENCE_WARNINGS,
    FLOOR_GATE_M,
    HEALTH_NAMES,
    HEALTHY,
    MUJOCO_WARNING,
    NON_FINITE,
    TILTED,
    TOO_FAR,
    add_drag_kernel,
    copy_state,
    drag_kernel,
    drone_state,
    first_unhealthy,
    floor_gate,
    floor_gate_kernel,
    flush_stage_forces,
    health_kernel,
    unmix_kernel,
)
from .params import QuadParams
from .stages import DragStage, WindStage
from .world import World

#: The simulator and, re-exported, the names its modules define (imports from swarm_mj.physics.sim keep working).
__all__ = [
    "BELOW_FLOOR",
    "DIVERGENCE_WARNINGS",
    "DIVERGENCE_WARNING_IDS",
    "FLOOR_GATE_M",
    "HEALTHY",
    "HEALTH_NAMES",
    "MUJOCO_WARNING",
    "NON_FINITE",
    "TILTED",
    "TOO_FAR",
    "DragStage",
    "ForceStage",
    "Monitor",
    "Sim",
    "WindStage",
    "add_drag_kernel",
    "apply_forces",
    "copy_state",
    "drag_kernel",
    "drone_state",
    "drone_views",
    "first_unhealthy",
    "floor_gate",
    "floor_gate_kernel",
    "flush_stage_forces",
    "health_kernel",
    "hold_inputs",
    "log_stage_forces",
    "period_physics",
    "physics_steps",
    "track_monitors",
    "unhealthy",
    "unmix_kernel",
]

_W_QACC, _W_QPOS, _W_QVEL, _W_CTRL = DIVERGENCE_WARNING_IDS


class Monitor(Protocol):
    """Reads the state after every physics step (never writes it): counters such as ground contacts."""

    name: str

    def reset(self, sim: Sim) -> None: ...

    def reset_rows(self, sim: Sim, rows: np.ndarray) -> None:
        """As :meth:`reset` for the drones of ``rows`` (N,) bool (the copies :meth:`Sim.reset_copies` puts
        back), the others untouched."""

    def after_step(self, sim: Sim) -> None: ...


class ForceStage(Protocol):
    name: str

    def reset(self, sim: Sim) -> None: ...

    def reset_rows(self, sim: Sim, rows: np.ndarray) -> None:
        """As :meth:`reset` for the drones of ``rows`` (N,) bool (the copies :meth:`Sim.reset_copies` puts
        back), the others untouched."""

    def apply(self, sim: Sim, force: np.ndarray, torque: np.ndarray) -> None:
        """ADD this stage's world-frame force (N, 3) [N] and torque (N, 3) [N·m] at each drone's CoM
        for the coming physics step. N = all drones of all copies, in sim order (copy-major)."""


def _index(ids: np.ndarray) -> slice | np.ndarray:
    """A slice when ids form an arithmetic progression (numpy then returns views), else the ids."""
    ids = np.asarray(ids)
    if len(ids) == 1:
        return slice(int(ids[0]), int(ids[0]) + 1)
    step = int(ids[1] - ids[0])
    if step > 0 and np.all(np.diff(ids) == step):
        return slice(int(ids[0]), int(ids[-1]) + 1, step)
    return ids


class Sim:
    """Steps a :class:`~swarm_mj.physics.world.World` one control period at a time (see the module docstring).

    world: N drones = ``n_copies`` copies of n = N / n_copies drones, copy-major.
    force_stages: extra :class:`ForceStage` s, applied after drag and wind (also :meth:`add_stage`).
    monitors: :class:`Monitor` s run after every physics step (also :meth:`add_monitor`).
    floor_z, max_distance, max_tilt: the health limits (m, m, rad; ``max_tilt`` None: not checked).
    """

    def __init__(
        self,
        world: World,
        control_period: float = 0.01,
        *,
        n_copies: int = 1,
        force_stages: Sequence[ForceStage] = (),
        monitors: Sequence[Monitor] = (),
        floor_z: float = -0.5,
        max_distance: float = 1e3,
        max_tilt: float | None = None,
    ) -> None:
        m = world.model
        dt = m.opt.timestep
        nsub = int(round(control_period / dt))
        if nsub < 1 or abs(nsub * dt - control_period) > 1e-9 * max(1.0, control_period):
            raise UserError(f"physics timestep {dt} s must divide the control period {control_period} s")
        if m.nq != 7 * world.n_drones or m.nu != 4 * world.n_drones:
            raise UserError("the model must hold only the drones' free joints and four motors per drone")
        if not isinstance(n_copies, (int, np.integer)) or n_copies < 1 or world.n_drones % n_copies:
            raise UserError(f"n_copies must divide the {world.n_drones} drones of the model, got {n_copies!r}")
        self.world = world
        self.model = m
        self.data = mujoco.MjData(m)
        self.n_total = N = world.n_drones
        self.n_copies = int(n_copies)
        self.n = N // self.n_copies  # drones per copy
        self.control_period = float(control_period)
        self.n_substeps = nsub
        self.floor_z = float(floor_z)
        self.max_distance = float(max_distance)
        self.max_tilt = np.inf if max_tilt is None else float(max_tilt)
        p = world.params
        self.params: QuadParams = p
        self._f_min, self._f_max = p.f_min, p.f_max
        self._unmix_t, self._mix_t = p.unmix_t, p.mix_t  # the vehicle's rotor mixing (docs/vehicles.md)
        d = self.data
        self.qpos = d.qpos.reshape(N, 7)  # views into MjData
        self.qvel = d.qvel.reshape(N, 6)
        self.pos = self.qpos[:, 0:3]  # (N, 3)
        self.quat = self.qpos[:, 3:7]  # (N, 4) w, x, y, z
        self.vel = self.qvel[:, 0:3]  # (N, 3) world frame
        self.omega = self.qvel[:, 3:6]  # (N, 3) body frame
        self.ctrl = d.ctrl.reshape(N, 4)  # (N, 4) = U1..U4 applied
        idx = _index(world.body_ids)
        self._xfrc_force = d.xfrc_applied[idx, 0:3]  # (N, 3) views
        self._xfrc_torque = d.xfrc_applied[idx, 3:6]
        if not np.shares_memory(self._xfrc_force, d.xfrc_applied):
            raise RuntimeError("internal: drone bodies are not evenly spaced in the model")
        self._warnings = d.warning.number  # (7,) live view of MuJoCo's warning counters
        self._geom_drone = world.geom_drone
        self.rotor_thrust = np.zeros((N, 4))  # (N, 4) F1..F4 produced (the last step's)
        # First-order rotor lag (actuators with dyntype="filter", docs/aero.md): MuJoCo integrates the
        # actuator states; rotor_thrust reports the produced thrust (from the states), rotor_command
        # what was commanded (after saturation). Without lag the two are the same.
        self.motor_lag = m.na == 4 * N and m.na > 0
        self._act = d.act.reshape(N, 4) if self.motor_lag else None
        self.rotor_command = np.zeros((N, 4))  # (N, 4)
        self._force = np.zeros((N, 3))  # (N, 3) stage sums (general path)
        self._torque = np.zeros((N, 3))
        self.kinematics = Kinematics(
            pos=self.pos, quat=self.quat, vel=self.vel, rotor_thrust=self.rotor_thrust
        )  # what force stages read
        self._ncon = _mjstep.ncon_view(d)
        self.drag = DragStage()
        self.wind = WindStage()
        self.stages: list[ForceStage] = [self.drag, self.wind, *force_stages]
        self.monitors: list[Monitor] = list(monitors)
        self._gate = floor_gate(world)  # (floor geom id, its contype, z_near) or None: no solid floor
        self._gate_on = self._gate is not None
        self._calls: _Calls | None = None  # the compiled calls bound to the records (:meth:`_bound`)
        self.reset()

    @property
    def floor_gate(self) -> bool:
        """Whether the solid floor is tested for contacts only in control periods where a drone could
        reach it (:func:`floor_gate_kernel`; True by default, the same run bit for bit at less cost).
        False tests it at every physics step."""
        return self._gate_on

    @floor_gate.setter
    def floor_gate(self, on: bool) -> None:
        self._gate_on = bool(on) and self._gate is not None
        self._floor_solid()
        self._record = self._physics()
        self._calls = None  # rebound at the next step (:meth:`_bound`)

    def _floor_solid(self) -> None:
        if self._gate is not None:
            self.model.geom_contype[self._gate[0]] = self._gate[1]

    @property
    def ext_force(self) -> np.ndarray:
        """(N, 3) the wind force of the current period (the wind stage's)."""
        return self.wind.force

    def add_stage(self, stage: ForceStage) -> None:
        """Append a force stage (applied after the others); it is reset now."""
        self.stages.append(stage)
        stage.reset(self)
        self._set_path()

    @property
    def force_stages(self) -> list[ForceStage]:
        """The extra force stages (after drag and wind), in the order they are applied."""
        return self.stages[2:] if self._fused else [s for s in self.stages if s is not self.drag and s is not self.wind]

    def stage_forces(self) -> dict[str, np.ndarray] | None:
        """Copies of the force (N, 3) of each extra stage that keeps one (``stage.force``, e.g.
        downwash, ground effect) over the last physics step; None when there is no extra stage."""
        if len(self.stages) <= 2:
            return None
        return {name: f.copy() for name, f in self.kept_forces()}

    def kept_forces(self) -> list[tuple[str, np.ndarray]]:
        """(name, force (N, 3)) of each extra stage that keeps its force (after drag and wind), the
        stage's own array (no copy: it holds the last physics step's until the next)."""
        return [(s.name, s.force) for s in self.stages[2:] if hasattr(s, "force")]

    def add_monitor(self, monitor: Monitor) -> None:
        """Append a monitor (run after every physics step); it is reset now."""
        self.monitors.append(monitor)
        monitor.reset(self)
        self._calls = None

    def _set_path(self) -> None:
        """Drag and wind first (the default): they run fused in one compiled call and the extra
        stages add into zeroed buffers; else every stage in turn (the general path)."""
        head = [type(s) for s in self.stages[:2]]
        self._fused = head == [DragStage, WindStage]
        self._extra = self.stages[2:] if self._fused else []
        self._record = self._physics()
        why = self.not_compiled()
        self._compiled = None if why else tuple(st.record() for st in self._extra)  # type: ignore[attr-defined]
        self._calls = None

    def _bound(self) -> _Calls:
        """The compiled calls of a control period bound to this simulator's records (:func:`swarm_mj._jit.bind`:
        a call through Numba's dispatcher re-types every record field at every call). Bound at the first
        step or check after the records were (re)built: :meth:`reset`, :meth:`add_stage`,
        :meth:`add_monitor`, :attr:`floor_gate` set ``_calls`` to None."""
        if self._calls is None:
            self._calls = _Calls(self)
        return self._calls

    def compile_period(self) -> bool:
        """Compile :func:`period_physics` for this simulator's records now (else :meth:`step` loops over the
        physics steps in Python until it is in Numba's cache: the chunk driver's compile, in the background
        of a first run, and ``swarm-mj warm-up`` compile it too); True if :meth:`step` now flies a control
        period in one compiled call (it needs every force stage compiled and a compiled ``mj_step``)."""
        self._calls = _Calls(self, compile=True)
        return self._calls.compiled

    def not_compiled(self) -> str | None:
        """Why the force stages cannot fly in a compiled driver (None: they can): the first one that is
        not drag, wind or a stage with a registered compiled kernel (``record()`` returning a record of
        :data:`swarm_mj.pipeline.registry.FORCE_KERNELS`), named."""
        if not self._fused:
            return "force stages other than drag and wind first"
        for st in self._extra:
            why = registry.why_not_compiled(st, registry.FORCE_KERNELS, "force stage", "kernel")
            if why is not None:
                return why
        return None

    def monitors_not_compiled(self) -> str | None:
        """Why the monitors cannot fly in a compiled driver (None: they can), naming the first one
        without a registered compiled step (:data:`swarm_mj.pipeline.registry.MONITOR_KERNELS`)."""
        for mon in self.monitors:
            why = registry.why_not_compiled(mon, registry.MONITOR_KERNELS, "monitor", "step")
            if why is not None:
                return why
        return None

    def compiled_stages(self) -> tuple:
        """The records of the extra force stages, in order, for a compiled driver (see :meth:`not_compiled`)."""
        if self._compiled is None:
            raise RuntimeError(f"internal: {self.not_compiled()}")
        return self._compiled

    def _physics(self) -> Physics:
        d = self.data
        ids = np.asarray(self.world.body_ids)
        fid, solid, z_near = self._gate or (0, 0, 0.0)
        addr = _mjstep.mj_step_address() or 0
        return Physics(
            fn=np.uint64(addr),
            m_addr=np.uint64(self.model._address),
            d_addr=np.uint64(d._address),
            ncon=self._ncon if self._ncon is not None else np.zeros(1, dtype=np.int32),
            warn=self._warnings,
            qpos=self.qpos,
            qvel=self.qvel,
            ctrl=self.ctrl,
            xfrc=d.xfrc_applied,
            body0=int(ids[0]),
            body_step=int(ids[1] - ids[0]) if len(ids) > 1 else 1,
            rotor_thrust=self.rotor_thrust,
            rotor_command=self.rotor_command,
            act=self._act if self._act is not None else np.zeros((self.n_total, 4)),
            lag=bool(self.motor_lag),
            wind=self.wind.force,
            neg_drag=np.ascontiguousarray(self.drag.neg_drag, dtype=float),
            force=self._force,
            torque=self._torque,
            unmix_t=self._unmix_t,
            mix_t=self._mix_t,
            f_min=float(self._f_min),
            f_max=float(self._f_max),
            nsub=int(self.n_substeps),
            T=float(self.control_period),
            floor_z=float(self.floor_z),
            max_distance=float(self.max_distance),
            max_tilt=float(self.max_tilt),
            gate_on=bool(self._gate_on),
            gate_z=float(z_near),
            contype=self.model.geom_contype,
            gate_id=int(fid),
            gate_solid=int(solid),
        )

    def record(self) -> Physics:
        """The simulator for a compiled driver (:class:`swarm_mj.pipeline.records.Physics`), valid until the next
        :meth:`reset` or change of the stages or the floor gate."""
        return self._record

    # ------------------------------------------------------------------ state
    @property
    def time(self) -> float:
        return float(self.data.time)

    @property
    def pairs_in_contact(self) -> AbstractSet[tuple[int, int]]:
        """The drone pairs (i, j) touching after the last physics step (read-only: the contact counting's
        own; a driver that steps the physics itself hands each step with one back to :meth:`after_physics_step`)."""
        return self._pairs_in_contact

    def reset(
        self, positions: np.ndarray | None = None, yaws: np.ndarray | None = None, velocities: np.ndarray | None = None
    ) -> None:
        """Back to rest at ``positions`` (N, 3) with ``yaws`` (N,) (defaults: the world's)."""
        mujoco.mj_resetData(self.model, self.data)
        pos = self.world.initial_positions if positions is None else np.asarray(positions, float)
        yaw = self.world.initial_yaws if yaws is None else np.asarray(yaws, float)
        self.pos[:] = pos
        self.quat[:] = 0.0
        self.quat[:, 0] = np.cos(yaw / 2)
        self.quat[:, 3] = np.sin(yaw / 2)
        if velocities is not None:
            self.vel[:] = velocities
        self.rotor_thrust[:] = 0.0
        self.rotor_command[:] = 0.0
        self._force[:] = 0.0
        self._torque[:] = 0.0
        self.contact_events = 0  # pairs of drones coming into contact (rising edges)
        self.contact_steps = 0  # physics steps with any drone–drone contact
        self.contact_log: list[tuple[float, int, int]] = []  # (t, i, j) at each rising edge
        self._pairs_in_contact: set[tuple[int, int]] = set()
        self.parked = np.zeros(self.n_copies, dtype=bool)  # (m,) copies held at their start
        self._parked_rows = np.zeros((self.n_total, 1), dtype=bool)
        self._any_parked = False
        self._park_qpos = self.qpos.copy()  # (N, 7) where parked drones are held
        for stage in self.stages:
            stage.reset(self)
        self._set_path()
        self._floor_solid()
        mujoco.mj_forward(self.model, self.data)
        for mon in self.monitors:
            mon.reset(self)

    def reset_copies(
        self, copies: np.ndarray, positions: np.ndarray | None = None, yaws: np.ndarray | None = None
    ) -> None:
        """Put only the copies of the bool mask ``copies`` (m,) back at rest at the rows of ``positions``
        (N, 3) and ``yaws`` (N,) (defaults: the world's), as :meth:`reset` would, leaving the other
        copies alone (a vector environment's per-copy auto-reset): their state, rotor lag, inputs and
        applied forces, the solver's warm start and the contact bookkeeping of their drones are cleared,
        ``mj_forward`` finds the contacts at the starts (derived quantities only: the other copies' state
        is untouched) and every force stage and monitor resets their rows (``reset_rows``).
        MuJoCo's warning counters and ``time`` are shared by all copies and are left as they are."""
        mask = np.asarray(copies, dtype=bool).reshape(self.n_copies)
        rows = np.repeat(mask, self.n)  # (N,)
        pos = self.world.initial_positions if positions is None else np.asarray(positions, float)
        yaw = self.world.initial_yaws if yaws is None else np.asarray(yaws, float)
        self.qpos[rows, 0:3] = pos[rows]
        self.qpos[rows, 3:7] = 0.0
        self.qpos[rows, 3] = np.cos(yaw[rows] / 2)
        self.qpos[rows, 6] = np.sin(yaw[rows] / 2)
        self.qvel[rows] = 0.0
        self.ctrl[rows] = 0.0
        self.rotor_thrust[rows] = 0.0
        self.rotor_command[rows] = 0.0
        if self._act is not None:
            self._act[rows] = 0.0  # the rotors' lag states (mj_resetData's zero)
        self._xfrc_force[rows] = 0.0
        self._xfrc_torque[rows] = 0.0
        self.data.qacc_warmstart.reshape(self.n_total, 6)[rows] = 0.0
        self.parked[mask] = False
        self._park_qpos[rows] = self.qpos[rows]
        self._pairs_in_contact = {p for p in self._pairs_in_contact if not rows[p[0]]}
        self._floor_solid()
        mujoco.mj_forward(self.model, self.data)  # the contacts at the starts, as reset's
        for stage in self.stages:
            stage.reset_rows(self, rows)
        for mon in self.monitors:
            mon.reset_rows(self, rows)

    # ------------------------------------------------------------------ step
    def step(self, U: np.ndarray, wind_force: np.ndarray | None = None) -> None:
        """Advance one control period with commanded U (N, 4) and the wind force (N, 3) or (3,).

        U is mapped to rotor thrusts, clipped to [f_min, f_max] per rotor and mapped back
        (docs/interpretations.md §1); the result is held in ``ctrl`` for the whole period.
        Parked copies get zero input and are put back at their start first.
        """
        U = np.asarray(U, dtype=np.float64)
        parked = self._any_parked
        if parked:
            U = self._hold_parked(U)
        self.wind.set(wind_force)
        calls = self._calls or self._bound()
        if U.shape == self.ctrl.shape:  # else the dispatcher types U (and its shape is the caller's)
            period = calls.period
            U = np.ascontiguousarray(U)  # (N, 4) C order: the bound calls' type
        else:
            period = calls.any_shape()
        saved = timer_pause()  # MuJoCo's profiling clock: off while we step (swarm_mj/physics/_mjstep.py)
        try:
            self._fly_period(calls, period, U)
        finally:
            timer_resume(saved)
        if self.motor_lag:
            unmix_kernel(self._act, self._unmix_t, self.rotor_thrust)
        if parked:
            self._put_back()

    def _fly_period(self, calls: _Calls, period: Callable[..., int], U: np.ndarray) -> None:
        """1. and 2. of the module docstring, the one loop over a period's physics steps. ``period(phys, stages,
        monitors, U, s, python_each)`` saturates U at s = 0, flies the physics steps from s and returns 0 when the
        period is flown, else the number of the step after the one it hands back after: Python then counts
        that step's contacts and runs the monitors (:meth:`after_physics_step`) and calls it again from there.
        The compiled :func:`period_physics` hands back only after a step with a contact, or after every step
        while Python must see each one (:meth:`_python_each`): exactly where the chunk driver hands back
        (swarm_mj/pipeline/fast.py). Its Python counterpart (:func:`python_period`) hands back after every step."""
        phys, stages, monitors, every = calls.phys, calls.stages, calls.monitors, not calls.compiled
        s = period(phys, stages, monitors, U, 0, every or self._python_each(calls))
        while s:
            self.after_physics_step()
            if s == self.n_substeps:
                return
            s = period(phys, stages, monitors, U, s, every or self._python_each(calls))

    def _python_each(self, calls: _Calls) -> bool:
        """Python must see every physics step: drones still in contact, or a monitor whose Python
        ``after_step`` does more than its compiled step now (none compiled, or one not ``compiled_ready``,
        or one that ``holds_steps``)."""
        if self._pairs_in_contact:
            return True
        if not self.monitors:
            return False
        return calls.monitors_python or any(not m.compiled_ready() or m.holds_steps() for m in self.monitors)  # type: ignore[attr-defined]

    def after_physics_step(self) -> None:
        """2c. of the module docstring, what follows each ``mj_step``: drone–drone contacts, then the
        monitors (the chunk driver, swarm_mj/pipeline/period.py, hands each step with a contact back to this)."""
        if self.data.ncon or self._pairs_in_contact:
            self._count_contacts()
        for mon in self.monitors:
            mon.after_step(self)

    def _stage_forces(self) -> None:
        """One physics step's forces into xfrc_applied where the stages do not start with drag and wind (the
        general path): every stage adds its force and torque into zeroed sums, which are then set."""
        force, torque = self._force, self._torque
        force[:] = 0.0
        torque[:] = 0.0
        if self.motor_lag:
            unmix_kernel(self._act, self._unmix_t, self.rotor_thrust)
        for stage in self.stages:
            stage.apply(self, force, torque)
        self._xfrc_force[:] = force
        self._xfrc_torque[:] = torque

    # ------------------------------------------------------------------ health
    def health(self, out: np.ndarray | None = None) -> np.ndarray:
        """The health mask (m,) int8, one code per copy (``HEALTHY`` = 0, see :data:`HEALTH_NAMES`):
        non-finite state, a drone below the floor, too far, tilted beyond ``max_tilt``, or a
        MuJoCo divergence warning since the last reset (every copy then: MuJoCo resets them all).
        Written into ``out`` (m,) int8 if given, else a fresh array."""
        if out is None:
            out = np.empty(self.n_copies, dtype=np.int8)
        health_kernel(self.qpos, self.qvel, self.n, self.floor_z, self.max_distance, self.max_tilt, out)
        if self.mujoco_warned():
            out[:] = MUJOCO_WARNING
        return out

    def mujoco_warned(self) -> bool:
        """MuJoCo counted a divergence warning (:data:`DIVERGENCE_WARNINGS`) since the last reset."""
        w = self._warnings
        return bool(w[_W_QACC] or w[_W_QPOS] or w[_W_QVEL] or w[_W_CTRL])

    def check(self) -> None:
        """Raise :class:`SimulationDiverged` if a copy is unhealthy (:meth:`health`), naming why."""
        calls = self._bound()
        if not calls.unhealthy(calls.phys):  # the chunk driver's test
            return
        if self.mujoco_warned():
            code = MUJOCO_WARNING
        else:
            code = first_unhealthy(
                self.qpos, self.qvel, self.n, self.n_copies, self.floor_z, self.max_distance, self.max_tilt
            )
            if code == HEALTHY:
                return
        pos = self.pos
        when = f"simulation diverged at t = {self.time:.2f} s"
        if code == MUJOCO_WARNING:
            names = [mujoco.mjtWarning(int(w)).name for w in DIVERGENCE_WARNINGS if self._warnings[int(w)]]
            raise SimulationDiverged(
                f"simulation diverged: MuJoCo reported {', '.join(names)} (a state it cannot "
                f"integrate) and reset the simulation"
            )
        if code == NON_FINITE:
            raise SimulationDiverged(f"{when}: non-finite state")
        if code == BELOW_FLOOR:
            k = int(np.argmin(pos[:, 2]))
            raise SimulationDiverged(f"{when}: {self.world.names[k]} fell through the floor (z = {pos[k, 2]:.2f} m)")
        if code == TILTED:
            raise SimulationDiverged(f"{when}: a drone tilted beyond {np.rad2deg(self.max_tilt):g}°")
        raise SimulationDiverged(f"{when}: a drone flew beyond {self.max_distance:g} m")

    def park(self, copies: np.ndarray | Iterable[int]) -> None:
        """Hold the given copies (a bool mask (m,) or indices) at rest at their start with zero input
        (put back before and after every step) from now on (e.g. diverged tuner candidates), so that
        a bad state never reaches MuJoCo, which would reset every copy."""
        mask = np.zeros(self.n_copies, dtype=bool)
        mask[np.asarray(copies)] = True
        self.parked |= mask
        self._any_parked = bool(self.parked.any())
        self._parked_rows = np.repeat(self.parked, self.n)[:, None]  # (N, 1)
        self._put_back()

    def _put_back(self) -> None:
        rows = self._parked_rows
        np.copyto(self.qpos, self._park_qpos, where=rows)
        np.copyto(self.qvel, 0.0, where=rows)

    def _hold_parked(self, U: np.ndarray) -> np.ndarray:
        self._put_back()
        return np.where(self._parked_rows, 0.0, U)

    # ------------------------------------------------------------------ contacts
    def _count_contacts(self) -> None:
        pairs = touching_pairs(self.data, self._geom_drone)
        if pairs:
            self.contact_steps += 1
            for pair in pairs - self._pairs_in_contact:
                self.contact_events += 1
                self.contact_log.append((float(self.data.time), pair[0], pair[1]))
        self._pairs_in_contact = pairs

    def drone_contacts(self) -> list[tuple[int, int]]:
        """Pairs of drones (i < j) whose geoms are in contact right now."""
        return sorted(touching_pairs(self.data, self._geom_drone))


def python_period(model: mujoco.MjModel, data: mujoco.MjData, hold: Callable, forces: Callable) -> Callable[..., int]:
    """:func:`period_physics` with ``mj_step`` called from Python, one physics step a call: ``period(phys,
    stages, monitors, U, s0, python_each)`` saturates at ``s0`` = 0 (``hold(phys, U)``), applies the step's
    forces (``forces()``), steps MuJoCo and returns s0 + 1 (Python sees every step)."""

    def period(phys: Physics, stages: tuple, monitors: tuple, U: np.ndarray, s0: int, python_each: bool) -> int:  # noqa: ARG001
        if s0 == 0:
            hold(phys, U)
        forces()
        mujoco.mj_step(model, data)
        return s0 + 1

    return period


class _Calls:
    """:class:`Sim`'s calls of a control period bound to its records (:func:`swarm_mj._jit.bind`); built by
    :meth:`Sim._bound`, dropped whenever a record is rebuilt. ``period``: :func:`period_physics` (``compiled``)
    where the force stages are compiled, a kernel can call ``mj_step`` (:func:`swarm_mj.physics._mjstep.available`)
    and it is compiled for these records already (in memory or Numba's on-disk cache: compiling it costs a first
    run 2-3 s, so it is compiled with the chunk driver, :func:`swarm_mj.pipeline.fast.compile_now`, in the
    background or by ``swarm-mj warm-up``), else :func:`python_period` (saturation bound, the forces of
    :meth:`forces`)."""

    def __init__(self, sim: Sim, compile: bool = False) -> None:  # noqa: A002
        self._sim = sim
        #: the records the calls are bound to (passed with them: never another record)
        self.phys, self.stages = phys, stages = sim._record, sim._compiled
        self.unhealthy = bind(unhealthy, phys)
        #: the compiled monitors' records; ``monitors_python``: some monitor has none (Python sees each step)
        self.monitors_python = sim.monitors_not_compiled() is not None
        self.monitors: tuple = () if self.monitors_python else tuple(m.record() for m in sim.monitors)  # type: ignore[attr-defined]
        U = np.zeros(sim.ctrl.shape)  # (N, 4) C order, as Sim.step passes it
        args = (phys, stages, self.monitors, U, 0, False)
        self.compiled = stages is not None and _mjstep.available() and (compile or compiled(period_physics, *args))
        if self.compiled:
            self.period = bind(period_physics, *args)
        else:
            self.period = python_period(sim.model, sim.data, bind(hold_inputs, phys, U), self.forces())

    def any_shape(self) -> Callable[..., int]:
        """The period for a U of another shape than ``ctrl``'s: :func:`python_period`, saturating through
        Numba's dispatcher (which types U, or refuses it)."""
        return python_period(self._sim.model, self._sim.data, hold_inputs, self.forces())

    def forces(self) -> Callable[[], None]:
        """One physics step's forces into xfrc_applied, from Python: :func:`apply_forces` (drag −K·v + the wind,
        the produced rotor thrusts, the compiled stages), then each stage without a compiled kernel adds its
        force and torque (``apply``) and their sums are added (:func:`flush_stage_forces`); where the stages do
        not start with drag and wind, :meth:`Sim._stage_forces`."""
        sim = self._sim
        if not sim._fused:
            return sim._stage_forces
        xf, xt = sim._xfrc_force, sim._xfrc_torque
        stages = () if self.stages is None else self.stages
        apply = functools.partial(bind(apply_forces, self.phys, stages, sim.kinematics, xf, xt), self.phys, stages)
        kin, extra, force, torque = sim.kinematics, sim._extra, sim._force, sim._torque
        if self.stages is not None:
            return functools.partial(apply, kin, xf, xt)

        def forces() -> None:
            apply(kin, xf, xt)
            for stage in extra:
                stage.apply(sim, force, torque)
            flush_stage_forces(xf, xt, force, torque)  # xf += force, xt = torque; both back to zero

        return forces
