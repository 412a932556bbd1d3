"""Where the bundled assets and scenarios live (works from a checkout and an install)."""

from __future__ import annotations

from pathlib import Path

_PKG = Path(__file__).resolve().parent


def _first_existing(*candidates: Path) -> Path:
    for c in candidates:
        if c.exists():
            return c
    return candidates[0]


ASSETS_DIR: Path = _first_existing(_PKG / "assets", _PKG.parent / "assets")
SCENARIOS_DIR: Path = _first_existing(_PKG / "scenarios", _PKG.parent / "scenarios")
QUADROTOR_XML: Path = ASSETS_DIR / "quadrotor.xml"
