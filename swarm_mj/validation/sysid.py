"""The Neural-Swarm system identification and the measured residual force Fa (docs/validation.md, "Method").

Thrust model of one rotor (the dataset's sysid files, ``C_ij`` lines), in grams-force:

    f(p, v) = C_00 + C_10 p + C_01 v + C_20 p² + C_11 v p,   p = PWM / 65536,  v = V_bat / 4.2 V

Thrust T = Σ_k f(p_k, v) (four rotors), delayed as the dataset does (first-order filter
T_d[i+1] = (1 − α) T_d[i] + α T[i], α = 0.16 per 10-ms sample), and the residual (their ``fa_delay``):

    Fa = m a_w − T_d R e3,      a_w = the logged world-frame acceleration *with* gravity

(m a_w = m (a + g e3)): Fa is what the rotors' thrust and gravity leave unexplained, e.g. downwash.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import UserError
from .flight import DroneLog, rotation_z_axis

#: Standard gravity as the dataset uses it (m/s²): grams-force ↔ newtons.
G = 9.81
#: Battery-voltage normalisation of the thrust model's v (V): the dataset's system_id.py.
VBAT_SCALE = 4.2
_COEF = re.compile(r"^\s*(C_(?:00|10|01|20|11))\s*=\s*([-+0-9.eE]+)\s*$")
_MASS = re.compile(r"^\s*mass\s*:\s*([0-9.]+)\s*g\s*$", re.IGNORECASE)
_ASSIGN = re.compile(r"((?:CF\d+\s*,\s*)*CF\d+)\s*:[^\n]*?\buse\s+([A-Za-z0-9_]+)(?:\.txt)?", re.IGNORECASE)


@dataclass(frozen=True)
class ThrustModel:
    """One rotor's thrust (gf) from its normalised PWM and the normalised battery voltage (module
    docstring), and the vehicle's mass (g) where the file gives it."""

    source: str
    c00: float
    c10: float
    c01: float
    c20: float
    c11: float
    mass_g: float | None = None

    def rotor_thrust_g(self, p: np.ndarray, v: np.ndarray) -> np.ndarray:
        """f(p, v) (gf) for p = PWM/65536 and v = V_bat / 4.2 V (broadcast)."""
        return self.c00 + self.c10 * p + self.c01 * v + self.c20 * p * p + self.c11 * v * p


def read_thrust_model(path: Path) -> ThrustModel:
    """Parse a sysid file (defaultcf.txt, parrot_frame.txt): its first C_00..C_11 block (the thrust
    fit; the d.. and e.. blocks are the inverse and the max-thrust fits) and a ``mass: NNg`` line."""
    try:
        text = path.read_text()
    except OSError as e:
        raise UserError(f"{path}: cannot read the system-identification file: {e.strerror or e}") from None
    coef: dict[str, float] = {}
    mass = None
    for line in text.splitlines():
        m = _COEF.match(line)
        if m and m[1] not in coef:
            coef[m[1]] = float(m[2])
        mm = _MASS.match(line)
        if mm:
            mass = float(mm[1])
    missing = [k for k in ("C_00", "C_10", "C_01", "C_20", "C_11") if k not in coef]
    if missing:
        raise UserError(f"{path}: not a thrust model: no {', '.join(missing)}")
    return ThrustModel(
        source=path.name,
        c00=coef["C_00"],
        c10=coef["C_10"],
        c01=coef["C_01"],
        c20=coef["C_20"],
        c11=coef["C_11"],
        mass_g=mass,
    )


def readme_assignments(session: Path) -> dict[str, str]:
    """{drone id: sysid file name} as the session's readme.txt assigns them ("CF50, CF51: ... use
    defaultcf.txt for system id"); {} where there is no readme."""
    p = session / "readme.txt"
    if not p.is_file():
        return {}
    out: dict[str, str] = {}
    for m in _ASSIGN.finditer(p.read_text(errors="replace")):
        for d in re.findall(r"CF\d+", m[1], re.IGNORECASE):
            out.setdefault(d.lower(), m[2] + ".txt")
    return out


def thrust_g(model: ThrustModel, log: DroneLog) -> np.ndarray:
    """Total thrust T (gf) of the four rotors from the log's PWM and battery voltage."""
    v = (log.vbat / VBAT_SCALE)[:, None]
    return np.sum(model.rotor_thrust_g(log.pwm, v), axis=1)


def motor_delay(x: np.ndarray, alpha: float) -> np.ndarray:
    """First-order delay y[0] = x[0], y[i+1] = (1 − α) y[i] + α x[i] (the dataset's motor delay)."""
    if alpha >= 1.0:
        return np.asarray(x, float).copy()
    y = np.empty(len(x))
    y[0] = x[0]
    for i in range(len(x) - 1):
        y[i + 1] = (1.0 - alpha) * y[i] + alpha * x[i]
    return y


def residual_force_g(log: DroneLog, model: ThrustModel, mass_g: float, delay_alpha: float) -> np.ndarray:
    """(k, 3) Fa = m a_w − T_d R e3 in grams-force (module docstring), the log on a uniform grid."""
    t = motor_delay(thrust_g(model, log), delay_alpha)
    return mass_g * log.acc / G - t[:, None] * rotation_z_axis(log.quat)
