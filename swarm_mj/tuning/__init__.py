"""Gain tuning: a general Flower Pollination Algorithm optimiser (SPEC §6)."""

from .fpa import FPAResult, fpa, levy_steps, random_search

__all__ = ["FPAResult", "fpa", "levy_steps", "random_search"]
