"""The simulation truth of a run as arrays: from truth.csv (``contracts.truthtable``) or from TruthRecords."""

from __future__ import annotations

import csv
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, fields
from operator import attrgetter
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from contracts.messages import TruthRecord
from contracts.truthtable import TruthTable, TruthTableError


@dataclass(frozen=True)
class Truth:
    """The truth, one row per control period; NaN where a record has None (-1 for ``frame_id``)."""

    t_s: NDArray[np.float64]
    obt_s: NDArray[np.float64]
    omega_rad_s: NDArray[np.float64]  # (N, 3)
    pointing_error_rad: NDArray[np.float64]
    target_in_fov: NDArray[np.bool_]
    theta_rad: NDArray[np.float64]
    range_m: NDArray[np.float64]  # spacecraft to Dimorphos
    range_didymos_m: NDArray[np.float64]  # spacecraft to the Didymos centre
    los_dimorphos_inertial: NDArray[np.float64]  # (N, 3) unit vectors, spacecraft to Dimorphos
    frame_id: NDArray[np.int64]
    dimorphos_px: NDArray[np.float64]  # (N, 2) full-resolution (col, row)
    didymos_px: NDArray[np.float64]  # (N, 2)
    wheel_momentum_nms: NDArray[np.float64]  # (N, wheels)
    wheel_torque_nm: NDArray[np.float64]  # (N, wheels)
    skipped_rows: int = 0
    skip_reason: str = ""  # why the first skipped row was skipped

    def __len__(self) -> int:
        return int(self.t_s.size)

    @classmethod
    def from_records(cls, records: Sequence[TruthRecord], skipped_rows: int = 0, skip_reason: str = "") -> Truth:
        """The arrays of a sequence of records (an in-process run's truth, or truth.csv read back)."""
        # every field of every record read in one pass (a getter of them all per record), then one column each:
        # 14 attribute look-ups a record from C instead of 14 Python passes over the records
        columns = dict(zip(_FIELDS, zip(*map(_ROW, records)))) if records else {name: () for name in _FIELDS}

        def vec(name: str, width: int) -> NDArray[np.float64]:
            nan = (np.nan,) * width
            rows = [nan if v is None else v for v in columns[name]]
            return np.array(rows, dtype=float).reshape(len(records), width)

        def scalar(name: str) -> NDArray[np.float64]:
            col = columns[name]
            return np.array(col if None not in col else [np.nan if v is None else v for v in col],
                            dtype=float).reshape(len(records))

        wheels = len(records[0].wheel_momentum_nms) if records else 0
        return cls(
            t_s=scalar("t_s"),
            obt_s=scalar("obt_s"),
            omega_rad_s=vec("omega_rad_s", 3),
            pointing_error_rad=scalar("pointing_error_rad"),
            target_in_fov=np.array(columns["target_in_fov"], dtype=bool).reshape(len(records)),
            theta_rad=scalar("theta_rad"),
            range_m=scalar("range_m"),
            range_didymos_m=scalar("range_didymos_m"),
            los_dimorphos_inertial=vec("los_dimorphos_inertial", 3),
            frame_id=np.array([-1 if f is None else f for f in columns["frame_id"]], dtype=np.int64),
            dimorphos_px=vec("dimorphos_px", 2),
            didymos_px=vec("didymos_px", 2),
            wheel_momentum_nms=vec("wheel_momentum_nms", wheels),
            wheel_torque_nm=vec("wheel_torque_nm", wheels),
            skipped_rows=skipped_rows,
            skip_reason=skip_reason,
        )


_FIELDS = ("t_s", "obt_s", "omega_rad_s", "pointing_error_rad", "target_in_fov", "theta_rad", "range_m",
           "range_didymos_m", "los_dimorphos_inertial", "frame_id", "dimorphos_px", "didymos_px",
           "wheel_momentum_nms", "wheel_torque_nm")
_ROW = attrgetter(*_FIELDS)  # a record's fields above, as a tuple


_CHUNK_ROWS = 1024  # records turned into arrays at a time: a long run's truth is never held as objects


def _truth_rows(path: Path) -> Iterator[TruthRecord | TruthTableError]:
    """Each data row of a truth.csv, in order: its record, or the error that skips it (naming its line). Raises
    TruthTableError naming the file if the header is unusable. The file is read a row at a time."""
    with open(path, newline="") as f:
        reader = csv.reader(f)
        header = next(reader, None)
        if header is None:
            raise TruthTableError(f"{path}: empty file, no header")
        try:
            table = TruthTable.for_header(header)
        except TruthTableError as err:
            raise TruthTableError(f"{path}: {err}") from None
        for n, row in enumerate(reader, start=2):
            try:
                if len(row) != len(header):
                    raise TruthTableError(f"{len(row)} cells, the header has {len(header)}")
                yield table.record(dict(zip(header, row, strict=True)))
            except TruthTableError as err:
                yield TruthTableError(f"line {n}: {err}")


@dataclass
class _Skipped:
    """Rows of a truth.csv skipped so far: how many, and why the first was."""

    rows: int = 0
    reason: str = ""


def _record_chunks(path: Path, size: int, skipped: _Skipped) -> Iterator[list[TruthRecord]]:
    """The records of a truth.csv in order, in lists of at most ``size``; the rows skipped counted in ``skipped``."""
    chunk: list[TruthRecord] = []
    for row in _truth_rows(path):
        if isinstance(row, TruthTableError):
            skipped.rows += 1
            skipped.reason = skipped.reason or str(row)
            continue
        chunk.append(row)
        if len(chunk) == size:
            yield chunk
            chunk = []
    if chunk:
        yield chunk


def read_truth_records(path: Path) -> tuple[list[TruthRecord], int, str]:
    """The records of a truth.csv, how many rows were skipped and why the first was.

    A row is skipped, and counted, if its cell count differs from the header's (a node killed mid-write) or a
    cell does not read (``TruthTableError``). Raises TruthTableError naming the file if the header is unusable.
    """
    skipped = _Skipped()
    records = [r for chunk in _record_chunks(path, _CHUNK_ROWS, skipped) for r in chunk]
    return records, skipped.rows, skipped.reason


def _lines(path: Path) -> int:
    """The number of lines of a file (a last line without its newline counted), read in blocks."""
    n, last = 0, b"\n"
    with open(path, "rb") as f:
        while block := f.read(1 << 20):
            n += block.count(b"\n")
            last = block[-1:]
    return n + (last != b"\n")


def load_truth(path: Path) -> Truth:
    """truth.csv as arrays; see ``read_truth_records`` for the rows it skips and the errors it raises. Read in
    chunks of ``_CHUNK_ROWS`` records, each turned into arrays and copied into arrays sized from the file's line
    count before the next is read: the memory it takes beyond the arrays does not grow with the run (an hour's run
    held 42,000 records and its 1.5 million cells at once, then its arrays twice while they were joined)."""
    skipped = _Skipped()
    rows = max(_lines(path) - 1, 0)  # at most one record a line after the header
    out: dict[str, NDArray] | None = None
    at = 0
    names = [f.name for f in fields(Truth) if f.name not in ("skipped_rows", "skip_reason")]
    for chunk in _record_chunks(path, _CHUNK_ROWS, skipped):
        part = Truth.from_records(chunk)
        if out is None:
            out = {n: np.empty((max(rows, len(part)), *getattr(part, n).shape[1:]), getattr(part, n).dtype)
                   for n in names}
        for n in names:
            a = getattr(part, n)
            if at + len(a) > out[n].shape[0]:  # more records than line feeds (lone CR line ends): grow by doubling
                size = max(at + len(a), 2 * out[n].shape[0])
                out[n] = np.concatenate([out[n][:at], np.empty((size - at, *a.shape[1:]), a.dtype)])
            out[n][at : at + len(a)] = a
        at += len(part)
    if out is None:
        return Truth.from_records([], skipped.rows, skipped.reason)
    return Truth(**{n: v[:at] for n, v in out.items()}, skipped_rows=skipped.rows,  # type: ignore[arg-type]
                 skip_reason=skipped.reason)
