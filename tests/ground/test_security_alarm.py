"""Ground raises a security alarm for a verification report of a TC it never sent and for a TC the spacecraft
refused as unauthentic; the archive keeps the alarms and counts them."""

from __future__ import annotations

from pathlib import Path

from contracts import pus, sdls
from ground.archive import Archive
from scenario import compose
from scenario.model import scenario_from_dict


def _tm(report: pus.TmReport, seq: int) -> bytes:
    return pus.encode_tm(report, 0x0C1, seq, 1000.0 + seq, 0, destination_id=1)


def test_reports_of_foreign_tcs_and_refusals_raise_alarms(tmp_path: Path) -> None:
    """The report of a TC ground sent is quiet; one of a TC it never sent (success or failure) and a security
    rejection event each raise one alarm, which the archive stores with its packet."""
    seg = compose.ground_segment(scenario_from_dict({"name": "x", "ground": {"upload_nominal_at_s": 0.0}}),
                                 keys=sdls.KeyRing.generate())
    units, _, _ = seg.step(0.0, (), ())
    assert units and seg.radiated and all(sdls.packet_of(u) == p for u, p in zip(units, seg.radiated))
    ours = pus.request_id_of(seg.radiated[0])
    foreign = pus.RequestId(apid=0x0C1, seq_count=4000)
    downlink = (_tm(pus.Verification(stage=pus.Stage.COMPLETION, request_id=ours), 0),
                _tm(pus.Verification(stage=pus.Stage.COMPLETION, request_id=foreign), 1),
                _tm(pus.Verification(stage=pus.Stage.ACCEPTANCE, request_id=foreign, failure_code=9, reason="MAC"), 2),
                _tm(pus.TcSecurityRejectedEvent(spi=3, arsn=17, failure_code=int(pus.FailureCode.REPLAYED)), 3))
    _, received, log = seg.step(10.0, downlink, (10.0,) * 4)
    alarms = [p.alarm for p in received]
    assert alarms[0] is None and all(a is not None and a.startswith("SECURITY ALARM") for a in alarms[1:])
    assert "sequence 4000, which ground never sent" in alarms[1] and "failure 0x0009" in alarms[2]
    assert "REPLAYED, SPI 3, ARSN 17" in alarms[3]
    assert seg.state.alarms == alarms[1:] and all(a in log for a in alarms[1:])
    with Archive(tmp_path / "archive.sqlite") as archive:
        for p in received:
            stored = archive.store(p.raw, p.receipt_utc_s)
            if p.alarm:
                archive.alarm(p.receipt_utc_s, p.alarm, stored.packet_id)
        assert archive.alarms() == [(10.0, a) for a in alarms[1:]]
        assert archive.counts()["alarms"] == 3


def test_scheduled_tcs_count_apart_and_are_known_to_ground() -> None:
    """TCs inside the timeline's inserts take sequence counts from 0x2000 on, the radiated ones stay gapless from
    0, and ground counts both as its own (no alarm for their reports)."""
    sc = scenario_from_dict({"name": "x", "ground": {"upload_nominal_at_s": 0.0, "timeline_file": None}})
    from timeline.parse import timeline_from_data

    tl = timeline_from_data({"commands": [{"time": "CA-50s", "command": "stop_imaging"},
                                          {"time": "+1s", "command": "start_imaging"}]}, "t")
    seg = compose.ground_segment(sc, tl, sdls.KeyRing.generate())
    seg.step(0.0, (), ())
    radiated = [pus.decode_tc(p) for p in seg.radiated]
    assert [h.seq_count for h, _ in radiated] == [0, 1, 2, 3]  # trajectory, time reports, bad-pixel map, insert
    assert isinstance(radiated[2][1], pus.LoadBadPixelMap)
    insert = radiated[-1][1]
    assert isinstance(insert, pus.InsertCaRelativeActivities)
    inner = [a.request_id.seq_count for a in insert.activities]
    assert inner == [0x2000, 0x2001]
    assert {a.request_id for a in insert.activities} <= seg.state.sent_requests
