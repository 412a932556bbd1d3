"""Exception types shared by every room of the package.

The CLI turns :class:`UserError` into one line on stderr and exit status 2, and
:class:`SimulationDiverged` or :class:`OutputError` into one line and exit status 1.
"""

from __future__ import annotations


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


class SimulationDiverged(SwarmError, RuntimeError):
    """The physics produced NaN, a drone fell through the floor or flew away. Exit status 1."""

    exit_code = 1


class OutputError(SwarmError, OSError):
    """An output file could not be written (e.g. no space left on the device). Exit status 1."""

    exit_code = 1


class RenderError(SwarmError, RuntimeError):
    """Headless rendering is unavailable (no EGL). Exit status 1."""

    exit_code = 1
