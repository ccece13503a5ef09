"""Telemetry archive: nothing lost, gaps found, bad packets kept raw, queries and CSV export exact, fast enough."""

from __future__ import annotations

import csv
import sqlite3
import tempfile
import time
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from contracts.pus import (
    FaultCode,
    FaultEvent,
    Housekeeping,
    Mode,
    ModeChangedEvent,
    PingReply,
    RequestId,
    Stage,
    TimeReport,
    Verification,
    encode_tm,
    split_packets,
)
from ground.archive import Archive, ArchiveError, parameters_of
from contracts.link import LinkConfig

APID = 0x0C1


def _hk(i: int) -> Housekeeping:
    """A housekeeping report whose values follow i (float32-exact)."""
    return Housekeeping(
        mode=Mode(i % 5),
        q=(0.5, -0.5, 0.5, 0.5),
        rate_rad_s=(i * 0.25, -i * 0.125, 1.0),
        wheel_speed_rad_s=(float(i), 2.0 * i, 3.0 * i),
        wheel_momentum_nms=(0.0, 0.5, 1.0),
        pointing_error_rad=None if i % 2 else i * 0.5,
        best_ca_obt_s=1000.0 + i if i % 3 == 0 else None,
        best_ca_distance_km=55.0 if i % 3 == 0 else None,
    )


def _hk_packets(n: int, seq0: int = 0, obt0: float = 100.0) -> list[bytes]:
    return [encode_tm(_hk(i), APID, (seq0 + i) % 16384, obt0 + 0.5 * i, i % 65536) for i in range(n)]


def test_every_packet_is_stored_and_counted(tmp_path: Path) -> None:
    """N mixed packets in: N rows, per-service counts, and tm.bin holding exactly the packets sent, in order."""
    reports = [
        _hk(1),
        PingReply(),
        TimeReport(obt_s=12.5),
        ModeChangedEvent(from_mode=Mode.STANDBY, to_mode=Mode.ACQUISITION, cause="C/A-240 s"),
        FaultEvent(fault_code=FaultCode.WHEELS_CANNOT_CONTROL, reason="wheel 2 stuck"),
        Verification(stage=Stage.ACCEPTANCE, request_id=RequestId(apid=APID, seq_count=4)),
        _hk(2),
    ]
    sent = [encode_tm(r, APID, i, 10.0 + i, i) for i, r in enumerate(reports)]
    with Archive(tmp_path / "a.sqlite", batch_size=3) as arc:
        results = [arc.store(p, 1000.0 + i) for i, p in enumerate(sent)]
        counts = arc.counts()
    assert [r.packet_id for r in results] == list(range(1, 8)) and all(r.decoded for r in results)
    assert counts["stored"] == counts["decoded"] == 7 and counts["undecodable"] == 0
    assert counts["TM[3,25]"] == 2 and counts["TM[17,2]"] == 1 and counts["TM[9,2]"] == 1
    assert counts["TM[5,1]"] == 1 and counts["TM[5,4]"] == 1 and counts["TM[1,1]"] == 1
    assert counts["gaps"] == counts["missing"] == 0
    assert split_packets((tmp_path / "tm.bin").read_bytes()) == sent
    with sqlite3.connect(tmp_path / "a.sqlite") as db:
        assert [bytes(r) for (r,) in db.execute("SELECT raw FROM packets ORDER BY id")] == sent


@settings(max_examples=25, deadline=None)
@given(
    st.integers(0, 16383),
    st.lists(st.booleans(), min_size=2, max_size=60),
)
def test_gaps_match_the_dropped_runs(seq0: int, keep: list[bool]) -> None:
    """Dropping packets (across the 14-bit wrap) yields one gap per run of drops, with its size and position."""
    keep[0] = keep[-1] = True
    packets = _hk_packets(len(keep), seq0)
    expected = []
    run = 0
    for i, k in enumerate(keep):
        if not k:
            run += 1
        elif run:
            expected.append(((seq0 + i - run) % 16384, (seq0 + i) % 16384, run))
            run = 0
    with tempfile.TemporaryDirectory() as d, Archive(Path(d) / "a.sqlite") as arc:
        results = [arc.store(p, 0.0) for p, k in zip(packets, keep, strict=True) if k]
        gaps = arc.gaps()
        counts = arc.counts()
    assert [(g.expected_seq, g.received_seq, g.missing) for g in gaps] == expected
    assert all(g.apid == APID for g in gaps)
    assert counts["missing"] == keep.count(False) and counts["gaps"] == len(expected)
    assert sum(r.missing for r in results) == keep.count(False)


def test_duplicates_and_late_packets_are_not_gaps(tmp_path: Path) -> None:
    """A repeated packet is a duplicate, an older one arriving late is 'late'; neither is a gap nor moves the count."""
    p = _hk_packets(5)
    with Archive(tmp_path / "a.sqlite") as arc:
        kinds = [arc.store(x, 0.0).anomaly for x in (p[0], p[1], p[3], p[3], p[2], p[4])]
        counts = arc.counts()
        gaps = arc.gaps()
    assert kinds == [None, None, "gap", "duplicate", "late", None]
    assert counts["duplicates"] == 1 and counts["late"] == 1 and counts["gaps"] == 1 and counts["missing"] == 1
    assert [(g.expected_seq, g.received_seq) for g in gaps] == [(2, 3)]


def test_long_outage_is_a_gap_not_a_late_packet(tmp_path: Path) -> None:
    """A jump of more than half the count range with a later OBT is a gap of that size."""
    first = encode_tm(PingReply(), APID, 10, 1.0, 0)
    after = encode_tm(PingReply(), APID, 10 + 9000, 20000.0, 1)
    with Archive(tmp_path / "a.sqlite") as arc:
        arc.store(first, 0.0)
        result = arc.store(after, 1.0)
    assert (result.anomaly, result.missing) == ("gap", 8999)


def test_corrupted_packet_is_kept_raw_and_counted(tmp_path: Path) -> None:
    """A packet with a bad CRC is stored raw with its error, counted, written to tm.bin, and leaves a gap."""
    p = _hk_packets(3)
    bad = bytearray(p[1])
    bad[30] ^= 0x40
    bad_raw = bytes(bad)
    with Archive(tmp_path / "a.sqlite") as arc:
        results = [arc.store(x, 5.0) for x in (p[0], bad_raw, p[2], b"\x08")]
        counts = arc.counts()
        lost = arc.undecodable()
        gaps = arc.gaps()
    assert [r.decoded for r in results] == [True, False, True, False]
    assert "CrcMismatch" in (results[1].error or "") and "TruncatedPacket" in (results[3].error or "")
    assert counts["stored"] == 4 and counts["undecodable"] == 2 and counts["decoded"] == 2
    assert [u.raw for u in lost] == [bad_raw, b"\x08"] and lost[0].packet_id == 2
    assert [(g.expected_seq, g.received_seq, g.missing) for g in gaps] == [(1, 2, 1)]
    assert (tmp_path / "tm.bin").read_bytes() == p[0] + bad_raw + p[2] + b"\x08"


def test_query_returns_the_values_sent_in_the_obt_window(tmp_path: Path) -> None:
    """query(name, from, to) gives exactly the values sent with OBT in [from, to], in OBT order; None is absent."""
    packets = _hk_packets(40)
    with Archive(tmp_path / "a.sqlite") as arc:
        for p in packets:
            arc.store(p, 0.0)
        speeds = arc.query("Housekeeping.wheel_speed_rad_s[1]", 105.0, 110.0)
        pointing = arc.query("Housekeeping.pointing_error_rad")
        modes = arc.query("Housekeeping.mode", 100.0, 101.0)
    assert [(s.obt_s, s.value) for s in speeds] == [(100.0 + 0.5 * i, 2.0 * i) for i in range(10, 21)]
    assert [s.value for s in pointing] == [i * 0.5 for i in range(0, 40, 2)]
    assert [s.value for s in modes] == [0, 1, 2]


def test_csv_export_parses_back(tmp_path: Path) -> None:
    """The exported CSV read back with the csv module equals the archive's values, empty where absent."""
    names = ["Housekeeping.rate_rad_s[0]", "Housekeeping.best_ca_obt_s", "ModeChangedEvent.cause"]
    packets = _hk_packets(12)
    packets.append(encode_tm(ModeChangedEvent(from_mode=0, to_mode=1, cause="cmd, \"quoted\""), APID, 12, 200.0, 0))
    with Archive(tmp_path / "a.sqlite") as arc:
        for i, p in enumerate(packets):
            arc.store(p, 50.0 + i)
        n = arc.export_csv(names, tmp_path / "out.csv")
        truth = {name: {s.packet_id: s.value for s in arc.query(name)} for name in names}
    with open(tmp_path / "out.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert n == len(rows) == 13
    assert [float(r["obt_s"]) for r in rows] == [100.0 + 0.5 * i for i in range(12)] + [200.0]
    for r in rows:
        pid = int(r["packet_id"])
        assert float(r["receipt_utc_s"]) == 50.0 + pid - 1
        for name in names[:2]:
            expected = truth[name].get(pid)
            assert (float(r[name]) if r[name] else None) == expected
        assert (r[names[2]] or None) == truth[names[2]].get(pid)
    assert rows[-1][names[2]] == 'cmd, "quoted"'


def test_reopening_continues_ids_and_sequence(tmp_path: Path) -> None:
    """A reopened archive keeps its packets, continues ids, and still detects a gap across the restart."""
    p = _hk_packets(6)
    with Archive(tmp_path / "a.sqlite") as arc:
        for x in p[:3]:
            arc.store(x, 0.0)
    with Archive(tmp_path / "a.sqlite") as arc:
        r = arc.store(p[4], 1.0)
        counts = arc.counts()
    assert r.packet_id == 4 and (r.anomaly, r.missing) == ("gap", 1)
    assert counts["stored"] == 4
    assert split_packets((tmp_path / "tm.bin").read_bytes()) == p[:3] + [p[4]]


def test_highest_rate_has_no_loss_and_keeps_up(tmp_path: Path) -> None:
    """2,000 HK packets: all stored, none missing, each value queryable, archived faster than the link can send."""
    n = 2000
    packets = _hk_packets(n, seq0=16000)
    # Highest telemetry rate: the whole downlink filled with HK packets (215 octets).
    link_rate_pkt_s = LinkConfig().downlink_rate_bps / (8 * len(packets[0]))
    with Archive(tmp_path / "a.sqlite") as arc:
        t0 = time.perf_counter()
        for i, p in enumerate(packets):
            arc.store(p, i * 0.01)
        arc.flush()
        elapsed = time.perf_counter() - t0
        counts = arc.counts()
        samples = arc.query("Housekeeping.wheel_speed_rad_s[0]")
    assert counts["stored"] == counts["decoded"] == counts["TM[3,25]"] == n
    assert counts["gaps"] == counts["missing"] == counts["undecodable"] == 0
    assert [s.value for s in samples] == [float(i) for i in range(n)]
    assert split_packets((tmp_path / "tm.bin").read_bytes()) == packets
    assert n / elapsed > 2 * link_rate_pkt_s, f"{n / elapsed:.0f} packets/s vs link {link_rate_pkt_s:.0f}"


def test_parameter_names_flatten_the_report() -> None:
    """A report's parameters are <Report>.<field>, [i] for items, nested with '.', None skipped."""
    names = dict(parameters_of(_hk(1)))
    assert names["Housekeeping.q[3]"] == 0.5 and names["Housekeeping.mode"] == 1
    assert "Housekeeping.pointing_error_rad" not in names and "Housekeeping.wheel_speed_rad_s[2]" in names
    v = dict(parameters_of(Verification(stage=Stage.START, request_id=RequestId(apid=3, seq_count=9), failure_code=7)))
    assert v == {
        "Verification.stage": 3,
        "Verification.request_id.apid": 3,
        "Verification.request_id.seq_count": 9,
        "Verification.failure_code": 7,
        "Verification.reason": "",
    }


def test_misuse_raises_archive_errors(tmp_path: Path) -> None:
    """A non-finite receipt time, an unknown export parameter and use after close raise ArchiveError."""
    arc = Archive(tmp_path / "a.sqlite")
    arc.store(_hk_packets(1)[0], 0.0)
    with pytest.raises(ArchiveError, match="receipt_utc_s"):
        arc.store(_hk_packets(1)[0], float("nan"))
    with pytest.raises(ArchiveError, match="Housekeeping.nope"):
        arc.export_csv(["Housekeeping.nope"], tmp_path / "x.csv")
    arc.close()
    arc.close()
    with pytest.raises(ArchiveError, match="closed"):
        arc.store(_hk_packets(1)[0], 0.0)
