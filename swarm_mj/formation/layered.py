"""The anti-collision's compiled kernels: the layered rule's limited paths
(:class:`~swarm_mj.formation.planner.LayeredRule`), its formed step (:func:`formed_update`, which
both drivers of the control period call) and the pairwise helpers of the separation step
(:func:`horizontal_distances`, :func:`react_needed`, :func:`any_below`, :func:`merge_rows`).

Each follower the rule steers flies a horizontal path (p, v, a (n, 2)) and an altitude path
(zp, zv, za (n,)) whose position, velocity and acceleration go to the controller; the paths
are limited in speed, acceleration (and tilt) and jerk (:class:`PathLimits`, from the rule's
:class:`~swarm_mj.formation.rule_params.LayersParams`). Ours, not the paper's (see the rule's
docstring and docs/interpretations.md §4).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from .._jit import jit
from ..pipeline.records import Rule as FormedRecord
from .rule_params import LayersParams


class PathLimits(NamedTuple):
    """What the path kernels read (m, s): built once per rule by :func:`path_limits`. A field named
    as a field of :class:`~swarm_mj.formation.rule_params.LayersParams` is that field's value; the
    others are derived by the rule (:class:`~swarm_mj.formation.planner.LayeredRule`)."""

    max_accel: float  # (m/s²) horizontal path acceleration
    jerk: float  # (m/s³) the paths' jerk
    velocity_gain: float  # (1/s) the paths' velocity loop gain
    v_max: float  # (m/s) horizontal path speed: max_speed, capped to stop within the sensing range
    tan_tilt: float  # tan(max_tilt_deg)
    g: float  # (m/s²)
    v_up: float  # (m/s) altitude path speed up: climb_speed, capped likewise
    climb_accel: float  # (m/s²) altitude path acceleration up
    descent_speed: float  # (m/s) altitude path speed down
    a_down_formed: float  # (m/s²) altitude path acceleration down once joined: min(formed_descent_accel, descent_accel)
    braking_share: float  # share of its acceleration limit a path plans to brake with
    path_approach_gain: float  # (1/s) a horizontal path's final approach: speed ≤ this · distance
    altitude_approach_gain: float  # (1/s) an altitude path's final approach: speed ≤ this · distance
    thrust_floor: float  # (m/s²) least vertical specific force the tilt limit is taken from


def path_limits(params: LayersParams, **derived: float) -> PathLimits:
    """The :class:`PathLimits` of a rule: each field named as a field of ``params`` from it, the
    others from ``derived`` (a missing one is a KeyError: a new field is either a parameter or
    derived by the rule)."""
    own = set(params.keys)
    return PathLimits(**{k: float(getattr(params, k) if k in own else derived[k]) for k in PathLimits._fields})


def idle_record(n: int) -> FormedRecord:
    """A formed-step record (:class:`~swarm_mj.pipeline.records.Rule`) of stand-ins for n drones,
    ``on`` False (a run without the layered rule: nothing of it is read); the same types as a rule's own."""
    z, e, b = np.zeros((n, 3)), np.zeros((n, 2)), np.zeros(n, dtype=np.bool_)
    limits = PathLimits(**dict.fromkeys(PathLimits._fields, 1.0))
    return FormedRecord(
        on=False,
        jet_aware=False,
        safety=0.0,
        overlap=0.0,
        offset=np.zeros(n),
        prev_pos=z,
        vel=z.copy(),
        prev_t=np.full(1, np.nan),
        dt=np.zeros(1),
        formation_alt=np.zeros(1),
        slot_h=np.zeros((n, n)),
        path_p=e,
        path_v=e.copy(),
        path_a=e.copy(),
        blocked=b,
        zp=np.zeros(n),
        zv=np.zeros(n),
        za=np.zeros(n),
        limits=limits,
        vel_d=z.copy(),
        acc_d=z.copy(),
        steer=b.copy(),
        slot_of=np.arange(n, dtype=np.int64),
        sensed_vel=z.copy(),
        vel_sensed=np.zeros(1, dtype=np.bool_),
    )


def _limits_sample() -> PathLimits:
    return path_limits(LayersParams(), v_max=4.0, tan_tilt=0.5, g=9.81, v_up=4.0, a_down_formed=5.0)


def _formed_samples():
    n = 2
    z1, z2, z3 = np.zeros(n), np.zeros((n, 2)), np.zeros((n, 3))
    b = np.zeros(n, dtype=np.bool_)
    return [
        (
            0.01,
            z3,
            1.0,
            z1,
            np.zeros(3),
            z2,
            z2.copy(),
            z2.copy(),
            b,
            z1.copy(),
            z1.copy(),
            z1.copy(),
            _limits_sample(),
            z3.copy(),
            z3.copy(),
            z3.copy(),
        )
    ]


def _paths_samples():
    n = 2
    z1, z2 = np.zeros(n), np.zeros((n, 2))
    b = np.zeros(n, dtype=np.bool_)
    return [(0.01, z2, z2.copy(), z2.copy(), z2.copy(), z2.copy(), b, z1, _limits_sample())]


def _altitude_samples():
    z1 = np.zeros(2)
    return [(0.01, z1, z1.copy(), z1.copy(), z1.copy(), z1.copy(), _limits_sample(), 5.0)]


@jit(samples=_paths_samples)
def advance_paths_kernel(
    dt: float,
    goal: np.ndarray,
    goal_vel: np.ndarray,
    p: np.ndarray,
    v: np.ndarray,
    a: np.ndarray,
    blocked: np.ndarray,
    za: np.ndarray,
    lim: PathLimits,
) -> None:
    """One step of the layered rule's horizontal paths (see LayeredRule._advance_paths), in place:
    p, v, a (n, 2) move towards goal (n, 2) moving at goal_vel (n, 2), within ``lim``.

    Invariant: |a| ≤ min(max_accel, max(g + za, thrust_floor)·tan_tilt), |Δa| ≤ jerk·dt per step,
    and the speed asked relative to the goal is ≤ v_max, ≤ path_approach_gain·distance and ≤
    √(2·braking_share·max_accel·e_eff), e_eff the distance left after the lag 2·max_accel/jerk +
    1/velocity_gain: a path stops at the goal without overshooting as long as the goal moves no
    faster than v_max. A blocked drone is asked for zero velocity (it brakes to rest at max_accel)."""
    a_max, jerk, k_v, v_max = lim.max_accel, lim.jerk, lim.velocity_gain, lim.v_max
    n = p.shape[0]
    lag = 2.0 * a_max / jerk + 1.0 / k_v
    for i in range(n):
        ex = goal[i, 0] - p[i, 0]
        ey = goal[i, 1] - p[i, 1]
        dist = np.sqrt(ex * ex + ey * ey)
        rx = v[i, 0] - goal_vel[i, 0]
        ry = v[i, 1] - goal_vel[i, 1]
        e_eff = max(dist - np.sqrt(rx * rx + ry * ry) * lag, 0.0)
        speed = min(min(v_max, np.sqrt(2.0 * lim.braking_share * a_max * e_eff)), lim.path_approach_gain * dist)
        k = speed / max(dist, 1e-9)
        vx = goal_vel[i, 0] + ex * k
        vy = goal_vel[i, 1] + ey * k
        s = min(1.0, v_max / max(np.sqrt(vx * vx + vy * vy), 1e-9))
        vx *= s
        vy *= s
        if blocked[i]:
            vx = 0.0
            vy = 0.0
        a_lim = min(a_max, max(lim.g + za[i], lim.thrust_floor) * lim.tan_tilt)
        ax = k_v * (vx - v[i, 0])
        ay = k_v * (vy - v[i, 1])
        s = min(1.0, a_lim / max(np.sqrt(ax * ax + ay * ay), 1e-12))
        ax *= s
        ay *= s
        dx = ax - a[i, 0]
        dy = ay - a[i, 1]
        s = min(1.0, jerk * dt / max(np.sqrt(dx * dx + dy * dy), 1e-12))
        a[i, 0] += dx * s
        a[i, 1] += dy * s
        v[i, 0] += a[i, 0] * dt
        v[i, 1] += a[i, 1] * dt
        p[i, 0] += v[i, 0] * dt
        p[i, 1] += v[i, 1] * dt


@jit(samples=_altitude_samples)
def advance_altitude_kernel(
    dt: float,
    target: np.ndarray,
    target_vel: np.ndarray,
    zp: np.ndarray,
    zv: np.ndarray,
    za: np.ndarray,
    lim: PathLimits,
    ad: float,
) -> None:
    """One step of the layered rule's altitude paths (see LayeredRule._advance_altitude), in place:
    zp, zv, za (n,) towards target (n,) moving at target_vel (n,), within ``lim`` and the downward
    acceleration limit ``ad`` (m/s²).

    Invariant: −ad ≤ za ≤ climb_accel (less thrust is limited to ``ad``: eq. (18)'s U1 stays off its
    floor), |Δza| ≤ jerk·dt, −descent_speed ≤ zv asked ≤ v_up, and the speed asked towards the
    target is ≤ altitude_approach_gain·|e| and ≤ √(2·braking_share·a·e_eff) with a the acceleration
    that will brake it: no overshoot of a still target."""
    vu, au, vd, jerk, k_v = lim.v_up, lim.climb_accel, lim.descent_speed, lim.jerk, lim.velocity_gain
    share = lim.braking_share
    n = zp.shape[0]
    lag = (au + ad) / jerk + 1.0 / k_v
    for i in range(n):
        e = target[i] - zp[i]
        up = e >= 0.0
        e_eff = max(abs(e) - abs(zv[i]) * lag, 0.0)
        v_stop = np.sqrt(2.0 * share * ad * e_eff) if up else np.sqrt(2.0 * share * au * e_eff)
        speed = min(min(vu if up else vd, v_stop), lim.altitude_approach_gain * abs(e))
        sgn = 1.0 if e > 0.0 else (-1.0 if e < 0.0 else 0.0)
        v_des = min(max(target_vel[i] + sgn * speed, -vd), vu)
        a_des = min(max(k_v * (v_des - zv[i]), -ad), au)
        za[i] += min(max(a_des - za[i], -jerk * dt), jerk * dt)
        zv[i] += za[i] * dt
        zp[i] += zv[i] * dt


@jit(samples=_formed_samples)
def formed_step_kernel(
    dt: float,
    pos_d: np.ndarray,
    formation_alt: float,
    offset: np.ndarray,
    lead_vel: np.ndarray,
    p: np.ndarray,
    v: np.ndarray,
    a: np.ndarray,
    blocked: np.ndarray,
    zp: np.ndarray,
    zv: np.ndarray,
    za: np.ndarray,
    lim: PathLimits,
    out_pos: np.ndarray,
    out_vel: np.ndarray,
    out_acc: np.ndarray,
) -> None:
    """The paths of the layered rule once every follower is formed (:func:`formed_paths`), after
    the reactive rule has set the altitude offsets (n,): the horizontal paths p, v, a (n, 2) follow
    the slots pos_d[:, :2] moving at the leader's velocity lead_vel (3,), the altitude paths
    zp, zv, za (n,) follow formation_alt + offset (descending with at most ``lim.a_down_formed``);
    writes the followers' references into out_pos (from pos_d), out_vel, out_acc (n, 3) (the
    leader's row: pos_d, zero, zero)."""
    n = pos_d.shape[0]
    blocked[:] = False
    if dt > 0.0:
        goal = np.empty((n, 2))
        goal_vel = np.empty((n, 2))
        z_target = np.empty(n)
        z_target_vel = np.empty(n)
        for i in range(n):
            goal[i, 0] = pos_d[i, 0]
            goal[i, 1] = pos_d[i, 1]
            goal_vel[i, 0] = lead_vel[0]
            goal_vel[i, 1] = lead_vel[1]
            z_target[i] = formation_alt + offset[i]
            z_target_vel[i] = lead_vel[2]
        advance_paths_kernel(dt, goal, goal_vel, p, v, a, blocked, za, lim)
        advance_altitude_kernel(dt, z_target, z_target_vel, zp, zv, za, lim, lim.a_down_formed)
    else:
        a[:] = 0.0
        za[:] = 0.0
    for j in range(3):
        out_pos[0, j] = pos_d[0, j]
        out_vel[0, j] = 0.0
        out_acc[0, j] = 0.0
    for i in range(1, n):
        out_pos[i, 0] = p[i, 0]
        out_pos[i, 1] = p[i, 1]
        out_pos[i, 2] = zp[i]
        out_vel[i, 0] = v[i, 0]
        out_vel[i, 1] = v[i, 1]
        out_vel[i, 2] = zv[i]
        out_acc[i, 0] = a[i, 0]
        out_acc[i, 1] = a[i, 1]
        out_acc[i, 2] = za[i]


# --------------------------------------------------------------------------- the formed step
def _record_samples():
    n = 2
    z3 = np.zeros((n, 3))
    return [(idle_record(n), z3, z3.copy(), 0.01, 1.0)]


@jit(inline=True, samples=lambda: [(0.01, *([np.zeros((2, 3))] * 3), np.full(1, np.nan), np.zeros(1))])
def estimate_velocities(
    t: float, pos: np.ndarray, prev_pos: np.ndarray, vel: np.ndarray, prev_t: np.ndarray, dt_out: np.ndarray
) -> float:
    """Each drone's velocity estimated from its successive positions (decentralised: no drone reads
    another's velocity), in place: vel (n, 3) = (pos − prev_pos) / dt with dt = t − prev_t[0] (0 at
    the first update, prev_t[0] NaN; vel kept when dt ≤ 0); then prev_pos (n, 3), prev_t (1,) ← pos,
    t and dt_out (1,) ← dt, which it returns."""
    dt = 0.0 if np.isnan(prev_t[0]) else t - prev_t[0]
    n = pos.shape[0]
    if dt > 0.0:
        for i in range(n):
            for j in range(3):
                vel[i, j] = pos[i, j] - prev_pos[i, j]
        for i in range(n):
            for j in range(3):
                vel[i, j] /= dt
    prev_t[0] = t
    for i in range(n):
        for j in range(3):
            prev_pos[i, j] = pos[i, j]
    dt_out[0] = dt
    return dt


@jit(inline=True, samples=lambda: [(idle_record(2), 0.01, np.zeros((2, 3)), 1.0, np.zeros(2))])
def formed_paths(rule: FormedRecord, dt: float, pos_d: np.ndarray, formation_alt: float, offset: np.ndarray) -> Any:
    """The paths of the ``rule`` record's swarm (:func:`formed_step_kernel`) towards the slots
    pos_d (n, 3) and formation_alt + offset (n,): returns pos_d (n, 3) adjusted, and writes the
    steered drones' velocity and acceleration references into rule.vel_d, rule.acc_d (n, 3)."""
    out = np.empty((pos_d.shape[0], 3))
    formed_step_kernel(
        dt, pos_d, formation_alt, offset, rule.vel[0], rule.path_p, rule.path_v, rule.path_a, rule.blocked,
        rule.zp, rule.zv, rule.za, rule.limits, out, rule.vel_d, rule.acc_d,
    )  # fmt: skip
    return out


@jit(inline=True, samples=lambda: [(np.zeros((2, 3)), np.arange(2, dtype=np.int64))])
def slotted(pos_d: np.ndarray, slot_of: np.ndarray) -> np.ndarray:
    """The setpoints (n, 3) with drone i's row the slot ``slot_of[i]`` of pos_d (n, 3) (a new array:
    pos_d[slot_of]; row 0, the leader's, stays its own)."""
    out = np.empty_like(pos_d)
    for i in range(pos_d.shape[0]):
        for c in range(pos_d.shape[1]):
            out[i, c] = pos_d[slot_of[i], c]
    return out


@jit(inline=True, samples=_record_samples)
def formed_update(rule: FormedRecord, pos: np.ndarray, pos_d: np.ndarray, t: float, formation_alt: float) -> Any:
    """The layered rule's update once every follower is formed (:meth:`LayeredRule.update
    <swarm_mj.formation.planner.LayeredRule.update>`; both drivers of the control period call it),
    on the ``rule`` record over the rule's own arrays, the positions pos (n, 3) and the slots
    pos_d (n, 3): returns (busy, pos_d adjusted (n, 3)).

    busy True: Fig. 5 has work to do (an offset held, drones within D̄ horizontally; for
    ``jet-aware`` also slots within D̄, or keep-outs overlapping in plan view), and nothing but the
    jet-aware slot distances and formation altitude (rule.slot_h, rule.formation_alt) is written:
    the rule's Python reaction flies the period. Else the velocity estimate
    (:func:`estimate_velocities`; under a sensing model ``rule.sensed_vel``, the drone's view's) and the
    paths (:func:`formed_paths`) with the offsets held.
    Drone i's slot is row ``rule.slot_of[i]`` of pos_d (:func:`slotted`; identity but for a rule
    that assigns slots, docs/barrier.md)."""
    n = pos.shape[0]
    pos_d = slotted(pos_d, rule.slot_of)
    if formed_busy(rule, pos, pos_d, formation_alt):
        return True, pos_d
    dt = estimate_velocities(t, pos, rule.prev_pos, rule.vel, rule.prev_t, rule.dt)
    if rule.vel_sensed[0]:  # a sensing model: the velocities of the drone's view
        for i in range(n):
            for j in range(3):
                rule.vel[i, j] = rule.sensed_vel[i, j]
    return False, formed_paths(rule, dt, pos_d, formation_alt, rule.offset)


@jit(inline=True)
def formed_busy(rule: FormedRecord, pos: np.ndarray, pos_d: np.ndarray, formation_alt: float) -> bool:
    """Fig. 5 has work to do at the positions pos (n, 3), the slots pos_d (n, 3) already :func:`slotted` (an
    offset held, drones within D̄ horizontally; for ``jet-aware`` also slots within D̄, or keep-outs
    overlapping in plan view). Writes nothing but the jet-aware slot distances and formation altitude
    (rule.slot_h, rule.formation_alt: the same values whenever it is asked again)."""
    n = pos.shape[0]
    h = horizontal_distances(pos)
    if rule.jet_aware:
        sh = horizontal_distances(pos_d)
        for i in range(n):  # (element-wise: a slice assignment compiles numba's shape-mismatch error, ~5 s)
            for j in range(n):
                rule.slot_h[i, j] = sh[i, j]
        rule.formation_alt[0] = formation_alt
        if any_below(rule.slot_h, rule.safety):
            return True
        for i in range(1, n):
            for j in range(n):
                if h[i, j] < rule.overlap:
                    return True
    return react_needed(rule.offset, h, rule.safety)


@jit(inline=True)
def formed_check(rule: FormedRecord, obs: Any) -> bool:
    """The layered rule's registered check (:data:`swarm_mj.pipeline.registry.RULE_CHECKS`): its step
    (:func:`formed_step`) would hand this period back, on the observation ``obs``; changes nothing a step
    reads differently (:func:`formed_busy`)."""
    if not rule.on:
        return False
    return formed_busy(rule, obs.pos, slotted(obs.sp, rule.slot_of), obs.pos[0, 2])


@jit(inline=True)
def formed_step(rule: FormedRecord, obs: Any, t: float) -> Any:
    """The layered rule's compiled step, the chunk driver's (:data:`swarm_mj.pipeline.registry.RULE_KERNELS`'
    contract: ``step(record, obs, t) -> (react, pos_d, vel_d, acc_d)``): :func:`formed_update` on the
    observation ``obs`` (:class:`~swarm_mj.pipeline.records.Obs`: its positions, slots, the leader's
    altitude as the formation's), then the steered drones' rows of vel_d, acc_d (n, 3) from the rule
    (:meth:`Rule.references <swarm_mj.formation.rules.Rule.references>` does the same merge). react True:
    Fig. 5 has work to do (the Python rule flies this period). ``rule.on`` False (a run without the
    layered rule: :func:`idle_record`): the slots and their references, untouched."""
    if not rule.on:
        return False, obs.sp, obs.spv, obs.spa
    react, pos_d = formed_update(rule, obs.pos, obs.sp, t, obs.pos[0, 2])
    if react:
        return True, obs.sp, obs.spv, obs.spa
    vel_d, acc_d = merge_rows(rule.steer, rule.vel_d, rule.acc_d, obs.spv, obs.spa)
    return False, pos_d, vel_d, acc_d


# --------------------------------------------------------------------------- pairwise helpers
@jit(samples=lambda: [(np.zeros(2), np.full((2, 2), np.inf), 0.8)])
def react_needed(offset: np.ndarray, h: np.ndarray, safety: float) -> bool:
    """Fig. 5 has work to do: a drone holds an altitude offset (n,), or two drones are closer
    than ``safety`` horizontally (h (n, n))."""
    for x in offset:
        if x != 0.0:
            return True
    for x in h.flat:
        if x < safety:
            return True
    return False


@jit(samples=lambda: [(np.full((2, 2), np.inf), 0.8)])
def any_below(h: np.ndarray, limit: float) -> bool:
    """Some pair (i, j), j < i, of the distances h (n, n) is below ``limit``."""
    for i in range(h.shape[0]):
        for j in range(i):
            if h[i, j] < limit:
                return True
    return False


@jit(samples=lambda: [(np.ones(2, dtype=np.bool_), *([np.zeros((2, 3))] * 4))])
def merge_rows(steer: np.ndarray, rule_vel: np.ndarray, rule_acc: np.ndarray, vel: np.ndarray, acc: np.ndarray):
    """Copies of vel, acc (n, 3) whose rows where steer (n,) is set come from rule_vel, rule_acc."""
    v = vel.copy()
    a = acc.copy()
    for i in range(steer.shape[0]):
        if steer[i]:
            for j in range(3):
                v[i, j] = rule_vel[i, j]
                a[i, j] = rule_acc[i, j]
    return v, a


@jit(samples=lambda: [(np.zeros((2, 3)),)])
def horizontal_distances(pos: np.ndarray) -> np.ndarray:
    """Pairwise horizontal distances (n, n) of positions (n, 3), +inf on the diagonal."""
    n = pos.shape[0]
    h = np.empty((n, n))
    for i in range(n):
        h[i, i] = np.inf
        for j in range(i + 1, n):
            dx = pos[j, 0] - pos[i, 0]
            dy = pos[j, 1] - pos[i, 1]
            d = np.sqrt(dx * dx + dy * dy)
            h[i, j] = d
            h[j, i] = d
    return h
