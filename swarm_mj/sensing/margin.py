"""The measurement-robust margin a barrier needs from the sensing bounds (docs/sensing.md, "The
measurement-robust margin"): what the barrier adds to its keep-out under a sensing model
(:func:`barrier_margin`).

A drone i decides on d̂ = ‖p̂_j − p̂_i‖, where p̂_j is the last message it holds from j (sent
``age`` ago, with noise e_j) and p̂_i its own estimate (noise e_i). The true distance differs by at
most ‖e_j − e_i‖ plus how far j has moved since it sent (or, when i extrapolates the message with its
velocity and age, the error of that prediction). :func:`robust_margin` bounds the sum at a confidence
level: keeping d̂ ≥ r + δ keeps the true distance ≥ r at that instant with that confidence per term.
"""

from __future__ import annotations

import math
from typing import NamedTuple

from .channel import channel_config
from .params import SensingParams


class Margin(NamedTuple):
    """The margin's terms (docs/sensing.md, "The measurement-robust margin")."""

    k: float  # the noise quantile: P(‖x‖ ≤ k·σ) = confidence for x ~ N(0, σ²·I₃)
    lost_in_a_row: int  # consecutive lost copies covered at the confidence level
    age_s: float  # the bound on the age of a held entry (s)
    noise_m: float  # k·√(σ_pos² + σ_own²): the position noise of a pair (m)
    staleness_m: float  # how far the sender may have moved from what is held, or the prediction's error (m)
    total_m: float  # δ = noise_m + staleness_m (m)
    velocity_mps: float  # the bound on the error of the relative velocity i holds (m/s)


def noise_quantile(confidence: float) -> float:
    """k with P(‖x‖ ≤ k·σ) = ``confidence`` for x ~ N(0, σ²·I₃): the chi distribution with 3 degrees
    of freedom, F(k) = erf(k/√2) − √(2/π)·k·e^(−k²/2), inverted by bisection."""
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must be in (0, 1), got {confidence!r}")

    def cdf(k: float) -> float:
        return math.erf(k / math.sqrt(2.0)) - math.sqrt(2.0 / math.pi) * k * math.exp(-0.5 * k * k)

    lo, hi = 0.0, 1.0
    while cdf(hi) < confidence:
        hi *= 2.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if cdf(mid) < confidence:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def lost_in_a_row(packet_loss: float, confidence: float) -> int:
    """The fewest m with P(more than m copies in a row lost) = p^(m+1) ≤ 1 − confidence (0 when p is 0)."""
    if packet_loss <= 0.0:
        return 0
    return max(0, math.ceil(math.log(1.0 - confidence) / math.log(packet_loss) - 1e-12) - 1)


def age_bound(params: SensingParams, period_s: float, confidence: float) -> tuple[float, int]:
    """(A, m): the age of an entry a drone holds stays ≤ A = L + (m + 1)·Δ − T with the confidence
    level, where L = ⌈latency/T⌉·T (the delivery delay on the tick grid), Δ = ⌈1/(rate·T)⌉·T (the
    longest gap between two broadcasts of a sender; T when every period) and m =
    :func:`lost_in_a_row`. 0 for the ``perfect`` channel."""
    cfg = channel_config(params, period_s)
    gap_ticks = 1 if cfg.interval_ticks == 0.0 else math.ceil(cfg.interval_ticks - 1e-9)
    m = lost_in_a_row(params.packet_loss, confidence)
    return (cfg.delay_ticks + (m + 1) * gap_ticks - 1) * period_s, m


def robust_margin(
    params: SensingParams,
    period_s: float,
    speed_bound_mps: float,
    *,
    accel_bound_mps2: float | None = None,
    confidence: float = 0.999,
) -> Margin:
    """The margin δ (m) a barrier adds to its keep-out distance for ``params`` at the control period
    ``period_s``, with every drone's speed ≤ ``speed_bound_mps`` (and, when the held message is
    extrapolated with its velocity and age, acceleration ≤ ``accel_bound_mps2``):

        δ = k·√(σ_p² + σ_own²) + s,  s = v̄·A                      (held as is)
                                     s = min(v̄·A, k·σ_v·A + ā·A²/2)  (extrapolated)

    with k = :func:`noise_quantile` (confidence), A = :func:`age_bound`. Each term holds with the
    confidence level; 0 for the ``perfect`` channel."""
    if speed_bound_mps < 0 or (accel_bound_mps2 is not None and accel_bound_mps2 < 0):
        raise ValueError("the speed and acceleration bounds must be >= 0")
    k = noise_quantile(confidence)
    age, m = age_bound(params, period_s, confidence)
    noise = k * math.hypot(params.position_noise_m, params.own_position_noise_m)
    stale = speed_bound_mps * age if age > 0 else 0.0  # (an unbounded speed over no age: nothing)
    vel_err = k * math.hypot(params.velocity_noise_mps, params.own_velocity_noise_mps)
    if accel_bound_mps2 is not None:
        stale = min(stale, k * params.velocity_noise_mps * age + 0.5 * accel_bound_mps2 * age * age)
        vel_err += accel_bound_mps2 * age
    else:
        vel_err += 2.0 * speed_bound_mps if age > 0 else 0.0
    return Margin(
        k=k, lost_in_a_row=m, age_s=age, noise_m=noise, staleness_m=stale, total_m=noise + stale, velocity_mps=vel_err
    )


class BarrierMargin(NamedTuple):
    """The margin a barrier flies with under a sensing model (docs/sensing.md, "The measurement-robust margin")."""

    needed_m: float  # δ of :func:`robust_margin` at the confidence asked
    applied_m: float  # δ flown: needed_m, or the room the formation leaves when that is less
    room_m: float  # half what the formation's closest positions leave beyond the keep-out (m)
    confidence: float
    accel_bound_mps2: float  # ā: the vehicle's largest acceleration, thrust-to-weight·g + g


def barrier_margin(
    params: SensingParams,
    period_s: float,
    thrust_accel_mps2: float,
    g: float,
    spacing_m: float,
    width_m: float,
    confidence: float,
) -> BarrierMargin:
    """The margin of a barrier whose keep-out is ``width_m`` wide (horizontally) for a formation whose
    closest positions are ``spacing_m`` apart: :func:`robust_margin` with the held messages extrapolated
    (every drone's tracks are, swarm_mj.sensing.tracker), no speed bound (v̄ = inf: the extrapolated
    term is the one that bounds), ā = ``thrust_accel_mps2`` + g (no drone accelerates more: full thrust
    against gravity); applied up to half the room the formation leaves, (spacing − width)/2, so that the
    formation can still be reached (the summary says when it is less than needed)."""
    need = robust_margin(
        params, period_s, math.inf, accel_bound_mps2=thrust_accel_mps2 + g, confidence=confidence
    ).total_m
    room = max(0.0, 0.5 * (spacing_m - width_m))
    return BarrierMargin(
        needed_m=need, applied_m=min(need, room), room_m=room, confidence=confidence,
        accel_bound_mps2=thrust_accel_mps2 + g,
    )  # fmt: skip
