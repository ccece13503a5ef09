"""Mission PUS packets: round trips, independent parsing by spacepackets, layout, and typed decoding errors."""

from __future__ import annotations

import binascii
import math
import struct

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from spacepackets.ecss.req_id import RequestId as SpRequestId
from spacepackets.ecss.tc import PusTc
from spacepackets.ecss.tm import PusTm

from contracts.cuc import cuc_decode, cuc_encode
from contracts.pus import (
    HK_SIZE,
    BadArgument,
    CrcMismatch,
    DeleteActivities,
    FailureCode,
    Housekeeping,
    InsertActivities,
    LengthMismatch,
    MalformedPacket,
    Mode,
    ModeChangedEvent,
    NavigationReport,
    PacketError,
    Ping,
    PingReply,
    RequestId,
    SetCameraCadence,
    SetMode,
    SetTimeReportRate,
    Stage,
    StartImaging,
    TimeReport,
    TruncatedPacket,
    UnknownService,
    UploadNominalTrajectory,
    Verification,
    WrongApid,
    decode_tc,
    decode_tm,
    encode_tc,
    encode_tm,
    request_id_of,
    split_packets,
)
from tests.contracts.strategies import apids, counters, grid_obt, reports, seqs, telecommands

# Values of every packet, generated from the dictionary (tests/contracts/strategies.py).
commands = telecommands

_SETTINGS = settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])

# ------------------------------------------------------------------------------------------------ round trips
# (every packet's round trip: tests/contracts/test_dictionary.py)


@_SETTINGS
@given(commands, apids, seqs)
def test_spacepackets_parses_our_telecommands(cmd: object, apid: int, seq: int) -> None:
    """PusTc.unpack (with its CRC check) reads what we build; stdlib crc_hqx agrees the CRC is intact."""
    raw = encode_tc(cmd, apid, seq)  # type: ignore[arg-type]
    tc = PusTc.unpack(raw)
    assert (tc.apid, tc.seq_count, tc.service) == (apid, seq, cmd.SERVICE)  # type: ignore[attr-defined]
    assert tc.message_subtype == cmd.subservice()  # type: ignore[attr-defined]
    assert tc.packet_len == len(raw)
    assert binascii.crc_hqx(raw[:-2], 0xFFFF) == struct.unpack(">H", raw[-2:])[0]
    assert SpRequestId.from_pus_tc(tc).pack() == RequestId(apid=apid, seq_count=seq).packed()


@_SETTINGS
@given(reports, apids, seqs, grid_obt, counters)
def test_spacepackets_parses_our_telemetry(report: object, apid: int, seq: int, obt_s: float, counter: int) -> None:
    """PusTm.unpack with a 7-octet time stamp reads what we build; the stamp is our CUC of the OBT."""
    raw = encode_tm(report, apid, seq, obt_s, counter)  # type: ignore[arg-type]
    tm = PusTm.unpack(raw, timestamp_len=7)
    assert (tm.apid, tm.seq_count, tm.service, tm.message_subtype) == (
        apid,
        seq,
        report.SERVICE,  # type: ignore[attr-defined]
        report.subservice(),  # type: ignore[attr-defined]
    )
    assert tm.pus_tm_sec_header.message_counter == counter
    assert bytes(tm.timestamp) == cuc_encode(obt_s) and cuc_decode(tm.timestamp) == obt_s
    assert binascii.crc_hqx(raw[:-2], 0xFFFF) == struct.unpack(">H", raw[-2:])[0]


def test_ping_matches_the_ecss_reference_bytes() -> None:
    """A ping to APID 1, count 22 is byte-for-byte the PUS-C example of the spacepackets documentation."""
    assert encode_tc(Ping(), 1, 22).hex(",") == "18,01,c0,16,00,06,2f,11,01,00,00,ab,62"


def _hk_with_q0(x: float) -> Housekeeping:
    return Housekeeping(
        mode=Mode.SAFE, q=(x, 0, 0, 1), rate_rad_s=(0, 0, 0), wheel_speed_rad_s=(x,), wheel_momentum_nms=(0,)
    )


@given(st.floats(allow_nan=False, allow_infinity=False, min_value=-1e30, max_value=1e30))
def test_float32_fields_round_to_nearest_float32(x: float) -> None:
    """An arbitrary float64 in a float32 field comes back as the nearest float32 (relative error <= 2^-24)."""
    hk = _hk_with_q0(x)
    _, back = decode_tm(encode_tm(hk, 1, 0, 0.0, 0))
    assert back.q[0] == struct.unpack(">f", struct.pack(">f", x))[0]  # type: ignore[union-attr]
    assert abs(back.q[0] - x) <= abs(x) * 2.0**-24 + 1.5e-45  # type: ignore[union-attr]


# -------------------------------------------------------------------------------------------------- layouts


def test_housekeeping_layout_is_as_documented() -> None:
    """HK source data is 221 octets at the documented offsets (85 of navigation, three u16 TC security counters,
    then 11 + 11 task times, two latencies, three u32 counters, the estimated gyro bias and attitude sigma, the wheel
    masks and two u16 FDIR counters); the whole packet is 6 + 14 + 221 + 2 octets."""
    last = tuple(1e-4 * (k + 1) for k in range(11))
    hk = Housekeeping(
        mode=Mode.AUTONOMOUS_TRACKING,
        q=(0.5, -0.5, 0.25, 0.625),
        rate_rad_s=(1e-3, -2e-3, 3e-3),
        wheel_speed_rad_s=(10.0, 20.0, 30.0),
        wheel_momentum_nms=(0.001, 0.002, 0.003),
        pointing_error_rad=1.5e-4,
        best_ca_obt_s=1234567.890625,
        best_ca_distance_km=55.5,
        best_mse_rad2=None,
        task_time_last_s=last,
        task_time_max_s=tuple(2 * x for x in last),
        exposure_to_centroid_s=None,
        centroid_to_torque_s=0.25,
        task_overruns=7,
        frame_overruns=3,
        skipped_releases=65536,
        gyro_bias_rad_s=(1.0, -2.0, 0.5),
        attitude_sigma_rad=0.25,
        wheels_in_use=0b1011,
        wheels_failed=0b0100,
        frames_discarded=9,
        measurements_rejected=513,
    )
    assert HK_SIZE == 221
    raw = encode_tm(hk, 0xC1, 1, 100.0, 0)
    assert len(raw) == 6 + 7 + 7 + 221 + 2 == 243
    d = raw[20:-2]
    assert len(d) == 221
    assert struct.unpack(">H", d[0:2]) == (1,)
    assert (d[2], d[3], d[4]) == (4, 0b10011, 3)
    assert struct.unpack(">4f", d[5:21]) == (0.5, -0.5, 0.25, 0.625)
    assert struct.unpack(">3f", d[21:33]) == tuple(struct.unpack(">f", struct.pack(">f", v))[0] for v in hk.rate_rad_s)
    assert struct.unpack(">4f", d[33:49]) == (10.0, 20.0, 30.0, 0.0)
    assert struct.unpack(">f", d[65:69])[0] == pytest.approx(1.5e-4, rel=1e-7)
    assert struct.unpack(">d", d[69:77]) == (1234567.890625,)
    assert struct.unpack(">f", d[77:81]) == (55.5,)
    assert math.isnan(struct.unpack(">f", d[81:85])[0])
    assert struct.unpack(">3H", d[85:91]) == (0, 0, 0)
    assert struct.unpack(">11f", d[91:135]) == pytest.approx(last, rel=1e-7)
    assert struct.unpack(">11f", d[135:179]) == pytest.approx(tuple(2 * x for x in last), rel=1e-7)
    assert math.isnan(struct.unpack(">f", d[179:183])[0]) and struct.unpack(">f", d[183:187]) == (0.25,)
    assert struct.unpack(">3I", d[187:199]) == (7, 3, 65536)
    assert struct.unpack(">4f", d[199:215]) == (1.0, -2.0, 0.5, 0.25)
    assert (d[215], d[216]) == (0b1011, 0b0100)
    assert struct.unpack(">2H", d[217:221]) == (9, 513)


def test_navigation_report_is_49_octets() -> None:
    """The navigation report's source data is u32 + u8 + 4 f32 + u32 + 3 f64 = 49 octets."""
    raw = encode_tm(NavigationReport(frame_id=7), 0xC1, 1, 1.0, 0)
    assert len(raw) == 6 + 14 + 49 + 2
    assert raw[20:25] == b"\x00\x00\x00\x07\x00"


def test_request_id_is_the_first_four_octets_of_the_tc() -> None:
    """A verification report quotes the TC's first 4 octets, as spacepackets' RequestId does."""
    raw = encode_tc(SetMode(mode=Mode.STANDBY), 0x0C1, 1234)
    rid = request_id_of(raw)
    assert rid.packed() == raw[:4] == SpRequestId.from_pus_tc(PusTc.unpack(raw)).pack()


def test_mode_accepts_names() -> None:
    """Modes can be given by name, as the timeline spells them."""
    assert SetMode(mode="NOMINAL_TRACKING").mode is Mode.NOMINAL_TRACKING  # type: ignore[arg-type]


# ----------------------------------------------------------------------------------------------------- errors


def _valid_tc() -> bytes:
    return encode_tc(SetCameraCadence(period_s=1.0, exposure_s=0.01), 0x0C1, 77)


@_SETTINGS
@given(commands, st.data())
def test_any_single_bit_flip_is_rejected(cmd: object, data: st.DataObject) -> None:
    """CRC-16 plus header checks reject every single-bit corruption with a PacketError."""
    raw = bytearray(encode_tc(cmd, 0x0C1, 5))  # type: ignore[arg-type]
    bit = data.draw(st.integers(0, 8 * len(raw) - 1))
    raw[bit // 8] ^= 0x80 >> (bit % 8)
    with pytest.raises(PacketError):
        decode_tc(bytes(raw))


@given(st.integers(6, 200), st.integers(0, 7))
def test_payload_corruption_is_a_crc_error_with_request_id(pos: int, bit: int) -> None:
    """A flipped bit after the primary header raises CrcMismatch carrying the TC's request id."""
    raw = bytearray(_valid_tc())
    raw[pos % (len(raw) - 6) + 6] ^= 1 << bit
    with pytest.raises(CrcMismatch) as exc:
        decode_tc(bytes(raw))
    assert exc.value.failure_code == FailureCode.BAD_CRC
    assert exc.value.request_id == RequestId(apid=0x0C1, seq_count=77)


@given(st.data())
def test_every_truncation_is_reported(data: st.DataObject) -> None:
    """Any strict prefix of a valid TC or TM raises TruncatedPacket."""
    tc = _valid_tc()
    tm = encode_tm(TimeReport(obt_s=5.0), 0x0C1, 3, 5.0, 1)
    n_tc = data.draw(st.integers(0, len(tc) - 1))
    n_tm = data.draw(st.integers(0, len(tm) - 1))
    with pytest.raises(TruncatedPacket) as exc:
        decode_tc(tc[:n_tc])
    assert exc.value.failure_code == FailureCode.TRUNCATED
    assert (exc.value.request_id is None) == (n_tc < 4)
    with pytest.raises(TruncatedPacket):
        decode_tm(tm[:n_tm])


def test_trailing_octets_are_a_length_error() -> None:
    """A packet followed by extra octets raises LengthMismatch (bad length)."""
    with pytest.raises(LengthMismatch) as exc:
        decode_tc(_valid_tc() + b"\x00")
    assert exc.value.failure_code == FailureCode.BAD_LENGTH


@pytest.mark.parametrize(
    ("service", "sub", "code"),
    [
        (42, 1, FailureCode.UNKNOWN_SERVICE),
        (17, 9, FailureCode.UNKNOWN_SUBSERVICE),
        (200, 99, FailureCode.UNKNOWN_SUBSERVICE),
    ],
)
def test_unknown_service_is_typed(service: int, sub: int, code: FailureCode) -> None:
    """A TC built by spacepackets for a service/subtype we do not define raises UnknownService with its code."""
    raw = bytes(PusTc(service=service, message_subtype=sub, apid=0x0C1, seq_count=9).pack())
    with pytest.raises(UnknownService) as exc:
        decode_tc(raw)
    assert exc.value.failure_code == code
    assert (exc.value.service, exc.value.subservice) == (service, sub)
    assert exc.value.request_id == RequestId(apid=0x0C1, seq_count=9)


def _tc(service: int, sub: int, app_data: bytes) -> bytes:
    return bytes(PusTc(service=service, message_subtype=sub, apid=1, seq_count=2, app_data=app_data).pack())


@pytest.mark.parametrize(
    ("raw", "field"),
    [
        (_tc(200, 1, b"\x09"), "SetMode.mode"),
        (_tc(200, 1, b""), "SetMode.mode"),
        (_tc(200, 1, b"\x01\x00"), "SetMode"),
        (_tc(200, 3, struct.pack(">dd", 1.0, 2.0)), "SetCameraCadence"),
        (_tc(200, 3, struct.pack(">dd", -1.0, 0.1)), "SetCameraCadence.period_s"),
        (_tc(200, 2, struct.pack(">11d", 1, 55, 7, 1, 0, 0, 1, 0, 0, 1, 1)), "UploadNominalTrajectory"),
        (_tc(200, 2, struct.pack(">11d", 1, 55, 7, 2, 0, 0, 0, 1, 0, 1, 1)), "UploadNominalTrajectory"),
        (_tc(200, 4, struct.pack(">Bd", 2, 1.0)), "StartImaging.flags"),
        (_tc(9, 1, b""), "SetTimeReportRate.rate_exponent"),
        (_tc(11, 5, b"\x00\x02" + RequestId(apid=1, seq_count=1).packed()), "DeleteActivities.request_ids[1]"),
        (_tc(11, 5, b"\x00\x01\x00\x01\xc0\x01"), "DeleteActivities.request_ids[0]"),
        (_tc(11, 4, b"\x00\x01\x02" + bytes(6)), "InsertActivities.activities[0].release_obt_s"),
        (_tc(11, 4, b"\x00\x01" + cuc_encode(1.0) + bytes(3)), "InsertActivities.activities[0].tc_packet"),
        (_tc(200, 8, b"\x00\x01" + struct.pack(">d", -5.0) + cuc_encode(1.0) + bytes(3)),
         "InsertCaRelativeActivities.activities[0].tc_packet"),
    ],
)
def test_bad_arguments_name_the_field(raw: bytes, field: str) -> None:
    """Well-formed packets with bad application data raise BadArgument naming the field, with the request id."""
    with pytest.raises(BadArgument) as exc:
        decode_tc(raw)
    assert exc.value.field.startswith(field)
    assert exc.value.failure_code == FailureCode.BAD_ARGUMENT
    assert exc.value.request_id == RequestId(apid=1, seq_count=2)


def test_scheduled_tm_packet_is_rejected() -> None:
    """An activity wrapping a telemetry packet instead of a TC is a bad argument."""
    tm = encode_tm(PingReply(), 1, 0, 0.0, 0)
    raw = _tc(11, 4, b"\x00\x01" + cuc_encode(1.0) + tm)
    with pytest.raises(BadArgument, match="telemetry"):
        decode_tc(raw)


def test_unknown_event_id_is_a_bad_argument() -> None:
    """An event report with an undefined event id raises BadArgument on event_id."""
    raw = bytes(PusTm(service=5, message_subtype=1, timestamp=cuc_encode(1.0), source_data=b"\x00\x63").pack())
    with pytest.raises(BadArgument, match="event_id"):
        decode_tm(raw)


def test_tm_with_foreign_time_stamp_is_malformed() -> None:
    """A TM stamped with CDS (not our CUC P-field) raises MalformedPacket naming the time stamp."""
    raw = bytes(PusTm(service=17, message_subtype=2, timestamp=bytes([0x40]) + bytes(6)).pack())
    with pytest.raises(MalformedPacket, match="time stamp"):
        decode_tm(raw)


def test_telemetry_is_not_a_telecommand() -> None:
    """decode_tc refuses a TM packet and decode_tm a TC packet."""
    with pytest.raises(MalformedPacket, match="TM"):
        decode_tc(encode_tm(PingReply(), 1, 0, 0.0, 0))
    with pytest.raises(MalformedPacket, match="TC"):
        decode_tm(_valid_tc())


def test_wrong_apid_is_rejected_when_asked() -> None:
    """decode_tc with expected_apid refuses a TC addressed elsewhere."""
    with pytest.raises(WrongApid) as exc:
        decode_tc(_valid_tc(), expected_apid=0x0C2)
    assert exc.value.failure_code == FailureCode.WRONG_APID
    assert decode_tc(_valid_tc(), expected_apid=0x0C1)[0].apid == 0x0C1


def test_failure_codes_are_distinct() -> None:
    """Each kind of decoding error reports with its own service 1 code."""
    codes = [e.failure_code for e in (TruncatedPacket(""), LengthMismatch(""), CrcMismatch(""), MalformedPacket(""))]
    codes += [UnknownService(1, 1, False).failure_code, UnknownService(1, 1, True).failure_code]
    codes += [BadArgument("f", "x").failure_code, WrongApid("").failure_code]
    assert len(set(codes)) == len(codes)


def test_failure_report_answers_a_bad_tc() -> None:
    """Verification.failure_for turns a decoding error into an acceptance-failure report that round-trips."""
    with pytest.raises(PacketError) as exc:
        decode_tc(_tc(200, 1, b"\x09"))
    report = Verification.failure_for(exc.value)
    assert report is not None and not report.success and report.subservice() == 2
    assert report.failure_code == FailureCode.BAD_ARGUMENT and "SetMode.mode" in report.reason
    assert decode_tm(encode_tm(report, 0x0C1, 0, 1.0, 0))[1] == report
    assert Verification.failure_for(TruncatedPacket("x")) is None


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"apid": 2048, "seq": 0}, "apid"),
        ({"apid": 0, "seq": 16384}, "seq"),
    ],
)
def test_encode_rejects_header_fields_out_of_range(kwargs: dict[str, int], field: str) -> None:
    """APID and sequence count outside the primary header's bits raise BadArgument naming them."""
    with pytest.raises(BadArgument) as exc:
        encode_tc(Ping(), **kwargs)
    assert exc.value.field == field


def test_values_that_do_not_fit_are_refused_at_construction() -> None:
    """Too-long texts and floats beyond float32 are refused when the value is built."""
    with pytest.raises(ValueError, match="cause"):
        ModeChangedEvent(from_mode=Mode.SAFE, to_mode=Mode.STANDBY, cause="x" * 256)
    with pytest.raises(ValueError, match="q"):
        _hk_with_q0(1e39)
    with pytest.raises(ValueError, match="reason"):
        Verification(stage=Stage.ACCEPTANCE, request_id=RequestId(apid=1, seq_count=1), reason="no failure")


@_SETTINGS
@given(st.one_of(commands.map(lambda c: encode_tc(c, 1, 1)), reports.map(lambda r: encode_tm(r, 1, 1, 0.0, 0))),
       st.data())
def test_decoders_raise_only_packet_errors(raw: bytes, data: st.DataObject) -> None:
    """Any octets with a valid frame and CRC but scrambled data decode or raise a PacketError, nothing else."""
    body = bytearray(raw[:-2])
    for _ in range(data.draw(st.integers(1, 4))):
        body[data.draw(st.integers(6, len(body) - 1))] = data.draw(st.integers(0, 255))
    cut = data.draw(st.integers(6 + 5, len(body)))
    body = body[:cut]
    body[4:6] = struct.pack(">H", len(body) + 2 - 7)
    packet = bytes(body) + struct.pack(">H", binascii.crc_hqx(bytes(body), 0xFFFF))
    for decode in (decode_tc, decode_tm):
        try:
            decode(packet)
        except PacketError:
            pass


@given(st.binary(max_size=64))
def test_random_octets_raise_only_packet_errors(raw: bytes) -> None:
    """Arbitrary octets never escape the decoders as anything but a PacketError."""
    for decode in (decode_tc, decode_tm):
        try:
            decode(raw)
        except PacketError:
            pass


# ------------------------------------------------------------------------------------------------- streams


@settings(max_examples=50, deadline=None)
@given(st.lists(st.tuples(reports, apids, seqs), min_size=0, max_size=8))
def test_split_packets_recovers_concatenated_packets(items: list[tuple[object, int, int]]) -> None:
    """Splitting a concatenation of packets gives back each packet, in order."""
    packets = [encode_tm(r, a, s, 1.0, 0) for r, a, s in items]  # type: ignore[arg-type]
    assert split_packets(b"".join(packets)) == packets


def test_split_packets_reports_a_cut_tail() -> None:
    """A stream that ends inside a packet raises TruncatedPacket naming the offset."""
    p = encode_tm(PingReply(), 1, 0, 0.0, 0)
    with pytest.raises(TruncatedPacket, match=f"octet {len(p)}"):
        split_packets(p + p[:-1])
    with pytest.raises(TruncatedPacket, match="primary header"):
        split_packets(p + p[:3])
