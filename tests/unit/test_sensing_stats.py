"""The channel does what its settings say (docs/sensing.md, "The channel"), measured from the views
alone: drones fly known analytic paths (x = x0 + u·t, y and z still, velocity (u, 0, 0)), the
channel is observed every 10 ms for 200 s, and from what the receivers hold we measure, without the
channel's own bookkeeping (its ``age`` is checked against the measurement, not used by it):

* σ of the position error (the still y and z axes) and of the velocity error (all axes);
* the latency: the send time of each message recovered from its x (s = (x − x0)/u), its arrival tick
  minus s, averaged;
* the loss rate: over the messages another receiver got, the share this receiver missed;
* the update rate: the distinct messages of each sender, corrected for those nobody got;
* the age bound of the robust margin: the share of held entries older than A_c.

Each matches its setting within 5 standard errors of its estimator (a false alarm once in ~3·10⁶
per check for a Gaussian estimator), the estimator's standard error written beside each check.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
import pytest

from swarm_mj.sensing import Channel, SensingParams, age_bound

T = 0.01  # the control period (s)
K = 20_000  # ticks: 200 s
N = 5  # drones
U = 1.0 + 0.25 * np.arange(N)  # (N,) x speeds (m/s)
X0 = -3.0 * np.arange(N)  # (N,) x at t = 0 (m)
Y = np.arange(N, dtype=float)  # (N,) still y (m)
Z = 1.0 + 0.1 * np.arange(N)  # (N,) still z (m)


class Message(NamedTuple):
    sender: int
    tick: int  # the arrival tick (the same at every receiver of it)
    pos: np.ndarray  # (3,)
    vel: np.ndarray  # (3,)
    receivers: frozenset[int]


def _fly(params: SensingParams, seed: int = 11):
    """The views of K ticks: pos (K, N, N, 3), vel, mask (K, N, N), age (K, N, N)."""
    ch = Channel(params, T)
    ch.reset(N, seed)
    P = np.empty((K, N, N, 3))
    V = np.empty((K, N, N, 3))
    M = np.empty((K, N, N), dtype=bool)
    A = np.empty((K, N, N))
    vel = np.c_[U, np.zeros(N), np.zeros(N)]
    for k in range(K):
        t = k * T
        view = ch.observe(t, np.c_[X0 + U * t, Y, Z], vel)
        P[k], V[k], M[k], A[k] = view.pos, view.vel, view.mask, view.age
    return P, V, M, A


def _messages(P, V, M) -> tuple[list[Message], np.ndarray]:
    """Every distinct message (a sender's numbers, as every receiver of it holds them) and the
    arrival ticks (K, N, N) of the entry each receiver holds (−1: none)."""
    found: dict[tuple[int, bytes], tuple[int, np.ndarray, np.ndarray, set[int]]] = {}
    arrived = np.full(M.shape, -1, dtype=np.int64)
    for i in range(N):
        for j in range(N):
            if i == j:
                continue
            p, m = P[:, i, j], M[:, i, j]
            new = m & np.r_[True, np.any(p[1:] != p[:-1], axis=1) | ~m[:-1]]  # a message arrives
            idx = np.flatnonzero(new)
            last = np.maximum.accumulate(np.where(new, np.arange(K), -1))
            arrived[:, i, j] = np.where(m, last, -1)
            for k in idx:
                key = (j, p[k].tobytes())
                if key not in found:
                    found[key] = (k, p[k], V[k, i, j], set())
                assert found[key][0] == k  # one message arrives at every receiver at the same tick
                found[key][3].add(i)
    msgs = [Message(j, k, pos, vel, frozenset(r)) for (j, _), (k, pos, vel, r) in found.items()]
    return msgs, arrived


def _sigma(errors: np.ndarray) -> tuple[float, float]:
    """σ estimated from zero-mean errors, and its standard error σ/√(2N)."""
    s = float(np.sqrt(np.mean(errors**2)))
    return s, s / math.sqrt(2 * errors.size)


CASES = {
    # a rate that does not divide the control rate, a latency off the tick grid, heavy loss
    "custom": SensingParams(
        position_noise_m=0.05, velocity_noise_mps=0.2, rate_hz=30.0, latency_s=0.043, packet_loss=0.2
    ),
    "mocap": SensingParams(preset="mocap"),
    "uwb": SensingParams(preset="uwb"),
}  # fmt: skip


@pytest.fixture(scope="module", params=list(CASES))
def flown(request):
    params = CASES[request.param]
    P, V, M, A = _fly(params)
    msgs, arrived = _messages(P, V, M)
    return params, msgs, arrived, M, A


def test_noise_sigma_of_positions_and_velocities(flown):
    params, msgs, *_ = flown
    pos = np.array([m.pos for m in msgs])  # (messages, 3)
    vel = np.array([m.vel for m in msgs])
    j = np.array([m.sender for m in msgs])
    s_p, se_p = _sigma(np.c_[pos[:, 1] - Y[j], pos[:, 2] - Z[j]])
    s_v, se_v = _sigma(vel - np.c_[U[j], np.zeros(len(j)), np.zeros(len(j))])
    assert abs(s_p - params.position_noise_m) <= 5 * se_p, (s_p, se_p)
    assert abs(s_v - params.velocity_noise_mps) <= 5 * se_v, (s_v, se_v)


def test_latency_from_the_send_time_of_a_known_trajectory(flown):
    """lag = arrival time − s, s = (x − x0)/u: its mean is the delivery delay (the noise on x adds
    σ/u of spread, standard error σ/(u·√messages)); the delay is the setting rounded up to the tick
    grid, L ≤ delay < L + T."""
    params, msgs, *_ = flown
    j = np.array([m.sender for m in msgs])
    x = np.array([m.pos[0] for m in msgs])
    lag = np.array([m.tick for m in msgs]) * T - (x - X0[j]) / U[j]
    se = params.position_noise_m * math.sqrt(np.mean(1.0 / U[j] ** 2) / lag.size)
    delay = round(float(np.mean(lag)) / T) * T  # the measured delay on the grid
    assert abs(np.mean(lag) - delay) <= 5 * se, (np.mean(lag), delay, se)
    assert params.latency_s - 1e-12 <= delay < params.latency_s + T, (delay, params.latency_s)
    spread, se_spread = _sigma((lag - delay) * U[j])  # constant delay: the spread is the x noise alone
    assert abs(spread - params.position_noise_m) <= 5 * se_spread, (spread, se_spread)


def _loss(msgs) -> tuple[float, float, int]:
    """The share of the copies a receiver missed among the messages another receiver got (each
    receiver's fate is independent of the others'), its binomial standard error, and the count."""
    got = missed = 0
    for m in msgs:
        for i in range(N):
            if i == m.sender or not (m.receivers - {i}):
                continue
            got += i in m.receivers
            missed += i not in m.receivers
    n = got + missed
    p = missed / n
    return p, math.sqrt(max(p * (1 - p), 1e-12) / n), n


def test_loss_rate(flown):
    params, msgs, *_ = flown
    p, se, _ = _loss(msgs)
    assert abs(p - params.packet_loss) <= 5 * se, (p, se)


def test_update_rate(flown):
    """Distinct messages per sender per second of the sends that could arrive, divided by the share
    that someone got, 1 − p^(N−1) (p measured); the schedule sends a whole number of times, ±1."""
    params, msgs, *_ = flown
    p, se_p, _ = _loss(msgs)
    seen = 1.0 - p ** (N - 1)
    j = np.array([m.sender for m in msgs])
    x = np.array([m.pos[0] for m in msgs])
    delay = round(float(np.mean(np.array([m.tick for m in msgs]) * T - (x - X0[j]) / U[j])) / T) * T
    duration = K * T - delay  # the messages sent in the last `delay` seconds have not arrived
    want = (1.0 / T) if params.rate_hz is None else min(params.rate_hz, 1.0 / T)
    for j in range(N):
        count = sum(m.sender == j for m in msgs)
        rate = count / seen / duration
        sends = want * duration
        # binomial spread of the count around sends·seen, plus p's own error through p^(N−1)
        se = math.sqrt(sends * seen * (1 - seen)) / seen / duration + sends * (N - 1) * p ** (N - 2) * se_p / duration
        assert abs(rate - want) <= 5 * se + 1.0 / duration, (j, rate, want, se)


def test_age_field_and_the_margins_age_bound(flown):
    """The age of a held entry measured as (tick − its arrival tick)·T + the measured delay equals the
    view's ``age``; the share of entries older than the margin's A_c (c = 0.99) is ≤ 1 − c."""
    params, msgs, arrived, M, A = flown
    j = np.array([m.sender for m in msgs])
    x = np.array([m.pos[0] for m in msgs])
    delay = round(float(np.mean(np.array([m.tick for m in msgs]) * T - (x - X0[j]) / U[j])) / T) * T
    k = np.arange(K)[:, None, None]
    held = arrived >= 0
    age = (k - arrived) * T + delay
    assert np.allclose(A[held], age[held], rtol=0, atol=1e-9)
    assert np.array_equal(held, M)
    bound, _ = age_bound(params, T, 0.99)
    start = int(1.0 / T)  # after the first second (every pair has heard every sender)
    over = np.mean(age[start:][held[start:]] > bound + 1e-9)
    n = held[start:].sum()
    assert over <= 0.01 + 5 * math.sqrt(0.01 * 0.99 / n), (over, bound)
