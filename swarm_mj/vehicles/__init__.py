"""Vehicles as data: a vehicle is a TOML file (docs/vehicles.md).

A vehicle file has at least ``mass`` (kg), ``arm_length`` (m, centre to motor) and ``rotor_radius``
(m) under these names; the bundled vehicles (``paper``, ``crazyflie21``) are such files in this folder.
:func:`load_vehicle` takes a bundled name or a path and returns a :class:`Vehicle`.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..errors import UserError

_HERE = Path(__file__).resolve().parent
#: The keys every vehicle file must have, with their units.
REQUIRED = {"mass": "kg", "arm_length": "m", "rotor_radius": "m"}


@dataclass(frozen=True)
class Vehicle:
    """One vehicle's parameters as its file gives them (SI units); ``extra`` holds the file's other keys."""

    name: str
    mass: float
    arm_length: float
    rotor_radius: float
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def rotor_span(self) -> float:
        """Centre to rotor tip: ``arm_length + rotor_radius`` (m), the vehicle's horizontal size."""
        return self.arm_length + self.rotor_radius


def bundled() -> list[str]:
    """The names of the bundled vehicles."""
    return sorted(p.stem for p in _HERE.glob("*.toml"))


def load_vehicle(name_or_path: str | Path) -> Vehicle:
    """The vehicle named ``name_or_path`` (a bundled name, or a path to a vehicle TOML file).

    Raises :class:`~swarm_mj.errors.UserError` naming the file and the key for a missing file, a
    TOML syntax error, a missing key or a non-positive value."""
    s = str(name_or_path)
    path = _HERE / f"{s}.toml" if s in bundled() else Path(s)
    if not path.is_file():
        raise UserError(f"unknown vehicle {s!r}: not a file; bundled vehicles: {', '.join(bundled())}")
    try:
        data = tomllib.loads(path.read_text())
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as e:
        raise UserError(f"{path}: cannot read the vehicle file: {e}") from None
    for key, unit in REQUIRED.items():
        v = data.get(key)
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v) or v <= 0:
            raise UserError(f"{path}: vehicle key {key!r} must be a positive number ({unit}), got {v!r}")
    name = data.get("name", path.stem)
    if not isinstance(name, str):
        raise UserError(f"{path}: vehicle key 'name' must be a string, got {name!r}")
    extra = {k: v for k, v in data.items() if k not in REQUIRED and k != "name"}
    return Vehicle(name, float(data["mass"]), float(data["arm_length"]), float(data["rotor_radius"]), extra)
