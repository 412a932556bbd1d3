"""The anti-collision's compiled kernels: the layered rule's limited paths
(:class:`~swarm_mj.formation.planner.LayeredRule`) and the pairwise helpers of the separation
step and of the fused loop (:func:`horizontal_distances`, :func:`react_needed`, :func:`any_below`,
:func:`merge_rows`).

Each follower the rule steers flies a horizontal path (p, v, a (n, 2)) and an altitude path
(zp, zv, za (n,)) whose position, velocity and acceleration go to the controller; the paths
are limited in speed, acceleration (and tilt) and jerk. Ours, not the paper's (see the rule's
docstring and docs/interpretations.md §4).
"""

from __future__ import annotations

import numpy as np

from .._jit import jit

# Fixed in the kernels (compile-time constants: the kernels' signatures, which the fused loop
# calls, do not carry them; docs/anticollision.md, "fixed in the kernels"). Not scenario keys.
#: Share of its acceleration limit a path plans to brake with (v = √(2·BRAKING_SHARE·a·e)): 20 %
#: left for the lag of the acceleration turning round.
BRAKING_SHARE = 0.8
#: Gain (1/s) of a horizontal path's final approach: speed ≤ this · distance to the goal.
PATH_APPROACH_GAIN = 3.0
#: Gain (1/s) of an altitude path's final approach: speed ≤ this · distance to the target.
ALTITUDE_APPROACH_GAIN = 4.0
#: Least vertical specific force (m/s²) the tilt limit of a horizontal path is taken from:
#: a ≤ max(g + z̈, this)·tan(max tilt), so that a path braking a descent still steers.
THRUST_FLOOR = 1.0


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
            np.array([6.0, 120.0, 15.0, 4.0, 0.5, 9.81, 4.0, 8.0, 1.5, 5.0]),
            z3.copy(),
            z3.copy(),
            z3.copy(),
        )
    ]


def _paths_samples():
    n = 2
    z1, z2 = np.zeros(n), np.zeros((n, 2))
    return [
        (
            0.01,
            z2,
            z2.copy(),
            z2.copy(),
            z2.copy(),
            z2.copy(),
            np.zeros(n, dtype=np.bool_),
            z1,
            6.0,
            120.0,
            15.0,
            4.0,
            0.5,
            9.81,
        )
    ]


def _altitude_samples():
    z1 = np.zeros(2)
    return [(0.01, z1, z1.copy(), z1.copy(), z1.copy(), z1.copy(), 4.0, 8.0, 1.5, 5.0, 120.0, 15.0)]


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
    a_max: float,
    jerk: float,
    k_v: float,
    v_max: float,
    tan_tilt: float,
    g: float,
) -> None:
    """One step of the layered rule's horizontal paths (see LayeredRule._advance_paths), in place:
    p, v, a (n, 2) move towards goal (n, 2) moving at goal_vel (n, 2).

    Invariant: |a| ≤ min(a_max, max(g + za, THRUST_FLOOR)·tan_tilt), |Δa| ≤ jerk·dt per step, and
    the speed asked relative to the goal is ≤ v_max and ≤ √(2·BRAKING_SHARE·a_max·e_eff), e_eff
    the distance left after the lag 2·a_max/jerk + 1/k_v: a path stops at the goal without
    overshooting as long as the goal moves no faster than v_max. A blocked drone is asked for
    zero velocity (it brakes to rest at a_max)."""
    n = p.shape[0]
    lag = 2.0 * a_max / jerk + 1.0 / k_v
    for i in range(n):
        ex = goal[i, 0] - p[i, 0]
        ey = goal[i, 1] - p[i, 1]
        dist = np.sqrt(ex * ex + ey * ey)
        rx = v[i, 0] - goal_vel[i, 0]
        ry = v[i, 1] - goal_vel[i, 1]
        e_eff = max(dist - np.sqrt(rx * rx + ry * ry) * lag, 0.0)
        speed = min(min(v_max, np.sqrt(2.0 * BRAKING_SHARE * a_max * e_eff)), PATH_APPROACH_GAIN * dist)
        k = speed / max(dist, 1e-9)
        vx = goal_vel[i, 0] + ex * k
        vy = goal_vel[i, 1] + ey * k
        s = min(1.0, v_max / max(np.sqrt(vx * vx + vy * vy), 1e-9))
        vx *= s
        vy *= s
        if blocked[i]:
            vx = 0.0
            vy = 0.0
        a_lim = min(a_max, max(g + za[i], THRUST_FLOOR) * tan_tilt)
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
    vu: float,
    au: float,
    vd: float,
    ad: float,
    jerk: float,
    k_v: float,
) -> None:
    """One step of the layered rule's altitude paths (see LayeredRule._advance_altitude), in place:
    zp, zv, za (n,) towards target (n,) moving at target_vel (n,).

    Invariant: −ad ≤ za ≤ au (less thrust is limited to ``ad``: eq. (18)'s U1 stays off its floor),
    |Δza| ≤ jerk·dt, −vd ≤ zv asked ≤ vu, and the speed asked towards the target is ≤
    √(2·BRAKING_SHARE·a·e_eff) with a the acceleration that will brake it: no overshoot of a
    still target."""
    n = zp.shape[0]
    lag = (au + ad) / jerk + 1.0 / k_v
    for i in range(n):
        e = target[i] - zp[i]
        up = e >= 0.0
        e_eff = max(abs(e) - abs(zv[i]) * lag, 0.0)
        v_stop = np.sqrt(2.0 * BRAKING_SHARE * ad * e_eff) if up else np.sqrt(2.0 * BRAKING_SHARE * au * e_eff)
        speed = min(min(vu if up else vd, v_stop), ALTITUDE_APPROACH_GAIN * abs(e))
        sgn = 1.0 if e > 0.0 else (-1.0 if e < 0.0 else 0.0)
        v_des = min(max(target_vel[i] + sgn * speed, -vd), vu)
        a_des = min(max(k_v * (v_des - zv[i]), -ad), au)
        za[i] += min(max(a_des - za[i], -jerk * dt), jerk * dt)
        zv[i] += za[i] * dt
        zp[i] += zv[i] * dt


#: The order of :func:`formed_step_kernel`'s ``limits``: the horizontal paths' acceleration limit,
#: jerk, velocity gain, speed limit, tan(max tilt), g, then the altitude paths' climb speed and
#: acceleration, descent speed and acceleration (the rule's fields of the same names).
FORMED_LIMITS = ("a_max", "jerk", "k_v", "v_max", "tan_tilt", "g", "vu", "au", "vd", "ad")


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
    limits: np.ndarray,
    out_pos: np.ndarray,
    out_vel: np.ndarray,
    out_acc: np.ndarray,
) -> None:
    """The layered rule once every follower is formed (LayeredRule._update_formed), after the
    reactive rule has set the altitude offsets (n,): the horizontal paths p, v, a (n, 2) follow
    the slots pos_d[:, :2] moving at the leader's velocity lead_vel (3,), the altitude paths
    zp, zv, za (n,) follow formation_alt + offset; writes the followers' references into
    out_pos (from pos_d), out_vel, out_acc (n, 3) (the leader's row: pos_d, zero, zero).
    ``limits`` (10,): a_max, jerk, k_v, v_max, tan_tilt, g, vu, au, vd, ad (:data:`FORMED_LIMITS`)."""
    a_max, jerk, k_v, v_max, tan_tilt, g = limits[0], limits[1], limits[2], limits[3], limits[4], limits[5]
    vu, au, vd, ad = limits[6], limits[7], limits[8], limits[9]
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
        advance_paths_kernel(dt, goal, goal_vel, p, v, a, blocked, za, a_max, jerk, k_v, v_max, tan_tilt, g)
        advance_altitude_kernel(dt, z_target, z_target_vel, zp, zv, za, vu, au, vd, ad, jerk, k_v)
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
