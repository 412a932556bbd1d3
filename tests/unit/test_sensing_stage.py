"""Each drone's own view (swarm_mj/sensing/tracker.py, stage.py, log.py; docs/sensing.md) against
independent hand computations: the track's gain (its closed form against the scalar Kalman filter's
Riccati recursion iterated to its fixed point), a message taken in bit for bit, dead reckoning over the
age, a correction spread over the broadcast interval, the stage under a zero model (the truth and the
oracle's setpoints bit for bit, from the stage alone and from ``SwarmEnv``'s observation), which records
fly the oracle, the observation's view keys, and the run summary's belief errors on a hand-made log.
Whole flights are tests/integration/test_sensing_runs.py's."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from swarm_mj.env import SwarmEnv
from swarm_mj.formation.slots import setpoints_into
from swarm_mj.scenario import load_scenario
from swarm_mj.sensing import PRESETS, SensingParams
from swarm_mj.sensing.log import ViewLog, belief_errors, view_summary
from swarm_mj.sensing.stage import UNSEEN_M, OwnView, SensingStage, is_oracle, sensing_stage, view_keys
from swarm_mj.sensing.tracker import TRACK_ACCEL, VELOCITY_RAMP_TICKS, start_tracks, track_gain, track_step

T = 0.01  # the control period (s)


def _bits(a: np.ndarray) -> np.ndarray:
    """The float64 array's bit patterns (equal patterns: equal bit for bit, −0.0 included)."""
    return np.ascontiguousarray(a, dtype=np.float64).view(np.uint64)


def _zero(preset: str, rate_hz: float | None = 0.0) -> SensingParams:
    """A model with no noise, no latency, no loss, every period (rate 0 or at least the control rate)
    and no range, on the preset ``preset``."""
    return SensingParams(
        preset=preset, position_noise_m=0.0, velocity_noise_mps=0.0, rate_hz=rate_hz, latency_s=0.0,
        packet_loss=0.0, range_m=math.inf, own_position_noise_m=0.0, own_velocity_noise_mps=0.0,
    )  # fmt: skip


# --- the track's gain ---------------------------------------------------------------------------


def _riccati_gain(q: float, r: float) -> float:
    """The steady-state gain of the scalar Kalman filter of a random walk (process variance q per
    step) measured with variance r, by iterating the Riccati recursion from P = r to its fixed point:
    P⁻ ← P⁺ + q, K = P⁻/(P⁻ + r), P⁺ = (1 − K)·P⁻."""
    p_plus = r
    gain = 1.0
    for _ in range(100_000):
        p_minus = p_plus + q
        new = p_minus / (p_minus + r)
        p_plus = (1.0 - new) * p_minus
        if abs(new - gain) < 1e-15:
            return new
        gain = new
    raise AssertionError("the Riccati recursion did not settle")


def test_track_gain_is_one_for_exact_messages():
    for sigma_vel, interval, latency in [(0.0, 0.01, 0.0), (0.2, 0.04, 0.05), (1.0, 0.1, 0.3)]:
        assert track_gain(0.0, sigma_vel, interval, latency) == 1.0


@pytest.mark.parametrize(
    "sigma_pos, sigma_vel, interval, latency",
    [(0.05, 0.2, 0.04, 0.05), (0.0023, 0.011, 0.01, 0.026), (0.10, 0.10, 0.10, 0.01)],
)
def test_track_gain_is_the_steady_kalman_gain_of_its_prediction_error(sigma_pos, sigma_vel, interval, latency):
    """The prediction over one interval Δ errs by (σ_v + ā·L)·Δ + ½·ā·Δ² (one σ, the module's model);
    the gain is the steady-state Kalman gain with that as the process σ and σ_p as the measurement's."""
    a = TRACK_ACCEL
    q_sigma = (sigma_vel + a * latency) * interval + 0.5 * a * interval**2
    want = _riccati_gain(q_sigma**2, sigma_pos**2)
    got = track_gain(sigma_pos, sigma_vel, interval, latency)
    assert 0.0 < got < 1.0
    assert got == pytest.approx(want, rel=1e-9, abs=1e-12)


def test_track_gain_hand_case():
    """σ_p 0.05 m, σ_v 0.2 m/s, Δ 0.04 s, L 0.05 s, ā 4 m/s²: q = (0.4·0.04 + 2·0.0016) = 0.0192 m,
    Q = 3.6864e-4, R = 2.5e-3; P⁻ = Q/2 + √(Q²/4 + Q·R) = 1.8432e-4 + √(3.3974e-8 + 9.216e-7)
    = 1.8432e-4 + 9.7753e-4 = 1.16185e-3 (to 5 digits); α = P⁻/(P⁻ + R) = 1.16185/3.66185 = 0.31729."""
    assert track_gain(0.05, 0.2, 0.04, 0.05, accel=4.0) == pytest.approx(0.31729, abs=1e-5)


# --- the track's step ---------------------------------------------------------------------------


def _one_pair(x0, v0=(0.0, 0.0, 0.0), seen=-1):
    """Tracks of two drones, drone 0's track of drone 1 at x0 moving with v0, last message ``seen``."""
    s = start_tracks(np.array([[0.0, 0.0, 0.0], x0], dtype=float))
    s.v[0, 1] = v0
    s.seen_tick[0, 1] = seen
    return s


def _held(pos, vel, tick, age):
    """The channel's held arrays for drone 0 holding (pos, vel) sent at ``tick``, ``age`` old."""
    hp, hv = np.zeros((2, 2, 3)), np.zeros((2, 2, 3))
    ht, ag = np.full((2, 2), -1, dtype=np.int64), np.full((2, 2), np.inf)
    hp[0, 1], hv[0, 1], ht[0, 1], ag[0, 1] = pos, vel, tick, age
    return hp, hv, ht, ag


def test_alpha_one_and_zero_age_copies_the_message_bit_for_bit():
    rng = np.random.default_rng(3)
    for _ in range(20):
        pos, vel = rng.normal(size=3) * 7.0, rng.normal(size=3)
        s = _one_pair(rng.normal(size=3), rng.normal(size=3), seen=4)  # an older message was taken in
        track_step(s, *_held(pos, vel, 9, 0.0), T, 1.0, 1)
        assert np.array_equal(_bits(s.x[0, 1]), _bits(pos))
        assert np.array_equal(_bits(s.v[0, 1]), _bits(vel))
        assert s.seen_tick[0, 1] == 9


def test_a_message_is_dead_reckoned_over_its_age_then_moved_with_its_velocity():
    p, v, age = np.array([1.0, 2.0, 3.0]), np.array([0.5, -1.0, 2.0]), 0.03
    s = _one_pair([9.0, 9.0, 9.0])
    hp, hv, ht, ag = _held(p, v, 0, age)
    track_step(s, hp, hv, ht, ag, T, 1.0, 1)
    assert s.x[0, 1] == pytest.approx([1.015, 1.97, 3.06], abs=1e-14)  # p + v·age by hand
    for m in range(1, 4):  # nothing new: the track moves on with v·T per tick
        track_step(s, hp, hv, ht, ag + m * T, T, 1.0, 1)
        assert s.x[0, 1] == pytest.approx(p + v * (age + m * T), abs=1e-14)
    assert np.array_equal(s.x[1], start_tracks(np.array([[0.0, 0.0, 0.0], [9.0, 9.0, 9.0]])).x[1])  # row 1 untouched


def test_a_first_message_is_taken_as_it_is_whatever_the_gain():
    s = _one_pair([9.0, 9.0, 9.0])
    track_step(s, *_held([1.0, 2.0, 3.0], [0.0, 0.0, 0.0], 5, 0.0), T, 0.2, 4)
    assert np.array_equal(s.x[0, 1], [1.0, 2.0, 3.0])
    assert s.fix_left[0, 1] == 0


@pytest.mark.parametrize("m", [1, 3, 4, 10])
def test_a_correction_spread_over_m_ticks_adds_up_to_alpha_times_the_innovation(m):
    """A track at x⁻ moving with v; a message ẑ (age 0, velocity w) at tick 7 with gain α over m ticks:
    each of the m ticks adds α·(ẑ − x⁻)/m to x, each of the first r = min(m, VELOCITY_RAMP_TICKS) adds
    (w − v)/r to the velocity it moves with (v·T predicted into x⁻ before the message, each later tick
    moving x by the velocity of the tick before); after them x has taken α·(ẑ − x⁻) in all, the velocity
    is w, and nothing more is added."""
    alpha = 0.3
    x_old, v, z = np.array([1.0, -2.0, 0.5]), np.array([0.2, 0.1, -0.3]), np.array([1.4, -1.7, 0.9])
    w = np.array([-0.1, 0.4, 0.05])
    s = _one_pair(x_old, v, seen=3)
    hp, hv, ht, ag = _held(z, w, 7, 0.0)
    x_minus = x_old + v * T  # the prediction of the message's tick
    track_step(s, hp, hv, ht, ag, T, alpha, m)
    r = min(m, VELOCITY_RAMP_TICKS)
    step_x, step_v = alpha * (z - x_minus) / m, (w - v) / r
    want_x, want_v = x_minus + step_x, v + step_v
    assert s.x[0, 1] == pytest.approx(want_x, abs=1e-14)
    assert s.v[0, 1] == pytest.approx(want_v, abs=1e-14)
    for tick in range(1, m + 3):
        track_step(s, hp, hv, ht, ag + tick * T, T, alpha, m)
        want_x = want_x + want_v * T
        if tick < m:
            want_x = want_x + step_x
        if tick < r:
            want_v = want_v + step_v
        assert s.x[0, 1] == pytest.approx(want_x, abs=1e-13), tick
        assert s.v[0, 1] == pytest.approx(want_v, abs=1e-13), tick
    assert s.v[0, 1] == pytest.approx(w, abs=1e-13)
    assert s.fix_left[0, 1] == 0


# --- the stage under a zero model ---------------------------------------------------------------


@pytest.mark.parametrize("preset", list(PRESETS))
@pytest.mark.parametrize("rate_hz", [0.0, 1.0 / T, 400.0])
def test_zero_model_stage_is_the_truth_and_the_oracles_setpoints_bit_for_bit(preset, rate_hz):
    """A random flight of 4 drones through :class:`SensingStage` (zero model): every drone's belief of
    every drone is the true position, and its setpoints are :func:`setpoints_into`'s of the true leader."""
    n, K = 4, 60
    rng = np.random.default_rng(17)
    starts = rng.normal(size=(n, 3))
    pos = starts + np.cumsum(rng.normal(scale=0.02, size=(K, n, 3)), axis=0)
    pos[0] = starts
    vel = rng.normal(size=(K, n, 3))
    offsets = rng.normal(size=(n - 1, 3))
    stage = SensingStage(_zero(preset, rate_hz), T, n)
    stage.reset(starts, seed=5)
    assert stage.alpha == 1.0
    prev, lvel = np.zeros(3), np.zeros(3)
    sp, spv, spa, yaw = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3)), np.empty(n)
    for k in range(K):
        plan = (rng.normal(size=3), rng.normal(size=3), rng.normal(size=3))
        D = 1.0 + 0.1 * math.sin(k)
        view = stage.observe(k, pos[k], vel[k], plan, D, offsets)
        setpoints_into(k, T, pos[k, 0], prev, lvel, *plan, 0.0, D, offsets, sp, spv, spa, yaw)
        assert np.array_equal(_bits(view.pos), _bits(np.broadcast_to(pos[k][None], (n, n, 3))))
        assert np.array_equal(_bits(view.setpoint), _bits(np.broadcast_to(sp[None], (n, n, 3))))
        assert np.array_equal(_bits(view.setpoint_vel), _bits(np.broadcast_to(spv[None], (n, n, 3))))
        assert np.array_equal(_bits(view.setpoint_acc), _bits(spa))
        assert np.array_equal(_bits(view.own_vel), _bits(vel[k]))
        assert np.array_equal(view.mask, ~np.eye(n, dtype=bool))
        assert np.all(view.age[view.mask] == 0.0) and np.all(np.isinf(np.diag(view.age)))
        if k > 0:  # what each sender broadcasts: its position's difference over the period
            assert view.vel == pytest.approx(np.broadcast_to(((pos[k] - pos[k - 1]) / T)[None], (n, n, 3)), rel=1e-9)


def test_zero_model_env_view_is_the_observations_truth_and_setpoints():
    """``SwarmEnv`` under a zero model (range inf on a scenario with a rules' range) flown a few periods
    on a climbing thrust: each drone's view_pos is obs["pos"], its view_setpoint obs["setpoint"]."""
    sc = load_scenario("anti_collision")
    sc = dataclasses.replace(sc, sensing=_zero("mocap"))
    env = SwarmEnv(sc, seed=3)
    n = env.n
    assert env.sensing is not None
    U = np.zeros((n, 4))
    U[:, 0] = 1.2 * env.params.m * env.params.g
    obs = env.reset().observation
    for k in range(40):
        for key, want in [("view_pos", "pos"), ("view_setpoint", "setpoint"), ("view_setpoint_vel", "setpoint_vel")]:
            assert np.array_equal(_bits(obs[key]), _bits(np.broadcast_to(obs[want][None], (n, n, 3)))), (k, key)
        assert np.array_equal(_bits(obs["own_pos"]), _bits(obs["pos"]))
        assert np.array_equal(_bits(obs["own_vel"]), _bits(obs["vel"]))
        obs = env.step(U).observation


# --- which records fly the oracle ---------------------------------------------------------------


@pytest.mark.parametrize(
    "params, oracle",
    [
        (SensingParams(), True),
        (SensingParams(range_m=3.0), True),  # the rules apply their own range
        (SensingParams(rate_hz=0.0), True),  # 0: every period, perfect's own
        (SensingParams(preset="mocap"), False),
        (SensingParams(preset="uwb"), False),
        (_zero("mocap"), False),  # zero settings, but another preset: through the stage
        (SensingParams(position_noise_m=1e-6), False),
        (SensingParams(rate_hz=50.0), False),
        (SensingParams(latency_s=0.01), False),
        (SensingParams(packet_loss=0.01), False),
        (SensingParams(own_velocity_noise_mps=0.1), False),
    ],
)
def test_is_oracle_and_the_stage_it_gives(params, oracle):
    assert is_oracle(params) is oracle
    stage = sensing_stage(params, T, 3)
    assert (stage is None) is oracle
    assert sensing_stage(params, T, 1) is None  # one drone: no others to see
    assert sensing_stage(None, T, 3) is None


# --- the observation's view keys ----------------------------------------------------------------


def test_view_keys_shapes_and_neighbours_only_where_held_and_near():
    n = 4
    pos = np.zeros((n, n, 3))
    own = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [5.0, 0.0, 1.0], [0.0, 1.0, 1.0]])
    pos[:] = own[None]  # every drone believes every drone at its true place...
    pos[2, 0] = [50.0, 0.0, 1.0]  # ...but drone 2 believes the leader 45 m off (held: in spite of the range)
    mask = ~np.eye(n, dtype=bool)
    mask[1, 3] = False  # drone 1 holds nothing from drone 3
    view = OwnView(
        pos=pos, vel=np.ones((n, n, 3)), mask=mask, age=np.where(mask, 0.02, np.inf), setpoint=np.zeros((n, n, 3)),
        setpoint_vel=np.zeros((n, n, 3)), setpoint_acc=np.zeros((n, 3)), own_vel=np.full((n, 3), 0.5),
    )  # fmt: skip
    keys = view_keys(view, sensing_range=2.0)
    shapes = {"view_pos": (n, n, 3), "view_vel": (n, n, 3), "view_mask": (n, n), "view_age": (n, n)}
    shapes |= {"view_setpoint": (n, n, 3), "view_setpoint_vel": (n, n, 3), "own_pos": (n, 3), "own_vel": (n, 3)}
    shapes |= {"neighbours": (n, n, 3), "neighbour_mask": (n, n)}
    assert {k: v.shape for k, v in keys.items()} == shapes
    assert np.array_equal(keys["own_pos"], own)
    assert np.array_equal(keys["view_mask"], mask.astype(float))
    # by hand: within 2 m (or the leader, when held), held, not oneself
    want = np.zeros((n, n), dtype=bool)
    want[0, 1] = want[1, 0] = want[0, 3] = want[3, 0] = True  # 1 m apart
    want[1, 3] = False  # 1.41 m apart but not held
    want[3, 1] = True  # 1.41 m apart, held
    want[2, 0] = True  # the leader, 45 m off in drone 2's view: always, when held
    assert np.array_equal(keys["neighbour_mask"], want.astype(float))
    assert np.all(keys["neighbours"][~want] == 0.0)
    assert np.array_equal(keys["neighbours"][want], (pos - own[:, None, :])[want])
    assert np.array_equal(keys["neighbours"][2, 0], [50.0 - 5.0, 0.0, 0.0])


# --- the summary of what the drones believed ----------------------------------------------------


def test_belief_errors_and_view_summary_against_a_hand_case():
    """Two periods, three drones. Errors held off the diagonal: 0.5 (3-4-5 scaled), 5, 0.13 (5-12-13
    scaled) and 0 in period 0; 1 in period 1; an entry held but believed unseen (x at UNSEEN_M) is left
    out, so are entries not held and the diagonal (wrong on purpose)."""
    k, n = 2, 3
    truth = np.array([[[0, 0, 1], [1, 0, 1], [0, 2, 1]], [[1, 1, 1], [2, 1, 1], [1, 3, 1]]], dtype=float)
    log = ViewLog.allocate(k, n)
    log.pos[:] = truth[:, None, :, :]  # every belief exact...
    log.pos[:, np.arange(n), np.arange(n)] += 7.0  # ...but the diagonals (never counted)
    log.pos[0, 0, 1] += [0.3, 0.4, 0.0]  # 0.5
    log.pos[0, 0, 2] += [0.0, 3.0, 4.0]  # 5
    log.pos[0, 1, 2] += [0.05, 0.0, 0.12]  # 0.13
    log.pos[0, 2, 1] += [0.0, 0.0, 0.0]  # 0
    log.pos[1, 2, 0] += [0.0, 0.0, -1.0]  # 1
    log.pos[1, 1, 0] = [UNSEEN_M + 1.0, 1.0, 1.0]  # held, but believed unseen: left out
    log.pos[0, 1, 0] += [9.0, 0.0, 0.0]  # not held: left out
    held = [(0, 0, 1), (0, 0, 2), (0, 1, 2), (0, 2, 1), (1, 2, 0), (1, 1, 0)]
    for kk, i, j in held:
        log.mask[kk, i, j] = True
        log.age[kk, i, j] = 0.01 * (1 + i + j + 3 * kk)  # oldest: (1, 2, 0) → 0.06, (1, 1, 0) → 0.05
    e = np.sort(belief_errors(log, truth))
    assert e == pytest.approx([0.0, 0.13, 0.5, 1.0, 5.0], abs=1e-12)
    s = view_summary(log, truth)
    # the median of 5 is the 3rd; p99 at rank 0.99·4 = 3.96: 1 + 0.96·(5 − 1) = 4.84
    assert s["belief_error_m"] == pytest.approx({"median": 0.5, "p99": 4.84, "max": 5.0}, abs=1e-12)
    assert s["held_share"] == pytest.approx(6 / (k * n * (n - 1)))
    assert s["oldest_held_s"] == pytest.approx(0.06)


def test_view_summary_with_nothing_held():
    log = ViewLog.allocate(3, 2)
    s = view_summary(log, np.zeros((3, 2, 3)))
    assert s == {"belief_error_m": {"median": None, "p99": None, "max": None}, "held_share": 0.0, "oldest_held_s": None}
