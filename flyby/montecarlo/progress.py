"""The progress line of a campaign on stderr: runs done, failures so far, rate and estimated time left."""

from __future__ import annotations

import sys
from typing import TextIO

from contracts.clock import Clock, WallClock

BAR_WIDTH = 30


def eta_text(seconds: float | None) -> str:
    """A duration for people: '42 s', '7 min', '2.5 h'; '?' when unknown."""
    if seconds is None:
        return "?"
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 5400:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"


class Progress:
    """Counts finished runs and redraws one line: a bar, done/total, failures, runs per second, ETA."""

    def __init__(self, total: int, already: int = 0, stream: TextIO | None = None, clock: Clock | None = None) -> None:
        self.total = total
        self.already = already  # stored before this session (a resumed campaign)
        self.done = 0
        self.errors = 0  # runs that raised
        self.failed = 0  # runs that completed but missed a requirement
        self.stream = stream if stream is not None else sys.stderr
        self.clock = clock or WallClock()
        self.t0 = self.clock.now()
        self._tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self._last_printed = -1

    def rate_per_s(self) -> float | None:
        """Runs finished per second in this session."""
        dt = self.clock.now() - self.t0
        return self.done / dt if self.done and dt > 0 else None

    def line(self) -> str:
        """The progress line."""
        n = self.already + self.done
        frac = n / self.total if self.total else 1.0
        filled = int(round(BAR_WIDTH * frac))
        rate = self.rate_per_s()
        left = None if rate is None else (self.total - n) / rate
        speed = "-" if rate is None else f"{rate:.2f} run/s"
        return (f"[{'#' * filled}{'.' * (BAR_WIDTH - filled)}] {n}/{self.total} runs, {self.failed} missed a "
                f"requirement, {self.errors} raised, {speed}, ETA {eta_text(left)}")

    def update(self, ok: bool, passed: bool = True) -> None:
        """Count a finished run (``ok``: it did not raise; ``passed``: it met every requirement) and redraw (on a
        terminal; elsewhere a line every 5 %)."""
        self.done += 1
        if not ok:
            self.errors += 1
        elif not passed:
            self.failed += 1
        if self._tty:
            print("\r" + self.line(), end="", file=self.stream, flush=True)
            return
        step = max(1, self.total // 20)
        n = self.already + self.done
        if n // step != self._last_printed or n == self.total:
            self._last_printed = n // step
            print(self.line(), file=self.stream, flush=True)

    def finish(self) -> None:
        """End the progress line."""
        if self._tty:
            print(file=self.stream, flush=True)
