"""The control period, written once (docs/design.md, "The control period, written once"): :func:`fly_chunk`
composes periods k .. k_end − 1 from the stages below, compiled functions over the records of
:mod:`swarm_mj.pipeline.records`, and returns where and why it stopped. Every driver runs it: the chunk driver
compiled, for up to ``CHUNK`` periods a call; :meth:`swarm_mj.env.SwarmEnv.step`, the vector env's step, a
run's other periods and the tuner its Python body for one period
(:mod:`swarm_mj.pipeline.stepper`: :func:`swarm_mj._jit.python_body` with the owners' Python stages in place
of some callees, the others compiled and bound to the caller's records). The rule's step is the rule's own
compiled step, registered for its record's type (:data:`swarm_mj.pipeline.registry.RULE_KERNELS`), which its
Python ``update`` calls too, and the barrier filter's period is one compiled function its Python call shares:

=========================  =====================================================================
stage                      function
=========================  =====================================================================
each drone's copy          under a sensing model, :func:`_copies_period`: every copy asked first
                           (``RULE_CHECKS[type(rule)]``), then copy i on drone i's view, its row i
the rule's step            ``_rule_period``: ``RULE_KERNELS[type(rule)]``, chosen when the driver is
                           compiled (the layered rule's: :func:`~swarm_mj.formation.layered.formed_step`,
                           Fig. 5's check, the velocity estimate, the paths, the merge of rows)
separation filter          then ``FILTER_KERNELS[type(filt)]`` (the barrier filter's period,
                           :func:`~swarm_mj.formation.barrier.barrier_step`, which ``BarrierFilter``
                           calls too), for a rule record with the fields it reads
downwash feedforward       :func:`feedforward_force`; from each drone's view: :func:`own_observation`
                           (:func:`viewed_feedforward`, the payloads' ``payload_tick``)
lag prediction             :func:`~swarm_mj.control.lag.predict_kernel`
backstepping, mixer        :func:`~swarm_mj.control.backstepping.backstepping_kernel`,
                           :func:`~swarm_mj.physics.mixing.attitude_priority_kernel` (or
                           :func:`~swarm_mj.physics.mixing.yaw_last_kernel`)
the command's check        :func:`all_finite`
log rows                   :func:`log_inputs`, :func:`log_outputs`
the wind                   :func:`hold_wind` (period k's, held over it)
saturation, floor gate     :func:`~swarm_mj.physics.sim.hold_inputs`
physics steps              :func:`~swarm_mj.physics.sim.physics_steps` (``Sim.step`` calls both through
                           :func:`~swarm_mj.physics.sim.period_physics`), per step:
force stages               :func:`apply_forces` (drag + wind, then each registered stage's kernel,
                           :data:`swarm_mj.pipeline.registry.FORCE_KERNELS`, in the simulator's order)
``mj_step``                MuJoCo's C function through :func:`swarm_mj.physics._mjstep.step_call`
monitors                   :func:`~swarm_mj.physics.sim.track_monitors` (the steps without a contact)
health check               :func:`~swarm_mj.physics.sim.unhealthy`
observation                :func:`observe_into` (into the driver's buffers; :func:`observe` on new ones)
each drone's view          :func:`~swarm_mj.sensing.stage.sense_step` (the channel, the tracks, each
                           drone's setpoints; ``SensingStage.observe`` calls it too), :func:`log_view`
=========================  =====================================================================

A compiled driver hands control back to Python for what the step path does in Python
(Fig. 5 acting, a contact, an unhealthy state, a non-finite command): :data:`REACT`,
:data:`CONTACT`, :data:`UNHEALTHY`, :data:`BAD_ACTION`.
"""

from __future__ import annotations

import numpy as np

from .._jit import AVAILABLE, jit
from ..control.backstepping import backstepping_kernel
from ..control.lag import predict_kernel
from ..formation.slots import setpoints_into
from ..physics.aero import downwash as _downwash
from ..physics.mixing import attitude_priority_kernel, yaw_last_kernel
from ..physics.observation import observe_kernel_into
from ..physics.sim import drone_views, hold_inputs, log_stage_forces, physics_steps, unhealthy, unmix_kernel
from ..sensing.payload import payload_tick
from ..sensing.stage import sense_step
from . import registry
from .records import Obs

#: :func:`fly_chunk` status: the chunk is done; Fig. 5 must act (Python flies this period);
#: a contact to count (then resume); unhealthy (Python raises); a non-finite command.
DONE, REACT, CONTACT, UNHEALTHY, BAD_ACTION = 0, 1, 2, 3, 4


# --------------------------------------------------------------------------- the stages


def _rule_period(rule, filt, obs, t):  # pragma: no cover - replaced by the overload when compiled
    """The rule's period in a compiled driver: its registered step, then its separation filter."""
    raise NotImplementedError("compiled code only (the chunk driver)")


def _rule_period_compiled(rule, filt, obs, t):
    """The rule's period for the record types of ``rule`` and ``filt``, chosen when the driver is compiled:
    the rule's step, :data:`registry.RULE_KERNELS` ``[type(rule)]``, then, for a record with the fields a
    separation filter reads (:data:`registry.FILTER_READS`), the filter's period, :data:`registry.FILTER_KERNELS`
    ``[type(filt)]``, on the velocities the step estimated, the time since the rule's last update and the
    drones it steers. Returns (react, pos_d, vel_d, acc_d); react True: the Python rule flies the period."""
    step = registry.RULE_KERNELS[rule.instance_class]
    if not set(registry.FILTER_READS) <= set(rule.instance_class._fields):

        def impl(rule, filt, obs, t):
            return step(rule, obs, t)

        return impl
    separate = registry.FILTER_KERNELS[filt.instance_class]

    def impl_filtered(rule, filt, obs, t):
        dt = t - rule.prev_t[0]
        react, pos_d, vel_d, acc_d = step(rule, obs, t)
        if react or not filt.on:
            return react, pos_d, vel_d, acc_d
        pos_d, vel_d, acc_d = separate(filt, t, obs.pos, rule.vel, dt, pos_d, vel_d, acc_d, rule.steer)
        return False, pos_d, vel_d, acc_d

    return impl_filtered


def _rule_busy(rule, obs):  # pragma: no cover - replaced by the overload when compiled
    """The rule's step would hand this period back (its registered check)."""
    raise NotImplementedError("compiled code only (the chunk driver)")


def _rule_busy_compiled(rule, obs):
    """:data:`registry.RULE_CHECKS` ``[type(rule)]``, chosen when the driver is compiled (a copy of a rule is
    asked before any copy steps, so that a period handed back leaves every copy as it was)."""
    check = registry.RULE_CHECKS[rule.instance_class]

    def impl(rule, obs):
        return check(rule, obs)

    return impl


def _take_view_velocities(rule, vel):  # pragma: no cover - replaced by the overload when compiled
    """The velocities (n, 3) of the copy's drone's view into its rule's record, where the rule takes them."""
    raise NotImplementedError("compiled code only (the chunk driver)")


def _take_view_velocities_compiled(rule, vel):
    """A record with ``sensed_vel`` (the layered rule's: its ``sense_velocities``) takes them; another, not."""
    if "sensed_vel" not in rule.instance_class._fields:
        return lambda rule, vel: None

    def impl(rule, vel):
        for i in range(vel.shape[0]):  # (loops, not slice copies: those compile slowly)
            for c in range(3):
                rule.sensed_vel[i, c] = vel[i, c]
        rule.vel_sensed[0] = True

    return impl


if AVAILABLE:  # the rule's step found in the registry by its record's type when the driver is compiled
    from numba.extending import overload

    overload(_rule_period, inline="always")(_rule_period_compiled)
    overload(_rule_busy, inline="always")(_rule_busy_compiled)
    overload(_take_view_velocities, inline="always")(_take_view_velocities_compiled)


# --------------------------------------------------------------------------- the oracle or each drone's view
# The chunk driver's stages that differ under a sensing model, chosen by the type of its ``view`` argument when
# it is compiled: None (the ``perfect`` oracle: the run's rule on the true observation, no sensing code in the
# compiled driver) or a :class:`~swarm_mj.pipeline.records.Viewing`.


def _period_rules(rules, filts, view, obs, t):  # pragma: no cover - replaced by the overload when compiled
    """(react, pos_d, vel_d, acc_d): the rule's period (the oracle's rule, or every drone's copy)."""
    raise NotImplementedError("compiled code only (the chunk driver)")


def _period_inputs(ff, view, obs, k, ctl):  # pragma: no cover - replaced by the overload when compiled
    """(observation, feedforward record) the command runs on."""
    raise NotImplementedError("compiled code only (the chunk driver)")


def _period_sense(view, obs, refs, k):  # pragma: no cover - replaced by the overload when compiled
    """Each drone's view of period k, after its observation (the sensing stage's tick)."""
    raise NotImplementedError("compiled code only (the chunk driver)")


def _period_view_log(view, k):  # pragma: no cover - replaced by the overload when compiled
    """Row k of the run's view log."""
    raise NotImplementedError("compiled code only (the chunk driver)")


def _rules_compiled(rules, filts, view, obs, t):
    if not isinstance(view, types.NoneType):
        return lambda rules, filts, view, obs, t: _copies_period(rules, filts, view, obs, t)

    def oracle(rules, filts, view, obs, t):
        n = obs.pos.shape[0]
        if filts[0].on and filts[0].ev_count[0] + n > filts[0].ev_t.shape[0]:
            return True, obs.sp, obs.spv, obs.spa  # its event buffer could overflow: Python flies this period
        return _rule_period(rules[0], filts[0], obs, t)

    return oracle


def _inputs_compiled(ff, view, obs, k, ctl):
    if isinstance(view, types.NoneType):
        return lambda ff, view, obs, k, ctl: (obs, ff)
    # each drone's controller on its own estimates, its feedforward from its view (its last U1: its packet's)
    return lambda ff, view, obs, k, ctl: (own_observation(ff, view, obs, k, ctl.U_last[:, 0].copy()), view.no_ff)


def _sense_compiled(view, obs, refs, k):
    if isinstance(view, types.NoneType):
        return lambda view, obs, refs, k: None

    def tick(view, obs, refs, k):
        sense_step(view.sense, view.rng, k, obs.pos, obs.vel, refs.pos[k], refs.vel[k], refs.acc[k], refs.D[k],
                   refs.unit_offsets)  # fmt: skip

    return tick


def _view_log_compiled(view, k):
    if isinstance(view, types.NoneType):
        return lambda view, k: None

    def row(view, k):
        if view.log:
            log_view(view, k)

    return row


if AVAILABLE:  # calls, not inlined: inlined ("always") these four broke the oracle's realistic anti_collision
    # run's parity with the per-period path (its golden summary); as calls it is bit for bit again
    from numba.core import types

    overload(_period_rules)(_rules_compiled)
    overload(_period_inputs)(_inputs_compiled)
    overload(_period_sense)(_sense_compiled)
    overload(_period_view_log)(_view_log_compiled)


@jit(inline=True)
def _viewed(obs, sense, i):
    """The observation as drone i sees it (its row of the view: where it believes each drone is, its setpoints
    from its leader belief); the rest of ``obs`` as it is."""
    return Obs(
        pos=sense.pos[i], vel=obs.vel, quat=obs.quat, omega=obs.omega, rpy=obs.rpy, rpy_rate=obs.rpy_rate,
        rel=obs.rel, mask=obs.mask, dist=obs.dist, sp=sense.sp[i], spv=sense.spv[i], spa=sense.spa, yaw=obs.yaw,
        wf=obs.wf,
    )  # fmt: skip


@jit
def _copies_period(rules, filts, view, obs, t):
    """The rule's period under a sensing model (swarm_mj.formation.own_view): ``rules`` and ``filts`` hold one
    copy per drone; copy i is fed drone i's view (:func:`_viewed`), its step and filter (:func:`_rule_period`),
    and drone i flies row i of what it returns. Every copy is asked first (its registered check, and whether
    its filter's event buffer could overflow), so that a period handed back leaves every copy as it was.
    Returns (react, pos_d, vel_d, acc_d); react True: Python flies the period."""
    n = obs.pos.shape[0]
    for i in range(n):
        rule, filt = rules[i], filts[i]  # (each once: an element of a tuple is a switch over its n)
        if filt.on and filt.ev_count[0] + n > filt.ev_t.shape[0]:
            return True, obs.sp, obs.spv, obs.spa  # its event buffer could overflow: Python flies this period
        if _rule_busy(rule, _viewed(obs, view.sense, i)):
            return True, obs.sp, obs.spv, obs.spa
    pos_d, vel_d, acc_d = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3))
    for i in range(n):
        rule, filt = rules[i], filts[i]
        _take_view_velocities(rule, view.sense.vel[i])
        _, p, v, a = _rule_period(rule, filt, _viewed(obs, view.sense, i), t)
        for c in range(3):
            pos_d[i, c] = p[i, c]
            vel_d[i, c] = v[i, c]
            acc_d[i, c] = a[i, c]
    return False, pos_d, vel_d, acc_d


@jit(on_demand=True)
def viewed_feedforward(ff, pay, k, view_pos, mask, age, quat, thrust, out) -> None:
    """Each drone's downwash feedforward from its own view, into out (n, 3): the senders' attitude (n, 4) and
    last thrust (n,) of period k into the payloads (:func:`~swarm_mj.sensing.payload.payload_tick`, with the
    view's mask and ages (n, n)), then drone i's row of :func:`feedforward_force` at the positions it believes
    (view_pos[i] (n, 3)), with the attitudes and thrusts of the packets it holds and its own
    (:func:`~swarm_mj.physics.aero.downwash.downwash_on`: that row alone). A call from the chunk driver, and the
    per-period path's policy calls it too."""
    n = thrust.shape[0]
    payload_tick(pay, k, quat, thrust, mask, age)
    q, rotor, torque = np.empty((n, 4)), np.empty((n, 4)), np.empty(3)
    for i in range(n):
        for j in range(n):  # the packets drone i holds, and its own attitude and thrust (shared over its rotors)
            mine = j == i
            for c in range(4):
                q[j, c] = quat[i, c] if mine else pay.quat[i, j, c]
                rotor[j, c] = (thrust[i] if mine else pay.thrust[i, j]) / 4.0
        _downwash.downwash_on(i, view_pos[i], q, rotor, ff.L, ff.dirs, ff.rho, ff.r, ff.half_cda, ff.half_cda_body,
                              ff.r, out[i], torque)  # fmt: skip


@jit(inline=True)
def own_observation(ff, view, obs, k, thrust):
    """What drone i's controller is given when each drone decides from its own view: its own estimated position
    and velocity, and, with the downwash feedforward (``view.feedforward``), the force predicted from where it
    believes the others are (:func:`viewed_feedforward`, ``thrust`` (n,) each drone's last U1: what its
    next packet carries) added to the known force; the command then runs with ``view.no_ff``."""
    sense = view.sense
    wf = obs.wf
    if view.feedforward:
        wf = np.empty_like(obs.wf)
        viewed_feedforward(ff, view.pay, k, sense.pos, sense.mask, sense.age, obs.quat, thrust, wf)
        wf += obs.wf
    return Obs(
        pos=sense.own_pos, vel=sense.own_vel, quat=obs.quat, omega=obs.omega, rpy=obs.rpy, rpy_rate=obs.rpy_rate,
        rel=obs.rel, mask=obs.mask, dist=obs.dist, sp=obs.sp, spv=obs.spv, spa=obs.spa, yaw=obs.yaw, wf=wf,
    )  # fmt: skip


@jit(inline=True)
def log_view(view, k) -> None:
    """Row k of the run's view log (swarm_mj.sensing.log.ViewLog.record): what each drone believes and holds."""
    s = view.sense
    n = s.mask.shape[0]
    for i in range(n):
        for j in range(n):
            view.log_mask[k, i, j] = s.mask[i, j]
            view.log_age[k, i, j] = s.age[i, j]
            view.log_held_tick[k, i, j] = s.ch.held_tick[i, j]
            for c in range(3):
                view.log_pos[k, i, j, c] = s.pos[i, j, c]
                view.log_held_pos[k, i, j, c] = s.ch.held_pos[i, j, c]


@jit(inline=True)
def feedforward_force(ff, pos, quat, thrust) -> None:
    """The downwash feedforward (swarm_mj.control.policy.DownwashFeedforward): ff.force (n, 3) = the jets'
    force on each drone at pos (n, 3), quat (n, 4), each drone's thrust (n,) shared over its rotors."""
    n = pos.shape[0]
    ff.pos[:] = pos
    ff.quat[:] = quat
    for i in range(n):
        for r in range(4):
            ff.rotor[i, r] = thrust[i] / 4.0
    ff.sum_force[:] = 0.0
    ff.sum_torque[:] = 0.0
    _downwash.downwash_kernel(
        ff.pos, ff.quat, ff.rotor, ff.n, ff.L, ff.dirs, ff.rho, ff.r, ff.half_cda, ff.half_cda_body, ff.r,
        ff.force, ff.torque, ff.sum_force, ff.sum_torque,
    )  # fmt: skip


@jit(inline=True)
def command(ctl, ff, pred, obs, pos_d, vel_d, acc_d, first):
    """U1..U4 (n, 4) of the built-in policy from the references (n, 3): the known external force
    (the wind given to the controller, plus the downwash feedforward from the last command),
    the attitude predicted over the rotors' lag, backstepping (eqs. 17–24), the attitude-priority
    mixer (or the yaw-last one). Reads of ``obs`` the drones' state, yaw references and wind force
    only. Writes ctl.att_d, ctl.prev_att_d, ctl.U_last (the thrust the next feedforward uses) and the
    predictor's last rates.

    ``first``: no command since the controller's reset (the per-period path's first period; the chunk
    driver starts later): the feedforward takes each drone's last thrust as m·g, the lag prediction
    holds the rates (its last rates are the current ones), backstepping's desired-attitude rates are
    zero. The per-period path calls this function's Python body (``_jit.python_body``: its callees
    compiled), so its statements are ones NumPy and Numba both run: array expressions, no loops."""
    zeros1, zeros3 = ctl.zeros1, ctl.scratch[0]
    ext = obs.wf
    if ff.on:
        if first:
            ctl.U_last[:, 0] = ctl.gains.m * ctl.gains.g
        feedforward_force(ff, obs.pos, obs.quat, ctl.U_last[:, 0])
        ext = ctl.scratch[4]
        np.add(obs.wf, ff.force, ext)
    wind = ext if ctl.use_wind else zeros3
    rpy_in, rate_in, body_in = obs.rpy, obs.rpy_rate, obs.omega
    if pred.on:
        rpy_in, rate_in, body_in = ctl.scratch[1], ctl.scratch[2], ctl.scratch[3]
        predict_kernel(
            obs.rpy, obs.rpy_rate, obs.omega, pred.prev_rate, pred.prev_body, pred.d_att, pred.k_rate, first, rpy_in,
            rate_in, body_in,
        )  # fmt: skip
    omega = body_in if ctl.exact else zeros3
    U = backstepping_kernel(
        ctl.gains, rpy_in, rate_in, omega, obs.pos, obs.vel, pos_d, vel_d, acc_d, obs.yaw, zeros1, zeros1, wind,
        ctl.use_wind, ctl.prev_att_d, first, ctl.exact, ctl.att_d,
    )  # fmt: skip
    if ctl.priority:
        if ctl.yaw_last:
            yaw_last_kernel(U, ctl.unmix_t, ctl.mix_t, ctl.f_min, ctl.f_max, ctl.U_out)
        else:
            attitude_priority_kernel(U, ctl.unmix_t, ctl.mix_t, ctl.f_min, ctl.f_max, ctl.U_out)
        U = ctl.U_out
    ctl.U_last[:] = U
    return U


@jit(inline=True)
def log_inputs(log, k, t, obs, pos_d, att_d, wind_speed, D) -> None:
    """Row k of the log from the observation, the command computed from it (pos_d, att_d (n, 3)), the
    wind speed (3,) and D of that instant (the step path runs this function's Python body: pipeline/stepper.py)."""
    log.t[k] = t
    log.pos[k] = obs.pos
    log.vel[k] = obs.vel
    log.quat[k] = obs.quat
    log.rpy[k] = obs.rpy
    log.pos_d[k] = pos_d
    log.slot[k] = obs.sp
    log.att_d[k] = att_d
    log.wind_speed[k] = wind_speed
    log.D[k] = D


@jit(inline=True)
def observe(phys, refs, k):
    """The observation of period k (:class:`~swarm_mj.pipeline.records.Obs`, fresh arrays; SwarmEnv's keys):
    :func:`observe_into` new buffers."""
    n = phys.qpos.shape[0]
    obs = Obs(
        pos=np.empty((n, 3)),
        vel=np.empty((n, 3)),
        quat=np.empty((n, 4)),
        omega=np.empty((n, 3)),
        rpy=np.empty((n, 3)),
        rpy_rate=np.empty((n, 3)),
        rel=np.empty((n, n, 3)),
        mask=np.empty((n, n)),
        dist=np.empty((n, n)),
        sp=np.empty((n, 3)),
        spv=np.empty((n, 3)),
        spa=np.empty((n, 3)),
        yaw=np.empty(n),
        wf=np.empty((n, 3)),
    )
    observe_into(phys.qpos, phys.qvel, phys.T, refs, obs, k)
    return obs


@jit(inline=True)
def observe_into(qpos, qvel, T, refs, obs, k) -> None:
    """The observation of period k into the buffers of ``obs`` (the chunk driver's; :func:`observe` new ones)
    from the simulator's qpos (n, 7), qvel (n, 6) and control period T (its record's fields, passed alone:
    a Python caller's bound call then unboxes three values, not the record's 33): the state, the neighbours
    within sensing range, the formation setpoints (the leader's velocity estimated, paper §4;
    refs.prev_leader, refs.leader_vel updated), the known wind force (refs.wind_force[k] on every drone
    when the controller is given it, else zero)."""
    n = qpos.shape[0]
    observe_kernel_into(
        qpos, qvel, refs.sensing_range, obs.pos, obs.vel, obs.quat, obs.omega, obs.rpy, obs.rpy_rate,
        obs.rel, obs.mask, obs.dist,
    )  # fmt: skip
    setpoints_into(
        k, T, obs.pos[0], refs.prev_leader, refs.leader_vel, refs.pos[k], refs.vel[k], refs.acc[k], refs.yaw[k],
        refs.D[k], refs.unit_offsets, obs.sp, obs.spv, obs.spa, obs.yaw,
    )  # fmt: skip
    obs.wf[:] = 0.0
    if refs.wind_known:
        for i in range(n):
            for j in range(3):
                obs.wf[i, j] = refs.wind_force[k, j]


# --------------------------------------------------------------------------- the chunk driver


@jit(inline=True, samples=lambda: [(np.zeros((2, 4)),)])
def all_finite(a: np.ndarray) -> bool:
    """True if every entry of a (any shape) is finite (the period's check of its command)."""
    for x in a.flat:
        if not np.isfinite(x):
            return False
    return True


@jit(inline=True)
def hold_wind(phys, refs, k) -> None:
    """The wind force of period k (refs.wind_force[k], uniform) on every drone, held over the period."""
    for i in range(phys.wind.shape[0]):
        for j in range(3):
            phys.wind[i, j] = refs.wind_force[k, j]


@jit
def fly_chunk(k, s0, k_end, python_each, phys, refs, obs, rules, filts, view, ctl, ff, pred, log, stages, monitors):
    """Control periods k .. k_end − 1, written once (module docstring): the chunk driver calls it compiled for
    up to ``CHUNK`` periods, the step path runs its Python body for one (:mod:`swarm_mj.pipeline.stepper`).
    Returns (status, k, s): :data:`DONE` at k_end (``obs`` holds its observation), or where it stopped:
    :data:`REACT` (the rule hands period k back before anything acted), :data:`BAD_ACTION` (a non-finite
    command, nothing applied), :data:`CONTACT` (physics step s − 1 of period k had a contact: Python counts
    it, then calls again with ``s0`` = s), :data:`UNHEALTHY` (after period k − 1's physics, not observed).

    ``obs`` holds the observation of period k (in) and of the period where it stops (out). ``s0`` > 0
    resumes period k after physics step s0 − 1 (a contact Python counted); ``python_each``: Python
    still holds drones in contact, so every physics step goes back to it. ``stages``, ``monitors``:
    the records of the simulator's compiled force stages and monitors, in its order. ``rules``: the rule's
    record (its step: ``registry.RULE_KERNELS[type(rule)]``), a 1-tuple; ``filts``: the rule's barrier
    separation filter (:class:`~swarm_mj.formation.barrier.BarrierRecord`; ``on`` False: none), after the
    rule's step as in ``LayeredRule.references``. ``view``: None for the oracle, or under a sensing model a
    :class:`~swarm_mj.pipeline.records.Viewing` (the driver compiled for it): each period's view is the
    sensing stage's tick after the observation
    (:func:`~swarm_mj.sensing.stage.sense_step`), ``rules`` and ``filts`` hold one copy per drone, each deciding
    its drone's references from that drone's view (:func:`_copies_period`), and the command is
    :func:`command` on :func:`own_observation`."""
    kin, xf, xtorque = drone_views(phys)
    while k < k_end:
        if s0 == 0:
            t = k * phys.T
            react, pos_d, vel_d, acc_d = _period_rules(rules, filts, view, obs, t)
            if react:
                return REACT, k, 0
            seen, known = _period_inputs(ff, view, obs, k, ctl)
            U = command(ctl, known, pred, seen, pos_d, vel_d, acc_d, False)
            if not all_finite(U):
                return BAD_ACTION, k, 0
            log_inputs(log, k, t, obs, pos_d, ctl.att_d, refs.wind_speed[k], refs.D[k])
            _period_view_log(view, k)
            hold_wind(phys, refs, k)
            hold_inputs(phys, U)
        s = physics_steps(phys, stages, monitors, kin, xf, xtorque, s0, python_each)
        if s > 0:
            return CONTACT, k, s
        s0 = 0
        log_outputs(log, k, phys, stages)
        k += 1
        if unhealthy(phys):
            return UNHEALTHY, k, 0
        observe_into(phys.qpos, phys.qvel, phys.T, refs, obs, k)
        _period_sense(view, obs, refs, k)
    return DONE, k, 0


@jit(inline=True)
def log_outputs(log, k, phys, stages) -> None:
    """Row k of the log from what the period applied (RunLog.applied): the held U1..U4, the wind force,
    the produced rotor thrusts (read from the lagged rotors' states) and each force stage's force."""
    log.U[k] = phys.ctrl
    log.wind_force[k] = phys.wind
    if phys.lag:
        unmix_kernel(phys.act, phys.unmix_t, phys.rotor_thrust)
    log.rotor[k] = phys.rotor_thrust
    log_stage_forces(stages, log.forces, k)
