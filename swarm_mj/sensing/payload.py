"""What a message carries besides the sender's position and velocity: its attitude and its last thrust
command, for the downwash feedforward (docs/sensing.md, "The message's payload").

A sender's broadcast at period s carries its attitude at s and the thrust U1 of its last command (the
one it flew over period s − 1), exactly, in the same packet as its position: it arrives when that
packet arrives (the same delay, the same losses). A receiver holds the payload of the latest packet it
holds from each sender, which it finds from the packet's age in its view (its send period,
k − age/T). Before the first packet from a sender, the receiver takes it level at hover thrust.
"""

from __future__ import annotations

import numpy as np


class Payloads:
    """Each receiver's held payload of each sender: ``push`` the senders' (attitude, thrust) of period k,
    then ``take(k, mask, age)`` with the view's mask and ages of period k: (quat (n, n, 4), thrust (n, n))."""

    def __init__(self, n: int, delay_ticks: int, period_s: float, hover: float) -> None:
        self.n, self.T, self.hover = n, float(period_s), float(hover)
        c = int(delay_ticks) + 1  # the periods a packet is in flight, plus the one it is sent in
        self.ring_quat = np.zeros((c, n, 4))
        self.ring_thrust = np.zeros((c, n))
        self.quat = np.zeros((n, n, 4))
        self.quat[..., 0] = 1.0
        self.thrust = np.full((n, n), self.hover)
        self.sent = np.full((n, n), -1, dtype=np.int64)  # the send period of the payload held (−1: none)

    def push(self, k: int, quat: np.ndarray, thrust: np.ndarray) -> None:
        """The senders' attitude (n, 4) and last thrust (n,) at period k."""
        c = k % self.ring_thrust.shape[0]
        self.ring_quat[c] = quat
        self.ring_thrust[c] = thrust

    def take(self, k: int, mask: np.ndarray, age: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The payloads held at period k: where the view holds a packet (mask (n, n)) sent later than the
        one held (its send period k − age/T), the packet's, from the ring."""
        ages = np.where(mask, age, 0.0)
        sent = np.where(mask, k - np.rint(ages / self.T).astype(np.int64), -1)
        new = mask & (sent > self.sent)
        if new.any():
            i, j = np.nonzero(new)
            c = sent[i, j] % self.ring_thrust.shape[0]
            self.quat[i, j] = self.ring_quat[c, j]
            self.thrust[i, j] = self.ring_thrust[c, j]
            self.sent[i, j] = sent[i, j]
        return self.quat, self.thrust
