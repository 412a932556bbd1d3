"""The barrier filter's compiled kernels (docs/barrier.md; the mathematics: swarm_mj/formation/barrier.py):
the decentralised filter of every drone's nominal acceleration (:func:`filter_accelerations`, and
:func:`apply_filter` from :class:`~.barrier_params.BarrierParams`), the guarded nominal onto the planner's
reference or round the leader on the lanes (:func:`lane_nominal_kernel`) and the take-off gate
(:func:`takeoff_wait_kernel`)."""

from __future__ import annotations

import numpy as np

from .._jit import jit
from ..physics.params import DEFAULT_PARAMS, QuadParams
from .barrier_joint import joint_command
from .barrier_params import BarrierParams, BarrierRecord, new_record
from .barrier_qp import limit_rows, min_over_limits, project_polyhedron
from .keepout import pair_row, split_rhs


@jit(inline=True)
def _neighbour_rows(
    rec, i, pos, vel, sensed_pos, sensed_vel, sensed_acc, u_nom, filters, limits, A, b, rj, un, p, v, a
):
    """Drone i's barrier constraints (B) against each drone within ``sensing_range`` (on its reference
    state, and with ``both_states`` on its sensed one) as rows 0 .. m − 1 of A·u ≥ b (its share of each,
    :func:`filter_accelerations`), those no input within its limits can violate pruned; the keep-right
    tie-break added to its nominal ``un`` (3,) once per neighbour it pushes into; ``rj`` (≥ m,) the
    neighbour of each row. p, v, a (3,): work buffers. Returns (m, violated): the rows written, and
    whether the nominal violates one of them."""
    radii, gain, tiebreak = rec.radii, rec.gain, rec.tiebreak
    floor, priority_share, both_states = rec.floor_m, rec.priority_share, rec.both_states
    n = pos.shape[0]
    r2 = rec.sensing_range * rec.sensing_range
    m = 0
    violated = False
    for j in range(n):
        if j == i:
            continue
        turned = False
        for src in range(2 if both_states else 1):
            d2 = 0.0
            for c in range(3):
                if src == 0:  # the drone's own (reference) state
                    p[c] = pos[i, c] - sensed_pos[j, c]
                    v[c] = vel[i, c] - sensed_vel[j, c]
                else:  # its sensed (real) state
                    p[c] = sensed_pos[i, c] - sensed_pos[j, c]
                    v[c] = sensed_vel[i, c] - sensed_vel[j, c]
                d2 += p[c] * p[c]
            if d2 > r2 or (sensed_pos[i, 2] < floor and sensed_pos[j, 2] < floor):
                continue
            bs, h, hd = pair_row(p, v, radii, gain, a)
            bs = split_rhs(bs, i, j, filters, priority_share, a, sensed_acc)  # drone i's share
            lhs = a[0] * u_nom[i, 0] + a[1] * u_nom[i, 1] + a[2] * u_nom[i, 2]
            if lhs >= bs and min_over_limits(a, max(limits[i, 0], rec.reserve_a_h), limits[i, 1], limits[i, 2]) >= bs:
                continue  # no input within the limits (the reserve's) can violate it, nor does the nominal: redundant
            if lhs < bs:
                violated = True
                if tiebreak > 0.0 and not turned:  # keep right: ẑ × n̂, n̂ from j to i (horizontal)
                    turned = True
                    nh = np.sqrt(p[0] * p[0] + p[1] * p[1])
                    if nh > 1e-9:
                        un[0] += tiebreak * (-p[1] / nh)
                        un[1] += tiebreak * (p[0] / nh)
            for c in range(3):
                A[m, c] = a[c]
            b[m] = bs
            rj[m] = j
            m += 1
    return m, violated


@jit(inline=True)
def _most_asked(A, b, rj, m, lim, reserve_a_h, sh, na):
    """The neighbour whose row of A·u ≥ b (rows 0 .. m − 1, neighbours ``rj``; their horizontal columns
    divided by ``sh``, the QP's metric) asks most beyond what the drone's limits give along its normal
    ((b − max_U A·u)/‖A‖, U the limits ``lim`` (3,) widened to the reserve's horizontal ``reserve_a_h``
    if larger): where a relaxation comes from (−1 without rows). na (3,): a work buffer."""
    worst, who = -np.inf, -1
    a_h = max(lim[0], reserve_a_h)
    for k in range(m):
        na[0], na[1], na[2] = -A[k, 0] * sh, -A[k, 1] * sh, -A[k, 2]
        norm = np.sqrt(na[0] ** 2 + na[1] ** 2 + na[2] ** 2)
        excess = (b[k] + min_over_limits(na, a_h, lim[1], lim[2])) / max(norm, 1e-12)
        if excess > worst:
            worst, who = excess, rj[k]
    return who


@jit(inline=True)
def _project_command(A, b, m, ml, un, hcost_i, relax_weight, A4, b4, lim, reserve_a_h):
    """One drone's QP over its m barrier rows and ml limit rows of A·u ≥ b (its limits ``lim`` (3,) = (a_h,
    a_up, a_down)), in its metric diag(√c, √c, 1) (c = ``hcost_i``; the rows and ``un`` scaled in place):
    the projection of its nominal ``un``; where no input satisfies every row and ``reserve_a_h`` > a_h,
    the same rows with the horizontal limit ``reserve_a_h`` (the reserve, docs/barrier.md); where none
    does still, the relaxed one within the widest limits tried (A4 (m_max + 1, 4), b4: work buffers).
    Returns (w, relaxed, sh, reserve): the solution in the metric (w = (sh·u_x, sh·u_y, u_z)), whether it
    was relaxed, √c, and whether the reserve was needed."""
    sh = np.sqrt(hcost_i)  # the metric diag(sh, sh, 1): w = (sh·u_x, sh·u_y, u_z)
    if sh != 1.0:
        for k in range(m + ml):
            A[k, 0] /= sh
            A[k, 1] /= sh
        un[0] *= sh
        un[1] *= sh
    w, ok = project_polyhedron(un, A[: m + ml], b[: m + ml])
    reserve = False
    if not ok and reserve_a_h > lim[0]:  # the reserve: the same rows within the wider tilt
        limit_rows(A[m:], b[m:], reserve_a_h, lim[1], lim[2])
        for k in range(m, m + ml):
            A[k, 0] /= sh
            A[k, 1] /= sh
        w, ok = project_polyhedron(un, A[: m + ml], b[: m + ml])
        reserve = True
    relaxed = False
    if not ok:
        # relaxation: A·u + ‖A‖·δ ≥ b, δ ≥ 0, cost ‖u − un‖² + w·δ², in w = (u, √w·δ); the rows
        # are those just tried (in the drone's metric), the limits' (after row m) without δ
        sw = np.sqrt(relax_weight)
        for k in range(m + ml):
            for c in range(3):
                A4[k, c] = A[k, c]
            A4[k, 3] = np.sqrt(A[k, 0] ** 2 + A[k, 1] ** 2 + A[k, 2] ** 2) / sw if k < m else 0.0
            b4[k] = b[k]
        A4[m + ml, :] = 0.0
        A4[m + ml, 3] = 1.0
        b4[m + ml] = 0.0
        w0 = np.zeros(4)
        for c in range(3):
            w0[c] = un[c]
        w4, ok4 = project_polyhedron(w0, A4[: m + ml + 1], b4[: m + ml + 1])
        relaxed = True
        for c in range(3):
            w[c] = w4[c]
    return w, relaxed, sh, reserve


@jit(inline=True)
def _clusters(rec, boxed, filters, sensed_pos):
    """The clusters of the joint fallback (swarm_mj/formation/barrier_joint.py): the connected sets of the
    graph joining each boxed drone (``boxed`` (n,): its split has no input within its limits) to every
    filtering drone within its sensing range (sensed positions). Returns (cluster (n,) int, −1 for
    none; the number of clusters)."""
    n = sensed_pos.shape[0]
    r2 = rec.sensing_range * rec.sensing_range
    comp = np.full(n, -1, dtype=np.int64)
    stack = np.empty(n, dtype=np.int64)
    count = 0
    for k0 in range(n):
        if not boxed[k0] or comp[k0] >= 0:
            continue
        comp[k0] = count
        stack[0] = k0
        top = 1
        while top > 0:
            top -= 1
            x = stack[top]
            for l2 in range(n):
                if filters[l2] and comp[l2] < 0 and (boxed[x] or boxed[l2]) and _dist2(sensed_pos, x, l2) <= r2:
                    comp[l2] = count
                    stack[top] = l2
                    top += 1
        count += 1
    return comp, count


@jit(inline=True)
def _dist2(x, k, l2):
    return (x[k, 0] - x[l2, 0]) ** 2 + (x[k, 1] - x[l2, 1]) ** 2 + (x[k, 2] - x[l2, 2]) ** 2


def _filter_samples():
    z = np.zeros((2, 3))
    pos = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 1.0]])
    rec = new_record(BarrierParams(), DEFAULT_PARAMS, 2, True)
    lim = np.tile([3.9, 5.0, 3.0], (2, 1))
    return [(rec, pos, z, pos, z, z, z, np.ones(2, dtype=np.bool_), lim, np.ones(2))]


@jit(on_demand=True, samples=_filter_samples)
def filter_accelerations(
    rec: BarrierRecord,
    pos: np.ndarray,
    vel: np.ndarray,
    sensed_pos: np.ndarray,
    sensed_vel: np.ndarray,
    sensed_acc: np.ndarray,
    u_nom: np.ndarray,
    filters: np.ndarray,
    limits: np.ndarray,
    hcost: np.ndarray,
):
    """The decentralised barrier filter (swarm_mj/formation/barrier.py's docstring, "Filter"), for n drones at once.

    rec: the filter's record (:class:`BarrierRecord`), of which it reads the parameters only:
    ``radii`` (the filter's keep-out), ``gain`` (k), ``tiebreak``, ``relax_weight``,
    ``sensing_range``, ``floor_m``, ``priority_share``, ``both_states``, ``reserve_a_h``, ``own_row`` (≥ 0: only that
    drone's QP is solved, the others keep u_nom, unflagged; row i reads its own pos, vel, u_nom,
    limits and hcost, and of the others their sensed state and ``filters`` only, never their
    filtered commands, so that row is the same bit for bit).
    pos, vel (n, 3): each drone's own (reference) state; sensed_pos, sensed_vel, sensed_acc (n, 3):
    what the others sense of it (the acceleration only enters the constraint against a drone that
    does not filter, A·u_i ≥ b + A·a_j, as it does not give way); u_nom (n, 3) nominal
    accelerations; filters (n,) bool: which drones filter (a drone that does not keeps u_nom and its
    neighbours take all of each pair's constraint); limits (n, 3): each drone's input limits
    (a_h, a_up, a_down) (m/s²); hcost (n,) ≥ 1: each drone's cost of a horizontal change of its
    command relative to a vertical one, the QP's metric ‖diag(√c, √c, 1)·(u − u_nom)‖² (1: the
    plain projection; docs/barrier.md, "the descent's metric").
    ``priority_share``: the share of a burden (b > 0) the lower index of a pair of filtering drones
    takes (½: equal; room, b ≤ 0, is split in halves). A pair whose two drones are both below
    ``floor_m`` (on the ground, sensed_pos) is not filtered. ``both_states``: each neighbour's
    constraint is also imposed on the drone's sensed state (sensed_pos[i], sensed_vel[i]), so that a
    drone that lags its reference is kept out too (docs/barrier.md, "tracking").
    Returns u (n, 3), active (n,) (a barrier constraint changed the command), relaxed (n,) (the
    constraints were infeasible within the limits, the reserve's included, and relaxed), n_constraints
    (n,) (the neighbour constraints kept after the exact pruning), reserve (n,) (infeasible within the
    limits, the horizontal one widened to ``reserve_a_h``: the reserve, docs/barrier.md), against (n,)
    int (a relaxed drone's neighbour whose row asked most beyond its limits, :func:`_most_asked`; −1
    where not relaxed), joint (n,) (its command is its cluster's joint QP's, :func:`_joint_fallback`:
    with ``joint_fallback``, where some drone's split had no input within its limits, and only where
    every row is computed, ``own_row`` −1)."""
    n = pos.shape[0]
    u = u_nom.copy()
    active = np.zeros(n, dtype=np.bool_)
    relaxed = np.zeros(n, dtype=np.bool_)
    reserve = np.zeros(n, dtype=np.bool_)
    against = np.full(n, -1, dtype=np.int64)
    joint = np.zeros(n, dtype=np.bool_)
    kept = np.zeros(n, dtype=np.int64)
    m_max = 2 * n + 10
    A = np.zeros((m_max, 3))
    b = np.zeros(m_max)
    rj = np.zeros(m_max, dtype=np.int64)
    A4 = np.zeros((m_max + 1, 4))
    b4 = np.zeros(m_max + 1)
    p = np.empty(3)
    v = np.empty(3)
    a = np.empty(3)
    un = np.empty(3)
    only = rec.own_row
    boxed = np.zeros(n, dtype=np.bool_)
    for i in range(n):
        if not filters[i] or (only >= 0 and i != only):
            continue
        for c in range(3):
            un[c] = u_nom[i, c]
        m, violated = _neighbour_rows(
            rec, i, pos, vel, sensed_pos, sensed_vel, sensed_acc, u_nom, filters, limits, A, b, rj, un, p, v, a
        )
        kept[i] = m
        if violated:  # else the nominal satisfies every barrier constraint: unchanged
            active[i] = True
            ml = limit_rows(A[m:], b[m:], limits[i, 0], limits[i, 1], limits[i, 2])
            w, relaxed_i, sh, reserve[i] = _project_command(
                A, b, m, ml, un, hcost[i], rec.relax_weight, A4, b4, limits[i], rec.reserve_a_h
            )
            relaxed[i] = relaxed_i
            boxed[i] = relaxed_i or reserve[i]
            if relaxed_i:  # the neighbour that asked most (the rows as the metric scaled them)
                against[i] = _most_asked(A, b, rj, m, limits[i], rec.reserve_a_h, sh, p)
            u[i, 0] = w[0] / sh
            u[i, 1] = w[1] / sh
            u[i, 2] = w[2]
    if rec.joint_fallback and only < 0 and boxed.any():
        _joint_fallback(rec, pos, vel, sensed_pos, sensed_vel, sensed_acc, u_nom, filters, limits, hcost, boxed,
                        u, active, relaxed, reserve, against, joint)  # fmt: skip
    return u, active, relaxed, kept, reserve, against, joint


@jit(inline=True)
def _joint_fallback(rec, pos, vel, sensed_pos, sensed_vel, sensed_acc, u_nom, filters, limits, hcost, boxed,
                    u, active, relaxed, reserve, against, joint):  # fmt: skip
    """Each cluster round a boxed drone (:func:`_clusters`) flies its joint QP's solution
    (swarm_mj/formation/barrier_joint.py) in place of its members' split ones (u, active, relaxed,
    reserve, against, joint (n, ...) updated; a cluster whose QP has no solution keeps the split's)."""
    comp, count = _clusters(rec, boxed, filters, sensed_pos)
    for c_i in range(count):
        member = comp == c_i
        uc, ok, res = joint_command(rec, pos, vel, sensed_pos, sensed_vel, sensed_acc, u_nom, filters, limits,
                                    hcost, member)  # fmt: skip
        if not ok:
            continue  # nothing meets the cluster's rows either: the split's commands, relaxed where they were
        for k in range(comp.shape[0]):
            if member[k]:
                u[k] = uc[k]
                joint[k] = True
                active[k] = True
                relaxed[k] = False
                reserve[k] = res
                against[k] = -1


def apply_filter(
    bp: BarrierParams,
    pos: np.ndarray,
    vel: np.ndarray,
    u_nom: np.ndarray,
    filters: np.ndarray,
    sensed: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
    vehicle: QuadParams = DEFAULT_PARAMS,
    limits: np.ndarray | None = None,
    hcost: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`filter_accelerations` with the parameters of ``bp`` (the separation step's entry point).

    pos, vel, u_nom (n, 3); filters (n,) bool; sensed: (positions, velocities, accelerations) (n, 3)
    the others sense (default: pos, vel and zero); limits (n, 3): each drone's (a_h, a_up, a_down)
    (default: ``bp``'s for every drone); hcost (n,): each drone's cost of a horizontal change
    (default 1: the plain projection). Returns (u, active, relaxed, n_constraints, reserve, against, joint)."""
    c = np.ascontiguousarray
    sp, sv, sa = (pos, vel, np.zeros_like(pos)) if sensed is None else sensed
    n = pos.shape[0]
    if limits is None:
        limits = np.tile([bp.horizontal_limit(vehicle.g), bp.accel_up, bp.accel_down], (n, 1))
    f8 = np.float64
    return filter_accelerations(
        new_record(bp, vehicle, n, True),  # the filter reads its parameters only
        *(c(x, dtype=f8) for x in (pos, vel, sp, sv, sa, u_nom)),
        c(filters, dtype=np.bool_),
        c(limits, dtype=f8),
        np.ones(n) if hcost is None else c(hcost, dtype=f8),
    )


@jit
def lane_nominal_kernel(
    ref: np.ndarray,
    ref_vel: np.ndarray,
    leader: np.ndarray,
    pos_d: np.ndarray,
    vel_d: np.ndarray,
    acc_d: np.ndarray,
    radius: float,
    gains: np.ndarray,
    lanes: bool,
    rows: np.ndarray,
    u: np.ndarray,
) -> None:
    """The guarded nominal accelerations of the drones flagged ``rows`` (n,) into ``u`` (n, 3) (other
    rows untouched): the PD onto the reference, acc_d + k_p·(pos_d − r) + k_d·(vel_d − ṙ), and, with
    ``lanes``, a two-lane roundabout round the leader (docs/barrier.md, ``guard_lanes``).

    In the leader's frame (horizontal), a follower whose reference is more than ``arrive_angle``
    round the leader from it flies round on a lane, the shorter way: counter-clockwise on the ring
    of radius D_k + ``lane_inner``·``radius`` (D_k the reference's distance from the leader),
    clockwise on D_k + ``lane_outer``·``radius`` (``radius`` the keep-out's horizontal radius: the
    formed ring and the two lanes are a keep-out apart, so traffic in opposite directions does not
    meet head-on), at ``lane_speed`` (at most ``lane_turn_gain``·r·|angle left|, so that it stops on
    its slot's ray), pulled onto its lane radially at k_p/k_d; the others fly the PD, radially in
    from the lane (the formed ring is not crossed). The vertical is the PD in both. Row 0 (the
    leader) never goes round on a lane. ``gains`` (7,): k_p, k_d, lane_speed, arrive_angle,
    lane_turn_gain, lane_inner, lane_outer (:func:`~.barrier_params.guard_gains`)."""
    kp, kd, speed, arrive, turn, inner, outer = gains[0], gains[1], gains[2], gains[3], gains[4], gains[5], gains[6]
    for i in range(ref.shape[0]):
        if not rows[i]:
            continue
        for c in range(3):  # straight to the slot
            u[i, c] = acc_d[i, c] + kp * (pos_d[i, c] - ref[i, c]) + kd * (vel_d[i, c] - ref_vel[i, c])
        if not lanes or i == 0:
            continue
        ox, oy = ref[i, 0] - leader[0], ref[i, 1] - leader[1]  # offset from the leader
        kx, ky = pos_d[i, 0] - leader[0], pos_d[i, 1] - leader[1]  # the slot's
        gap = (np.arctan2(ky, kx) - np.arctan2(oy, ox) + np.pi) % (2.0 * np.pi) - np.pi  # the shorter way, rad
        if abs(gap) <= arrive:
            continue
        r = max(np.sqrt(ox * ox + oy * oy), 1e-9)
        rx, ry = ox / r, oy / r  # radial
        sgn = 1.0 if gap > 0.0 else -1.0
        tx, ty = -ry * sgn, rx * sgn  # the way to go
        lane = np.sqrt(kx * kx + ky * ky) + (inner if gap > 0.0 else outer) * radius
        v_t = min(speed, turn * r * abs(gap))  # slowing onto the slot's ray
        pull = (kp / kd) * (lane - r)
        u[i, 0] = acc_d[i, 0] + kd * (vel_d[i, 0] + v_t * tx + pull * rx - ref_vel[i, 0])
        u[i, 1] = acc_d[i, 1] + kd * (vel_d[i, 1] + v_t * ty + pull * ry - ref_vel[i, 1])


@jit
def takeoff_wait_kernel(
    positions: np.ndarray,
    radii: np.ndarray,
    filters: np.ndarray,
    velocities: np.ndarray,
    accelerations: np.ndarray,
    predict: bool,
    floor: float,
    gate_rho: float,
    gate_rho_ground: float,
    horizon: float,
    wait: np.ndarray,
    leader_goal: np.ndarray,
    use_goal: bool,
    held: np.ndarray,
) -> None:
    """The take-off gate (swarm_mj/formation/barrier.py's docstring), into ``wait`` (n,) bool: a filtering
    drone on the ground (below ``floor``) whose ρ (``radii`` (3,)) to an airborne drone is below ``gate_rho``, or
    to a grounded drone of lower index below ``gate_rho_ground``, holds where it is (and does not filter this
    period). With ``predict``: also when that airborne drone is predicted within ``gate_rho`` (at its
    ``velocities`` and ``accelerations`` (n, 3), sampled every 0.25 s over ``horizon`` s; a grounded one
    is taken where it stands). ``use_goal``: also inside the keep-out of the leader's way, the segment from drone 0
    to its reference ``leader_goal`` (3,). ``held`` (n,) bool: the drones the gate held at the last
    period, which it holds on while the condition holds, even risen above ``floor`` (lifted by the
    ground effect or a mispredicted downwash while held: it is still the gate's)."""
    n = positions.shape[0]
    for i in range(n):
        wait[i] = False
        if not filters[i] or (positions[i, 2] >= floor and not held[i]):
            continue
        for j in range(n):
            if j == i or not (j < i or positions[j, 2] >= floor):
                continue
            rho2 = 0.0
            for c in range(3):
                q = (positions[i, c] - positions[j, c]) / radii[c]
                rho2 += q * q
            k = 1
            while predict and positions[j, 2] >= floor and 0.25 * k < horizon + 1e-9:
                tau = 0.25 * k  # every 0.25 s over the horizon, the other drone straight on
                d2 = 0.0
                for c in range(3):
                    ahead = positions[j, c] + (tau * velocities[j, c] + 0.5 * tau * tau * accelerations[j, c])
                    q = (positions[i, c] - ahead) / radii[c]
                    d2 += q * q
                rho2 = min(rho2, d2)
                k += 1
            if use_goal and j == 0:  # the leader's way to its reference, sampled every tenth
                w2 = 1e9
                for k in range(1, 11):
                    d2 = 0.0
                    for c in range(3):
                        on = positions[0, c] + 0.1 * k * (leader_goal[c] - positions[0, c])
                        q = (positions[i, c] - on) / radii[c]
                        d2 += q * q
                    w2 = min(w2, d2)
                if np.sqrt(w2) < 1.0:
                    wait[i] = True
                    break
            if np.sqrt(rho2) < (gate_rho if positions[j, 2] >= floor else gate_rho_ground):
                wait[i] = True
                break
