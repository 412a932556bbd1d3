"""The barrier filter restricted to one drone's row (``own_row``, swarm_mj/formation/barrier_filter.py's
``barrier_step``; what each drone's own copy of the rule flies under a sensing model,
swarm_mj/formation/own_view.py) gives that row bit for bit as the filter of every row: its references,
its state and its relax events, period after period, over random states (hypothesis), and every row of
the state it reads of the others; the other rows are the planner's. tests/integration/test_own_row_runs.py
flies it (own rows on and off: the same runs).
"""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from swarm_mj.formation.barrier_filter import BarrierFilter, barrier_step
from swarm_mj.formation.barrier_params import BarrierParams, new_record
from swarm_mj.physics.params import DEFAULT_PARAMS

_ROW_STATE = ("guarded", "ref", "ref_vel", "escaping", "pressed_s", "best_m", "was_relaxed", "active", "prev_acc")
#: the state row i reads of every drone (the sensed accelerations, the take-off gate's held drones): a restricted
#: filter keeps every row of it as the full filter does (its QP and its state updates are row i's only)
_SHARED_STATE = ("sensed_acc", "prev_vel", "start", "waited", "flags")


def _bits(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float64).view(np.uint64)


def _drain(rec) -> list[tuple[float, int]]:
    """The record's relax events (t, drone), its buffer emptied (as BarrierFilter.take_events does)."""
    k = int(rec.ev_count[0])
    out = [(float(rec.ev_t[j]), int(rec.ev_drone[j])) for j in range(k)]
    rec.ev_count[0] = 0
    return out


def _fly(seed: int, n: int, periods: int, bp: BarrierParams):
    """A crowded random swarm (some drones on the ground, the others within a few keep-outs of each
    other, their planner's references pulling them together) for ``periods`` periods: the filter of
    every row and the n filters restricted to one row each, on the same inputs. Yields, per period,
    (full record, full output, restricted records, their outputs, planner's references, events)."""
    rng = np.random.default_rng(seed)
    dt = 0.02
    pos = rng.uniform([-0.8, -0.8, 0.3], [0.8, 0.8, 1.4], (n, 3))
    pos[rng.random(n) < 0.3, 2] = 0.02  # on the ground: the take-off gate
    vel = rng.normal(0.0, 0.4, (n, 3))
    steer = np.ones(n, dtype=np.bool_)
    steer[0] = False  # the leader flies its trajectory
    goal = pos[::-1].copy() + rng.normal(0.0, 0.2, (n, 3))  # each drone's reference through the others
    full = new_record(bp, DEFAULT_PARAMS, n, True)
    # with the joint fallback a drone's copy computes every row and counts its own (BarrierFilter.restrict_to)
    own = [new_record(bp, DEFAULT_PARAMS, n, True, *((-1, i) if bp.joint_fallback else (i,))) for i in range(n)]
    for k in range(periods):
        t = k * dt
        pos_d = pos + np.clip(goal - pos, -0.4, 0.4)
        vel_d = (goal - pos) * 0.8
        acc_d = rng.normal(0.0, 1.0, (n, 3))
        out = barrier_step(full, t, pos, vel, dt, pos_d, vel_d, acc_d, steer)
        outs = [barrier_step(r, t, pos, vel, dt, pos_d, vel_d, acc_d, steer) for r in own]
        yield full, out, own, outs, (pos_d, vel_d, acc_d), _drain(full), [_drain(r) for r in own]
        vel = vel + dt * out[2] + rng.normal(0.0, 0.05, (n, 3))  # the drones roughly fly what the filter says
        pos = pos + dt * vel
        pos[:, 2] = np.maximum(pos[:, 2], 0.02)


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    n=st.integers(2, 7),
    leader_filters=st.booleans(),
    leader_yields=st.booleans(),
    lanes=st.booleans(),
    both_states=st.booleans(),
    jerk=st.sampled_from([0.0, 40.0]),
    joint=st.booleans(),
)
def test_a_filter_restricted_to_one_row_gives_that_row_bit_for_bit(
    seed, n, leader_filters, leader_yields, lanes, both_states, jerk, joint
):
    bp = BarrierParams(
        leader_filters=leader_filters,
        leader_yields=leader_yields,
        guard_lanes=lanes,
        both_states=both_states,
        vertical_jerk_limit=jerk,
        escape_after_s=0.2,  # the deadlock escape's state within the flight
        escape_min_m=0.05,
        joint_fallback=joint,
    )
    for full, out, own, outs, refs, events, own_events in _fly(seed, n, 60, bp):
        for i, (rec, o, ev) in enumerate(zip(own, outs, own_events)):
            for c in range(3):  # (pos, vel, acc): row i as the full filter's; the others the planner's
                assert np.array_equal(_bits(o[c][i]), _bits(out[c][i]))
                others = np.arange(n) != i  # the planner's; with the joint fallback its prediction, the full's
                assert np.array_equal(_bits(o[c][others]), _bits((out if joint else refs)[c][others]))
            for name in _ROW_STATE:
                assert np.array_equal(getattr(rec, name)[i], getattr(full, name)[i]), name
            for name in _SHARED_STATE:
                assert np.array_equal(_bits(getattr(rec, name)), _bits(getattr(full, name))), name
            assert ev == [e for e in events if e[1] == i]


def test_the_restricted_filters_share_the_full_filters_work():
    """On a crowded start the filter changes several drones' commands (so the property above compares
    QP solutions, not only untouched nominals); the restricted filters' tallies add up to the full
    filter's, each counting its own drone."""
    bp = BarrierParams(escape_after_s=0.2, escape_min_m=0.05)
    acted = np.zeros(6, dtype=bool)
    for step in _fly(7, 6, 60, bp):
        acted |= step[0].active
    full, own = step[0], step[2]  # after the last period
    assert acted.sum() >= 2
    assert np.array_equal(sum(r.counts for r in own), full.counts)


def test_restrict_to_sets_the_row_through_a_reset():
    """A drone's copy counts its own drone; it computes that row only, or with the joint fallback every row."""
    for joint, computed in ((False, 2), (True, -1)):
        f = BarrierFilter(BarrierParams(joint_fallback=joint))
        f.restrict_to(2)
        assert (f.record().own_row, f.record().tally_row) == (computed, 2)
        f.reset(4)  # a run's start: a new record, the same drone
        assert (f.record().own_row, f.record().tally_row) == (computed, 2)
    assert (BarrierFilter().record().own_row, BarrierFilter().record().tally_row) == (-1, -1)
