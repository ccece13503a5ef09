"""PUS-C on board (ECSS-E-ST-70-41C): success reports only as the ack flags ask and failures always, reports and
responses to the TC's source, one message type counter per (service, subtype, destination), the time reference
status, and the time report rate as commanded."""

from __future__ import annotations

import pytest

from contracts import pus, sdls
from contracts.messages import SensorData, StepRequest
from obsw.config import ObswConfig
from obsw.software import FlightSoftware

CFG = ObswConfig()
KEYS = sdls.KeyRing.generate()


class Board:
    """A flight software and the ground's end of the link."""

    def __init__(self) -> None:
        self.fsw = FlightSoftware(CFG, KEYS)
        self.ground = sdls.Sender(KEYS)
        self.k = 0

    def step(self, *packets: bytes, obt_s: float | None = None) -> list[tuple[pus.TmHeader, pus.TmReport]]:
        """One control period with these TCs uplinked."""
        obt = 1000.0 + CFG.control_period_s * self.k if obt_s is None else obt_s
        req = StepRequest(step=self.k, obt_s=obt, uplink=tuple(self.ground.secure(p) for p in packets),
                          sensors=SensorData(star_tracker_q=(0, 0, 0, 1), gyro_rad_s=(0, 0, 0),
                                             wheel_speed_rad_s=(0, 0, 0)))
        self.k += 1
        return [pus.decode_tm(p) for p in self.fsw.step(req, None).downlink]


@pytest.mark.parametrize("flags", range(16))
def test_success_reports_follow_the_ack_flags(flags: int) -> None:
    """A ping with ack flags f gets TM[1,1] iff bit 3, TM[1,3] iff bit 2, TM[1,7] iff bit 0 (ECSS numbering)."""
    tm = Board().step(pus.encode_tc(pus.Ping(), CFG.apid, 1, ack_flags=flags))
    got = [h.subservice for h, r in tm if isinstance(r, pus.Verification)]
    assert got == [s for f, s in ((1, 1), (2, 3), (8, 7)) if flags & f]
    assert [r for _, r in tm if isinstance(r, pus.PingReply)]


@pytest.mark.parametrize("flags", [0b0000, 0b1111])
def test_failures_are_reported_whatever_the_flags(flags: int) -> None:
    """A refused command gets its completion failure, and a corrupted one its acceptance failure, with no flag set."""
    illegal = pus.encode_tc(pus.SetMode(mode=pus.Mode.AUTONOMOUS_TRACKING), CFG.apid, 2, ack_flags=flags)
    corrupted = bytearray(pus.encode_tc(pus.Ping(), CFG.apid, 3, ack_flags=flags))
    corrupted[-1] ^= 0xFF
    tm = Board().step(illegal, bytes(corrupted))
    failures = [(r.request_id.seq_count, h.subservice) for h, r in tm if isinstance(r, pus.Verification)
                and not r.success]
    assert failures == [(2, 8), (3, 2)]


def test_reports_go_to_the_source_and_counters_count_per_type_and_destination() -> None:
    """Two sources ping: each gets its verification reports and ping reply; each (service, subtype, destination)
    counts 0, 1, 2... on its own; housekeeping goes to the configured ground id; the sequence count is gapless."""
    board = Board()
    tm = []
    for k in range(3):
        tm += board.step(pus.encode_tc(pus.Ping(), CFG.apid, 10 + k, source_id=7),
                         pus.encode_tc(pus.Ping(), CFG.apid, 20 + k, source_id=9))
    by_key: dict[tuple[int, int, int], list[int]] = {}
    for h, r in tm:
        by_key.setdefault((h.service, h.subservice, h.destination_id), []).append(h.msg_counter)
        if isinstance(r, pus.Verification):
            assert h.destination_id == (7 if r.request_id.seq_count < 20 else 9)
    assert by_key[(17, 2, 7)] == by_key[(17, 2, 9)] == by_key[(1, 7, 7)] == by_key[(1, 1, 9)] == [0, 1, 2]
    assert by_key[(3, 25, CFG.ground_id)] == [0]
    seqs = [h.seq_count for h, _ in tm]
    assert seqs == list(range(len(seqs)))


def test_time_reference_status_marks_the_period_of_a_jump() -> None:
    """Packets are stamped FREE_RUNNING, and STEPPED in the period where OBT jumped."""
    board = Board()
    first = board.step(obt_s=1000.0)
    jumped = board.step(pus.encode_tc(pus.Ping(), CFG.apid, 1), obt_s=1005.0)
    after = board.step(pus.encode_tc(pus.Ping(), CFG.apid, 2), obt_s=1005.1)
    assert {h.time_status for h, _ in first + after} == {pus.TimeReferenceStatus.FREE_RUNNING}
    assert {h.time_status for h, _ in jumped} == {pus.TimeReferenceStatus.STEPPED}
    assert any(isinstance(r, pus.ClockJumpEvent) for _, r in jumped)


def test_time_reports_carry_the_commanded_rate() -> None:
    """After TC[9,1] with exponent 2, TM[9,2] reports rate 2, one every 4 s of OBT (to a control period); after
    TC[200,6], rate 0."""
    board = Board()
    reports = []
    for k in range(90):
        tcs = (pus.encode_tc(pus.SetTimeReportRate(rate_exponent=2), CFG.apid, 1),) if k == 0 else ()
        reports += [(h.obt_s, r.rate_exponent) for h, r in board.step(*tcs) if isinstance(r, pus.TimeReport)]
    assert [rate for _, rate in reports] == [2, 2, 2]
    gaps = [b - a for (a, _), (b, _) in zip(reports, reports[1:])]
    assert len(gaps) == 2 and all(abs(g - 4.0) <= CFG.control_period_s + 2**-15 for g in gaps), gaps
    later = board.step(pus.encode_tc(pus.RequestTimeReports(count=1), CFG.apid, 2)) + board.step()
    assert [r.rate_exponent for _, r in later if isinstance(r, pus.TimeReport)] == [0]
