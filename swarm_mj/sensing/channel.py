"""The channel between the drones: each drone's own view of the swarm (docs/sensing.md).

Modelled on dm_control's observables (an update interval, a delay, a corruptor), vectorised over
drones: every control tick each sender whose broadcast falls due sends its state plus Gaussian
noise; each (sender, receiver) copy is lost with probability ``packet_loss``, independently, or
does not reach a receiver out of ``range_m`` (the true distance at send time); a copy is delivered
at the first tick at or after its send time + ``latency_s``; a receiver holds the latest message
delivered from each sender, unchanged until the next (no extrapolation: the entry's ``age`` says how
old it is). The followers' knowledge of the leader (sender 0) goes through the same channel.

The state is a record of typed arrays (:class:`ChannelState`, shapes on each field) and the step is
one compiled function of it, the static :class:`ChannelConfig` and the run's generator, which it draws
from in a fixed order: :func:`channel_tick`, inlined in the sensing stage's tick (both drivers of the
control period), or :func:`channel_step` from Python. :class:`Channel` holds one run's state and its seeded
generator (``numpy.random.Generator`` from a ``SeedSequence`` of (seed, copy, :data:`SENSING_STREAM`)).
A draw is made only for a term that is on: with no noise, no loss and every period the generator
draws nothing and the view is the truth's own numbers (copies, no arithmetic).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from .._jit import jit
from .params import SensingParams

#: The sensing stream's entry in the seed sequence (seed, copy, stream): its own generator, so that
#: turning sensing on shifts no other stream (the wind, the random starts).
SENSING_STREAM = 0x5E45

_EPS = 1e-9  # ticks: float slack of the schedule's and the delay's rounding


class ChannelConfig(NamedTuple):
    """The channel's static numbers for one run (from :class:`SensingParams` and the control period)."""

    period_s: float  # the control period T (s): the channel's tick
    interval_ticks: float  # a sender's broadcast interval in ticks, 1/(rate·T); 0: every tick
    delay_ticks: int  # ticks from a send to its delivery: ⌈latency/T⌉
    range_m: float  # a copy reaches receivers closer than this (m); inf: all
    leader_in_range: bool  # sender 0 (the leader) reaches every receiver whatever the range
    sigma_pos: float  # σ per axis of a broadcast position (m)
    sigma_vel: float  # σ per axis of a broadcast velocity (m/s)
    loss: float  # probability that one copy (sender → receiver) is lost
    sigma_own_pos: float  # σ per axis of a drone's own position (m)
    sigma_own_vel: float  # σ per axis of a drone's own velocity (m/s)


class ChannelState(NamedTuple):
    """The channel's state between ticks (updated in place by :func:`channel_step`)."""

    tick: np.ndarray  # (1,) int64: the last tick observed (−1 before the first)
    t0: np.ndarray  # (1,) float: the time of tick 0 (s), the first observation's
    phase: np.ndarray  # (n,) float: each sender's first broadcast, in ticks after tick 0 (0 ≤ φ < interval)
    buf_tick: np.ndarray  # (C,) int64: the send tick of each slot of messages in flight (−1: empty), C = delay + 1
    buf_pos: np.ndarray  # (C, n, 3) the broadcast position of each sender in the slot (m)
    buf_vel: np.ndarray  # (C, n, 3) the broadcast velocity (m/s)
    buf_keep: np.ndarray  # (C, n, n) bool [slot, receiver, sender]: this copy reaches the receiver
    buf_gone: np.ndarray  # (C, n, n) bool [slot, receiver, sender]: sent out of range (the entry is dropped)
    held_pos: np.ndarray  # (n, n, 3) [receiver, sender]: the latest delivered position (m)
    held_vel: np.ndarray  # (n, n, 3) the latest delivered velocity (m/s)
    held_tick: np.ndarray  # (n, n) int64: the send tick of what the receiver holds (−1: nothing)


class View(NamedTuple):
    """Each drone's own view at one tick (row i: what drone i believes)."""

    pos: np.ndarray  # (n, n, 3) drone i's estimate of drone j's position (m); the diagonal: own_pos
    vel: np.ndarray  # (n, n, 3) drone i's estimate of drone j's velocity (m/s); the diagonal: own_vel
    mask: np.ndarray  # (n, n) bool: i holds a message from j sent within range (diagonal False)
    age: np.ndarray  # (n, n) s since j sent what i holds (inf where nothing)
    own_pos: np.ndarray  # (n, 3) each drone's own position for its controller (m)
    own_vel: np.ndarray  # (n, 3) its own velocity (m/s)


def channel_config(params: SensingParams, period_s: float, *, leader_in_range: bool = True) -> ChannelConfig:
    """The static numbers of the channel for ``params`` at the control period ``period_s``."""
    if not (period_s > 0 and math.isfinite(period_s)):
        raise ValueError(f"period_s must be positive and finite, got {period_s!r}")
    interval = 0.0
    if params.rate_hz is not None:
        interval = 1.0 / (params.rate_hz * period_s)
        if interval <= 1.0 + _EPS:  # at or above the control rate: every tick
            interval = 0.0
    return ChannelConfig(
        period_s=float(period_s),
        interval_ticks=interval,
        delay_ticks=int(math.ceil(params.latency_s / period_s - _EPS)) if params.latency_s > 0 else 0,
        range_m=float(params.range_m),
        leader_in_range=bool(leader_in_range),
        sigma_pos=params.position_noise_m,
        sigma_vel=params.velocity_noise_mps,
        loss=params.packet_loss,
        sigma_own_pos=params.own_position_noise_m,
        sigma_own_vel=params.own_velocity_noise_mps,
    )


def empty_state(n: int, cfg: ChannelConfig, phase: np.ndarray | None = None) -> ChannelState:
    """The state before the first tick: nothing in flight, nothing held; ``phase`` (n,) in ticks
    (zeros when None)."""
    c = cfg.delay_ticks + 1
    return ChannelState(
        tick=np.full(1, -1, dtype=np.int64),
        t0=np.zeros(1),
        phase=np.zeros(n) if phase is None else np.asarray(phase, dtype=float).copy(),
        buf_tick=np.full(c, -1, dtype=np.int64),
        buf_pos=np.zeros((c, n, 3)),
        buf_vel=np.zeros((c, n, 3)),
        buf_keep=np.zeros((c, n, n), dtype=bool),
        buf_gone=np.zeros((c, n, n), dtype=bool),
        held_pos=np.zeros((n, n, 3)),
        held_vel=np.zeros((n, n, 3)),
        held_tick=np.full((n, n), -1, dtype=np.int64),
    )


@jit(inline=True)
def _broadcasts(cfg, phase, s, k):
    """Sender s broadcasts at tick ``k`` (≥ 0): it has an instant φ + m·I (m ≥ 0, I the interval in
    ticks) in (k − 1, k]; every tick when I is 0."""
    if cfg.interval_ticks == 0.0:
        return True
    now = max(np.floor((k - phase[s]) / cfg.interval_ticks + _EPS) + 1.0, 0.0)  # broadcast instants up to k
    before = max(np.floor((k - 1 - phase[s]) / cfg.interval_ticks + _EPS) + 1.0, 0.0)
    return now > before


def _senders_samples() -> list:
    cfg = ChannelConfig(
        period_s=0.01, interval_ticks=2.5, delay_ticks=0, range_m=np.inf, leader_in_range=True, sigma_pos=0.0,
        sigma_vel=0.0, loss=0.0, sigma_own_pos=0.0, sigma_own_vel=0.0,
    )  # fmt: skip
    return [(cfg, np.zeros(2), 3)]


@jit(samples=_senders_samples)
def senders_at(cfg: ChannelConfig, phase: np.ndarray, k: int) -> np.ndarray:
    """(n,) bool: the senders that broadcast at tick ``k`` (≥ 0) (:func:`_broadcasts`)."""
    out = np.empty(phase.shape[0], dtype=np.bool_)
    for s in range(phase.shape[0]):
        out[s] = _broadcasts(cfg, phase, s, k)
    return out


@jit(inline=True)
def _deliver(state, cfg, k):
    """Deliver every slot due by tick ``k`` (send tick + delay ≤ k), oldest first, and free it."""
    n = state.held_tick.shape[0]
    while True:
        c = -1
        for q in range(state.buf_tick.shape[0]):  # the oldest slot due
            bt = state.buf_tick[q]
            if bt >= 0 and bt + cfg.delay_ticks <= k and (c < 0 or bt < state.buf_tick[c]):
                c = q
        if c < 0:
            return
        for r in range(n):  # [receiver, sender]
            for s in range(n):
                if state.buf_keep[c, r, s]:
                    for j in range(3):
                        state.held_pos[r, s, j] = state.buf_pos[c, s, j]
                        state.held_vel[r, s, j] = state.buf_vel[c, s, j]
                    state.held_tick[r, s] = state.buf_tick[c]
                elif state.buf_gone[c, r, s]:
                    state.held_tick[r, s] = -1
        state.buf_tick[c] = -1


@jit(inline=True)
def _send(state, cfg, k, pos, vel, rng):
    """Broadcast at tick ``k``: the due senders' noisy states into slot k mod C, with each copy's fate (the
    draws of the tick, each only where its term is on: the positions' noise, the velocities', the losses)."""
    n = pos.shape[0]
    c = k % state.buf_tick.shape[0]
    for s in range(n):
        for j in range(3):
            state.buf_pos[c, s, j] = pos[s, j]
            state.buf_vel[c, s, j] = vel[s, j]
    if cfg.sigma_pos > 0:
        noise = rng.standard_normal((n, 3))
        for s in range(n):
            for j in range(3):
                state.buf_pos[c, s, j] = pos[s, j] + cfg.sigma_pos * noise[s, j]
    if cfg.sigma_vel > 0:
        noise = rng.standard_normal((n, 3))
        for s in range(n):
            for j in range(3):
                state.buf_vel[c, s, j] = vel[s, j] + cfg.sigma_vel * noise[s, j]
    lost = rng.random((n, n)) < cfg.loss if cfg.loss > 0 else np.zeros((n, n), dtype=np.bool_)
    for s in range(n):
        sending = _broadcasts(cfg, state.phase, s, k)
        for r in range(n):
            near = True
            if not (math.isinf(cfg.range_m) or (cfg.leader_in_range and s == 0)):
                # the rules' seen_within arithmetic (formation/separation.py), on the true positions
                d0, d1, d2 = pos[s, 0] - pos[r, 0], pos[s, 1] - pos[r, 1], pos[s, 2] - pos[r, 2]
                near = d0 * d0 + d1 * d1 + d2 * d2 < cfg.range_m * cfg.range_m
            copy = sending and r != s
            state.buf_keep[c, r, s] = copy and near and not lost[r, s]
            state.buf_gone[c, r, s] = copy and not near
    state.buf_tick[c] = k


@jit(inline=True)
def channel_tick(state, cfg, k, pos, vel, rng, own_pos, own_vel, age):
    """One tick ``k`` (> the last) of the channel on the true states ``pos``, ``vel`` (n, 3): what is due is
    delivered, the due senders broadcast, what is due now (zero delay) is delivered. Writes each drone's own
    position and velocity for its controller (own_pos, own_vel (n, 3), the true ones with their noise) and the
    age (n, n) of what each receiver holds (inf: nothing); the held messages are ``state.held_*``. The draws
    of the tick, in a fixed order: the broadcast positions' noise, the velocities', the losses, the own
    position's noise, the own velocity's; none for a term that is off."""
    _deliver(state, cfg, k)  # frees the slot k mod C before it is written
    _send(state, cfg, k, pos, vel, rng)
    _deliver(state, cfg, k)
    state.tick[0] = k
    n = pos.shape[0]
    for i in range(n):
        for j in range(3):
            own_pos[i, j] = pos[i, j]
            own_vel[i, j] = vel[i, j]
    if cfg.sigma_own_pos > 0:
        noise = rng.standard_normal((n, 3))
        for i in range(n):
            for j in range(3):
                own_pos[i, j] = pos[i, j] + cfg.sigma_own_pos * noise[i, j]
    if cfg.sigma_own_vel > 0:
        noise = rng.standard_normal((n, 3))
        for i in range(n):
            for j in range(3):
                own_vel[i, j] = vel[i, j] + cfg.sigma_own_vel * noise[i, j]
    for r in range(n):
        for s in range(n):
            ht = state.held_tick[r, s]  # the diagonal never holds anything
            age[r, s] = (k - ht) * cfg.period_s if ht >= 0 else np.inf


def channel_step(
    state: ChannelState, cfg: ChannelConfig, k: int, pos: np.ndarray, vel: np.ndarray, rng: np.random.Generator
) -> View:
    """:func:`channel_tick` (compiled on its own for Python callers) at tick ``k`` (> the last), with the view
    of every drone. Updates ``state`` in place and draws from ``rng``."""
    if k <= int(state.tick[0]):
        raise ValueError(f"tick {k} is not after the last one ({int(state.tick[0])})")
    n = pos.shape[0]
    own_pos, own_vel, age = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, n))
    channel_tick(state, cfg, k, np.ascontiguousarray(pos, dtype=float), np.ascontiguousarray(vel, dtype=float), rng,
          own_pos, own_vel, age)  # fmt: skip
    view_pos = state.held_pos.copy()
    view_vel = state.held_vel.copy()
    diag = np.arange(n)
    view_pos[diag, diag] = own_pos
    view_vel[diag, diag] = own_vel
    return View(pos=view_pos, vel=view_vel, mask=state.held_tick >= 0, age=age, own_pos=own_pos, own_vel=own_vel)


def sensing_rng(seed: int, copy: int = 0) -> np.random.Generator:
    """The sensing stream's generator for ``seed`` and ``copy``."""
    return np.random.default_rng(np.random.SeedSequence([int(seed), int(copy), SENSING_STREAM]))


class Channel:
    """One run's channel: ``reset(n, seed, copy)``, then ``observe(t, pos, vel)`` once per control
    tick (t on the grid t0 + k·T, increasing) returns the :class:`View`."""

    def __init__(self, params: SensingParams, period_s: float, *, leader_in_range: bool = True) -> None:
        self.params = params
        self.config = channel_config(params, period_s, leader_in_range=leader_in_range)
        self.state: ChannelState | None = None
        self.rng: np.random.Generator | None = None

    def reset(self, n: int, seed: int, copy: int = 0) -> None:
        """A fresh channel for ``n`` drones, seeded by (seed, copy): the senders' phases drawn
        (only when they broadcast less often than every tick), nothing held."""
        if n < 1:
            raise ValueError(f"n must be >= 1, got {n}")
        self.rng = sensing_rng(seed, copy)
        interval = self.config.interval_ticks
        phase = self.rng.random(n) * interval if interval > 0 else None
        self.state = empty_state(n, self.config, phase)

    def observe(self, t: float, pos: np.ndarray, vel: np.ndarray) -> View:
        """The view at time ``t`` (s) of the true positions and velocities (n, 3)."""
        if self.state is None or self.rng is None:
            raise RuntimeError("Channel.observe before reset")
        n = self.state.phase.shape[0]
        if pos.shape != (n, 3) or vel.shape != (n, 3):
            raise ValueError(f"pos and vel must be ({n}, 3), got {pos.shape} and {vel.shape}")
        if int(self.state.tick[0]) < 0:
            self.state.t0[0] = t
        q = (t - float(self.state.t0[0])) / self.config.period_s
        k = int(round(q))
        if abs(q - k) > 1e-6:
            raise ValueError(f"t = {t} is not on the control-period grid t0 + k·{self.config.period_s}")
        return channel_step(self.state, self.config, k, pos, vel, self.rng)
