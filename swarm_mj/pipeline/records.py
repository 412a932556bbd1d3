"""The typed state records of one control period (docs/design.md, "The control period, written once").

Every stage of a control period (the rule's formed step, the feedforwards, backstepping, the
mixer, saturation, each force stage, ``mj_step``, the monitors, the health check, the
observation, the log row) is one compiled function over these records. A record is a
``typing.NamedTuple`` of arrays and scalars: Numba takes it as one argument, and its type (hence a
kernel's compile signature) comes from the record itself, so no list of argument types is kept
by hand. The arrays are live views or the owners' own buffers (nothing is copied per period); a
scalar a stage updates is a 1-element array.

Shapes: n drones (N = all drones of all copies where a record serves the simulator), K + 1
control instants of a run, S force stages. The records are built by their owners:
:meth:`swarm_mj.physics.sim.Sim.record` (:class:`Physics`), the force stages' ``record()``,
:meth:`swarm_mj.control.backstepping.Backstepping` (:class:`Gains`), the policy's parts, the
environment (:class:`Refs`, :class:`Obs`) and the runner's log (:class:`LogRows`).

This module imports no other module of the package (the records are plain data).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np


class Kinematics(NamedTuple):
    """What a force stage reads of the drones at the start of a physics step."""

    pos: np.ndarray  # (N, 3) world position of the centre of mass (m), a view of qpos
    quat: np.ndarray  # (N, 4) attitude (w, x, y, z), a view of qpos
    vel: np.ndarray  # (N, 3) world velocity (m/s), a view of qvel
    rotor_thrust: np.ndarray  # (N, 4) F1..F4 produced (N)


class Physics(NamedTuple):
    """The simulator (:class:`swarm_mj.physics.sim.Sim`) for a compiled driver: MuJoCo's addresses and views."""

    fn: np.uint64  # address of MuJoCo's C mj_step (0: none)
    m_addr: np.uint64  # address of the mjModel
    d_addr: np.uint64  # address of the mjData
    ncon: np.ndarray  # (1,) int32, a live view of mjData.ncon
    warn: np.ndarray  # (mjNWARNING,) int32, live view of mjData.warning.number
    qpos: np.ndarray  # (N, 7) view
    qvel: np.ndarray  # (N, 6) view
    ctrl: np.ndarray  # (N, 4) U1..U4 applied, view
    xfrc: np.ndarray  # (nbody, 6) mjData.xfrc_applied; the drones' rows are body0 + i·body_step
    body0: int
    body_step: int
    rotor_thrust: np.ndarray  # (N, 4) F1..F4 produced
    rotor_command: np.ndarray  # (N, 4) F1..F4 commanded (after saturation)
    act: np.ndarray  # (N, 4) the rotors' actuator states (rotor lag; zeros without)
    lag: bool  # first-order rotor lag in the model
    wind: np.ndarray  # (N, 3) the wind force held over the period (the wind stage's)
    neg_drag: np.ndarray  # (3,) −(Kx, Ky, Kz), paper eq. (1)
    force: np.ndarray  # (N, 3) the extra stages' sum over one physics step
    torque: np.ndarray  # (N, 3)
    unmix_t: np.ndarray  # (4, 4) U → rotor thrusts (eqs. 26–29), transposed
    mix_t: np.ndarray  # (4, 4) rotor thrusts → U, transposed
    f_min: float  # rotor thrust limits (N)
    f_max: float
    nsub: int  # physics steps per control period
    T: float  # control period (s)
    floor_z: float  # health limits (m, m, rad)
    max_distance: float
    max_tilt: float
    gate_on: bool  # the floor gate (swarm_mj.physics.sim.floor_gate_kernel)
    gate_z: float
    contype: np.ndarray  # (ngeom,) int32 mjModel.geom_contype
    gate_id: int
    gate_solid: int


class Refs(NamedTuple):
    """The run's references, precomputed per control instant, and the leader-velocity estimate."""

    pos: np.ndarray  # (K+1, 3) leader trajectory
    vel: np.ndarray  # (K+1, 3)
    acc: np.ndarray  # (K+1, 3)
    yaw: np.ndarray  # (K+1,)
    D: np.ndarray  # (K+1,) formation diameter D(t)
    unit_offsets: np.ndarray  # (n−1, 3) slot offsets for D = 1
    prev_leader: np.ndarray  # (3,) leader position at the last observation (updated)
    leader_vel: np.ndarray  # (3,) its finite-difference velocity (updated)
    sensing_range: float  # m
    wind_force: np.ndarray  # (K+1, 3) wind force per instant (uniform over drones)
    wind_speed: np.ndarray  # (K+1, 3)
    wind_known: bool  # the controller is given the wind force


class Obs(NamedTuple):
    """The observation of one control period (SwarmEnv's keys; leader = row 0)."""

    pos: np.ndarray  # (n, 3)
    vel: np.ndarray  # (n, 3)
    quat: np.ndarray  # (n, 4)
    omega: np.ndarray  # (n, 3) body rates
    rpy: np.ndarray  # (n, 3)
    rpy_rate: np.ndarray  # (n, 3)
    rel: np.ndarray  # (n, n, 3) neighbours
    mask: np.ndarray  # (n, n)
    dist: np.ndarray  # (n, n) 3D distances (+inf on the diagonal)
    sp: np.ndarray  # (n, 3) formation setpoint
    spv: np.ndarray  # (n, 3)
    spa: np.ndarray  # (n, 3)
    yaw: np.ndarray  # (n,)
    wf: np.ndarray  # (n, 3) the wind force given to the controller

    @classmethod
    def empty(cls, n: int, fill: bool = True) -> Obs:
        """Buffers for n drones: zeros, or uninitialised (``fill`` False: half the cost) for a stage that
        writes every one (``observe_into``)."""
        z = np.zeros if fill else np.empty
        return cls(
            pos=z((n, 3)),
            vel=z((n, 3)),
            quat=z((n, 4)),
            omega=z((n, 3)),
            rpy=z((n, 3)),
            rpy_rate=z((n, 3)),
            rel=z((n, n, 3)),
            mask=z((n, n)),
            dist=z((n, n)),
            sp=z((n, 3)),
            spv=z((n, 3)),
            spa=z((n, 3)),
            yaw=z(n),
            wf=z((n, 3)),
        )


class Rule(NamedTuple):
    """The layered rule's formed step (swarm_mj.formation.layered.formed_update), over the rule's own
    arrays (built once per reset by LayeredRule.record); ``on`` False: no rule (stand-ins)."""

    on: bool
    jet_aware: bool
    safety: float  # D̄ (m)
    overlap: float  # outlines overlapping (m), jet-aware
    offset: np.ndarray  # (n,) altitude offsets held
    prev_pos: np.ndarray  # (n, 3) positions at the last update
    vel: np.ndarray  # (n, 3) their finite-difference velocities
    prev_t: np.ndarray  # (1,) time of the last update (NaN: none yet)
    dt: np.ndarray  # (1,) the step between the last two updates
    formation_alt: np.ndarray  # (1,) the formation's altitude (jet-aware)
    slot_h: np.ndarray  # (n, n) horizontal slot distances (jet-aware)
    path_p: np.ndarray  # (n, 2) horizontal paths
    path_v: np.ndarray  # (n, 2)
    path_a: np.ndarray  # (n, 2)
    blocked: np.ndarray  # (n,) bool
    zp: np.ndarray  # (n,) altitude paths
    zv: np.ndarray  # (n,)
    za: np.ndarray  # (n,)
    limits: tuple  # the paths' limits (swarm_mj.formation.layered.PathLimits: a NamedTuple of floats)
    vel_d: np.ndarray  # (n, 3) references of the steered drones
    acc_d: np.ndarray  # (n, 3)
    steer: np.ndarray  # (n,) bool: the drones the rule steers
    slot_of: np.ndarray  # (n,) int64: drone i flies to the slot of row slot_of[i] (identity: its own)
    sensed_vel: np.ndarray  # (n, 3) the velocities the drone's view gives (swarm_mj.sensing), when vel_sensed
    vel_sensed: np.ndarray  # (1,) bool: vel is sensed_vel, not differenced from positions (a sensing model)


class Gains(NamedTuple):
    """Backstepping's constants (eqs. 17–24), from the gains (n, 12) and the airframe."""

    a_pos: np.ndarray  # (n, 3)
    c1_pos: np.ndarray  # (n, 3) 1 − a²
    c2_pos: np.ndarray  # (n, 3) a + b
    a_att: np.ndarray  # (n, 3)
    c1_att: np.ndarray  # (n, 3)
    c2_att: np.ndarray  # (n, 3)
    drag_over_m: np.ndarray  # (3,)
    m: float  # kg
    g: float  # m/s²
    inertia: np.ndarray  # (3,) Ix, Iy, Iz
    torque_scale: np.ndarray  # (3,) I / L
    cor: np.ndarray  # (3,) Coriolis coefficients
    L: float  # arm (m)
    T: float  # control period (s)


class Control(NamedTuple):
    """The controller of the built-in policy: backstepping, its memories, the mixer."""

    gains: Gains
    prev_att_d: np.ndarray  # (n, 2) previous (φ_d, θ_d)
    att_d: np.ndarray  # (n, 3) last commanded attitude (written)
    U_last: np.ndarray  # (n, 4) last command (written)
    exact: bool  # attitude_map == "exact"
    use_wind: bool  # wind feedforward
    priority: bool  # attitude-priority mixer (or yaw_last's, with yaw_last)
    yaw_last: bool  # the mixer gives up yaw first (mixing.yaw_last_kernel)
    unmix_t: np.ndarray  # (4, 4) U → rotor thrusts, transposed (the mixer's)
    mix_t: np.ndarray  # (4, 4) rotor thrusts → U, transposed
    f_min: float  # rotor thrust limits (N)
    f_max: float
    zeros1: np.ndarray  # (n,) zeros (the yaw references' rate and acceleration; never written)
    scratch: np.ndarray  # (5, n, 3): zeros (never written), the predicted rpy, rates, body rates, the known force
    U_out: np.ndarray  # (n, 4) the mixer's command (written)


class Feedforward(NamedTuple):
    """The downwash feedforward (swarm_mj.control.policy.DownwashFeedforward); ``on`` False: none."""

    on: bool
    n: int
    L: float
    dirs: np.ndarray  # (4, 2) rotor centres / L in the body frame (the vehicle's layout)
    rho: float
    r: float
    half_cda: float
    half_cda_body: float
    pos: np.ndarray  # (n, 3) buffers
    quat: np.ndarray  # (n, 4)
    rotor: np.ndarray  # (n, 4)
    force: np.ndarray  # (n, 3) the prediction (N)
    torque: np.ndarray  # (n, 3)
    sum_force: np.ndarray  # (n, 3)
    sum_torque: np.ndarray  # (n, 3)

    @classmethod
    def off(cls, n: int) -> Feedforward:
        """No feedforward for n drones (``on`` False): the stand-in a command without one passes."""
        z3, z4 = np.zeros((n, 3)), np.zeros((n, 4))
        return cls(
            on=False,
            n=n,
            L=0.0,
            dirs=np.zeros((4, 2)),
            rho=0.0,
            r=0.0,
            half_cda=0.0,
            half_cda_body=0.0,
            pos=z3,
            quat=z4,
            rotor=z4,
            force=z3,
            torque=z3,
            sum_force=z3,
            sum_torque=z3,
        )


class Predictor(NamedTuple):
    """The attitude predicted over the rotors' lag (swarm_mj.control.lag); ``on`` False: none."""

    on: bool
    d_att: float
    k_rate: float
    prev_rate: np.ndarray  # (n, 3)
    prev_body: np.ndarray  # (n, 3)

    @classmethod
    def off(cls, n: int) -> Predictor:
        """No lag prediction for n drones (``on`` False): the stand-in a command without one passes."""
        return cls(on=False, d_att=0.0, k_rate=0.0, prev_rate=np.zeros((n, 3)), prev_body=np.zeros((n, 3)))


class GroundTrack(NamedTuple):
    """The ground monitor's per-step bookkeeping without a contact (swarm_mj.physics.aero.ground)."""

    vel_before: np.ndarray  # (N, 3) velocity at the start of the last physics step
    vel_now: np.ndarray  # (N, 3)


class LogRows(NamedTuple):
    """The run log's arrays (swarm_mj.experiments.runner.RunLog), time axis first."""

    t: np.ndarray  # (K+1,)
    pos: np.ndarray  # (K+1, n, 3)
    vel: np.ndarray
    quat: np.ndarray  # (K+1, n, 4)
    rpy: np.ndarray
    pos_d: np.ndarray
    slot: np.ndarray
    att_d: np.ndarray
    U: np.ndarray  # (K+1, n, 4)
    rotor: np.ndarray  # (K+1, n, 4)
    wind_speed: np.ndarray  # (K+1, 3)
    wind_force: np.ndarray  # (K+1, n, 3)
    D: np.ndarray  # (K+1,)
    forces: np.ndarray  # (S, K+1, n, 3) each force stage's force, in the simulator's stage order


class Viewing(NamedTuple):
    """Each drone's own view in the chunk driver under a sensing model (swarm_mj.sensing, docs/sensing.md; the
    ``perfect`` oracle passes None instead)."""

    sense: Any  # the sensing stage's record (swarm_mj.sensing.stage.SenseRecord)
    rng: Any  # its generator (numpy.random.Generator, the stage's own: the driver draws from it)
    pay: Any  # the payloads held (swarm_mj.sensing.payload.PayloadRecord)
    no_ff: Feedforward  # the command's feedforward switched off (the view's force is in the known force)
    feedforward: bool  # the downwash feedforward, from each drone's view
    log: bool  # the view log's rows are written
    log_pos: np.ndarray  # (K, n, n, 3) the run's ViewLog (swarm_mj.sensing.log): what each drone believed
    log_mask: np.ndarray  # (K, n, n) bool
    log_age: np.ndarray  # (K, n, n)
    log_held_pos: np.ndarray  # (K, n, n, 3)
    log_held_tick: np.ndarray  # (K, n, n) int64
