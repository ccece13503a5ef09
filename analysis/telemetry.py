"""The telemetry of a run, decoded by kind: from tm.bin, else from the raw packets of archive.sqlite."""

from __future__ import annotations

import sqlite3
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

from analysis.report_columns import ReportColumns
from contracts import pus
from ground.archive import Archive, ArchiveError
from ground.segment import ReceivedPacket

MODE_NAMES = {m.value: m.name for m in pus.Mode}


@dataclass
class Telemetry:
    """The decoded telemetry of a run, by kind, each entry (packet OBT s, report), in stream order; the housekeeping,
    a report a second however long the run, as columns (``analysis.report_columns``)."""

    source: str
    packets: int = 0
    undecodable: int = 0
    truncated_tail_octets: int = 0
    housekeeping: ReportColumns[pus.Housekeeping] = field(default_factory=lambda: ReportColumns(pus.Housekeeping))
    navigation: list[tuple[float, pus.NavigationReport]] = field(default_factory=list)
    estimates: list[tuple[float, pus.EstimateReport]] = field(default_factory=list)
    mode_changes: list[tuple[float, pus.ModeChangedEvent]] = field(default_factory=list)
    events: list[tuple[float, pus.EventReport]] = field(default_factory=list)
    by_type: dict[tuple[int, int, str], int] = field(default_factory=dict)  # (service, subtype, report): count

    def add(self, decoded: tuple[pus.TmHeader, pus.TmReport] | None) -> None:
        """Count and file one packet's decoding (None: an undecodable packet)."""
        self.packets += 1
        if decoded is None:
            self.undecodable += 1
            return
        header, report = decoded
        key = (header.service, header.subservice, type(report).__name__)
        self.by_type[key] = self.by_type.get(key, 0) + 1
        t = header.obt_s
        if isinstance(report, pus.Housekeeping):
            self.housekeeping.append(t, report)
        elif isinstance(report, pus.NavigationReport):
            self.navigation.append((t, report))
        elif isinstance(report, pus.EstimateReport):
            self.estimates.append((t, report))
        elif isinstance(report, pus.EventReport):
            self.events.append((t, report))
            if isinstance(report, pus.ModeChangedEvent):
                self.mode_changes.append((t, report))


def decoded_telemetry(packets: Iterable[bytes], source: str) -> Telemetry:
    """Decode TM packets into a Telemetry, one at a time (no list of every decoded report is held); undecodable ones
    are counted, never fatal."""
    tm = Telemetry(source=source)
    for raw in packets:
        try:
            decoded: tuple[pus.TmHeader, pus.TmReport] | None = pus.decode_tm(raw)
        except pus.PacketError:
            decoded = None
        tm.add(decoded)
    tm.housekeeping.trim()
    return tm


def received_telemetry(received: Iterable[ReceivedPacket], source: str) -> Telemetry:
    """The Telemetry of the packets ground received (their decoding is kept, so nothing is decoded twice)."""
    return telemetry_of((None if p.header is None or p.report is None else (p.header, p.report)
                         for p in received), source)


def telemetry_of(decoded: Iterable[tuple[pus.TmHeader, pus.TmReport] | None], source: str) -> Telemetry:
    """A Telemetry from packets already decoded (None: an undecodable one, counted)."""
    tm = Telemetry(source=source)
    for item in decoded:
        tm.add(item)
    tm.housekeeping.trim()
    return tm


def load_telemetry(run_dir: Path) -> Telemetry | None:
    """The run's telemetry from tm.bin, else from the raw packets in archive.sqlite; None if neither exists;
    ArchiveError if only a damaged archive is there."""
    tm_bin = run_dir / "tm.bin"
    if tm_bin.is_file():
        packets, tail = pus.complete_packets(tm_bin.read_bytes())
        tm = decoded_telemetry(packets, "tm.bin")
        tm.truncated_tail_octets = tail
        return tm
    db = run_dir / "archive.sqlite"
    if db.is_file():
        try:
            archive = Archive.read_only(db)  # a report never changes the archive
            try:
                raws = archive.raw_packets()
            finally:
                archive.close()
        except sqlite3.DatabaseError as exc:
            raise ArchiveError(f"{db}: damaged database: {exc}") from None
        return decoded_telemetry(raws, "archive.sqlite (no tm.bin)")
    return None
