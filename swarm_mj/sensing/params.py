"""The sensing model's parameters (docs/sensing.md): one frozen record, its presets and the
``[sensing]`` table's parser.

:class:`SensingParams` is built by keyword; every field has a unit, a range and a reason in its
metadata (:data:`FIELDS` reads them), and a value out of range is one
:class:`~swarm_mj.errors.UserError` line naming the key. A field left out takes the value of the
record's ``preset`` (``perfect`` unless named), so ``SensingParams(preset="mocap", latency_s=0.05)``
is the ``mocap`` preset with a longer latency. :func:`parse_sensing_table` validates a scenario's
``[sensing]`` table (exactly the keys of the record) into it, in the style of ``scenario.py``'s errors.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from typing import Any

from ..errors import UserError
from ..starts import MAX_RANGE_M
from ..table_fields import finite


class _FromPreset(float):
    """The default of a field left out of the constructor (one object, told apart by identity)."""

    def __repr__(self) -> str:
        return "FROM_PRESET"


#: A field left out of the constructor: it takes the preset's value. A NaN given is refused.
FROM_PRESET: float = _FromPreset("nan")


def _f(unit: str, why: str, lo: float, hi: float, *, open_lo: bool = False, open_hi: bool = False):
    """A record field: unit, one-line reason and admissible range (``lo`` ≤ v ≤ ``hi``, each end
    open where asked); the default is the preset's value (:data:`FROM_PRESET`)."""
    meta = {"unit": unit, "why": why, "lo": lo, "hi": hi, "open_lo": open_lo, "open_hi": open_hi}
    return field(default=FROM_PRESET, metadata=meta)


#: The presets: every numeric field's value (sources in docs/sensing.md, "The presets").
PRESETS: dict[str, dict[str, float | None]] = {
    "perfect": {
        "position_noise_m": 0.0,
        "velocity_noise_mps": 0.0,
        "rate_hz": None,
        "latency_s": 0.0,
        "packet_loss": 0.0,
        "range_m": math.inf,
        "own_position_noise_m": 0.0,
        "own_velocity_noise_mps": 0.0,
    },
    "mocap": {
        "position_noise_m": 0.0023,
        "velocity_noise_mps": 0.011,
        "rate_hz": 100.0,
        "latency_s": 0.026,
        "packet_loss": 0.13,
        "range_m": math.inf,
        "own_position_noise_m": 0.0,
        "own_velocity_noise_mps": 0.0,
    },
    "uwb": {
        "position_noise_m": 0.10,
        "velocity_noise_mps": 0.10,
        "rate_hz": 10.0,
        "latency_s": 0.010,
        "packet_loss": 0.13,
        "range_m": math.inf,
        "own_position_noise_m": 0.0,
        "own_velocity_noise_mps": 0.0,
    },
}


@dataclass(frozen=True)
class SensingParams:
    """What each drone knows of the others and of itself (units, ranges, reasons: each field's
    metadata and docs/sensing.md). Velocities are broadcast, each with its own noise (not
    differenced from received positions)."""

    preset: str = "perfect"
    position_noise_m: float = _f("m", "σ per axis of the position a sender broadcasts (Gaussian)", 0.0, 10.0)
    velocity_noise_mps: float = _f("m/s", "σ per axis of the velocity a sender broadcasts (Gaussian)", 0.0, 10.0)
    rate_hz: float | None = _f(
        "Hz", "broadcasts of each sender per second (None or 0: every control period)", 0.0, 10000.0
    )
    latency_s: float = _f("s", "from a broadcast to its delivery (at the first control tick at or after)", 0.0, 2.0)
    packet_loss: float = _f(
        "",
        "probability that one broadcast from a sender to one receiver is lost (per pair, independent)",
        0.0,
        1.0,
        open_hi=True,
    )
    range_m: float = _f(
        "m",
        "a copy reaches a receiver closer than this (3D, true distance at send time); inf: no limit",
        0.0,
        math.inf,
        open_lo=True,
    )
    own_position_noise_m: float = _f("m", "σ per axis of each drone's own position for its controller", 0.0, 10.0)
    own_velocity_noise_mps: float = _f("m/s", "σ per axis of each drone's own velocity for its controller", 0.0, 10.0)

    def __post_init__(self) -> None:
        if not isinstance(self.preset, str) or self.preset not in PRESETS:
            raise UserError(f"unknown preset {self.preset!r}; choose one of {', '.join(PRESETS)}", where="preset")
        base = PRESETS[self.preset]
        for f in fields(self):
            if f.name == "preset":
                continue
            v = getattr(self, f.name)
            if v is FROM_PRESET:  # left out: the preset's value
                v = base[f.name]
            v = _checked(f.name, v, dict(f.metadata))
            object.__setattr__(self, f.name, v)

    @property
    def every_period(self) -> bool:
        """Each sender broadcasts every control period (``rate_hz`` None or 0)."""
        return self.rate_hz is None

    def table(self) -> dict[str, Any]:
        """The record as a ``[sensing]`` table (``rate_hz`` None written as 0; ``range_m`` inf left out)."""
        out: dict[str, Any] = {}
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name == "rate_hz" and v is None:
                v = 0.0
            if f.name == "range_m" and math.isinf(v):
                continue
            out[f.name] = v
        return out


#: Each numeric field: its unit, reason and range, as the record's metadata says.
FIELDS: dict[str, dict[str, Any]] = {f.name: dict(f.metadata) for f in fields(SensingParams) if f.name != "preset"}

#: The keys of a ``[sensing]`` table: exactly the record's fields.
TABLE_KEYS: tuple[str, ...] = tuple(f.name for f in fields(SensingParams))


def _range_text(meta: dict[str, Any]) -> str:
    lo = ("> " if meta["open_lo"] else ">= ") + f"{meta['lo']:g}"
    hi = ("< " if meta["open_hi"] else "<= ") + f"{meta['hi']:g}"
    return f"{lo} and {hi}"


def _checked(key: str, v: Any, meta: dict[str, Any], where: str | None = None) -> float | None:
    """``v`` as a float in the field's range (``rate_hz``: None or 0 → None); UserError naming the key."""
    w = where or key
    if key == "rate_hz" and v is None:
        return None
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise UserError(f"must be a number ({meta['unit'] or 'a probability'}), got {v!r}", where=w)
    if not finite(v) and not (key == "range_m" and v == math.inf):  # range_m = inf: no limit
        raise UserError(f"must be finite, got {v!r}", where=w)
    x = float(v)
    if key == "range_m" and MAX_RANGE_M < x < math.inf:  # the rules square it (overflow); the world is 1 km
        raise UserError(f"must be <= {MAX_RANGE_M:g} m, or inf (no limit), got {v!r}", where=w)
    lo_bad = x <= meta["lo"] if meta["open_lo"] else x < meta["lo"]
    hi_bad = x >= meta["hi"] if meta["open_hi"] else x > meta["hi"]
    if lo_bad or hi_bad:
        unit = f" {meta['unit']}" if meta["unit"] else ""
        raise UserError(f"must be {_range_text(meta)}{unit}, got {v!r}", where=w)
    if key == "rate_hz" and x == 0.0:
        return None
    return x


def sensing_preset(name: str) -> SensingParams:
    """The named preset (:class:`UserError` naming ``preset`` for an unknown name)."""
    return SensingParams(preset=name)


def parse_sensing_table(
    table: Any, where: str = "sensing", formation_sensing_range: float | None = None
) -> SensingParams:
    """A scenario's ``[sensing]`` table (a dict with exactly :data:`TABLE_KEYS`' keys, any left out)
    validated into :class:`SensingParams`: one :class:`UserError` line naming ``where.key`` otherwise.

    ``formation_sensing_range``: the scenario's ``[formation] sensing_range`` *when the file sets it*
    (its alias for ``range_m``): it becomes ``range_m``; both set is a mistake."""
    if not isinstance(table, dict):
        raise UserError("must be a table", where=where)
    unknown = set(table) - set(TABLE_KEYS)
    if unknown:
        raise UserError(
            f"unknown key(s) {', '.join(sorted(unknown))}; allowed: {', '.join(sorted(TABLE_KEYS))}", where=where
        )
    preset = table.get("preset", "perfect")
    if not isinstance(preset, str) or preset not in PRESETS:
        raise UserError(f"unknown preset {preset!r}; choose one of {', '.join(PRESETS)}", where=f"{where}.preset")
    values: dict[str, Any] = {}
    for key, v in table.items():
        if key != "preset":
            values[key] = _checked(key, v, FIELDS[key], where=f"{where}.{key}")
            if key == "rate_hz" and values[key] is None:  # 0 written: every period (None would read as "left out")
                values[key] = 0.0
    if formation_sensing_range is not None:
        if "range_m" in table:
            raise UserError("set range_m or its alias [formation] sensing_range, not both", where=f"{where}.range_m")
        values["range_m"] = _checked("range_m", formation_sensing_range, FIELDS["range_m"], "formation.sensing_range")
    return SensingParams(preset=preset, **values)
