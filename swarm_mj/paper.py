"""The paper's figures in one place: its vehicle (Table 1), gains (Table 4), FPA settings
(Table 2) and the results it reports (step response, Table 5, formation settling), printed
beside ours. Everything else imports them from here; where we depart from a value, the
departure and its reason are in docs/interpretations.md.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Table 1: mass (kg), inertia (kg·m²), arm length (m), linear drag (N·s/m), gravity (m/s²).
TABLE1_VEHICLE: dict[str, float] = {
    "m": 0.486,
    "Ix": 0.0038,
    "Iy": 0.0038,
    "Iz": 0.0071,
    "L": 0.25,
    "Kx": 0.0056,
    "Ky": 0.0056,
    "Kz": 0.0064,
    "g": 9.81,
}

#: Table 4: backstepping gains α1..α12 (roll, pitch, yaw, x, y, z pairs).
TABLE4_GAINS = np.array(
    [4.4025, 9.3048, 6.4184, 5.0494, 7.6955, 2.2141, 4.8548, 7.0579, 4.4025, 6.6385, 6.1893, 3.5344]
)


@dataclass(frozen=True)
class FPASettings:
    """Flower pollination settings: N flowers, iterations, switch probability p, step size γ and the
    Lévy exponent λ of the global pollination."""

    population: int = 50
    iterations: int = 14
    p: float = 0.04
    gamma: float = 0.02
    levy_lambda: float = 1.5


#: Table 2's FPA settings.
TABLE2_FPA = FPASettings()

#: §5.1: the step response (overshoot %, settling s) per axis.
PAPER_STEP = {
    "x": {"overshoot_pct": 0.0, "settling_s": 1.5},
    "y": {"overshoot_pct": 0.0, "settling_s": 1.5},
    "z": {"overshoot_pct": 0.0, "settling_s": 1.0},
    "psi": {"overshoot_pct": 0.0, "settling_s": 1.0},
}

#: Table 5: RMSE (m, deg) of the leader, keyed by (trajectory, wind on).
PAPER_TABLE5 = {
    ("circle", False): {"x": 0.0156, "y": 0.0631, "roll_deg": 0.0397, "pitch_deg": 0.0688},
    ("circle", True): {"x": 0.0398, "y": 0.0689, "roll_deg": 0.1205, "pitch_deg": 0.1965},
    ("lemniscate", False): {"x": 0.0075, "y": 0.0041, "roll_deg": 0.0173, "pitch_deg": 0.0379},
    ("lemniscate", True): {"x": 0.0321, "y": 0.0249, "roll_deg": 0.1125, "pitch_deg": 0.1841},
}

#: §5.2: the formation settles in about 3 s.
PAPER_FORMATION_SETTLING_S = 3.0

#: Paper Table 3: run, initial ISE, final ISE, improvement (%).
PAPER_TABLE3 = [(1, 59.24, 52.92, 10.67), (2, 60.47, 51.84, 14.27), (3, 60.34, 45.15, 25.17), (5, 68.35, 44.12, 35.45)]
#: Paper Fig. 7(b): roll and pitch reach ±45° (the clip of the desired angles).
PAPER_STEP_MAX_ANGLE_DEG = 45.0
