"""Physics presets: ``paper`` (the paper's model, unchanged) and ``realistic`` (docs/aero.md).

A scenario selects one with ``[aero] model = "paper" | "realistic"`` and may override each
switch (``ground``, ``downwash``, ``ground_effect``, ``motor_tau``); the CLI's ``--aero NAME``
replaces the model and keeps the scenario's own switch overrides.

=================  =======  ===========  ================================================
switch             paper    realistic    effect
=================  =======  ===========  ================================================
ground             false    true         solid floor at z = 0, landing gear, starts at rest
downwash           false    true         turbulent-jet downwash between drones
ground_effect      false    true         Cheeseman–Bennett thrust gain near the floor
motor_tau          0        0.015 s      first-order rotor lag (0: ideal rotors)
=================  =======  ===========  ================================================
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

from ...errors import UserError
from ...table_fields import finite
from .constants import AIR_DENSITY, DISC_DRAG_COEFFICIENT, ROTOR_PLANE_Z, ROTOR_RADIUS  # noqa: F401 (re-exported)

AERO_MODELS = ("paper", "realistic")
_KEYS = {"model", "ground", "downwash", "ground_effect", "motor_tau"}

#: Motor time constant of the ``realistic`` preset (s).
REALISTIC_MOTOR_TAU = 0.015


@dataclass(frozen=True)
class AeroConfig:
    """Which aerodynamic effects the simulator adds to the paper's model (docs/aero.md)."""

    model: str = "paper"
    ground: bool = False
    downwash: bool = False
    ground_effect: bool = False
    motor_tau: float = 0.0  # s; 0: the rotors produce their command at once (the paper)

    @property
    def is_paper(self) -> bool:
        """True when nothing is added: the simulation is the paper's, bit for bit."""
        return not (self.ground or self.downwash or self.ground_effect or self.motor_tau > 0)

    def to_dict(self) -> dict[str, Any]:
        return {
            "model": self.model,
            "ground": self.ground,
            "downwash": self.downwash,
            "ground_effect": self.ground_effect,
            "motor_tau": self.motor_tau,
        }


PRESETS: dict[str, AeroConfig] = {
    "paper": AeroConfig(),
    "realistic": AeroConfig(
        model="realistic", ground=True, downwash=True, ground_effect=True, motor_tau=REALISTIC_MOTOR_TAU
    ),
}
PAPER = PRESETS["paper"]


def preset(name: str, where: str = "--aero") -> AeroConfig:
    """The named preset (``paper`` or ``realistic``)."""
    if not isinstance(name, str) or name not in PRESETS:
        raise UserError(f"unknown aero model {name!r}; choose one of {', '.join(AERO_MODELS)}", where=where)
    return PRESETS[name]


def parse_aero(table: Any, where: str = "aero") -> AeroConfig:
    """The ``[aero]`` table of a scenario: a model and optional switch overrides."""
    if table is None:
        return PAPER
    if not isinstance(table, dict):
        raise UserError("must be a table", where=where)
    unknown = set(table) - _KEYS
    if unknown:
        raise UserError(
            f"unknown key(s) {', '.join(sorted(unknown))}; allowed: {', '.join(sorted(_KEYS))}", where=where
        )
    cfg = preset(table.get("model", "paper"), where=f"{where}.model")
    kw: dict[str, Any] = {}
    for key in ("ground", "downwash", "ground_effect"):
        if key in table:
            v = table[key]
            if not isinstance(v, bool):
                raise UserError(f"must be true or false, got {v!r}", where=f"{where}.{key}")
            kw[key] = v
    if "motor_tau" in table:
        v = table["motor_tau"]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not finite(v) or v < 0:
            raise UserError(f"must be a time constant >= 0 s, got {v!r}", where=f"{where}.motor_tau")
        kw["motor_tau"] = float(v)
    return replace(cfg, **kw) if kw else cfg


def vehicle_lag(cfg: AeroConfig, table: Any, params) -> AeroConfig:  # noqa: ANN001 - params: QuadParams
    """``cfg`` with the vehicle's rotor time constant (``params.motor_tau``, docs/vehicles.md) as its
    lag where the preset has lag and the ``[aero]`` table does not set ``motor_tau`` itself;
    unchanged otherwise (the paper's drone gives none)."""
    own = isinstance(table, dict) and "motor_tau" in table
    tau = getattr(params, "motor_tau", None)
    if tau is None or own or cfg.motor_tau == 0:
        return cfg
    return replace(cfg, motor_tau=float(tau))


def with_aero(sc, model: str | None):
    """Scenario ``sc`` flown under preset ``model`` (None: unchanged), keeping its own switch
    overrides; the TOML document (``sc.raw``) is updated too, so that sweeps re-parse it alike."""
    if model is None:
        return sc
    preset(model)
    raw = dict(sc.raw) if isinstance(sc.raw, dict) else {}
    table = dict(raw.get("aero", {}) or {})
    table["model"] = model
    raw["aero"] = table
    return sc.with_overrides(aero=vehicle_lag(parse_aero(table, where="--aero"), table, sc.params), raw=raw)


def install(sim, cfg: AeroConfig) -> None:
    """Attach the force stages and the ground monitor that ``cfg`` asks for to ``sim``."""
    from .downwash import DownwashStage
    from .ground import GroundContacts
    from .ground_effect import GroundEffectStage

    # the rotors and the body of the simulated vehicle (docs/vehicles.md); the paper's drone gets the
    # stages' defaults (rotor radius 0.09 m, size scale 1)
    p = sim.params
    s = p.size_scale
    stages: list = []
    if cfg.downwash:
        stages.append(DownwashStage.for_vehicle(p))
    if cfg.ground_effect:
        stages.append(GroundEffectStage(rotor_radius=p.rotor_radius, rotor_z=ROTOR_PLANE_Z * s))
    for st in stages:
        sim.add_stage(st)  # after drag and wind (docs/design.md, "the step pipeline")
    if cfg.ground:
        sim.add_monitor(GroundContacts(crash_speed=CRASH_SPEED, crash_tilt_deg=CRASH_TILT_DEG))


#: A touchdown faster than this (m/s, speed of the centre of mass) is a crash.
CRASH_SPEED = 1.0
#: A ground contact with the body tilted more than this from upright (degrees) is a crash.
CRASH_TILT_DEG = 30.0
