"""Ground verifies what it radiates: a TC without acceptance within the round-trip light time, its transmission and
the margin is re-sent with a new sequence count, up to max_resends times, then raised as an alarm; every on-board
event of medium or high severity raises an alarm, a low one does not."""

from __future__ import annotations

import re

import pytest

from contracts import pus
from scenario import compose
from scenario.model import scenario_from_dict

APID = 0x0C1


def _segment(**ground: object):  # noqa: ANN202
    return compose.ground_segment(scenario_from_dict({"name": "x", "ground": {"upload_nominal_at_s": 0.0, **ground}}))


def _tm(report: pus.TmReport, seq: int) -> bytes:
    return pus.encode_tm(report, APID, seq, 1000.0 + seq, 0, destination_id=1)


def _run(seg, until_s: float, accept: set[int] = frozenset()) -> tuple[list[tuple[float, int, str]], list[str]]:  # noqa: ANN001
    """Step ground every second from 0 to ``until_s``; acceptance reports come back for the TCs sent at the times
    in ``accept`` (s), one round trip later. (UTC, sequence count, name) of everything radiated, and the log."""
    sent, log, pending = [], [], []
    light = seg.cfg.link.one_way_light_time_s
    for k in range(int(until_s) + 1):
        t = float(k)
        back = [p for p in pending if p[0] <= t]
        pending = [p for p in pending if p[0] > t]
        downlink = tuple(_tm(pus.Verification(stage=pus.Stage.ACCEPTANCE, request_id=rid), i)
                         for i, (_, rid) in enumerate(back))
        _, _, lines = seg.step(t, downlink, (t,) * len(downlink))
        log += lines
        for raw in seg.radiated:
            header, cmd = pus.decode_tc(raw, expected_apid=APID)
            sent.append((t, header.seq_count, type(cmd).__name__))
            if k in accept:
                pending.append((t + 2 * light + 1.0, header.request_id))
    return sent, log


def test_an_unaccepted_upload_is_re_sent_with_new_counts_then_alarmed() -> None:
    """The nominal upload never acknowledged: each of its TCs re-sent twice, each time with a new sequence count,
    once the round trip, its transmission and the margin have passed; then one alarm per TC, and nothing more."""
    seg = _segment(max_resends=2, verification_margin_s=10.0)
    light = seg.cfg.link.one_way_light_time_s
    sent, log = _run(seg, 4 * (2 * light + 12.0) + 5.0)  # the bad-pixel map's transmission takes longer
    first = [s for s in sent if s[0] == 0.0]
    upload = ["UploadNominalTrajectory", "SetTimeReportRate", "LoadBadPixelMap"]
    assert [n for _, _, n in first] == upload
    names = [n for _, _, n in sent]
    assert all(names.count(n) == 3 for n in upload)
    assert [c for _, c, _ in sent] == list(range(len(sent)))  # every send its own sequence count
    resend_times = sorted({t for t, _, _ in sent if t > 0})
    assert resend_times[0] == pytest.approx(2 * light + 10.0, abs=1.0)
    warnings = [x for x in log if x.startswith("WARNING") and "re-sent" in x]
    alarms = [x for x in log if x.startswith("ALARM") and "given up" in x]
    assert len(warnings) == 2 * len(upload) and len(alarms) == len(upload) and seg.awaiting == 0
    raised = seg.take_alarms()
    assert seg.state.alarms == alarms == [text for _, text in raised]
    # each alarm comes a round trip and the margin after its TC's last send at the earliest
    last_sent = [float(m.group(1)) for _, text in raised if (m := re.search(r"sent at UTC ([0-9.]+) s", text))]
    assert all(t >= sent_at + 2 * light + 10.0 for (t, _), sent_at in zip(raised, last_sent, strict=True))


def test_an_accepted_tc_is_never_re_sent() -> None:
    """Acceptance reports arriving after one round trip: nothing re-sent, nothing awaited, no alarm."""
    seg = _segment()
    sent, log = _run(seg, 200.0, accept={0})
    assert [n for _, _, n in sent] == ["UploadNominalTrajectory", "SetTimeReportRate", "LoadBadPixelMap"]
    assert seg.awaiting == 0 and seg.state.alarms == []
    assert not [x for x in log if x.startswith(("WARNING", "ALARM"))]


@pytest.mark.parametrize(("severity", "alarmed"), [(pus.Severity.LOW, False), (pus.Severity.MEDIUM, True),
                                                    (pus.Severity.HIGH, True)])
def test_events_of_medium_or_high_severity_raise_an_alarm(severity: pus.Severity, alarmed: bool) -> None:
    """An on-board event raises an alarm (kept with its packet) from the configured severity up."""
    seg = _segment()
    event = pus.WheelFailedEvent(severity=severity, wheel=1, commanded_nms=1e-3, measured_nms=0.0)
    _, received, log = seg.step(10.0, (_tm(event, 0),), (10.0,))
    assert (received[0].alarm is not None) == alarmed
    if alarmed:
        assert received[0].alarm.startswith(f"ALARM: OBT 1000.00 s: {severity.name} event WheelFailedEvent")
        assert received[0].alarm in log and seg.state.alarms == [received[0].alarm]
