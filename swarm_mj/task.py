"""The swarm's task: observation, reward and termination, written once over a copies axis (docs/design.md,
"The environment: one task over copies").

As dm_control's ``Task`` stands apart from its ``Physics``, this module holds what an episode
*means*, apart from the physics side that flies it (:class:`swarm_mj.pipeline.swarm.SwarmPhysics`: the
simulator's copies, their wind, starts and contacts). Both environments call it:
:class:`swarm_mj.env.SwarmEnv` is its one-copy case (m = 1) and
:class:`swarm_mj.wrappers.vector.SwarmVectorEnv` its m-copy case (m swarms of n drones):

===============  ============================================================================
part             function
===============  ============================================================================
observation      :func:`swarm_mj.pipeline.period.observe` (the chunk driver's stage);
                 :func:`observe_copies` runs it per copy (each copy's own references, wind
                 and leader estimate) into a flat (m, dim) buffer; the keys:
                 :func:`observation_shapes`
reward           :func:`copy_reward` (formation keeping: :func:`formation_reward`)
termination      :func:`copy_outcome` (contact, divergence, the scenario's duration);
                 :func:`outcomes` over copies
===============  ============================================================================

Reward, per step and copy: ``−mean_i ‖p_i − slot_i‖ − PAIR_PENALTY·(pairs closer than CLOSE_PASS_M)
− CONTACT_PENALTY·(new contacts)`` (one drone: ``−‖p_0 − setpoint_0‖``), and ``DIVERGED_REWARD`` on
a step that diverged.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from dm_env import specs

from ._jit import jit
from .pipeline.period import observe
from .pipeline.records import Refs

#: Pairs closer than this (m, 3D) count against the reward.
CLOSE_PASS_M = 0.5
#: The reward's cost of one pair closer than CLOSE_PASS_M, of one new drone–drone contact, and the
#: reward of a step that diverged (docs/design.md, "The environment: one task over copies").
PAIR_PENALTY = 10.0
CONTACT_PENALTY = 100.0
DIVERGED_REWARD = -1000.0


class CopyRefs(NamedTuple):
    """The references every copy shares (the leader trajectory and D(t) at each control instant)."""

    T: float  # control period (s)
    sensing_range: float  # m
    pos: np.ndarray  # (K+1, 3) leader trajectory
    vel: np.ndarray  # (K+1, 3)
    acc: np.ndarray  # (K+1, 3)
    yaw: np.ndarray  # (K+1,)
    D: np.ndarray  # (K+1,) formation diameter
    unit_offsets: np.ndarray  # (n−1, 3) slot offsets for D = 1
    wind_known: bool  # the controller is given the wind force (the observation's ``wind_force``)
    relative: bool  # the wind acts on the relative airspeed (each drone's own force, computed in Python)


class CopyState(NamedTuple):
    """One copy's drones as :func:`~swarm_mj.pipeline.period.observe` reads them (the fields of
    :class:`~swarm_mj.pipeline.records.Physics` it uses)."""

    qpos: np.ndarray  # (n, 7)
    qvel: np.ndarray  # (n, 6)
    T: float  # control period (s)


def observation_shapes(n: int) -> dict[str, tuple[int, ...]]:
    """The observation of n drones: key -> shape (SwarmEnv's table, swarm_mj/env.py), in the order
    :func:`observe_copies` knows the keys (:data:`OBS_KEYS`)."""
    return {
        "time": (),
        "pos": (n, 3),
        "vel": (n, 3),
        "quat": (n, 4),
        "rpy": (n, 3),
        "rpy_rate": (n, 3),
        "body_rates": (n, 3),
        "setpoint": (n, 3),
        "setpoint_vel": (n, 3),
        "setpoint_acc": (n, 3),
        "setpoint_yaw": (n,),
        "leader_pos": (3,),
        "neighbours": (n, n, 3),
        "neighbour_mask": (n, n),
        "wind_force": (n, 3),
    }


#: The observation keys in the order :func:`observe_copies` knows them (its offs[i] is key i's offset).
OBS_KEYS = tuple(observation_shapes(1))


def view_shapes(n: int) -> dict[str, tuple[int, ...]]:
    """The keys a sensing stage adds to the observation of n drones (:func:`swarm_mj.sensing.stage.view_keys`;
    row i: what drone i believes): key -> shape. The stage also replaces ``neighbours`` and ``neighbour_mask``
    by the view's (the same shapes)."""
    return {
        "view_pos": (n, n, 3),
        "view_vel": (n, n, 3),
        "view_mask": (n, n),
        "view_age": (n, n),
        "view_setpoint": (n, n, 3),
        "view_setpoint_vel": (n, n, 3),
        "own_pos": (n, 3),
        "own_vel": (n, 3),
    }


#: The bounds of the observation keys that have them (the others are unbounded): a view's mask is 0/1, the age
#: of what a drone holds is ≥ 0 s, and inf where it holds nothing.
VIEW_BOUNDS = {"view_mask": (0.0, 1.0), "view_age": (0.0, np.inf)}


def observation_specs(n: int, sensing: bool = False) -> dict[str, specs.Array]:
    """The observation of n drones as dm_env specs, float64 (``SwarmEnv.observation_spec``): the keys of
    :func:`observation_shapes`, and with a sensing stage (``sensing``) those of :func:`view_shapes`,
    ``view_mask`` and ``view_age`` bounded (:data:`VIEW_BOUNDS`)."""
    out: dict[str, specs.Array] = {
        key: specs.Array(shape, np.float64, key) for key, shape in observation_shapes(n).items()
    }
    if sensing:
        for key, shape in view_shapes(n).items():
            if key in VIEW_BOUNDS:
                low, high = VIEW_BOUNDS[key]
                out[key] = specs.BoundedArray(shape, np.float64, low, high, key)
            else:
                out[key] = specs.Array(shape, np.float64, key)
    return out


def _reward_samples():
    d = np.full((2, 2), np.inf)
    return [(np.zeros((2, 3)), np.zeros((2, 3)), d, 0.5)]


@jit(samples=_reward_samples)
def formation_reward(pos: np.ndarray, setpoint: np.ndarray, dist: np.ndarray, close: float) -> tuple[float, int]:
    """Mean follower distance to its slot and the number of pairs closer than ``close`` (3D)."""
    n = pos.shape[0]
    err = 0.0
    for i in range(1, n):
        dx = pos[i, 0] - setpoint[i, 0]
        dy = pos[i, 1] - setpoint[i, 1]
        dz = pos[i, 2] - setpoint[i, 2]
        err += np.sqrt(dx * dx + dy * dy + dz * dz)
    pairs = 0
    for i in range(n):
        for j in range(i + 1, n):
            if dist[i, j] < close:
                pairs += 1
    return err / max(n - 1, 1), pairs


@jit(inline=True, samples=lambda: [(np.zeros((2, 3)), np.zeros((2, 3)), np.full((2, 2), np.inf), 0)])
def copy_reward(pos: np.ndarray, setpoint: np.ndarray, dist: np.ndarray, new_contacts: int) -> float:
    """One copy's reward (module docstring) from its positions and setpoints (n, 3), its 3D distances
    (n, n) and the contacts new this step."""
    if pos.shape[0] == 1:
        dx = pos[0, 0] - setpoint[0, 0]
        dy = pos[0, 1] - setpoint[0, 1]
        dz = pos[0, 2] - setpoint[0, 2]
        return -np.sqrt(dx * dx + dy * dy + dz * dz)
    err, close = formation_reward(pos, setpoint, dist, CLOSE_PASS_M)
    return -err - PAIR_PENALTY * close - CONTACT_PENALTY * new_contacts


@jit(inline=True)
def min_separation(dist: np.ndarray) -> float:
    """The smallest distance between two drones of a copy (its (n, n) distances; +inf for one drone)."""
    n = dist.shape[0]
    best = np.inf
    for i in range(n):
        for j in range(i + 1, n):
            best = min(best, dist[i, j])
    return best


@jit(samples=lambda: [(0.0, False, 0, 0, 1, True)])
def copy_outcome(
    reward: float, diverged: bool, new_contacts: int, k: int, n_steps: int, terminate_on_contact: bool
) -> tuple[float, bool, bool]:
    """(reward, terminated, truncated) of one copy after its period k: terminated on divergence (the
    reward then ``DIVERGED_REWARD``) or, with ``terminate_on_contact``, on a new drone–drone contact;
    else truncated at the scenario's duration (k ≥ n_steps)."""
    terminated = diverged or (terminate_on_contact and new_contacts > 0)
    truncated = not terminated and k >= n_steps
    return (DIVERGED_REWARD if diverged else reward), terminated, truncated


def _outcomes_samples():
    m = 2
    return [(np.zeros(m), np.zeros(m, np.bool_), np.zeros(m, np.int64), np.zeros(m, np.int64), 1, True)]


@jit(samples=_outcomes_samples)
def outcomes(
    reward: np.ndarray,
    diverged: np.ndarray,
    new_contacts: np.ndarray,
    k: np.ndarray,
    n_steps: int,
    terminate_on_contact: bool,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`copy_outcome` of every copy: fresh (reward, terminated, truncated) arrays (m,) from
    reward (m,), diverged (m,) bool, new_contacts (m,) and k (m,)."""
    m = reward.shape[0]
    r = np.empty(m)
    terminated = np.empty(m, np.bool_)
    truncated = np.empty(m, np.bool_)
    for c in range(m):
        r[c], terminated[c], truncated[c] = copy_outcome(
            reward[c], diverged[c], new_contacts[c], k[c], n_steps, terminate_on_contact
        )
    return r, terminated, truncated


def _observe_samples():
    n, m, K = 2, 2, 3
    qpos = np.zeros((m * n, 7))
    qpos[:, 3] = 1.0
    sizes = [int(np.prod(shape, dtype=np.int64)) for shape in observation_shapes(n).values()]
    offs = np.cumsum([0, *sizes[:-1]]).astype(np.int64)  # OBS_KEYS order
    z = np.zeros((K, 3))
    return [
        (
            qpos,
            np.zeros((m * n, 6)),
            n,
            CopyRefs(
                T=0.01,
                sensing_range=2.0,
                pos=z,
                vel=z,
                acc=z,
                yaw=np.zeros(K),
                D=np.ones(K),
                unit_offsets=np.zeros((n - 1, 3)),
                wind_known=True,
                relative=False,
            ),
            np.arange(m, dtype=np.int64),
            0,
            np.zeros(m, np.int64),
            np.zeros((m, 3)),
            np.zeros((m, 3)),
            np.zeros((m, K, 3)),
            np.zeros((m, n, 3)),
            offs,
            np.zeros((m, sum(sizes))),
            np.zeros(m, np.int64),
            np.zeros(m),
            np.zeros(m),
        )
    ]


@jit(on_demand=True, samples=_observe_samples)
def observe_copies(
    qpos: np.ndarray,
    qvel: np.ndarray,
    n: int,
    refs: CopyRefs,
    copies: np.ndarray,
    c0: int,
    ks: np.ndarray,
    prev_leader: np.ndarray,
    leader_vel: np.ndarray,
    wind: np.ndarray,
    wind_obs: np.ndarray,
    offs: np.ndarray,
    out: np.ndarray,
    new_contacts: np.ndarray,
    reward: np.ndarray,
    min_sep: np.ndarray,
) -> None:
    """The task over the given copies (global indices; copy c's drones are rows (c − c0)·n .. of this
    block's qpos (b·n, 7), qvel (b·n, 6)), each at its own sample ks[c] of ``refs``: its observation
    (:func:`~swarm_mj.pipeline.period.observe`, SwarmEnv's, on the copy's references: its wind force series
    wind[c] (m, K+1, 3), its leader estimate prev_leader[c], leader_vel[c] (m, 3) updated in place; with
    ``refs.relative`` its known wind force is wind_obs[c] (m, n, 3)) into out[c] (m, dim), key i of
    :data:`OBS_KEYS` at offs[i]; its :func:`copy_reward` (new_contacts[c]) into reward[c];
    its :func:`min_separation` into min_sep[c]. A copy with a non-finite state is skipped (its last
    observation stays)."""
    for idx in range(copies.shape[0]):
        c = copies[idx]
        r0 = (c - c0) * n
        q = qpos[r0 : r0 + n]
        v = qvel[r0 : r0 + n]
        finite = True
        for i in range(n):
            for j in range(7):
                if not np.isfinite(q[i, j]):
                    finite = False
            for j in range(6):
                if not np.isfinite(v[i, j]):
                    finite = False
        if not finite:
            continue
        k = ks[c]
        # the copy's references (its wind speed unread)
        r = Refs(
            pos=refs.pos,
            vel=refs.vel,
            acc=refs.acc,
            yaw=refs.yaw,
            D=refs.D,
            unit_offsets=refs.unit_offsets,
            prev_leader=prev_leader[c],
            leader_vel=leader_vel[c],
            sensing_range=refs.sensing_range,
            wind_force=wind[c],
            wind_speed=wind[c],
            wind_known=refs.wind_known,
        )
        pos, vel, quat, omega, rpy, rpy_rate, rel, mask, dist, sp, spv, spa, yaw, wf = observe(
            CopyState(q, v, refs.T), r, k
        )
        if refs.relative and refs.wind_known:
            wf = wind_obs[c]
        o = out[c]
        o[offs[0]] = k * refs.T
        for i in range(n):
            for j in range(3):
                o[offs[1] + 3 * i + j] = pos[i, j]
                o[offs[2] + 3 * i + j] = vel[i, j]
                o[offs[4] + 3 * i + j] = rpy[i, j]
                o[offs[5] + 3 * i + j] = rpy_rate[i, j]
                o[offs[6] + 3 * i + j] = omega[i, j]
                o[offs[7] + 3 * i + j] = sp[i, j]
                o[offs[8] + 3 * i + j] = spv[i, j]
                o[offs[9] + 3 * i + j] = spa[i, j]
                o[offs[14] + 3 * i + j] = wf[i, j]
            for j in range(4):
                o[offs[3] + 4 * i + j] = quat[i, j]
            o[offs[10] + i] = yaw[i]
            for i2 in range(n):
                o[offs[13] + n * i + i2] = mask[i, i2]
                for j in range(3):
                    o[offs[12] + 3 * (n * i + i2) + j] = rel[i, i2, j]
        for j in range(3):
            o[offs[11] + j] = pos[0, j]
        reward[c] = copy_reward(pos, sp, dist, new_contacts[c])
        min_sep[c] = min_separation(dist)
