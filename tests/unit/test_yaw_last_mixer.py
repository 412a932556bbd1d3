"""The yaw-last mixer (``mixing.yaw_last``; docs/vehicles.md, "Mixer"): roll and pitch are kept, the yaw is
scaled down just enough for the rotors' spread to fit their range, then the collective thrust is moved as
attitude priority moves it. Checked against rotor thrusts solved from each vehicle's own mixing matrix and a
brute-force search of the yaw share, and on the Crazyflie's numbers against the simulator's per-rotor clip."""

from __future__ import annotations

import numpy as np
import pytest

from swarm_mj.physics.mixing import attitude_priority, saturate, yaw_last
from swarm_mj.physics.params import DEFAULT_PARAMS
from swarm_mj.vehicles import load_vehicle

CF = load_vehicle("crazyflie21").params()
VEHICLES = {"paper": DEFAULT_PARAMS, "crazyflie21": CF}


def _rotors(p, U: np.ndarray) -> np.ndarray:
    """Rotor thrusts (n, 4) of U (n, 4), solved from the vehicle's U = F·MIXᵀ (not its UNMIX)."""
    return np.linalg.solve(p.mix_t.T, U.T).T


def _spread(F: np.ndarray) -> float:
    return float(F.max() - F.min())


def _random_commands(p, n: int, seed: int) -> np.ndarray:
    """Commands around hover with torques up to a few times what the rotors can give, and some that fit."""
    rng = np.random.default_rng(seed)
    f = p.f_max
    U = np.column_stack(
        [
            rng.uniform(0.0, 4.0 * f, n),
            rng.uniform(-2.0, 2.0, n) * f,
            rng.uniform(-2.0, 2.0, n) * f,
            rng.uniform(-3.0, 3.0, n) * f * p.L / (p.yaw_coefficient or p.L) / 10,
        ]
    )
    U[: n // 4, 1:] *= 0.05  # small torques: these fit
    return U


@pytest.mark.parametrize("name", list(VEHICLES))
def test_a_command_that_fits_is_left_alone(name):
    p = VEHICLES[name]
    U = np.array([[4 * 0.55 * p.f_max, 0.1 * p.f_max, -0.1 * p.f_max, 0.05 * p.f_max]])
    F = _rotors(p, U)
    assert F.min() >= p.f_min and F.max() <= p.f_max
    np.testing.assert_array_equal(yaw_last(U, p.f_min, p.f_max, p.unmix_t, p.mix_t), U)


@pytest.mark.parametrize("name", list(VEHICLES))
def test_roll_and_pitch_are_kept_and_the_yaw_is_given_up_just_enough(name):
    p = VEHICLES[name]
    room = p.f_max - p.f_min
    U = _random_commands(p, 400, seed=7)
    out = yaw_last(U, p.f_min, p.f_max, p.unmix_t, p.mix_t)
    tol = 1e-9 * p.f_max
    np.testing.assert_allclose(out[:, 1:3], U[:, 1:3], rtol=0, atol=tol)  # roll and pitch untouched
    grid = np.linspace(0.0, 1.0, 20001)
    scaled = 0
    for u, o in zip(U, out, strict=True):
        # the yaw share s kept, 0 ≤ s ≤ 1
        s = 1.0 if u[3] == 0 else o[3] / u[3]
        assert -1e-9 <= s <= 1 + 1e-9
        # the largest share whose spread fits, by brute force over the grid (independent of the kernel)
        F_rp = _rotors(p, np.array([[u[0], u[1], u[2], 0.0]]))[0]
        F_y = _rotors(p, np.array([[0.0, 0.0, 0.0, u[3]]]))[0]
        fits = grid[np.ptp(F_rp + grid[:, None] * F_y, axis=1) <= room]
        best = fits.max() if fits.size else 0.0
        assert s == pytest.approx(best, abs=1e-4)
        scaled += s < 1 - 1e-6
        # then the thrust moved as attitude priority moves it: the rotors in range wherever they can be
        np.testing.assert_allclose(o, attitude_priority(np.array([[*u[:3], s * u[3]]]), p.f_min, p.f_max,
                                   p.unmix_t, p.mix_t)[0], rtol=0, atol=tol)  # fmt: skip
        if _spread(F_rp) <= room:
            F = _rotors(p, o[None])[0]
            assert F.min() >= p.f_min - tol and F.max() <= p.f_max + tol
    assert scaled > 40  # the draw saturates the yaw often: the check is not vacuous


def test_the_crazyflie_keeps_its_roll_torque_where_attitude_priority_loses_it():
    """At hover thrust (0.0785 N a rotor), a roll torque that takes ±0.05 N on each side and a yaw torque
    that asks ±0.06 N on each rotor pair do not fit together in [0, 0.144] N. Attitude priority cannot
    shift them in (the spread is 0.22 N), so the simulator's per-rotor clip cuts roll and yaw alike;
    the yaw-last mixer delivers the roll torque whole and as much yaw as is left."""
    p = CF
    c = 1 / np.sqrt(2)
    hover = p.m * p.g / 4
    F_roll = np.array([-0.05, -0.05, 0.05, 0.05])  # rotors 3, 4 (left) up: positive roll ("x" numbering)
    F_yaw = np.array([-0.06, 0.06, -0.06, 0.06])  # rotors 2, 4 up: positive yaw
    F = hover + F_roll + F_yaw
    assert _spread(F) > p.f_max - p.f_min
    U = (F @ p.mix_t)[None]
    roll_asked = c * 0.05 * 4  # U2 = c·(−F1 − F2 + F3 + F4)
    assert U[0, 1] == pytest.approx(roll_asked)
    delivered = {}
    for name, mix in (("attitude_priority", attitude_priority), ("yaw_last", yaw_last)):
        U_applied, _ = saturate(mix(U, p.f_min, p.f_max, p.unmix_t, p.mix_t), p.f_min, p.f_max, p.unmix_t, p.mix_t)
        delivered[name] = U_applied[0]
    assert delivered["yaw_last"][1] == pytest.approx(roll_asked, rel=1e-12)
    assert delivered["attitude_priority"][1] < 0.9 * roll_asked
    # the yaw kept: the rotor range left by the roll, 0.144 − 2·0.05 = 0.044 N between the pairs' centres
    assert delivered["yaw_last"][3] == pytest.approx(U[0, 3] * (p.f_max - p.f_min - 0.1) / 0.12, rel=1e-9)
