"""The validation's constants, each with its reason (docs/validation.md, "Constants")."""

from __future__ import annotations

from dataclasses import dataclass, field

#: Mass (g) of the drones whose sysid file gives none: the dataset's own code (learning/training.py
#: of aerorobotics/neural-swarm, "small CF", m = 32) for ``defaultcf.txt``; a plain Crazyflie 2.1
#: (27 g) plus the uSD deck and markers. Checked on the data: alone in hover, Fa_z averages ≈ 0
#: with 32 g (tests/unit/test_neural_swarm.py), −5 g with 27 g.
DATASET_MASS_G = {"defaultcf.txt": 32.0}
#: The default vehicle of a drone by its sysid file: the plain Crazyflies are ``crazyflie21``.
DEFAULT_VEHICLE = {"defaultcf.txt": "crazyflie21"}
#: Calibration flights (session folder, experiment); every other flight is held out.
CALIBRATION = (("datacollection19_12_11_2019", "swap_small_small"), ("datacollection21_06_16_2020", "swap_ss"))


@dataclass(frozen=True)
class ValidationParams:
    """Tuned or chosen constants of the downwash validation (docs/validation.md gives each reason)."""

    #: The motor delay per 10-ms sample of the thrust (a drone's and its jet's): None, the one of its
    #: vehicle, α = DT / ``motor_tau`` (:func:`delay_alpha`: 0.16 for the Crazyflie's 62.5 ms, the
    #: dataset's own α in learning/utils.py ``Fa``); a number: that α for every drone.
    delay_alpha: float | None = None
    #: Centred moving average (samples) over the measured and every predicted Fa: the dataset's
    #: ``acc_smooth`` window (5 samples = 50 ms), against the accelerometer's vibration noise.
    smooth_window: int = 5
    #: A pass: the upper drone's centre comes within r_pass (m) horizontally of the lower drone's …
    r_pass: float = 0.10
    #: … and the pass's window is the stretch around it within r_window (m) (every model's force is
    #: < 1 % of its peak beyond 0.3 m at these depths).
    r_window: float = 0.30
    #: "Above": at least dz_min (m) higher (the drones' own heights are ~3 cm).
    dz_min: float = 0.10
    #: Vertical-separation bins (m) of the tables.
    dz_bins: tuple[float, ...] = (0.10, 0.25, 0.35, 0.45, 0.60, 0.80)
    #: Remove each log's free-air offset from its measured Fa_z (docs/validation.md, "The free-air offset").
    free_air_offset: bool = True
    #: Free air: the drone higher than this (m) and no other drone over it (within r_window
    #: horizontally and dz_min higher, the passes' "over").
    free_air_z_min: float = 0.2
    #: gym-pybullet-drones' empirical downwash (BaseAviary._downwash, cf2x.urdf): dw_coeff_1..3.
    gym_coeffs: tuple[float, float, float] = (2267.18, 0.16, -0.11)
    #: Wind (m/s, world frame) that carries the wake sideways: none in the lab.
    wind: tuple[float, float, float] = (0.0, 0.0, 0.0)
    #: Split names, in output order.
    splits: tuple[str, ...] = field(default=("calibration", "held_out"))


def delay_alpha(p: ValidationParams, motor_tau: float | None, dt: float, where: str) -> float:
    """The per-sample motor delay α of a drone (:attr:`ValidationParams.delay_alpha`): the fixed one, else
    dt / its vehicle's ``motor_tau`` (the Euler step of u' = (u_des − u)/τ, as the dataset identifies and
    applies it: systemid/plotMotorDelay.py integrates u' = λ (u_des − u) with Euler steps, λ = 16/s, and
    learning/utils.py filters with α = 0.16 per 10 ms); the simulator integrates the same τ exactly."""
    if p.delay_alpha is not None:
        return float(p.delay_alpha)
    if motor_tau is None:
        from ..errors import UserError

        raise UserError(f"{where}: the vehicle gives no motor_tau (s): the residual's motor delay is its rotor lag")
    return min(dt / motor_tau, 1.0)
