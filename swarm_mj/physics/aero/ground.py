"""The solid ground: landing gear, the rest height, and ground contacts and crashes (docs/aero.md).

With ``ground`` on, :func:`swarm_mj.physics.world.build_world` makes the floor (the plane z = 0)
collide with each drone's rotor disc and gives each drone a landing gear (a strut and a skid
plate) whose skid touches only the floor (never another drone: drone–drone contact geometry
is the paper's). A start
at z = 0 means "resting on the skid": the centre of mass is placed at :data:`REST_HEIGHT`.

Counting (:class:`GroundContacts`, run after every physics step):

* a drone has *taken off* once it is out of contact with the floor and its centre of mass
  is more than :data:`TAKEOFF_CLEARANCE` above the rest height;
* a *ground contact* is the first physics step of a contact with the floor after take-off
  (a touchdown); a drone must take off again before its next one counts;
* a *crash* is a ground contact whose touchdown speed (|v| of the centre of mass at the start of
  the physics step in which the contact begins) is above
  ``crash_speed`` (1 m/s), or during which the body tilts more than ``crash_tilt_deg``
  (30°) from upright; at most one crash per contact.
"""

from __future__ import annotations

import math

import numpy as np

from ..._jit import jit
from ...pipeline.records import GroundTrack, Kinematics

#: Landing gear: a strut (a capsule site, drawn only, radius STRUT_RADIUS) under the hub down to a thin square skid
#: plate turned 45° about z, corners 0.12 m from the centre under the arms, half-sizes
#: (SKID_HALF, SKID_HALF, SKID_HALF_Z), centred at z = SKID_Z in the body frame; the skid's bottom
#: face, 0.066 m below the centre of mass, is what rests on the floor (4 contact points).
STRUT_RADIUS = 0.008
SKID_HALF = 0.12 / 2**0.5
SKID_HALF_Z = 0.003
SKID_Z = -0.066 + SKID_HALF_Z
#: Height of the centre of mass of a level drone resting on its skid (m).
REST_HEIGHT = -(SKID_Z - SKID_HALF_Z)
#: Clearance above the rest height that counts as having taken off (m).
TAKEOFF_CLEARANCE = 0.05


def rest_positions(positions: np.ndarray, rest_height: float = REST_HEIGHT) -> np.ndarray:
    """Start positions (n, 3) with every z below the rest height raised to it (z = 0: on the ground).

    ``rest_height``: the vehicle's (``REST_HEIGHT`` × :attr:`swarm_mj.physics.params.QuadParams.size_scale`,
    the landing gear scales with the arm, docs/vehicles.md); the paper drone's by default."""
    p = np.array(positions, dtype=float)
    p[:, 2] = np.maximum(p[:, 2], rest_height)
    return p


@jit
def ground_track(rec: GroundTrack, kin: Kinematics) -> None:
    """The touchdown speed's bookkeeping after every physics step: the velocity (N, 3) at the start of
    the last step, and now."""
    rec.vel_before[:] = rec.vel_now
    rec.vel_now[:] = kin.vel


class GroundContacts:
    """Monitor: counts touchdowns and crashes (module docstring). ``log`` holds one
    ``(t, drone, speed m/s, tilt deg, crash)`` per ground contact, and one more (crash True)
    when a drone tips over during a contact that began as a soft touchdown."""

    name = "ground"

    def __init__(self, crash_speed: float = 1.0, crash_tilt_deg: float = 30.0) -> None:
        self.crash_speed = float(crash_speed)
        self.crash_tilt_deg = float(crash_tilt_deg)
        self._cos_tilt = math.cos(math.radians(self.crash_tilt_deg))

    def reset(self, sim) -> None:
        import mujoco  # here, not at the top: the CLI's parser reaches this module through the registry

        m = sim.model
        self.floor = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "floor")
        self.geom_drone = sim.world.geom_drone
        N = sim.pos.shape[0]
        self.ground_contacts = 0
        self.crashes = 0
        self.log: list[tuple[float, int, float, float, bool]] = []
        self.in_contact = self._contacts(sim)  # (N,) touching the floor now
        self.airborne = np.zeros(N, dtype=bool)  # (N,) taken off since the last contact
        self.episode = np.zeros(N, dtype=bool)  # (N,) in a counted contact
        self.episode_crashed = np.zeros(N, dtype=bool)
        self._all_airborne = False
        self._any_contact = bool(self.in_contact.any())
        self._takeoff_z = REST_HEIGHT * sim.params.size_scale + TAKEOFF_CLEARANCE  # gear scales with the arm
        self._vel_before = sim.vel.copy()  # (N, 3) velocity at the start of the last step
        self._vel_now = sim.vel.copy()
        self._record = GroundTrack(self._vel_before, self._vel_now)

    def reset_rows(self, sim, rows: np.ndarray) -> None:  # noqa: ANN001 - swarm_mj.physics.sim.Sim
        """As :meth:`reset` for the drones of ``rows`` (N,) bool, the copies
        :meth:`~swarm_mj.physics.sim.Sim.reset_copies` puts back (their contacts with the floor at their starts,
        found by its ``mj_forward``), the other drones untouched. ``ground_contacts``, ``crashes`` and ``log``
        count every copy of the model and are kept."""
        self.in_contact[rows] = self._contacts(sim)[rows]
        self.airborne[rows] = False
        self.episode[rows] = False
        self.episode_crashed[rows] = False
        self._all_airborne = bool(self.airborne.all())
        self._any_contact = bool(self.in_contact.any())
        self._vel_before[rows] = sim.vel[rows]
        self._vel_now[rows] = sim.vel[rows]

    def record(self) -> GroundTrack:
        """This monitor's per-step bookkeeping for a compiled driver (valid until the next :meth:`reset`)."""
        return self._record

    def compiled_ready(self) -> bool:
        """Its compiled step (:func:`ground_track`) is all it does now: every drone has taken off and
        none touches the ground."""
        return self._all_airborne and not self._any_contact

    def holds_steps(self) -> bool:
        """Its Python must see every physics step (a drone touches the ground)."""
        return self._any_contact

    def _contacts(self, sim) -> np.ndarray:
        d = sim.data
        out = np.zeros(sim.pos.shape[0], dtype=bool)
        nc = d.ncon
        if nc and self.floor >= 0:
            g = d.contact.geom[:nc]  # (ncon, 2)
            other = np.concatenate([g[g[:, 0] == self.floor, 1], g[g[:, 1] == self.floor, 0]])
            ids = self.geom_drone[other]
            out[ids[ids >= 0]] = True
        return out

    def _tilt_cos(self, sim, i: int) -> float:
        q = sim.quat[i]
        return float(1.0 - 2.0 * (q[1] * q[1] + q[2] * q[2]) / max(float(q @ q), 1e-300))

    def after_step(self, sim) -> None:
        # the touchdown speed is the speed before the step in which the contact began (the contact
        # impulse of that step has already slowed the drone down)
        ground_track(self._record, sim.kinematics)
        if not self._all_airborne:
            newly = ~self.airborne & ~self.in_contact & (sim.pos[:, 2] > self._takeoff_z)
            if newly.any():
                self.airborne |= newly
                self._all_airborne = bool(self.airborne.all())
        if sim.data.ncon == 0 and not self._any_contact:
            return
        contact = self._contacts(sim)
        for i in np.flatnonzero(contact & ~self.in_contact & self.airborne).tolist():
            speed = float(np.linalg.norm(self._vel_before[i]))
            tilt = math.degrees(math.acos(min(1.0, max(-1.0, self._tilt_cos(sim, i)))))
            crash = speed > self.crash_speed or tilt > self.crash_tilt_deg
            self.ground_contacts += 1
            self.crashes += int(crash)
            self.log.append((sim.time, i, speed, tilt, crash))
            self.airborne[i] = False
            self._all_airborne = False
            self.episode[i] = True
            self.episode_crashed[i] = crash
        for i in np.flatnonzero(contact & self.episode & ~self.episode_crashed).tolist():
            if self._tilt_cos(sim, i) < self._cos_tilt:  # tipped over while on the ground
                self.crashes += 1
                self.episode_crashed[i] = True
                self.log.append(
                    (
                        sim.time,
                        i,
                        float(np.linalg.norm(sim.vel[i])),
                        math.degrees(math.acos(max(-1.0, self._tilt_cos(sim, i)))),
                        True,
                    )
                )
        ended = ~contact & self.episode
        if ended.any():
            self.episode &= ~ended
            self.episode_crashed &= ~ended
        self.in_contact = contact
        self._any_contact = bool(contact.any())
