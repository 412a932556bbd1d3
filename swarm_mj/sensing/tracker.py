"""Each drone's track of every other drone: what it believes now, from the messages it holds
(docs/sensing.md, "What a drone believes").

A receiver holds the latest message from each sender (:mod:`.channel`): a position and a velocity,
sent ``age`` ago. It does not fly on that message as it is:

* **dead reckoning over the age**: the message's position advanced by its velocity over its age,
  ẑ = p + v·age (a message sent 26 ms ago describes where the sender was, not where it is);
* **a constant-velocity track** per (receiver, sender): the belief x moves with the sender's broadcast
  velocity every tick, x ← x + v·T, and each new message corrects it by a gain α, spread over the
  sender's broadcast interval (m ticks: x ← x + α·(ẑ − x⁻)/m per tick), so that the rules, which
  difference the positions they are given (paper §4's velocity estimate), see no step at a message;
* α is the steady-state Kalman gain of that track (:func:`track_gain`): the prediction over one
  interval Δ errs by (σ_v + ā·L)·Δ (the broadcast velocity's noise, and how much it has changed over
  the latency L under an acceleration ā the track does not model, :data:`TRACK_ACCEL`) plus ½·ā·Δ²,
  the message by σ_p. With exact messages (σ_p = 0) α is 1
  and the belief is ẑ itself (copied, no arithmetic): a channel without noise, latency or loss at the
  control rate gives the truth bit for bit.

Before its first message from a sender, a receiver believes the sender stands at its start (the
flight plan's pads, which every drone knows). The state is a record of arrays updated in place by
:func:`track_step`.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from .._jit import jit

#: ā (m/s²): the acceleration the constant-velocity track does not model, in the prediction error of
#: its gain (:func:`track_gain`): the followers' acceleration limit (``max_accel`` 4 m/s² of the
#: jet-aware and barrier planners). With 2 m/s² and without the latency term the ``mocap`` track lagged
#: the leader's take-off dash by up to 6 cm (α 0.06); with them by under 1 cm (docs/sensing.md).
TRACK_ACCEL = 4.0

#: The most ticks a track's velocity takes to reach a new message's (the ramp of :func:`track_step`):
#: 2. Stepped at once (1), a 0.1 m/s step of ``uwb`` every 0.1 s chattered a follower's barrier command
#: until it tumbled (stress 100140); ramped over the whole interval (10 ticks), the tracks of a sender
#: lagged it and a noisy 25-Hz model lost 2 of 6 circles (docs/sensing.md).
VELOCITY_RAMP_TICKS = 2


def track_gain(
    sigma_pos: float, sigma_vel: float, interval_s: float, latency_s: float = 0.0, accel: float = TRACK_ACCEL
) -> float:
    """α in [0, 1]: the steady-state Kalman gain of a track predicted with a velocity of noise
    ``sigma_vel`` (m/s), ``latency_s`` old, over ``interval_s`` between messages of position noise
    ``sigma_pos`` (m): q = (σ_v + ā·L)·Δ + ½·ā·Δ², Q = q², R = σ_p², P⁻ = Q/2 + √(Q²/4 + Q·R),
    α = P⁻/(P⁻ + R); 1 when R is 0."""
    r = sigma_pos * sigma_pos
    if r == 0.0:
        return 1.0
    q = ((sigma_vel + accel * latency_s) * interval_s + 0.5 * accel * interval_s * interval_s) ** 2
    p = 0.5 * q + math.sqrt(0.25 * q * q + q * r)
    return p / (p + r)


class TrackState(NamedTuple):
    """Each receiver's track of each sender (row i: drone i's; updated in place by :func:`track_step`)."""

    x: np.ndarray  # (n, n, 3) the believed position of sender j now (m); the diagonal: the drone's own
    v: np.ndarray  # (n, n, 3) the velocity it is moved with (m/s): the last message's
    seen_tick: np.ndarray  # (n, n) int64: the send tick of the last message taken in (−1: none)
    fix: np.ndarray  # (n, n, 3) the correction still to spread, per tick (m)
    fix_left: np.ndarray  # (n, n) int64: ticks it is still added
    vfix: np.ndarray  # (n, n, 3) the velocity's step to the new message's, per tick of its ramp (m/s)
    vfix_left: np.ndarray  # (n, n) int64: ticks of the ramp still to add


def start_tracks(starts: np.ndarray) -> TrackState:
    """The tracks before any message: every receiver believes every sender at its start (n, 3), at rest."""
    n = starts.shape[0]
    x = np.broadcast_to(np.asarray(starts, dtype=np.float64)[None, :, :], (n, n, 3)).copy()
    return TrackState(
        x=x,
        v=np.zeros((n, n, 3)),
        seen_tick=np.full((n, n), -1, dtype=np.int64),
        fix=np.zeros((n, n, 3)),
        fix_left=np.zeros((n, n), dtype=np.int64),
        vfix=np.zeros((n, n, 3)),
        vfix_left=np.zeros((n, n), dtype=np.int64),
    )


@jit(inline=True)
def track_step(
    s: TrackState,
    held_pos: np.ndarray,
    held_vel: np.ndarray,
    held_tick: np.ndarray,
    age: np.ndarray,
    period_s: float,
    alpha: float,
    spread_ticks: int,
) -> None:
    """One control tick of every track, from what the receivers hold now (the channel's held_pos,
    held_vel (n, n, 3), held_tick (n, n) (−1: nothing) and age (n, n) s): predict with v·T, take in
    each new message (held_tick past seen_tick) with the gain ``alpha`` spread over ``spread_ticks``
    (≥ 1); ``alpha`` 1 sets the belief to the message dead-reckoned over its age. In place. Inlined in the
    sensing stage's tick; compiled on its own for Python callers."""
    n = s.x.shape[0]
    ramp = min(spread_ticks, VELOCITY_RAMP_TICKS)
    for i in range(n):
        for j in range(n):
            if s.seen_tick[i, j] >= 0:  # a track that has a message: moved with its velocity
                for c in range(3):
                    s.x[i, j, c] += s.v[i, j, c] * period_s
            if s.fix_left[i, j] > 0:  # a correction still spreading
                for c in range(3):
                    s.x[i, j, c] += s.fix[i, j, c]
                s.fix_left[i, j] -= 1
            if s.vfix_left[i, j] > 0:  # a velocity still ramping
                for c in range(3):
                    s.v[i, j, c] += s.vfix[i, j, c]
                s.vfix_left[i, j] -= 1
            ht = held_tick[i, j]
            if ht < 0 or ht <= s.seen_tick[i, j]:
                continue
            a = age[i, j]
            first = s.seen_tick[i, j] < 0  # a first message: taken as it is
            for c in range(3):
                z = held_pos[i, j, c] + held_vel[i, j, c] * a if a > 0.0 else held_pos[i, j, c]  # dead-reckoned
                if alpha >= 1.0:
                    s.x[i, j, c] = z
                    s.v[i, j, c] = held_vel[i, j, c]
                else:
                    fix = alpha * (z - s.x[i, j, c]) / spread_ticks
                    vfix = (held_vel[i, j, c] - s.v[i, j, c]) / ramp
                    s.fix[i, j, c] = fix
                    s.vfix[i, j, c] = vfix
                    s.x[i, j, c] = z if first else s.x[i, j, c] + fix
                    s.v[i, j, c] = held_vel[i, j, c] if first else s.v[i, j, c] + vfix
            s.fix_left[i, j] = 0 if alpha >= 1.0 or first else spread_ticks - 1
            s.vfix_left[i, j] = 0 if alpha >= 1.0 or first else ramp - 1
            s.seen_tick[i, j] = ht
