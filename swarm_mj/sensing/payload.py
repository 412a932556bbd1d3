"""What a message carries besides the sender's position and velocity: its attitude and its last thrust
command, for the downwash feedforward (docs/sensing.md, "The message's payload").

A sender's broadcast at period s carries its attitude at s and the thrust U1 of its last command (the
one it flew over period s − 1), exactly, in the same packet as its position: it arrives when that
packet arrives (the same delay, the same losses). A receiver holds the payload of the latest packet it
holds from each sender, which it finds from the packet's age in its view (its send period,
k − age/T). Before the first packet from a sender, the receiver takes it level at hover thrust.

The state is a record of arrays (:class:`PayloadRecord`) and a period is one compiled function of it,
:func:`payload_tick`, which both drivers of the control period run.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .._jit import jit


class PayloadRecord(NamedTuple):
    """Each receiver's held payload of each sender, and the ring of the senders' recent ones."""

    T: float  # the control period (s)
    ring_quat: np.ndarray  # (C, n, 4) the senders' attitude at each of the last C periods (C = delay + 1)
    ring_thrust: np.ndarray  # (C, n) their last thrust U1 (N) at those periods
    quat: np.ndarray  # (n, n, 4) [receiver, sender]: the attitude of the packet held
    thrust: np.ndarray  # (n, n) its thrust (N)
    sent: np.ndarray  # (n, n) int64: the send period of the payload held (−1: none)


def payload_record(n: int, delay_ticks: int, period_s: float, hover: float) -> PayloadRecord:
    """The payloads before any packet: every sender level at ``hover`` thrust (N), nothing held."""
    c = int(delay_ticks) + 1  # the periods a packet is in flight, plus the one it is sent in
    quat = np.zeros((n, n, 4))
    quat[..., 0] = 1.0
    return PayloadRecord(
        T=float(period_s),
        ring_quat=np.zeros((c, n, 4)),
        ring_thrust=np.zeros((c, n)),
        quat=quat,
        thrust=np.full((n, n), float(hover)),
        sent=np.full((n, n), -1, dtype=np.int64),
    )


@jit(inline=True)
def payload_tick(rec, k, quat, thrust, mask, age) -> None:
    """Period k: the senders' attitude (n, 4) and last thrust (n,) into the ring, then, where the view holds
    a packet (mask (n, n)) sent later than the one held (its send period k − age/T, age (n, n) s), that
    packet's payload from the ring into ``rec.quat``, ``rec.thrust``."""
    n = thrust.shape[0]
    c = k % rec.ring_thrust.shape[0]
    for s in range(n):
        for j in range(4):
            rec.ring_quat[c, s, j] = quat[s, j]
        rec.ring_thrust[c, s] = thrust[s]
    for r in range(n):
        for s in range(n):
            if not mask[r, s]:
                continue
            sent = k - np.int64(np.rint(age[r, s] / rec.T))
            if sent > rec.sent[r, s]:
                q = sent % rec.ring_thrust.shape[0]
                for j in range(4):
                    rec.quat[r, s, j] = rec.ring_quat[q, s, j]
                rec.thrust[r, s] = rec.ring_thrust[q, s]
                rec.sent[r, s] = sent
