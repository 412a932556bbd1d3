"""The simulation core: MjData, drag and external forces, rotor saturation, stepping (DESIGN "sim").

Per physics step (``model.opt.timestep``) the core writes into ``xfrc_applied`` of each
drone body (world frame, at the centre of mass):

    F = −(Kx·ẋ, Ky·ẏ, Kz·ż) + F_ext          (paper eq. 1 drag; wind F^w of eq. 37)

plus, under an aerodynamic preset (docs/aero.md), the force and torque of each of
``force_stages`` (downwash, ground effect). The drag uses the velocity at the start of that
physics step, i.e. it is refreshed every physics step (twice per 10-ms control period at the
5-ms default) and held over the RK4 stages of the step. ``ctrl`` holds U1..U4 (after per-rotor saturation)
for the whole control period: a zero-order hold (SPEC §2).

State arrays are views into MjData with the drone axis first:
``pos (n, 3)``, ``quat (n, 4)`` (w, x, y, z), ``vel (n, 3)`` world frame,
``omega (n, 3)`` body frame.
"""

from __future__ import annotations

import mujoco
import numpy as np

from .errors import SimulationDiverged, UserError
from .kernels import drag_kernel, flush_stage_forces, saturate_kernel, state_ok, unmix_kernel
from .mixing import _MIX_T, _UNMIX_T
from .world import World


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
    """Steps a :class:`~swarm_mj.world.World` one control period at a time."""

    def __init__(self, world: World, control_period: float = 0.01, *, floor_z: float = -0.5,
                 max_distance: float = 1e3) -> None:
        m = world.model
        dt = m.opt.timestep
        nsub = int(round(control_period / dt))
        if nsub < 1 or abs(nsub * dt - control_period) > 1e-9 * max(1.0, control_period):
            raise UserError(f"physics timestep {dt} s must divide the control period {control_period} s")
        if m.nq != 7 * world.n_drones or m.nu != 4 * world.n_drones:
            raise UserError("the model must hold only the drones' free joints and four motors per drone")
        self.world = world
        self.model = m
        self.data = mujoco.MjData(m)
        self.n = world.n_drones
        self.control_period = float(control_period)
        self.n_substeps = nsub
        self.floor_z = float(floor_z)
        self.max_distance = float(max_distance)
        p = world.params
        self.params = p
        self._neg_drag = -p.drag                         # (3,)
        self._f_min, self._f_max = p.f_min, p.f_max
        d = self.data
        self.qpos = d.qpos.reshape(self.n, 7)            # views into MjData
        self.qvel = d.qvel.reshape(self.n, 6)
        self.pos = self.qpos[:, 0:3]                     # (n, 3)
        self.quat = self.qpos[:, 3:7]                    # (n, 4)
        self.vel = self.qvel[:, 0:3]                     # (n, 3) world frame
        self.omega = self.qvel[:, 3:6]                   # (n, 3) body frame
        self.ctrl = d.ctrl.reshape(self.n, 4)            # (n, 4) = U1..U4 applied
        self._xfrc_force = d.xfrc_applied[_index(world.body_ids), 0:3]
        if not np.shares_memory(self._xfrc_force, d.xfrc_applied):
            raise RuntimeError("internal: drone bodies are not evenly spaced in the model")
        self._geom_drone = world.geom_drone
        self.rotor_thrust = np.zeros((self.n, 4))        # (n, 4) F1..F4 of the last step
        self.ext_force = np.zeros((self.n, 3))           # (n, 3) last external force
        # Aerodynamic force stages and post-step monitors (swarm_mj.aero; empty under the paper's model):
        # each physics step, every stage ADDS its world force/torque (n, 3) at the CoM into zeroed buffers,
        # which are added to xfrc_applied after the drag; monitors run after each mj_step.
        self.force_stages: list = []
        self.monitors: list = []
        self._xfrc_torque = d.xfrc_applied[_index(world.body_ids), 3:6]
        self._stage_force = np.zeros((self.n, 3))       # (n, 3)
        self._stage_torque = np.zeros((self.n, 3))      # (n, 3)
        # First-order rotor lag (actuators with dyntype="filter"): rotor_thrust reports the produced thrust
        # (from the actuator states), rotor_command what was commanded (after saturation).
        self.motor_lag = m.na == 4 * self.n and m.na > 0
        self._act = d.act.reshape(self.n, 4) if self.motor_lag else None
        self.rotor_command = np.zeros((self.n, 4))      # (n, 4)
        self.reset()

    # ------------------------------------------------------------------ state
    @property
    def time(self) -> float:
        return float(self.data.time)

    def reset(self, positions: np.ndarray | None = None, yaws: np.ndarray | None = None,
              velocities: np.ndarray | None = None) -> None:
        """Back to rest at ``positions`` (n, 3) with ``yaws`` (n,) (defaults: the world's)."""
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
        self.ext_force[:] = 0.0
        self.contact_events = 0          # pairs of drones coming into contact (rising edges)
        self.contact_steps = 0           # physics steps with any drone–drone contact
        self.contact_log: list[tuple[float, int, int]] = []  # (t, i, j) at each rising edge
        self._pairs_in_contact: set[tuple[int, int]] = set()
        self.rotor_command[:] = 0.0
        self._stage_force[:] = 0.0
        self._stage_torque[:] = 0.0
        mujoco.mj_forward(self.model, self.data)
        for stage in self.force_stages:
            stage.reset(self)
        for mon in self.monitors:
            mon.reset(self)

    # ------------------------------------------------------------------ step
    def step(self, U: np.ndarray, ext_force: np.ndarray | None = None) -> None:
        """Advance one control period with commanded U (n, 4) and external world force (n, 3) or (3,).

        U is mapped to rotor thrusts, clipped to [f_min, f_max] per rotor and mapped back
        (SPEC §1); the result is held in ``ctrl`` for the whole period.
        """
        U = np.asarray(U, dtype=np.float64)
        saturate_kernel(U, _UNMIX_T, _MIX_T, self._f_min, self._f_max, self.ctrl, self.rotor_thrust)
        if ext_force is None:
            self.ext_force[:] = 0.0
        else:
            self.ext_force[:] = ext_force
        m, d = self.model, self.data
        xf, vel, ext, k = self._xfrc_force, self.vel, self.ext_force, self._neg_drag
        stages, monitors, lag = self.force_stages, self.monitors, self.motor_lag
        if lag:
            self.rotor_command[:] = self.rotor_thrust
        for _ in range(self.n_substeps):
            drag_kernel(vel, k, ext, xf)      # xf = −K·v + F_ext (world frame, at the CoM)
            if lag:
                unmix_kernel(self._act, _UNMIX_T, self.rotor_thrust)     # produced rotor thrusts
            if stages:
                f, tq = self._stage_force, self._stage_torque          # zero here (flushed each step)
                for stage in stages:
                    stage.apply(self, f, tq)
                flush_stage_forces(xf, self._xfrc_torque, f, tq)        # xf += f, torque = tq; f, tq = 0
            mujoco.mj_step(m, d)
            if d.ncon or self._pairs_in_contact:
                self._count_contacts()
            for mon in monitors:
                mon.after_step(self)
        if lag:
            unmix_kernel(self._act, _UNMIX_T, self.rotor_thrust)

    def check(self) -> None:
        """Raise :class:`SimulationDiverged` on NaN, a drone below the floor or far away."""
        code = state_ok(self.qpos, self.qvel, self.floor_z, self.max_distance)
        if code == 0:
            return
        pos = self.pos
        if code == 1:
            raise SimulationDiverged(f"simulation diverged at t = {self.time:.2f} s: non-finite state")
        if code == 2:
            k = int(np.argmin(pos[:, 2]))
            raise SimulationDiverged(
                f"simulation diverged at t = {self.time:.2f} s: {self.world.names[k]} fell through the floor "
                f"(z = {pos[k, 2]:.2f} m)")
        raise SimulationDiverged(f"simulation diverged at t = {self.time:.2f} s: a drone flew beyond "
                                 f"{self.max_distance:g} m")

    # ------------------------------------------------------------------ contacts
    def _count_contacts(self) -> None:
        d = self.data
        pairs: set[tuple[int, int]] = set()
        if d.ncon:
            g1 = self._geom_drone[d.contact.geom1[: d.ncon]]
            g2 = self._geom_drone[d.contact.geom2[: d.ncon]]
            for a, b in zip(g1.tolist(), g2.tolist()):
                if a >= 0 and b >= 0 and a != b:
                    pairs.add((min(a, b), max(a, b)))
        if pairs:
            self.contact_steps += 1
            for pair in pairs - self._pairs_in_contact:
                self.contact_events += 1
                self.contact_log.append((float(d.time), pair[0], pair[1]))
        self._pairs_in_contact = pairs

    def drone_contacts(self) -> list[tuple[int, int]]:
        """Pairs of drones (i < j) whose geoms are in contact right now."""
        d = self.data
        out = set()
        for c in range(d.ncon):
            a, b = self._geom_drone[d.contact.geom1[c]], self._geom_drone[d.contact.geom2[c]]
            if a >= 0 and b >= 0 and a != b:
                out.add((int(min(a, b)), int(max(a, b))))
        return sorted(out)
