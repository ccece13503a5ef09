"""The telemetry archive: every TM packet kept raw and decoded in SQLite, and appended to a raw ``tm.bin``.

This module is an adapter (it owns the disk); decoding is ``contracts.pus``. Tables:

- ``packets``: one row per packet received: ground receipt time (UTC s), OBT, APID, sequence count, service,
  subtype, message counter, report type, the raw octets, and the decoding error (NULL when decoded). An undecodable
  packet is kept raw with its error (never lost, never fatal); its APID and sequence count are
  filled from the primary header when 4 octets arrived (not trusted), its other header fields are NULL.
- ``parameters``: long format, one row per (packet, parameter): name, OBT, value. Names are ``<Report>.<field>``
  with ``[i]`` for sequence items and ``.`` into nested values, e.g. ``Housekeeping.q[3]``,
  ``Verification.request_id.seq_count``; absent (None) values and raw octets are not stored, a NaN reads back
  as NULL (SQLite has no NaN). Indexed on (name, obt_s).
- ``sequence_anomalies``: per APID, gaps in the 14-bit sequence count (with the number of packets missing),
  duplicates and late (out-of-order) packets.
- ``alarms``: the ground's alarms (security: a report about a TC it never sent, a TC the spacecraft refused as
  unauthentic; an on-board event of medium or high severity; a TC never accepted after its re-sends), each with its
  receipt time and the packet that raised it (none for a TC never accepted).

Sequence rule: with ``d = (seq - (last + 1)) mod 16384``, ``d == 0`` is in order; ``0 < d < 8192`` is a gap of ``d``
packets; ``d >= 8192`` is a late or duplicate packet if its OBT is not after the last one's, otherwise a gap of
``d`` (so a long outage is still a gap while a clock jump backwards does not hide one). Losses of a multiple of
16384 packets are invisible to any 14-bit count. Undecodable packets do not advance the sequence: whatever was
corrupted, their slot shows as a gap.

Writes are batched: ``store`` queues rows and every ``batch_size`` packets one transaction inserts them with
``executemany``; ``flush`` (also called by every query and by ``close``) writes what is queued. A crash loses at
most the queued batch, so call ``flush`` at the end of each ground step.
"""

from __future__ import annotations

import csv
import math
import sqlite3
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from enum import IntEnum
from pathlib import Path
from types import TracebackType
from typing import Any, NamedTuple

from pydantic import BaseModel

from contracts.errors import FlybyError
from contracts.pus import MAX_APID, MAX_SEQ_COUNT, SEQ_COUNT_MODULO, PacketError, TmHeader, decode_tm

_SCHEMA = """
CREATE TABLE IF NOT EXISTS packets (
    id INTEGER PRIMARY KEY,
    receipt_utc_s REAL NOT NULL,
    obt_s REAL,
    apid INTEGER,
    seq_count INTEGER,
    service INTEGER,
    subservice INTEGER,
    msg_counter INTEGER,
    report TEXT,
    raw BLOB NOT NULL,
    error TEXT
);
CREATE INDEX IF NOT EXISTS packets_obt ON packets (obt_s);
CREATE INDEX IF NOT EXISTS packets_service ON packets (service, subservice, obt_s);
CREATE TABLE IF NOT EXISTS parameters (
    packet_id INTEGER NOT NULL REFERENCES packets (id),
    name TEXT NOT NULL,
    obt_s REAL NOT NULL,
    value
);
CREATE INDEX IF NOT EXISTS parameters_name_obt ON parameters (name, obt_s);
CREATE TABLE IF NOT EXISTS sequence_anomalies (
    packet_id INTEGER NOT NULL REFERENCES packets (id),
    apid INTEGER NOT NULL,
    kind TEXT NOT NULL CHECK (kind IN ('gap', 'duplicate', 'late')),
    expected_seq INTEGER NOT NULL,
    received_seq INTEGER NOT NULL,
    missing INTEGER NOT NULL,
    receipt_utc_s REAL NOT NULL
);
CREATE TABLE IF NOT EXISTS alarms (
    packet_id INTEGER REFERENCES packets (id),
    receipt_utc_s REAL NOT NULL,
    text TEXT NOT NULL
);
"""
_HALF_WINDOW = SEQ_COUNT_MODULO // 2
Value = float | int | str


class ArchiveError(FlybyError):
    """A misuse of the archive (bad receipt time, unknown parameter, closed archive)."""


@dataclass(frozen=True, slots=True)
class StoreResult:
    """What happened to one stored packet."""

    packet_id: int
    decoded: bool
    error: str | None = None
    anomaly: str | None = None  # 'gap', 'duplicate' or 'late'
    missing: int = 0  # packets missing just before this one (gap size)


class Gap(NamedTuple):
    """A jump in one APID's sequence count: ``missing`` packets between ``expected_seq`` and ``received_seq``."""

    apid: int
    expected_seq: int
    received_seq: int
    missing: int
    packet_id: int
    receipt_utc_s: float


class Sample(NamedTuple):
    """One value of a parameter."""

    obt_s: float
    value: Value
    packet_id: int


class Undecodable(NamedTuple):
    """A packet kept raw because it could not be decoded."""

    packet_id: int
    receipt_utc_s: float
    error: str
    raw: bytes


def parameters_of(report: BaseModel) -> list[tuple[str, Value]]:
    """The (name, value) pairs a report is archived as: ``<Report>.<field>``, ``[i]`` for items, None skipped."""
    out: list[tuple[str, Value]] = []
    _flatten(type(report).__name__, report, out)
    return out


def _flatten(prefix: str, value: Any, out: list[tuple[str, Value]]) -> None:
    """Append the scalar leaves of ``value`` under ``prefix``."""
    if value is None or isinstance(value, bytes):
        return
    if isinstance(value, BaseModel):
        for name in type(value).model_fields:
            _flatten(f"{prefix}.{name}", getattr(value, name), out)
    elif isinstance(value, tuple):
        for i, item in enumerate(value):
            _flatten(f"{prefix}[{i}]", item, out)
    elif isinstance(value, (bool, IntEnum)):
        out.append((prefix, int(value)))
    elif isinstance(value, (int, float, str)):
        out.append((prefix, value))
    else:
        raise TypeError(f"{prefix}: cannot archive a {type(value).__name__}")


class Archive:
    """The telemetry archive in the SQLite file ``path``, with raw packets also appended to ``tm_bin``."""

    def __init__(self, path: str | Path, *, tm_bin: str | Path | None = None, batch_size: int = 500) -> None:
        """Open (creating if needed) the archive; ``tm_bin`` defaults to ``tm.bin`` beside the database."""
        if batch_size < 1:
            raise ArchiveError(f"batch_size must be >= 1, got {batch_size}")
        self.path = Path(path)
        self.tm_bin_path = Path(tm_bin) if tm_bin is not None else self.path.with_name("tm.bin")
        self.batch_size = batch_size
        self._db = sqlite3.connect(self.path)
        # WAL with NORMAL sync: durable at each checkpoint, and several times faster than the rollback journal.
        self._db.execute("PRAGMA journal_mode=WAL")
        self._db.execute("PRAGMA synchronous=NORMAL")
        self._db.executescript(_SCHEMA)
        self._bin = open(self.tm_bin_path, "ab")  # noqa: SIM115 - held open for the archive's life, closed in close()
        self._next_id = self._db.execute("SELECT COALESCE(MAX(id), 0) + 1 FROM packets").fetchone()[0]
        self._last: dict[int, tuple[int, float]] = {
            apid: (seq, obt)
            for apid, seq, obt in self._db.execute(
                "SELECT apid, seq_count, obt_s FROM packets WHERE id IN "
                "(SELECT MAX(id) FROM packets WHERE error IS NULL GROUP BY apid)"
            )
        }
        self._packets: list[tuple[Any, ...]] = []
        self._params: list[tuple[int, str, float, Value]] = []
        self._anomalies: list[tuple[Any, ...]] = []
        self._alarms: list[tuple[int | None, float, str]] = []
        self._raw: list[bytes] = []
        self._closed = False
        self._read_only = False
        self.damage: str | None = None  # set by a reader that had to fall back on tm.bin

    @classmethod
    def read_only(cls, path: str | Path) -> Archive:
        """Open an existing archive for reading only: nothing is ever written beside it (no journal, no -shm file),
        and a file that is not an intact archive raises ArchiveError saying what is wrong with it."""
        self = cls.__new__(cls)
        self.path = Path(path)
        self.tm_bin_path = self.path.with_name("tm.bin")
        self.batch_size = 1
        if not self.path.is_file():
            raise ArchiveError(f"{self.path}: no such file")
        if self.path.stat().st_size == 0:
            raise ArchiveError(f"{self.path}: empty file (0 octets): the ground node never wrote it")
        # immutable: SQLite neither locks nor creates a -wal/-shm file, so the run folder is left as it was
        self._db = sqlite3.connect(f"file:{self.path.resolve()}?mode=ro&immutable=1", uri=True)
        try:
            tables = {n for (n,) in self._db.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
            missing = {"packets", "parameters", "sequence_anomalies"} - tables
            if missing:
                raise ArchiveError(f"{self.path}: not a telemetry archive (no table {', '.join(sorted(missing))})")
            self._db.execute("SELECT COUNT(*) FROM packets").fetchone()
        except sqlite3.DatabaseError as exc:
            self._db.close()
            raise ArchiveError(f"{self.path}: damaged database: {exc}") from None
        except ArchiveError:
            self._db.close()
            raise
        self._bin = None
        self._next_id = 0
        self._last = {}
        self._packets, self._params, self._anomalies, self._raw, self._alarms = [], [], [], [], []
        self._closed = False
        self._read_only = True
        self.damage = None
        return self

    # ------------------------------------------------------------------------------------------------ writing

    def store(self, raw: bytes, receipt_utc_s: float) -> StoreResult:
        """Archive one TM packet received at ``receipt_utc_s`` (UTC s); bad packets are kept raw with their error."""
        self._check_open()
        if self._read_only:
            raise ArchiveError(f"archive {self.path} is open for reading only")
        if not isinstance(receipt_utc_s, (int, float)) or not math.isfinite(receipt_utc_s):
            raise ArchiveError(f"receipt_utc_s must be a finite number, got {receipt_utc_s!r}")
        raw = bytes(raw)
        pid = self._next_id
        self._next_id += 1
        self._raw.append(raw)
        try:
            header, report = decode_tm(raw)
        except PacketError as exc:
            error = f"{type(exc).__name__}: {exc}"
            # The primary header may itself be corrupt, so these are kept for inspection only, never sequenced.
            apid = int.from_bytes(raw[0:2], "big") & MAX_APID if len(raw) >= 4 else None
            seq = int.from_bytes(raw[2:4], "big") & MAX_SEQ_COUNT if len(raw) >= 4 else None
            self._packets.append((pid, receipt_utc_s, None, apid, seq, None, None, None, None, raw, error))
            result = StoreResult(packet_id=pid, decoded=False, error=error)
        else:
            self._packets.append(
                (
                    pid,
                    receipt_utc_s,
                    header.obt_s,
                    header.apid,
                    header.seq_count,
                    header.service,
                    header.subservice,
                    header.msg_counter,
                    type(report).__name__,
                    raw,
                    None,
                )
            )
            obt = header.obt_s
            self._params.extend((pid, name, obt, value) for name, value in parameters_of(report))
            result = self._sequence(pid, header, receipt_utc_s)
        if len(self._packets) >= self.batch_size:
            self.flush()
        return result

    def alarm(self, receipt_utc_s: float, text: str, packet_id: int | None = None) -> None:
        """Record an alarm raised at ``receipt_utc_s`` by the packet ``packet_id`` (None: by no packet), written at the
        next flush."""
        self._check_open()
        if self._read_only:
            raise ArchiveError(f"archive {self.path} is open for reading only")
        self._alarms.append((packet_id, receipt_utc_s, text))

    def store_many(self, packets: Iterable[bytes], receipt_utc_s: float) -> list[StoreResult]:
        """Archive several packets received at the same time."""
        return [self.store(p, receipt_utc_s) for p in packets]

    def _sequence(self, pid: int, header: TmHeader, receipt_utc_s: float) -> StoreResult:
        """Classify the packet's sequence count against the APID's last one and queue any anomaly."""
        last = self._last.get(header.apid)
        if last is None:
            self._last[header.apid] = (header.seq_count, header.obt_s)
            return StoreResult(packet_id=pid, decoded=True)
        last_seq, last_obt = last
        expected = (last_seq + 1) % SEQ_COUNT_MODULO
        d = (header.seq_count - expected) % SEQ_COUNT_MODULO
        if d == 0:
            self._last[header.apid] = (header.seq_count, header.obt_s)
            return StoreResult(packet_id=pid, decoded=True)
        if d >= _HALF_WINDOW and header.obt_s <= last_obt:
            kind = "duplicate" if header.seq_count == last_seq else "late"
            self._anomalies.append((pid, header.apid, kind, expected, header.seq_count, 0, receipt_utc_s))
            return StoreResult(packet_id=pid, decoded=True, anomaly=kind)
        self._last[header.apid] = (header.seq_count, header.obt_s)
        self._anomalies.append((pid, header.apid, "gap", expected, header.seq_count, d, receipt_utc_s))
        return StoreResult(packet_id=pid, decoded=True, anomaly="gap", missing=d)

    def flush(self) -> None:
        """Write every queued packet: raw octets to tm.bin, rows to SQLite in one transaction."""
        self._check_open()
        if not self._packets and not self._alarms:
            return
        assert self._bin is not None  # a read-only archive never queues packets
        self._bin.write(b"".join(self._raw))
        self._bin.flush()
        with self._db:
            self._db.executemany("INSERT INTO packets VALUES (?,?,?,?,?,?,?,?,?,?,?)", self._packets)
            self._db.executemany("INSERT INTO parameters VALUES (?,?,?,?)", self._params)
            self._db.executemany("INSERT INTO sequence_anomalies VALUES (?,?,?,?,?,?,?)", self._anomalies)
            self._db.executemany("INSERT INTO alarms VALUES (?,?,?)", self._alarms)
        self._alarms.clear()
        self._packets.clear()
        self._params.clear()
        self._anomalies.clear()
        self._raw.clear()

    def close(self) -> None:
        """Flush and close the database and tm.bin (idempotent)."""
        if self._closed:
            return
        try:
            self.flush()
        finally:
            self._closed = True
            if self._bin is not None:
                self._bin.close()
            self._db.close()

    def __enter__(self) -> Archive:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()

    def _check_open(self) -> None:
        if self._closed:
            raise ArchiveError(f"archive {self.path} is closed")

    # ------------------------------------------------------------------------------------------------ reading

    def query(self, parameter: str, obt_from: float = -math.inf, obt_to: float = math.inf) -> list[Sample]:
        """Every value of ``parameter`` with obt_from <= OBT <= obt_to, in OBT order (ties in arrival order)."""
        self.flush()
        rows = self._db.execute(
            "SELECT obt_s, value, packet_id FROM parameters WHERE name = ? AND obt_s BETWEEN ? AND ? "
            "ORDER BY obt_s, packet_id",
            (parameter, obt_from, obt_to),
        )
        return [Sample(*row) for row in rows]

    def decoded_packets(self) -> list[tuple[float, bytes]]:
        """(receipt UTC s, raw octets) of every decoded packet, in arrival order."""
        self.flush()
        rows = self._db.execute("SELECT receipt_utc_s, raw FROM packets WHERE error IS NULL ORDER BY id")
        return [(t, bytes(r)) for t, r in rows]

    def raw_packets(self) -> list[bytes]:
        """Every packet as received, in arrival order (undecodable ones included)."""
        self.flush()
        return [bytes(r) for (r,) in self._db.execute("SELECT raw FROM packets ORDER BY id")]

    def parameter_names(self) -> list[str]:
        """Every parameter name present in the archive, sorted."""
        self.flush()
        return [n for (n,) in self._db.execute("SELECT DISTINCT name FROM parameters ORDER BY name")]

    def export_csv(self, parameters: Sequence[str], path: str | Path) -> int:
        """Write one CSV row per packet holding any of ``parameters`` (one column each); return the row count.

        Columns: packet_id, receipt_utc_s, obt_s, apid, seq_count, then the parameters; a cell is empty where the
        packet does not carry the parameter. Floats are written with repr, so they read back exactly.
        """
        self.flush()
        names = list(dict.fromkeys(parameters))
        if not names:
            raise ArchiveError("export_csv needs at least one parameter name")
        known = set(self.parameter_names())
        unknown = [n for n in names if n not in known]
        if unknown:
            raise ArchiveError(f"no such parameter(s) in {self.path}: {', '.join(unknown)}")
        column = {n: i for i, n in enumerate(names)}
        marks = ",".join("?" * len(names))
        rows = self._db.execute(
            "SELECT p.id, p.receipt_utc_s, p.obt_s, p.apid, p.seq_count, v.name, v.value "
            f"FROM parameters v JOIN packets p ON p.id = v.packet_id WHERE v.name IN ({marks}) "
            "ORDER BY p.obt_s, p.id",
            names,
        )
        count = 0
        with open(path, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["packet_id", "receipt_utc_s", "obt_s", "apid", "seq_count", *names])
            current: list[Any] | None = None
            for pid, receipt, obt, apid, seq, name, value in rows:
                if current is None or current[0] != pid:
                    if current is not None:
                        w.writerow(current)
                        count += 1
                    current = [pid, repr(receipt), repr(obt), apid, seq] + [""] * len(names)
                current[5 + column[name]] = repr(value) if isinstance(value, float) else value
            if current is not None:
                w.writerow(current)
                count += 1
        return count

    def gaps(self) -> list[Gap]:
        """Every sequence-count gap, in arrival order."""
        self.flush()
        rows = self._db.execute(
            "SELECT apid, expected_seq, received_seq, missing, packet_id, receipt_utc_s FROM sequence_anomalies "
            "WHERE kind = 'gap' ORDER BY packet_id"
        )
        return [Gap(*row) for row in rows]

    def alarms(self) -> list[tuple[float, str]]:
        """Every alarm (receipt UTC s, text), in the order raised; none in an archive older than alarms."""
        self.flush()
        if not self._db.execute("SELECT 1 FROM sqlite_master WHERE type = 'table' AND name = 'alarms'").fetchone():
            return []
        return [(t, text) for t, text in self._db.execute("SELECT receipt_utc_s, text FROM alarms ORDER BY rowid")]

    def undecodable(self) -> list[Undecodable]:
        """Every packet kept raw because it could not be decoded, in arrival order."""
        self.flush()
        rows = self._db.execute("SELECT id, receipt_utc_s, error, raw FROM packets WHERE error IS NOT NULL ORDER BY id")
        return [Undecodable(pid, t, e, bytes(raw)) for pid, t, e, raw in rows]

    def counts(self) -> dict[str, int]:
        """Packet counts: ``stored``, ``decoded``, ``undecodable``, ``gaps``, ``missing`` (packets lost in gaps),
        ``duplicates``, ``late``, ``alarms``, and one ``TM[s,t]`` entry per service and subtype
        seen."""
        self.flush()
        db = self._db
        stored, undecodable = db.execute(
            "SELECT COUNT(*), COALESCE(SUM(error IS NOT NULL), 0) FROM packets"
        ).fetchone()
        out = {"stored": stored, "decoded": stored - undecodable, "undecodable": undecodable}
        anomalies = dict.fromkeys(("gap", "duplicate", "late"), (0, 0))
        for kind, n, missing in db.execute(
            "SELECT kind, COUNT(*), SUM(missing) FROM sequence_anomalies GROUP BY kind"
        ):
            anomalies[kind] = (n, missing)
        out["gaps"], out["missing"] = anomalies["gap"]
        out["duplicates"] = anomalies["duplicate"][0]
        out["late"] = anomalies["late"][0]
        out["alarms"] = len(self.alarms())
        for service, sub, n in db.execute(
            "SELECT service, subservice, COUNT(*) FROM packets WHERE error IS NULL "
            "GROUP BY service, subservice ORDER BY service, subservice"
        ):
            out[f"TM[{service},{sub}]"] = n
        return out
