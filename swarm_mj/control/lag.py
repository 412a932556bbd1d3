"""Rotor-lag compensation: the attitude fed back, predicted over the actuation delay (ours).

Why (issue 15, docs/interpretations.md §2): the backstepping gains of Table 4 were tuned for
rotors that produce their command at once. Through the desired-attitude rates (finite differences of
φ_d, θ_d over T) the position loop's velocity gain adds a stiffness of about (a+b)_att·(a+b)_pos
to the attitude loop: a lightly damped mode near 14 rad/s. With the rotors' first-order lag
(τ = 15 ms under ``--aero realistic``) plus the control period's hold, that mode is barely damped:
in a swarm every neighbour's jet rings it (roll and pitch swinging by ±30–50° at times, measured in
the ``circle`` swarm), and drones touched or flipped.

The fix is the textbook one for a known actuator delay: feed the controller the state the drone
will be in when its command takes effect. With the delay d_att = τ + T (rotor lag plus zero-order
hold) for the attitude and d_rate = τ for the rates,

    η_p = η + d_att · η̇                      (n, 3) Euler angles (φ, θ, ψ)
    η̇_p = η̇ + d_rate · (η̇ − η̇_prev) / T     (n, 3) their rates
    ω_p = ω + d_rate · (ω − ω_prev) / T       (n, 3) body rates

A first-order prediction from quantities the flight controller has (its gyro, its attitude
estimate); nothing is read from the simulator's rotor states. Measured under ``--aero realistic``:
in the ``circle`` swarm after the form-up, roll and pitch standard deviation 4.6° → 0.6°, peak 43° →
3.5° (``tests/integration/test_realistic_controller.py``); docs/interpretations.md §2.
"""

from __future__ import annotations

import numpy as np

from .._jit import jit
from ..pipeline.records import Predictor

__all__ = ["AttitudePredictor", "predict_kernel"]


def _predict_samples():
    z = np.zeros((2, 3))
    return [(z, z.copy(), z.copy(), z.copy(), z.copy(), 0.025, 1.5, False, z.copy(), z.copy(), z.copy())]


@jit(samples=_predict_samples)
def predict_kernel(
    rpy: np.ndarray,
    rate: np.ndarray,
    body: np.ndarray,
    prev_rate: np.ndarray,
    prev_body: np.ndarray,
    d_att: float,
    k_rate: float,
    first: bool,
    rpy_p: np.ndarray,
    rate_p: np.ndarray,
    body_p: np.ndarray,
) -> None:
    """The module docstring's prediction for (n, 3) arrays: rpy_p = rpy + d_att·rate,
    rate_p = rate + k_rate·(rate − prev_rate), body_p = body + k_rate·(body − prev_body) (k_rate =
    d_rate / T); then prev_rate, prev_body take rate, body. ``first``: no previous rates yet (they are
    taken as the current ones: the rates predicted constant)."""
    for i in range(rpy.shape[0]):
        for c in range(3):
            r = rate[i, c]
            b = body[i, c]
            pr = r if first else prev_rate[i, c]
            pb = b if first else prev_body[i, c]
            rpy_p[i, c] = rpy[i, c] + d_att * r
            rate_p[i, c] = r + k_rate * (r - pr)
            body_p[i, c] = b + k_rate * (b - pb)
            prev_rate[i, c] = r
            prev_body[i, c] = b


class AttitudePredictor:
    """η, η̇ and ω (n, 3) predicted over the actuation delay (module docstring).

    ``attitude_horizon`` d_att and ``rate_horizon`` d_rate in seconds; ``control_period`` T."""

    def __init__(self, n: int, attitude_horizon: float, rate_horizon: float, control_period: float) -> None:
        if attitude_horizon < 0 or rate_horizon < 0 or control_period <= 0:
            raise ValueError("horizons must be >= 0 and the control period > 0")
        self.n = n
        self.d_att = float(attitude_horizon)
        self.k_rate = float(rate_horizon) / float(control_period)
        self.reset()

    def reset(self) -> None:
        """Forget the previous rates (the first call predicts the rates as constant)."""
        self._first = True
        self._prev_rate = np.zeros((self.n, 3))
        self._prev_body = np.zeros((self.n, 3))
        self._record = Predictor(
            on=True, d_att=self.d_att, k_rate=self.k_rate, prev_rate=self._prev_rate, prev_body=self._prev_body
        )
        self._out = np.empty((3, self.n, 3))  # (η_p, η̇_p, ω_p), rewritten by every call

    def record(self) -> Predictor:
        """The predictor for a compiled driver (swarm_mj.pipeline.records; valid until the next :meth:`reset`)."""
        return self._record

    def __call__(
        self, rpy: np.ndarray, rpy_rate: np.ndarray, body_rates: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(η_p, η̇_p, ω_p) (n, 3) from η, η̇ and ω (n, 3) (:func:`predict_kernel`); views of one
        buffer that the next call overwrites."""
        rpy = np.ascontiguousarray(rpy, dtype=np.float64)
        rpy_rate = np.ascontiguousarray(rpy_rate, dtype=np.float64)
        body_rates = np.ascontiguousarray(body_rates, dtype=np.float64)
        out, first = self._out, self._first
        self._first = False
        predict_kernel(
            rpy, rpy_rate, body_rates, self._prev_rate, self._prev_body, self.d_att, self.k_rate, first, out[0], out[1],
            out[2],
        )  # fmt: skip
        return out[0], out[1], out[2]
