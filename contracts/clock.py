"""Clocks: the only module that reads the machine's time.

Everything else takes a ``Clock`` as an argument (as trio's ``Clock`` and SimPy's ``Environment`` do): real-time
pacing, bus timeouts and watchdogs use ``WallClock``, and ``SimClock`` stands in for it where only simulated time may
pass. Lock-step runs read no clock at all: their true time is the universe's step count, so they never depend on
how fast the machine is.
"""

from __future__ import annotations

import datetime
import re
import resource
import sys
import time
from dataclasses import dataclass
from typing import Protocol


class Clock(Protocol):
    """A source of seconds that never goes backwards."""

    def now(self) -> float:
        """Current time, s."""
        ...

    def sleep_until(self, t: float) -> None:
        """Return once ``now() >= t``."""
        ...


class SimClock:
    """A clock that only moves when told to."""

    def __init__(self, start: float = 0.0) -> None:
        self._t = start

    def now(self) -> float:
        """Current simulated time, s."""
        return self._t

    def advance(self, dt: float) -> float:
        """Move forward by ``dt`` >= 0 s and return the new time."""
        if dt < 0:
            raise ValueError(f"dt must be >= 0, got {dt}")
        self._t += dt
        return self._t

    def sleep_until(self, t: float) -> None:
        """Jump forward to ``t`` (never backwards)."""
        self._t = max(self._t, t)


class WallClock:
    """Monotonic wall time, s since an arbitrary origin."""

    def now(self) -> float:
        """Current monotonic time, s."""
        return time.monotonic()

    def sleep_until(self, t: float) -> None:
        """Sleep until the monotonic clock reaches ``t``."""
        dt = t - time.monotonic()
        if dt > 0:
            time.sleep(dt)


def monotonic_ns() -> int:
    """The host's monotonic clock, ns: the same clock in every process of the host (Linux's CLOCK_MONOTONIC), so
    time marks of different nodes compare (``contracts.hoptrace``)."""
    return time.perf_counter_ns()


def utc_now() -> datetime.datetime:
    """The machine's UTC now (for certificate validity)."""
    return datetime.datetime.now(datetime.timezone.utc)


def utc_stamp() -> str:
    """Local wall time as a compact UTC stamp for run-folder names (YYYYmmdd-HHMMSS)."""
    return time.strftime("%Y%m%d-%H%M%S", time.gmtime())


@dataclass(frozen=True)
class ProcessUsage:
    """What this process has used so far: processor time (user and system, all threads) and peak resident memory."""

    cpu_user_s: float
    cpu_system_s: float
    peak_rss_mb: float

    def line(self) -> str:
        """One log line, read back by ``parse``."""
        return (f"resources: cpu {self.cpu_user_s:.2f} s user, {self.cpu_system_s:.2f} s system, "
                f"peak RSS {self.peak_rss_mb:.1f} MB")

    @staticmethod
    def parse(text: str) -> ProcessUsage | None:
        """The last usage line in ``text`` (a node's log), or None."""
        found = re.findall(r"resources: cpu ([\d.]+) s user, ([\d.]+) s system, peak RSS ([\d.]+) MB", text)
        return None if not found else ProcessUsage(*(float(x) for x in found[-1]))


def process_usage() -> ProcessUsage:
    """This process's processor time and peak resident set size (the kernel's high-water mark)."""
    ru = resource.getrusage(resource.RUSAGE_SELF)
    # Linux reports ru_maxrss in KiB, macOS in bytes
    kib = ru.ru_maxrss / 1024.0 if sys.platform == "darwin" else float(ru.ru_maxrss)
    return ProcessUsage(ru.ru_utime, ru.ru_stime, kib / 1024.0)
