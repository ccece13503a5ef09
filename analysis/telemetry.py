"""The telemetry of a run, decoded by kind: from tm.bin, else from the raw packets of archive.sqlite."""

from __future__ import annotations

import sqlite3
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from contracts import pus
from ground.archive import Archive, ArchiveError
from ground.segment import ReceivedPacket

MODE_NAMES = {m.value: m.name for m in pus.Mode}


@dataclass
class Telemetry:
    """The decoded telemetry of a run, by kind, each entry (packet OBT s, report), in stream order."""

    source: str
    packets: int = 0
    undecodable: int = 0
    truncated_tail_octets: int = 0
    housekeeping: list[tuple[float, pus.Housekeeping]] = field(default_factory=list)
    navigation: list[tuple[float, pus.NavigationReport]] = field(default_factory=list)
    estimates: list[tuple[float, pus.EstimateReport]] = field(default_factory=list)
    mode_changes: list[tuple[float, pus.ModeChangedEvent]] = field(default_factory=list)
    events: list[tuple[float, pus.EventReport]] = field(default_factory=list)
    by_type: dict[tuple[int, int, str], int] = field(default_factory=dict)  # (service, subtype, report): count


def decoded_telemetry(packets: Sequence[bytes], source: str) -> Telemetry:
    """Decode TM packets into a Telemetry; undecodable ones are counted, never fatal."""
    pairs: list[tuple[pus.TmHeader, pus.TmReport] | None] = []
    for raw in packets:
        try:
            pairs.append(pus.decode_tm(raw))
        except pus.PacketError:
            pairs.append(None)
    return telemetry_of(pairs, source)


def received_telemetry(received: Iterable[ReceivedPacket], source: str) -> Telemetry:
    """The Telemetry of the packets ground received (their decoding is kept, so nothing is decoded twice)."""
    return telemetry_of([None if p.header is None or p.report is None else (p.header, p.report)
                         for p in received], source)


def telemetry_of(decoded: Sequence[tuple[pus.TmHeader, pus.TmReport] | None], source: str) -> Telemetry:
    """A Telemetry from packets already decoded (None: an undecodable one, counted)."""
    tm = Telemetry(source=source, packets=len(decoded))
    for item in decoded:
        if item is None:
            tm.undecodable += 1
            continue
        header, report = item
        key = (header.service, header.subservice, type(report).__name__)
        tm.by_type[key] = tm.by_type.get(key, 0) + 1
        t = header.obt_s
        if isinstance(report, pus.Housekeeping):
            tm.housekeeping.append((t, report))
        elif isinstance(report, pus.NavigationReport):
            tm.navigation.append((t, report))
        elif isinstance(report, pus.EstimateReport):
            tm.estimates.append((t, report))
        elif isinstance(report, pus.EventReport):
            tm.events.append((t, report))
            if isinstance(report, pus.ModeChangedEvent):
                tm.mode_changes.append((t, report))
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
