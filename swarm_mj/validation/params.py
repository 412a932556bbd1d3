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

    #: The dataset's motor delay (learning/utils.py ``Fa``: α = 0.16 per 10-ms sample, τ ≈ 57 ms).
    delay_alpha: float = 0.16
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
    #: Hub (m²) of a lower Crazyflie that meets the jet: the 33 mm × 33 mm main board with the
    #: battery under it (the arms are thin and lie under the rotor discs).
    hub_area: float = 0.033 * 0.033
    #: Rotor layout of the Neural-Swarm drones: Crazyflies fly "x" (rotors at 45° to the body axes).
    rotor_layout: str = "x"
    #: gym-pybullet-drones' empirical downwash (BaseAviary._downwash, cf2x.urdf): dw_coeff_1..3.
    gym_coeffs: tuple[float, float, float] = (2267.18, 0.16, -0.11)
    #: Wind (m/s, world frame) that carries the wake sideways: none in the lab.
    wind: tuple[float, float, float] = (0.0, 0.0, 0.0)
    #: Split names, in output order.
    splits: tuple[str, ...] = field(default=("calibration", "held_out"))
