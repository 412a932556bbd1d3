"""What a run flies: its vehicle and its gains, each chosen by one rule, written once here
(docs/vehicles.md, "The vehicle as a switch").

**The vehicle** is a scenario's ``[vehicle] model``, replaced by ``--vehicle NAME|FILE`` (``run``,
``video``, ``sweep``, ``stress``), by ``SwarmEnv(..., vehicle=)`` and the wrappers, or by
``Scenario.with_overrides(vehicle=...)``: a bundled vehicle's name, a vehicle file or a
:class:`~swarm_mj.vehicles.Vehicle`. Replacing it replaces the drone flown
(:func:`swarm_mj.scenario.vehicle_overrides`): its parameters, its mixer, its rotor lag where the
physics has lag and the scenario does not set its own, the start clearance its size asks for and,
unless the gains were chosen for the run or by the scenario, its gains.

**The gains** (:func:`choose_gains`): the ones given for the run (``--gains``, ``gains=``) > the
scenario's ``[controller] gains`` > the vehicle file's ``gains`` > Table 4. The summary names where
they came from (:data:`GAINS_ORIGINS`, :func:`gains_label`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from .control.backstepping import TABLE4_GAINS, load_gains
from .errors import UserError
from .physics.aero.presets import AeroConfig, preset, vehicle_lag
from .physics.params import QuadParams
from .resources import SCENARIOS_DIR
from .vehicles import Vehicle, bundled, load_vehicle

#: Where the gains flown came from (a run summary's ``gains.origin``), in the order of the rule:
#: the first that gives gains wins.
GAINS_ORIGINS = {
    "option": "given for the run",
    "scenario": "the scenario's",
    "vehicle": "the vehicle's",
    "default": "Table 4, the default",
}

#: What ``vehicle=`` takes: a bundled vehicle's name, a vehicle file or a Vehicle.
VehicleLike = str | Path | Vehicle


@dataclass(frozen=True)
class GainsChoice:
    """Gains chosen by :func:`choose_gains`: the (12,) or (n, 12) array, its source (``"table4"``,
    ``"inline"``, a file, or a caller's label) and its origin (a key of :data:`GAINS_ORIGINS`)."""

    gains: np.ndarray
    source: str
    origin: str


def choose_gains(
    *,
    option: tuple[np.ndarray, str] | None = None,
    scenario: tuple[np.ndarray, str] | None = None,
    vehicle: Path | None = None,
) -> GainsChoice:
    """The rule: ``option`` (gains given for the run, with their source) > ``scenario`` (its
    ``[controller] gains``) > ``vehicle`` (the vehicle file's gains file) > Table 4."""
    if option is not None:
        return GainsChoice(gains=option[0], source=option[1], origin="option")
    if scenario is not None:
        return GainsChoice(gains=scenario[0], source=scenario[1], origin="scenario")
    if vehicle is not None:
        return GainsChoice(gains=load_gains(vehicle), source=str(vehicle), origin="vehicle")
    return GainsChoice(gains=TABLE4_GAINS.copy(), source="table4", origin="default")


def resolve_vehicle(model: Any, base: Path, where: str) -> tuple[str, Vehicle, str | None]:
    """A vehicle as a scenario or a caller names it: (its label: the name or path as given, the
    :class:`~swarm_mj.vehicles.Vehicle`, the model a scenario document would name it by: a bundled name
    or an absolute path, None for a Vehicle built without a file). A path is relative to ``base``;
    :class:`UserError` naming ``where`` for anything else."""
    if isinstance(model, Vehicle):
        p = Path(model.path) if model.path else None
        return model.name, model, str(p.resolve()) if p is not None and p.is_file() else None
    if isinstance(model, Path):
        model = str(model)
    if not isinstance(model, str) or not model:
        raise UserError(
            f"must be a bundled vehicle ({', '.join(bundled())}) or a vehicle file, got {model!r}", where=where
        )
    if model in bundled():
        return model, load_vehicle(model), model
    path = Path(model) if Path(model).is_absolute() else base / model
    if not path.is_file():
        raise UserError(
            f"unknown vehicle {model!r}: neither a bundled vehicle ({', '.join(bundled())}) nor a file", where=where
        )
    return model, load_vehicle(path), str(path.resolve())


def _lag_on(aero: AeroConfig, params: QuadParams) -> float:
    """The rotor lag the physics ``aero`` gives a vehicle whose scenario sets none of its own: the
    preset's, replaced by the vehicle's time constant where the preset has lag."""
    own = preset(aero.model, where="aero.model").motor_tau
    return vehicle_lag(replace(aero, motor_tau=own), None, params).motor_tau


def relag(aero: AeroConfig, old: QuadParams, new: QuadParams) -> AeroConfig:
    """``aero`` of a scenario whose vehicle goes from ``old`` to ``new``: the lag follows the vehicle
    unless the scenario set its own (a lag other than the one ``old`` gave)."""
    if aero.motor_tau != _lag_on(aero, old):
        return aero
    return replace(aero, motor_tau=_lag_on(aero, new))


def display_path(path: str | Path) -> str:
    """A file as a summary names it: ``scenarios/...`` for a bundled one, relative to the working folder
    where it lies inside it, else as it is."""
    p = Path(path)
    try:
        rp = p.resolve()
    except OSError:
        return str(path)
    for root, prefix in ((SCENARIOS_DIR.resolve(), "scenarios"), (Path.cwd().resolve(), "")):
        if rp.is_relative_to(root):
            rel = rp.relative_to(root)
            return str(Path(prefix) / rel) if prefix else str(rel)
    return str(path)


def gains_name(source: str) -> str:
    """The gains' source as a summary names it: ``Table 4``, ``inline``, or the file (:func:`display_path`)."""
    if source == "table4":
        return "Table 4"
    return display_path(source) if Path(source).is_file() else source


def gains_text(name: str, origin: str) -> str:
    """The gains as the summary's text gives them: what they are and whose (:data:`GAINS_ORIGINS`), e.g.
    ``scenarios/gains/crazyflie21_fpa_seed0.toml (the vehicle's)`` or ``Table 4 (the default)``."""
    if origin == "default":
        return "Table 4 (the default)"
    return f"{name} ({GAINS_ORIGINS.get(origin, origin)})"
