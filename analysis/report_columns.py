"""Telemetry reports of one kind held as columns, their layout taken from the dictionary.

A decoded report is a frozen pydantic value of some 4 KB (the housekeeping's 60-odd numbers as Python floats in
tuples, its field dictionary); an hour of housekeeping at 1 Hz took 16 MB of the report's memory that way (the whole
tm.bin of that run is 1.1 MB). ``ReportColumns`` keeps each report as one row of float64 (8 octets a value: integers and
enumeration codes are exact up to 2**53, a float32 on the wire exactly) and the last report whole, for the counters a
report quotes "to the last housekeeping". The columns follow from the packet's ``LAYOUT``: a scalar is one column, a
vector its n, a padded array its slots; an absent optional value and the unused slots of a padded array are NaN
(so ``present`` also leaves out a value sent as NaN, which a chart could not draw either).
"""

from __future__ import annotations

import math
from typing import Any, Generic, TypeVar

import numpy as np
from numpy.typing import NDArray

from contracts.packet import Report
from contracts.wire import EnumCode, Number, Padded, Vector, WireType

R = TypeVar("R", bound=Report)

_FIRST_ROWS = 256  # the first allocation; it doubles as reports arrive


def _width(wire: WireType) -> tuple[int, bool] | None:
    """(columns, whether the field is a sequence) of a field on the wire, or None if it has no fixed number of
    numbers (a counted list, a string)."""
    if isinstance(wire, Number | EnumCode):
        return 1, False
    if isinstance(wire, Vector) and isinstance(wire.element, Number | EnumCode):
        return wire.n, True
    if isinstance(wire, Padded) and isinstance(wire.element, Number | EnumCode):
        return wire.slots, True
    return None


class ReportColumns(Generic[R]):
    """The reports of one kind, in arrival order: their packet times, each field as a column, the last report."""

    def __init__(self, kind: type[R]) -> None:
        spans: dict[str, tuple[int, int, bool]] = {}
        at = 0
        for item in kind.LAYOUT:
            if not item.is_field:
                continue
            width = _width(item.wire)
            if width is None:
                raise TypeError(f"{kind.__name__}.{item.name}: {item.wire.label} has no fixed number of columns")
            spans[item.name] = (at, *width)
            at += width[0]
        self.kind = kind
        self._spans = spans
        self._rows: NDArray[np.float64] = np.empty((0, at))
        self._t: NDArray[np.float64] = np.empty(0)
        self._n = 0
        self.last: tuple[float, R] | None = None

    def append(self, t_s: float, report: R) -> None:
        """Add ``report``, stamped ``t_s`` (its packet's OBT, s)."""
        if not isinstance(report, self.kind):
            raise TypeError(f"ReportColumns of {self.kind.__name__} given a {type(report).__name__}")
        if self._n == self._t.size:  # grow by doubling: appends cost a constant on average
            size = max(_FIRST_ROWS, 2 * self._t.size)
            rows, t = np.empty((size, self._rows.shape[1])), np.empty(size)
            rows[: self._n], t[: self._n] = self._rows[: self._n], self._t[: self._n]
            self._rows, self._t = rows, t
        row = self._rows[self._n]
        for name, (at, width, sequence) in self._spans.items():
            value: Any = getattr(report, name)
            if value is None:
                row[at : at + width] = math.nan
            elif sequence:
                used = len(value)
                row[at : at + used] = value
                row[at + used : at + width] = math.nan
            else:
                row[at] = value
        self._t[self._n] = t_s
        self._n += 1
        self.last = (t_s, report)

    def trim(self) -> None:
        """Release the rows allocated beyond the reports (up to as many again, from the doubling)."""
        self._rows, self._t = self._rows[: self._n].copy(), self._t[: self._n].copy()

    def __len__(self) -> int:
        return self._n

    def __bool__(self) -> bool:
        return self._n > 0

    @property
    def t_s(self) -> NDArray[np.float64]:
        """The packets' OBT, s, shape (N,) (a copy)."""
        return self._t[: self._n].copy()

    def column(self, name: str) -> NDArray[np.float64]:
        """Field ``name`` of every report: shape (N,) for a scalar, (N, columns) for a sequence; NaN where absent
        (a copy)."""
        if name not in self._spans:
            raise KeyError(f"{self.kind.__name__} has no field {name!r} (fields: {', '.join(self._spans)})")
        at, width, sequence = self._spans[name]
        block = self._rows[: self._n, at : at + width]
        return block.copy() if sequence else block[:, 0].copy()

    def present(self, *names: str) -> tuple[NDArray[np.float64], list[NDArray[np.float64]]]:
        """The packet times of the reports that have every field of ``names`` (no NaN), and those fields there."""
        cols = [self.column(n) for n in names]
        keep = np.ones(self._n, dtype=bool)
        for c in cols:
            keep &= np.isfinite(c) if c.ndim == 1 else np.isfinite(c).all(axis=1)
        return self._t[: self._n][keep], [c[keep] for c in cols]
