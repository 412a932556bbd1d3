"""Vehicles as data: a vehicle is a TOML file (docs/vehicles.md, "The vehicle file").

:data:`KEYS` is every key a vehicle file may have, with its unit, its kind, whether it is needed and what
it means (docs/vehicles.md's table lists the same keys; a test compares them). :func:`load_vehicle` takes
a bundled name (``paper``, ``crazyflie21``: files in this folder) or a path and checks the whole file
before anything flies, as a scenario is checked: an unknown key is refused with a "did you mean", a
missing key is called missing, every value is checked against its kind, ``gains`` is resolved (a bundled
gains name, or a path relative to the vehicle file) and a vehicle whose rotors cannot hold it up with
margin (thrust-to-weight below :data:`MIN_THRUST_TO_WEIGHT`) is refused; each mistake is one
:class:`~swarm_mj.errors.UserError` that names the file once. :meth:`Vehicle.params` gives the
:class:`~swarm_mj.physics.params.QuadParams` the simulator and the controller use (it needs the keys
marked "to fly").
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..errors import UserError, unknown_key
from ..physics.params import DEFAULT_PARAMS, QuadParams
from ..resources import SCENARIOS_DIR
from ..table_fields import finite

_HERE = Path(__file__).resolve().parent
#: The bundled gains files a vehicle file's ``gains`` may name without a path (their file stems).
GAINS_DIR = SCENARIOS_DIR / "gains"
#: The mixers a vehicle file's ``mixer`` may name (what ``mixer = "auto"`` becomes on it).
MIXERS = ("clip", "attitude_priority", "yaw_last")
#: Least thrust-to-weight ratio 4·max_thrust / (mass·g) a vehicle file may give: hovering takes at most
#: 1/1.4 = 71 % of the rotors' thrust, so each rotor keeps 40 % of its hover thrust in hand to climb and to
#: steer, and the drone holds its height tilted up to acos(1/1.4) = 44° (docs/vehicles.md, "Thrust to weight").
MIN_THRUST_TO_WEIGHT = 1.4


@dataclass(frozen=True)
class Key:
    """One key of a vehicle file: a row of docs/vehicles.md's table, "The vehicle file"."""

    unit: str  # SI unit, "" for none
    kind: str | tuple[str, ...]  # a key of KINDS, or the strings the value may be
    need: str  # "always" (load_vehicle), "to fly" (Vehicle.params) or "no" with the default where absent
    doc: str  # what it means, one line


#: What a value of each kind must be (the words of the error message).
KINDS = {
    "positive": "a positive number",
    "nonnegative": "a number >= 0",
    "3 positive": "3 positive numbers",
    "3 nonnegative": "3 numbers >= 0",
    "string": "a non-empty string",
    "gains": "a bundled gains name or the path of a gains file",
}

#: Every key a vehicle file may have (one line each; docs/vehicles.md's table lists the same keys).
KEYS: dict[str, Key] = {
    "name": Key(unit="", kind="string", need="no (file stem)", doc="the vehicle's name"),
    "mass": Key(unit="kg", kind="positive", need="always", doc="take-off mass"),
    "arm_length": Key(unit="m", kind="positive", need="always", doc="centre of mass to motor axis (the paper's L)"),
    "rotor_radius": Key(unit="m", kind="positive", need="always", doc="propeller radius"),
    "inertia": Key(unit="kg·m²", kind="3 positive", need="to fly", doc="[Ix, Iy, Iz], principal"),
    "drag": Key(unit="N·s/m", kind="3 nonnegative", need="to fly", doc="[Kx, Ky, Kz], the linear drag of eq. (1)"),
    "max_thrust": Key(unit="N", kind="positive", need="to fly", doc="thrust of one rotor at full command"),
    "min_thrust": Key(unit="N", kind="nonnegative", need="no (0)", doc="least thrust of one rotor, below max_thrust"),
    "yaw_torque_coefficient": Key(unit="m", kind="positive", need="no", doc="κ = rotor drag torque / rotor thrust"),
    "collision_radius": Key(
        unit="m", kind="positive", need="no (arm_length)", doc="radius of the disc that touches other drones"
    ),
    "motor_tau": Key(unit="s", kind="positive", need="no", doc="rotor time constant: the lag under --aero realistic"),
    "downwash_gain": Key(unit="", kind="positive", need="no (1)", doc="gain on its jet's force on the drones below"),
    "gains": Key(unit="", kind="gains", need="no", doc="the gains tuned for it, flown where a scenario names none"),
    "mixer": Key(unit="", kind=MIXERS, need="no", doc='what a scenario\'s mixer = "auto" becomes on it'),
    "layout": Key(
        unit="", kind=("+", "x"), need='no ("+")', doc='rotor layout: "+" (on the body axes) or "x" (at 45°)'
    ),
    "hub_area": Key(unit="m²", kind="nonnegative", need="no", doc="the hub plate a jet from above meets"),
    "height": Key(unit="m", kind="positive", need="no", doc="height of the colliding body"),
}


def thrust_to_weight(mass: float, max_thrust: float) -> float:
    """4·max_thrust / (mass·g): the rotors' full thrust over the weight (g of Table 1, 9.81 m/s²)."""
    return 4.0 * max_thrust / (mass * DEFAULT_PARAMS.g)


def bundled_gains() -> list[str]:
    """The names of the bundled gains files (what a vehicle file's ``gains`` may give without a path)."""
    return sorted(p.stem for p in GAINS_DIR.glob("*.toml"))


def resolve_gains(value: str, vehicle_file: str | Path) -> Path:
    """The gains file a vehicle file's ``gains`` names: a bundled gains name (no folder, no suffix:
    :func:`bundled_gains`), an absolute path, or a path relative to the vehicle file's own folder (so
    that the file and its gains move together). :class:`UserError` naming the path looked at otherwise."""
    names = ", ".join(bundled_gains())
    p = Path(value)
    if len(p.parts) == 1 and not p.suffix:
        f = GAINS_DIR / f"{value}.toml"
        if not f.is_file():
            raise UserError(
                f"vehicle key 'gains': no bundled gains named {value!r} (bundled: {names})",
                where=str(vehicle_file),
            )
        return f.resolve()
    f = p if p.is_absolute() else Path(vehicle_file).parent / p
    if not f.is_file():
        raise UserError(
            f"vehicle key 'gains': no gains file at {f.resolve()} (a relative path is read from the vehicle "
            f"file's folder); give its path or a bundled name ({names})",
            where=str(vehicle_file),
        )
    return f.resolve()


def _is_number(v: Any) -> bool:
    return not isinstance(v, bool) and isinstance(v, int | float) and finite(v)


def check_value(key: str, v: Any, where: str) -> None:
    """``v`` is what :data:`KEYS` asks of ``key``; :class:`UserError` naming ``where`` (the file) otherwise."""
    spec = KEYS[key]
    kind = spec.kind
    if isinstance(kind, tuple):
        ok, want = isinstance(v, str) and v in kind, "one of " + ", ".join(map(repr, kind))
    elif kind in ("string", "gains"):
        ok, want = isinstance(v, str) and bool(v), KINDS[kind]
    elif kind in ("positive", "nonnegative"):
        ok, want = _is_number(v) and (v > 0 if kind == "positive" else v >= 0), KINDS[kind]
    else:
        nums = isinstance(v, list) and len(v) == 3 and all(_is_number(x) for x in v)
        ok, want = nums and all(x > 0 if kind == "3 positive" else x >= 0 for x in v), KINDS[kind]
    if not ok:
        unit = f" ({spec.unit})" if spec.unit else ""
        raise UserError(f"vehicle key {key!r} must be {want}{unit}, got {v!r}", where=where)


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
        if isinstance(v, bool) or not isinstance(v, int | float) or not finite(v) or v <= 0:
            raise UserError(f"vehicle key {key!r} must be a positive number ({unit}), got {v!r}", where=self.path)
        return float(v)

    def _triple(self, key: str, unit: str) -> list[float]:
        v = self.extra.get(key)
        if v is None:
            raise UserError(f"missing key {key!r} ({unit}): needed to fly it", where=self.path)
        check_value(key, v, self.path)
        return [float(x) for x in v]

    def params(self) -> QuadParams:
        """The :class:`~swarm_mj.physics.params.QuadParams` of this vehicle (module docstring for the keys).

        Raises :class:`~swarm_mj.errors.UserError` naming the file and the key when a key needed to
        fly is missing (:data:`KEYS`, "to fly") or out of range."""
        Ix, Iy, Iz = self._triple("inertia", "kg·m²")
        Kx, Ky, Kz = self._triple("drag", "N·s/m")
        f_max = self._number("max_thrust", "N per rotor")
        if f_max is None:
            raise UserError("missing key 'max_thrust' (N): needed to fly it", where=self.path)
        f_min = self.extra.get("min_thrust", 0.0)
        if isinstance(f_min, bool) or not isinstance(f_min, int | float) or not 0 <= f_min < f_max:
            raise UserError(f"vehicle key 'min_thrust' must be >= 0 and < max_thrust, got {f_min!r}", where=self.path)
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
            if e.where:  # already names the file
                raise
            raise UserError(str(e), where=self.path) from None

    @property
    def gains_file(self) -> Path | None:
        """The gains tuned for this vehicle (the file's ``gains``: a gains file written by ``swarm-mj tune
        --vehicle``, by bundled name or by path, :func:`resolve_gains`), or None."""
        g = self.extra.get("gains")
        if g is None:
            return None
        check_value("gains", g, self.path)
        return resolve_gains(g, self.path)

    @property
    def mixer(self) -> str | None:
        """The mixer ``mixer = "auto"`` resolves to on this vehicle (the file's ``mixer``), or None."""
        v = self.extra.get("mixer")
        if v is not None:
            check_value("mixer", v, self.path)
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
        if isinstance(v, bool) or not isinstance(v, int | float) or not finite(v) or v < 0:
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
    """The vehicle named ``name_or_path`` (a bundled name, or a path to a vehicle TOML file), its whole
    file checked (module docstring).

    Raises :class:`~swarm_mj.errors.UserError` naming the file for a missing file, a TOML syntax error,
    an unknown key, a missing key, a value of the wrong kind, a ``gains`` file that is not there, or a
    thrust-to-weight below :data:`MIN_THRUST_TO_WEIGHT`."""
    s = str(name_or_path)
    path = _HERE / f"{s}.toml" if s in bundled() else Path(s)
    if not path.is_file():
        raise UserError(f"unknown vehicle {s!r}: not a file; bundled vehicles: {', '.join(bundled())}")
    where = str(path)
    try:
        data = tomllib.loads(path.read_text())
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as e:
        raise UserError(f"cannot read the vehicle file: {e}", where=where) from None
    for key in data:
        if key not in KEYS:
            raise unknown_key(key, KEYS, where=where, see='docs/vehicles.md, "The vehicle file"')
    for key, spec in KEYS.items():
        if spec.need == "always" and key not in data:
            raise UserError(f"missing key {key!r} ({spec.unit}): {spec.doc}", where=where)
    for key, v in data.items():
        check_value(key, v, where)
    if "max_thrust" in data:
        f_max, f_min = data["max_thrust"], data.get("min_thrust", 0.0)
        if f_min >= f_max:
            raise UserError(
                f"vehicle key 'min_thrust' must be below max_thrust ({f_max:g} N), got {f_min!r}", where=where
            )
        tw = thrust_to_weight(data["mass"], f_max)
        if tw < MIN_THRUST_TO_WEIGHT:
            shown = f"{tw:.2f}" if round(tw, 2) < MIN_THRUST_TO_WEIGHT else f"{tw:.4f}"
            raise UserError(
                f"thrust-to-weight {shown} (4 × max_thrust {f_max:g} N over mass {data['mass']:g} kg × g) is below "
                f"the minimum {MIN_THRUST_TO_WEIGHT:g}: the drone cannot hover with margin",
                where=where,
            )
    if "gains" in data:
        resolve_gains(data["gains"], path)
    return Vehicle(
        name=data.get("name", path.stem),
        mass=float(data["mass"]),
        arm_length=float(data["arm_length"]),
        rotor_radius=float(data["rotor_radius"]),
        extra={k: v for k, v in data.items() if k not in ("name", "mass", "arm_length", "rotor_radius")},
        path=where,
    )
