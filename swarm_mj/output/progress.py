"""The one progress bar: a single line on stderr, redrawn in place, quiet when stderr is not a terminal.

Used by the runner (simulation steps), the video renderer (frames), the sweeps, the stress test
and the report (completed runs). Two shapes, one class:

* a percentage (``unit=None``): ``circle [######-------------------]  24%   3.1 s``;
* a count (``unit="frames"``): ``video x.mp4 [###----] 120/750 frames  12.3 frames/s``.

``note(text)`` says what the program is doing during a long wait (starting workers, compiling
kernels) on the same line, until the next step is done; ``log(line)`` prints a full line above the bar (a finished run's
figures) and is printed even when the bar itself is quiet, unless ``lines=False``.
"""

from __future__ import annotations

import sys
import time as _time
from typing import TextIO

BAR_WIDTH = 25
CLEAR_TO_EOL = "\033[K"


class Progress:
    """A one-line progress bar on stderr (quiet when not a terminal unless forced).

    ``total``: the number of steps; ``label``: what is progressing; ``enabled``: None follows
    ``stderr.isatty()``, True/False force it; ``unit``: None shows a percentage and the elapsed
    time, a word (``"frames"``, ``"runs"``) shows ``done/total unit`` and the rate;
    ``lines``: whether ``log`` prints its lines (None follows ``enabled is not False``).
    """

    def __init__(
        self,
        total: int,
        label: str,
        enabled: bool | None = None,
        *,
        unit: str | None = None,
        lines: bool | None = None,
        stream: TextIO | None = None,
        min_interval: float = 0.0,
    ) -> None:
        self.total, self.label, self.unit = int(total), label, unit
        self.stream = stream if stream is not None else sys.stderr
        self.enabled = self._isatty() if enabled is None else bool(enabled)
        self.lines = (enabled is not False) if lines is None else bool(lines)
        self.min_interval = min_interval if unit is None else max(min_interval, 0.2)
        self.done = 0
        self._last_pct = -1
        self._last_t = -1.0
        self._drawn = False
        self._note = ""
        self._t0 = _time.perf_counter()

    def _isatty(self) -> bool:
        try:
            return bool(self.stream.isatty())
        except (AttributeError, ValueError):
            return False

    @property
    def elapsed(self) -> float:
        """Seconds since the bar was made."""
        return _time.perf_counter() - self._t0

    def _bar(self, frac: float) -> str:
        n = min(BAR_WIDTH, max(0, int(BAR_WIDTH * frac)))
        return "#" * n + "-" * (BAR_WIDTH - n)

    def _line(self) -> str:
        frac = self.done / max(self.total, 1)
        if self.unit is None:
            pct = int(100 * frac)
            text = f"{self.label} [{'#' * (pct // 4) + '-' * (25 - pct // 4)}] {pct:3d}%  {self.elapsed:5.1f} s"
        else:
            rate = self.done / max(self.elapsed, 1e-9)
            text = f"{self.label} [{self._bar(frac)}] {self.done}/{self.total} {self.unit}  {rate:5.1f} {self.unit}/s"
        return f"{text}  {self._note}" if self._note else text

    def _draw(self) -> None:
        self.stream.write("\r" + self._line() + CLEAR_TO_EOL)  # a shorter line leaves nothing behind
        self.stream.flush()
        self._drawn = True

    def update(self, k: int) -> None:
        """``k`` of ``total`` steps are done; redraws when the percentage (or, for counts, 0.2 s) moved.

        Progress clears the note of a wait (:meth:`note`): the wait is over."""
        if int(k) != self.done:
            self._note = ""
        self.done = int(k)
        if not self.enabled:
            return
        if self.unit is None:
            pct = int(100 * k / max(self.total, 1))
            if pct == self._last_pct:
                return
            self._last_pct = pct
        else:
            now = _time.perf_counter()
            if self.done < self.total and now - self._last_t < self.min_interval:
                return
            self._last_t = now
        self._draw()

    def advance(self, n: int = 1) -> None:
        """One more (or ``n`` more) step done."""
        self.update(self.done + n)

    def note(self, text: str) -> None:
        """Say what is happening during a long wait, on the bar's line (cleared with ``note("")``)."""
        self._note = text
        if self.enabled:
            self._draw()

    def log(self, line: str) -> None:
        """Print a full line above the bar (the bar is redrawn below it)."""
        if not self.lines:
            return
        if self.enabled and self._drawn:
            self.stream.write("\r" + CLEAR_TO_EOL)
        self.stream.write(line + "\n")
        self.stream.flush()
        if self.enabled and self._drawn:
            self._draw()

    def close(self) -> None:
        """End the bar's line."""
        if self.enabled:
            self.stream.write("\n")
            self.stream.flush()

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def say(line: str) -> None:
    """One line on stderr, flushed (for messages outside a bar)."""
    print(line, file=sys.stderr, flush=True)
