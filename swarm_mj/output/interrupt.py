"""Ctrl-C as a request, not an exception (``swarm-mj run``; docs/design.md, "the step pipeline").

A KeyboardInterrupt raised wherever the interpreter happens to be can land inside a compiled
kernel (it surfaces as a SystemError and the run is lost) or half-way through a C extension's
import. While a :class:`CooperativeInterrupt` is active, SIGINT only sets :attr:`requested`;
the run loop checks it once per control period and stops there, with the log of what ran.
This module imports nothing heavy, so that a command can enter it before it loads anything.
"""

from __future__ import annotations

import signal
import threading
from typing import Any


class CooperativeInterrupt:
    """While active (main thread, SIGINT at Python's default handler), SIGINT sets ``requested``
    instead of raising KeyboardInterrupt; the previous handler is restored when the outermost
    ``with`` ends (entering it again, e.g. by :func:`swarm_mj.experiments.runner.run`, nests)."""

    def __init__(self) -> None:
        self.requested = False
        self._previous: Any = None
        self._depth = 0

    def _handler(self, signum: int, frame: Any) -> None:
        self.requested = True

    def __enter__(self) -> CooperativeInterrupt:
        self._depth += 1
        if (
            self._depth == 1
            and threading.current_thread() is threading.main_thread()
            and signal.getsignal(signal.SIGINT) is signal.default_int_handler
        ):
            self._previous = signal.signal(signal.SIGINT, self._handler)
        return self

    def __exit__(self, *exc: object) -> None:
        if self._depth == 0:
            return  # already left (a caller may leave early, then again in a ``finally``)
        self._depth -= 1
        if self._depth == 0 and self._previous is not None:
            signal.signal(signal.SIGINT, self._previous)
            self._previous = None
