"""The attitude estimates of the last control periods, by OBT: which attitude a frame was exposed with.

``nearest(obt_s)`` is the estimate of the period nearest ``obt_s``, the earliest of equally near ones: what
``min(entries, key=lambda e: abs(e[0] - obt_s))`` gives. Theory of operation: while the window's times are in
order, the distance ``|t - obt_s|`` falls then rises along it (a correctly rounded subtraction is monotonic), so the
nearest is one of the two entries either side of ``obt_s``, found by bisection in O(log n) instead of n calls of a
key function (a frame asks two or three times, 3 % of a centroid-level run). A backward OBT step (a clock
jump) puts two entries out of order: for as long as they are both in the window, the search is ``min`` itself.
Pure: times come as arguments.
"""

from __future__ import annotations

from bisect import bisect_left
from collections import deque
from operator import itemgetter

import numpy as np

_TIME = itemgetter(0)


class AttitudeHistory:
    """The last ``periods`` (OBT s, attitude quaternion) pairs, in the order they were appended."""

    def __init__(self, periods: int, entries: tuple[tuple[float, np.ndarray], ...] = (), unordered: int = 0) -> None:
        if periods < 1:
            raise ValueError(f"periods must be >= 1, got {periods}")
        self._entries: deque[tuple[float, np.ndarray]] = deque(entries, maxlen=periods)
        # appends left before the last out-of-order pair has left the window (0: the window is in order)
        self._unordered = unordered

    def __len__(self) -> int:
        return len(self._entries)

    def append(self, obt_s: float, q: np.ndarray) -> None:
        """Add the estimate of the period at ``obt_s`` (the oldest leaves once ``periods`` are held)."""
        entries = self._entries
        if self._unordered:
            self._unordered -= 1
        if entries and not obt_s >= entries[-1][0]:  # a NaN counts as out of order
            self._unordered = entries.maxlen or 0
        entries.append((obt_s, q))

    def shifted(self, step_s: float) -> AttitudeHistory:
        """The same history with every time moved by ``step_s`` (a clock adjustment; the order is kept)."""
        periods = self._entries.maxlen or len(self._entries)
        return AttitudeHistory(periods, tuple((t + step_s, q) for t, q in self._entries), self._unordered)

    def nearest(self, obt_s: float) -> np.ndarray:
        """The attitude of the period nearest ``obt_s``, the earliest of equally near ones (ValueError if empty)."""
        entries = self._entries
        if self._unordered or not entries:
            return min(entries, key=lambda e: abs(e[0] - obt_s))[1]
        i = bisect_left(entries, obt_s, key=_TIME)  # the first at or after obt_s
        if i == len(entries):
            best = i - 1
        elif i == 0:
            best = 0
        else:
            best = i - 1 if abs(entries[i - 1][0] - obt_s) <= abs(entries[i][0] - obt_s) else i
        # the earliest entry of that time (a period repeated at one OBT is the same distance away)
        return entries[bisect_left(entries, entries[best][0], key=_TIME)][1]
