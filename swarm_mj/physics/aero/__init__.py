"""Aerodynamics beyond the paper's model: solid ground, downwash, ground effect, rotor lag (docs/aero.md).

Each aerodynamic force is a *force stage*: an object with ``name``, ``reset(sim)`` and
``apply(sim, force, torque)`` that ADDS its world-frame force (N, 3) [N] and torque (N, 3)
[N·m] at each drone's centre of mass for the coming physics step, reading only ``sim.pos``,
``vel``, ``quat``, ``omega``, ``ctrl``, ``rotor_thrust``, ``time``, ``n``, ``params``.
:func:`install` attaches the stages (and the ground-contact monitor) a preset asks for.
"""

from __future__ import annotations

from .presets import AERO_MODELS, PAPER, PRESETS, AeroConfig, install, parse_aero, preset, with_aero

__all__ = ["AERO_MODELS", "PAPER", "PRESETS", "AeroConfig", "install", "parse_aero", "preset", "with_aero"]
