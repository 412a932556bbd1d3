"""Exception types shared by every room of the package.

The CLI turns :class:`UserError` into one line on stderr and exit status 2, and
:class:`SimulationDiverged` or :class:`OutputError` into one line and exit status 1.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable


class SwarmError(Exception):
    """Base class of every error this package raises on purpose."""

    exit_code = 1


class UserError(SwarmError, ValueError):
    """A user mistake: bad scenario file, bad option, bad value. Exit status 2.

    ``where`` names the file (and field) so that the message is one clear line.
    """

    exit_code = 2

    def __init__(self, message: str, where: str | None = None) -> None:
        self.where = where
        super().__init__(f"{where}: {message}" if where else message)


#: Longest list of allowed keys an unknown-key message spells out (longer ones point to the docs).
_LIST_CHARS = 150


def unknown_key(key: str, allowed: Iterable[str], where: str | None = None, see: str | None = None) -> UserError:
    """The :class:`UserError` for an unknown key ``key`` of a table whose keys are ``allowed``: one short
    line with a "did you mean" where a key is close (:func:`difflib.get_close_matches`), else the allowed
    keys where they are few and ``see`` (where the docs list them, e.g. ``docs/vehicles.md``) otherwise."""
    keys = sorted(allowed)
    close = difflib.get_close_matches(key, keys, n=1)
    msg = f"unknown key {key!r}"
    if close:
        msg += f"; did you mean {close[0]!r}?"
    elif len(", ".join(keys)) <= _LIST_CHARS or see is None:
        shown = ", ".join(keys)
        if len(shown) > _LIST_CHARS:
            shown = shown[: shown.rfind(", ", 0, _LIST_CHARS)] + f", … ({len(keys)} keys)"
        msg += f"; allowed: {shown}"
    else:
        msg += f"; the {len(keys)} allowed keys are listed in {see}"
    return UserError(msg, where=where)


class SimulationDiverged(SwarmError, RuntimeError):
    """The physics produced NaN, a drone fell through the floor or flew away. Exit status 1."""

    exit_code = 1


class OutputError(SwarmError, OSError):
    """An output file could not be written (e.g. no space left on the device). Exit status 1."""

    exit_code = 1


class RenderError(SwarmError, RuntimeError):
    """Headless rendering is unavailable (no EGL). Exit status 1."""

    exit_code = 1
