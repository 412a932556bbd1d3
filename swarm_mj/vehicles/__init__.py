"""Vehicles as data: a vehicle is a TOML file (docs/vehicles.md).

A vehicle file has at least ``mass`` (kg), ``arm_length`` (m, centre to motor) and ``rotor_radius``
(m) under these names; the bundled vehicles (``paper``, ``crazyflie21``) are such files in this folder.
:func:`load_vehicle` takes a bundled name or a path and returns a :class:`Vehicle`. To be flown, a
vehicle also needs ``inertia`` ([Ix, Iy, Iz] kg·m²), ``drag`` ([Kx, Ky, Kz] N·s/m) and ``max_thrust``
(N per rotor); it may give ``min_thrust`` (N, default 0), ``yaw_torque_coefficient`` (m: the
rotors' drag-torque-to-thrust ratio; absent: the paper's yaw torque L·U4), ``collision_radius`` (m,
default ``arm_length``) and ``motor_tau`` (s, the rotor time constant: the lag under ``--aero
realistic`` and of ``swarm-mj tune --vehicle``; absent: the preset's 15 ms), ``downwash_gain`` (the
gain on its jet's force, fitted by ``swarm-mj validate downwash``; absent: 1), ``gains`` (the gains
file tuned for it, relative to the vehicle file; ``swarm-mj stress --vehicle`` flies them) and ``mixer``
(what a scenario's ``mixer = "auto"`` resolves to on this vehicle: ``"clip"`` or ``"attitude_priority"``,
e.g. where its own flight stack desaturates with attitude priority; absent: the rule of
:attr:`swarm_mj.scenario.Scenario.attitude_priority_on`).
:meth:`Vehicle.params` gives the :class:`~swarm_mj.physics.params.QuadParams` the simulator and the controller use.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..errors import UserError
from ..physics.params import QuadParams

_HERE = Path(__file__).resolve().parent
#: The keys every vehicle file must have, with their units.
REQUIRED = {"mass": "kg", "arm_length": "m", "rotor_radius": "m"}
#: The mixers a vehicle file's ``mixer`` may name (what ``mixer = "auto"`` becomes on it).
MIXERS = ("clip", "attitude_priority")


@dataclass(frozen=True)
class Vehicle:
    """One vehicle's parameters as its file gives them (SI units); ``extra`` holds the file's other keys."""

    name: str
    mass: float
    arm_length: float
    rotor_radius: float
    extra: dict[str, Any] = field(default_factory=dict)
    path: str = ""

    def _number(self, key: str, unit: str, default: float | None = None) -> float | None:
        v = self.extra.get(key, default)
        if v is None:
            return None
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v) or v <= 0:
            raise UserError(f"{self.path}: vehicle key {key!r} must be a positive number ({unit}), got {v!r}")
        return float(v)

    def _triple(self, key: str, unit: str, positive: bool) -> list[float]:
        v = self.extra.get(key)
        if v is None:
            raise UserError(f"{self.path}: vehicle key {key!r} is needed to fly it: 3 numbers ({unit})")
        ok = (
            isinstance(v, list)
            and len(v) == 3
            and all(not isinstance(x, bool) and isinstance(x, int | float) and math.isfinite(x) for x in v)
        )
        if not ok or any((x <= 0) if positive else (x < 0) for x in v):
            need = "positive" if positive else ">= 0"
            raise UserError(f"{self.path}: vehicle key {key!r} must be 3 {need} numbers ({unit}), got {v!r}")
        return [float(x) for x in v]

    def params(self) -> QuadParams:
        """The :class:`~swarm_mj.physics.params.QuadParams` of this vehicle (module docstring for the keys).

        Raises :class:`~swarm_mj.errors.UserError` naming the file and the key when a key needed to
        fly is missing or out of range."""
        Ix, Iy, Iz = self._triple("inertia", "kg·m²", True)
        Kx, Ky, Kz = self._triple("drag", "N·s/m", False)
        f_max = self._number("max_thrust", "N per rotor")
        if f_max is None:
            raise UserError(f"{self.path}: vehicle key 'max_thrust' is needed to fly it (N per rotor)")
        f_min = self.extra.get("min_thrust", 0.0)
        if isinstance(f_min, bool) or not isinstance(f_min, int | float) or not 0 <= f_min < f_max:
            raise UserError(f"{self.path}: vehicle key 'min_thrust' must be >= 0 and < max_thrust, got {f_min!r}")
        try:
            return QuadParams(
                m=self.mass,
                Ix=Ix,
                Iy=Iy,
                Iz=Iz,
                L=self.arm_length,
                Kx=Kx,
                Ky=Ky,
                Kz=Kz,
                f_min=float(f_min),
                f_max=f_max,
                rotor_radius=self.rotor_radius,
                collision_radius=self._number("collision_radius", "m"),
                yaw_coefficient=self._number("yaw_torque_coefficient", "m"),
                motor_tau=self.motor_tau,
                downwash_gain=self.downwash_gain,
                layout=self.layout,
                hub_area=self.hub_area,
                height=self._number("height", "m"),
            )
        except UserError as e:
            raise UserError(f"{self.path}: {e}") from None

    @property
    def gains_file(self) -> Path | None:
        """The gains tuned for this vehicle (the file's ``gains``, a gains file written by ``swarm-mj tune
        --vehicle``, relative to the vehicle file), or None; ``swarm-mj stress --vehicle`` flies them."""
        g = self.extra.get("gains")
        if g is None:
            return None
        p = Path(self.path).parent / g if isinstance(g, str) else None
        if p is None or not p.is_file():
            raise UserError(f"{self.path}: vehicle key 'gains' must name a gains file, got {g!r}")
        return p.resolve()

    @property
    def mixer(self) -> str | None:
        """The mixer ``mixer = "auto"`` resolves to on this vehicle (the file's ``mixer``), or None."""
        v = self.extra.get("mixer")
        if v is not None and v not in MIXERS:
            raise UserError(f"{self.path}: vehicle key 'mixer' must be one of {', '.join(MIXERS)}, got {v!r}")
        return v

    @property
    def motor_tau(self) -> float | None:
        """The rotor time constant the file gives (s), or None."""
        return self._number("motor_tau", "s")

    @property
    def downwash_gain(self) -> float:
        """Gain on the jet model's force on the drones below this one (the file's ``downwash_gain``,
        1 where it gives none): fitted on the calibration flights of ``swarm-mj validate downwash``
        only (docs/validation.md, "Calibration"); the simulator's downwash stage uses the same number."""
        g = self._number("downwash_gain", "dimensionless", 1.0)
        assert g is not None
        return g

    @property
    def layout(self) -> str:
        """The rotor layout (the file's ``layout``): ``"+"`` (default: rotors on the body axes, the
        paper's) or ``"x"`` (rotors at 45°, the Crazyflie's; docs/vehicles.md)."""
        from ..physics.mixing import LAYOUTS

        v = self.extra.get("layout", "+")
        if v not in LAYOUTS:
            choices = ", ".join(map(repr, LAYOUTS))
            raise UserError(f"{self.path}: vehicle key 'layout' must be one of {choices}, got {v!r}")
        return str(v)

    @property
    def hub_area(self) -> float | None:
        """The hub plate a jet from above meets (the file's ``hub_area``, m², >= 0), or None: the paper
        drone's hub scaled to the arm (``QuadParams.body_area``)."""
        v = self.extra.get("hub_area")
        if v is None:
            return None
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v) or v < 0:
            raise UserError(f"{self.path}: vehicle key 'hub_area' must be a number >= 0 (m²), got {v!r}")
        return float(v)

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
    return Vehicle(name, float(data["mass"]), float(data["arm_length"]), float(data["rotor_radius"]), extra, str(path))
