"""Whole flights under a sensing model (issue 49, docs/sensing.md), short ones:

* seeds: the same seed flies the same numbers (the log, the views, the summary), another seed draws
  other noise, and the sensing stream is its own (the wind's series and the random starts are the same
  with sensing on as off);
* a zero model (no noise, no latency, every period, no loss, no range) on any preset flies bit for bit
  as ``perfect`` (a hypothesis property over the presets and the broadcast rate, for every rule under
  the paper's physics, ``layers`` and ``barrier`` (its downwash feedforward on) under the realistic air);
* the model does what it says, measured from a run's recorded views alone (``log.views.held_pos``,
  ``held_tick`` against ``log.pos``): σ of the position noise, the latency, the loss rate and the update
  rate, each within 5 standard errors of its setting (the estimator's standard error beside each check);
  the velocity noise and each drone's own noise, which the log does not keep, from ``SwarmEnv``'s views.
  tests/unit/test_sensing_stats.py measures the channel alone the same way.
"""

from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from swarm_mj.env import SwarmEnv
from swarm_mj.experiments.runner import RunResult, run
from swarm_mj.scenario import load_scenario
from swarm_mj.sensing import PRESETS, SensingParams
from swarm_mj.sensing.stage import is_oracle

pytestmark = pytest.mark.slow

_TIMING = ("wall_time_s", "real_time_factor")  # the summary's wall-clock keys


def _bits(a: np.ndarray) -> np.ndarray:
    """The float64 array's bit patterns (equal patterns: equal bit for bit, NaN and −0.0 included)."""
    return np.ascontiguousarray(a, dtype=np.float64).view(np.uint64)


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    return a.shape == b.shape and bool(np.array_equal(_bits(a), _bits(b)))


def _summary(r: RunResult) -> dict:
    return {k: v for k, v in r.summary.items() if k not in _TIMING}


# --- seeds --------------------------------------------------------------------------------------


@functools.cache
def _mocap_run(seed: int) -> RunResult:
    sc = load_scenario("anti_collision").with_overrides(duration=3.0, sensing="mocap")
    return run(sc, seed=seed, progress=False, fused=False)


def test_same_seed_same_numbers_other_seed_other_noise():
    a, b = _mocap_run(7), run(load_scenario("anti_collision").with_overrides(duration=3.0, sensing="mocap"),
                              seed=7, progress=False, fused=False)  # fmt: skip
    assert a.error is None and a.summary["sensing"]["own_view"] is True
    for f in dataclasses.fields(a.log):
        x, y = getattr(a.log, f.name), getattr(b.log, f.name)
        if isinstance(x, np.ndarray):
            assert x.shape == y.shape and np.array_equal(x, y, equal_nan=x.dtype.kind == "f"), f.name
    assert a.log.views is not None and b.log.views is not None
    for f in dataclasses.fields(a.log.views):
        x, y = getattr(a.log.views, f.name), getattr(b.log.views, f.name)
        assert np.array_equal(x, y, equal_nan=x.dtype.kind == "f"), f.name
    assert _summary(a) == _summary(b)

    # another seed: the same scenario (no wind, the same pads), other noise on the same first messages
    c = _mocap_run(8)
    va, vc = a.log.views, c.log.views
    assert vc is not None
    assert not np.array_equal(va.held_pos, vc.held_pos)
    first = int(np.flatnonzero((va.held_tick >= 0).any(axis=(1, 2)))[0])  # the first period anything is held
    assert np.array_equal(a.log.pos[0], c.log.pos[0])  # what was sent at tick 0 is the same truth...
    both = (va.held_tick[first] == 0) & (vc.held_tick[first] == 0)
    assert both.sum() >= 10
    noise_a = va.held_pos[first][both] - a.log.pos[0][np.nonzero(both)[1]]
    noise_c = vc.held_pos[first][both] - c.log.pos[0][np.nonzero(both)[1]]
    assert np.all(noise_a != 0.0) and np.all(noise_c != 0.0)
    assert np.all(noise_a != noise_c)  # ...with other noise


def test_the_sensing_stream_is_its_own():
    """Sensing on changes the flight but not the wind's series (its turbulence drawn from the seed), nor
    the force it applies (from the wind alone: relative airspeed off), nor the random starts."""
    sc = load_scenario("wind_swarm")
    wind = dataclasses.replace(sc.wind, schedule=((0.0, math.inf, "xy"),))  # the wind on from the start
    sc = sc.with_overrides(duration=3.0, wind=wind)
    assert not sc.wind.relative_airspeed
    off = run(sc, seed=3, progress=False, fused=False)
    on = run(sc.with_overrides(sensing="mocap"), seed=3, progress=False, fused=False)
    assert on.log.views is not None and off.log.views is None
    assert not np.array_equal(off.log.pos, on.log.pos)  # the sensing changed the flight...
    assert np.all(np.abs(off.log.wind_force[:-1]).max(axis=(0, 1))[:2] > 0.1)
    assert _same(off.log.wind_speed, on.log.wind_speed)  # ...not the wind
    assert _same(off.log.wind_force, on.log.wind_force)

    many = load_scenario("swarm25_barrier")
    assert many.random_start is not None
    starts = [SwarmEnv(many, sensing=s, seed=5).physics.starts for s in ("perfect", "uwb")]
    assert _same(starts[0], starts[1])


# --- a zero model flies as perfect --------------------------------------------------------------

_CASES = [
    ("paper", "paper"),
    ("layers", "paper"),
    ("jet-aware", "paper"),
    ("barrier", "paper"),
    ("layers", "realistic"),
    ("barrier", "realistic"),  # the downwash feedforward from the packets' attitudes and thrusts
]


def _base(rule: str):
    # the followers cross past the leader: every rule acts (keep-out time > 0 in each perfect run)
    return load_scenario("anti_collision").with_overrides(duration=4.0, anti_collision=rule)


@functools.cache
def _perfect(rule: str, aero: str) -> RunResult:
    # step by step: fused=None would fly the chunk driver only where it is already compiled (else start
    # compiling it in the background, tens of CPU seconds), and the chunk driver's equality is its own tests'
    r = run(_base(rule), aero=aero, progress=False, fused=False)
    assert r.summary["sensing"]["own_view"] is False
    return r


@pytest.mark.parametrize("rule, aero", _CASES)
@settings(max_examples=3, deadline=None)
@example(preset="perfect", rate_hz=250.0)  # a perfect record that is not the oracle: through the stage
@given(
    preset=st.sampled_from(list(PRESETS)),
    rate_hz=st.one_of(st.just(0.0), st.just(None), st.floats(min_value=100.0, max_value=5000.0)),
)
def test_a_zero_model_flies_bit_for_bit_as_perfect(rule, aero, preset, rate_hz):
    want = _perfect(rule, aero)
    zero = SensingParams(
        preset=preset, position_noise_m=0.0, velocity_noise_mps=0.0, rate_hz=rate_hz, latency_s=0.0,
        packet_loss=0.0, range_m=math.inf, own_position_noise_m=0.0, own_velocity_noise_mps=0.0,
    )  # fmt: skip
    # dataclasses.replace: the channel without a range (with_overrides keeps the file's [formation] range)
    got = run(dataclasses.replace(_base(rule), sensing=zero), aero=aero, progress=False, fused=False)
    assert got.summary["sensing"]["own_view"] is (not is_oracle(zero))  # through the stage, each its own view
    assert (got.log.views is None) is is_oracle(zero)
    assert _same(got.log.pos, want.log.pos)
    assert _same(got.log.U, want.log.U)
    for key in ("contacts", "contact_steps", "crashes", "keepout_time_s", "formation", "min_separation_m"):
        assert got.summary[key] == want.summary[key], key
    assert str(got.error) == str(want.error)


# --- the model does what it says, from a run's recorded views -----------------------------------

STRONG = SensingParams(
    preset="mocap", position_noise_m=0.05, velocity_noise_mps=0.2, rate_hz=25.0, latency_s=0.043, packet_loss=0.2,
    range_m=math.inf,
)  # fmt: skip


@pytest.fixture(scope="module")
def strong_run():
    """The circle for 20 s under the strong model. The rule is ``barrier``: with the rule off the
    followers collide on the way to their slots (under ``perfect`` too), and under a model this strong
    ``layers`` loses a follower on some seeds (docs/sensing.md, "What a drone believes")."""
    sc = load_scenario("circle").with_overrides(duration=20.0, anti_collision="barrier", sensing=STRONG)
    r = run(sc, progress=False, fused=False)
    assert r.error is None and r.summary["contacts"] == 0
    views = r.log.views
    assert views is not None
    T = float(np.diff(r.log.t).mean())
    assert T == pytest.approx(sc.control_period, abs=1e-12)
    return r.log.pos, views.held_pos, views.held_tick, views.age, views.mask, sc.control_period


def _messages(held_tick: np.ndarray) -> dict[tuple[int, int, int], int]:
    """{(receiver, sender, send tick): the first period it is held} from the held send ticks (K, n, n)."""
    K, n, _ = held_tick.shape
    first: dict[tuple[int, int, int], int] = {}
    for i in range(n):
        for j in range(n):
            s = held_tick[:, i, j]
            new = (s >= 0) & np.r_[True, s[1:] != s[:-1]]
            for k in np.flatnonzero(new):
                first.setdefault((i, j, int(s[k])), int(k))
    return first


def test_position_noise_sigma(strong_run):
    """held_pos − the sender's true position at the send tick, once per message (every receiver holds
    the same broadcast): zero mean, σ = the setting within 5·σ/√(2N)."""
    pos, held_pos, held_tick, *_ = strong_run
    k, i, j = np.nonzero(held_tick >= 0)
    s = held_tick[k, i, j]
    err = held_pos[k, i, j] - pos[s, j]  # (entries, 3)
    _, one = np.unique(np.c_[j, s], axis=0, return_index=True)
    key = j * (1 << 32) + s
    for m in np.unique(key)[:50]:  # the receivers of one message hold the same numbers
        assert np.all(err[key == m] == err[key == m][0])
    e = err[one].ravel()
    sigma = math.sqrt(float(np.mean(e**2)))
    se = sigma / math.sqrt(2 * e.size)
    assert abs(sigma - STRONG.position_noise_m) <= 5 * se, (sigma, se, e.size)
    assert np.all(np.abs(err[one].mean(axis=0)) <= 5 * sigma / math.sqrt(len(one)))


def test_latency(strong_run):
    """The first period each (receiver, sender, send tick) is held, minus the send tick: a constant delay,
    the setting rounded up to the control grid (the smallest whole number of periods ≥ the latency)."""
    *_, held_tick, _, _, T = strong_run
    first = _messages(held_tick)
    lag = np.array([k - s for (_, _, s), k in first.items()])
    assert lag.size > 10_000
    assert np.all(lag == lag[0])  # delivery is deterministic: standard error 0
    delay = lag[0] * T
    assert delay - T < STRONG.latency_s <= delay + 1e-12, delay


def _loss_and_rate(held_tick: np.ndarray, T: float):
    """The loss rate (over the messages another receiver got, the share each receiver missed: each
    copy's fate independent), its binomial standard error, the sends of each sender that someone got
    among those delivered within the run, and the run's window of such sends (s)."""
    K, n, _ = held_tick.shape
    first = _messages(held_tick)
    lag = min(k - s for (_, _, s), k in first.items())
    sends: dict[tuple[int, int], set[int]] = {}
    for i, j, s in first:
        if s + lag <= K - 1:  # its delivery is within the run
            sends.setdefault((j, s), set()).add(i)
    got = missed = 0
    for (j, _), receivers in sends.items():
        for i in range(n):
            if i == j or not (receivers - {i}):
                continue
            got += i in receivers
            missed += i not in receivers
    p = missed / (got + missed)
    per_sender = np.bincount([j for j, _ in sends], minlength=n)
    return p, math.sqrt(p * (1 - p) / (got + missed)), per_sender, (K - lag) * T


def test_loss_rate(strong_run):
    *_, held_tick, _, _, T = strong_run
    p, se, _, _ = _loss_and_rate(held_tick, T)
    assert abs(p - STRONG.packet_loss) <= 5 * se, (p, se)


def test_update_rate(strong_run):
    """Distinct sends of each sender per second of the window, divided by the share someone got,
    1 − p^(n−1) (p measured): the setting within 5 standard errors (the binomial spread of that share
    and p's own error through p^(n−1)) plus one send (a schedule sends a whole number of times)."""
    *_, held_tick, _, _, T = strong_run
    n = held_tick.shape[1]
    p, se_p, per_sender, window = _loss_and_rate(held_tick, T)
    seen = 1.0 - p ** (n - 1)
    want = STRONG.rate_hz
    for j in range(n):
        rate = per_sender[j] / seen / window
        sends = want * window
        se = math.sqrt(sends * seen * (1 - seen)) / seen / window + sends * (n - 1) * p ** (n - 2) * se_p / window
        assert abs(rate - want) <= 5 * se + 1.0 / window, (j, rate, se)


def test_the_recorded_age_and_mask_are_the_held_messages(strong_run):
    """The views' age is (period − send tick)·T where a message is held, inf elsewhere; the mask is
    'something held' (no range)."""
    *_, held_tick, age, mask, T = strong_run
    held = held_tick >= 0
    assert np.array_equal(mask, held)
    k = np.arange(held_tick.shape[0])[:, None, None]
    assert np.allclose(age[held], ((k - held_tick) * T)[held], rtol=0, atol=1e-9)
    assert np.all(np.isinf(age[~held]))


def test_velocity_and_own_noise_sigma_from_the_observed_views():
    """What the run log does not keep, from ``SwarmEnv``'s observations of a 5 s flight: the velocity
    message a drone holds of another (the channel's, before its track ramps to it) is the sender's
    position difference over the period before its send tick
    (send tick = period − age/T) plus noise of σ_vel; each drone's own position (``own_pos``) and
    velocity (``own_vel``) are the true ones plus noise of the own σ's. Each within 5·σ/√(2N)."""
    from swarm_mj.control.policy import BacksteppingPolicy

    model = dataclasses.replace(STRONG, own_position_noise_m=0.01, own_velocity_noise_mps=0.05)
    sc = load_scenario("circle").with_overrides(duration=5.0, anti_collision="layers", sensing=model)
    env = SwarmEnv(sc, terminate_on_contact=False, seed=2)
    policy = BacksteppingPolicy(sc, env.params)
    T = env.T
    obs = env.reset().observation
    pos, vel_err, own_pos_err, own_vel_err = [], [], [], []
    held: list[tuple[int, np.ndarray, np.ndarray]] = []  # (period, held velocity messages, view_age)
    for k in range(env.n_steps):
        pos.append(obs["pos"].copy())
        own_pos_err.append(obs["own_pos"] - obs["pos"])
        own_vel_err.append(obs["own_vel"] - obs["vel"])
        held.append((k, env.sensing.channel.state.held_vel.copy(), obs["view_age"].copy()))  # as it came
        obs = env.step(policy.command(obs)).observation
    assert env.last_termination is None
    P = np.array(pos)  # (K, n, 3)
    seen: set[tuple[int, int]] = set()
    for k, vv, age in held:
        for i, j in zip(*np.nonzero(np.isfinite(age))):
            s = k - int(round(age[i, j] / T))
            if s < 1 or (j, s) in seen:  # the first period broadcasts no velocity; one sample per message
                continue
            seen.add((j, s))
            vel_err.append(vv[i, j] - (P[s, j] - P[s - 1, j]) / T)
    for errors, want in [
        (np.array(vel_err), model.velocity_noise_mps),
        (np.array(own_pos_err), model.own_position_noise_m),
        (np.array(own_vel_err), model.own_velocity_noise_mps),
    ]:
        e = errors.ravel()
        sigma = math.sqrt(float(np.mean(e**2)))
        assert abs(sigma - want) <= 5 * sigma / math.sqrt(2 * e.size), (sigma, want, e.size)
