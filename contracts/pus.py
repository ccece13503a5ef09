"""The mission's packets on the wire: PUS-C telecommands and telemetry on CCSDS space packets, built with spacepackets.

Every packet is a CCSDS space packet (unsegmented, secondary header present) with a PUS-C secondary header and a
CRC-16/CCITT (ibm-3740) trailer. Telemetry is stamped with OBT as a 7-octet CUC (``contracts.cuc``: P-field 0x2E,
4 coarse + 2 fine octets), so a TM header is 6 + 7 + 7 = 20 octets. All fields are big-endian.

What each packet carries is the dictionary (``contracts.dictionary``; ``flyby dictionary`` prints it as a table);
this module frames it and re-exports the dictionary's names, so callers write ``pus.SetMode``, ``pus.encode_tc``.

Decoding errors are ``PacketError`` subclasses carrying a PUS service-1 ``failure_code`` and, when the primary
header could be read, the ``request_id`` of the offending TC, so the OBSW can answer with a failure report.
"""

from __future__ import annotations

import binascii
import struct
from typing import TypeAlias, Union

from pydantic import Field
from spacepackets.ecss.tc import InvalidTcCrc16Error, PusTc

from contracts.cuc import CUC_LEN, CucError, cuc_decode, cuc_encode
from contracts.dictionary import *  # noqa: F403  (the facade: callers write pus.SetMode, pus.Housekeeping...)
from contracts.dictionary import (
    ALL_ACKS,
    CRC_LEN,
    DICTIONARY,
    TC_SECONDARY_HEADER_LEN,
    Housekeeping,
    Severity,
    TimeReferenceStatus,
)
from contracts.model import Frozen
from contracts.packet import Packet
from contracts.packet_errors import (
    MAX_APID,
    MAX_SEQ_COUNT,
    BadArgument,
    CrcMismatch,
    FailureCode,  # re-exported
    LengthMismatch,
    MalformedPacket,
    PacketError,
    RequestId,
    TruncatedPacket,
    UnknownService,
    WrongApid,
)
from contracts.wire import PRIMARY_HEADER_LEN, Reader
from contracts.wire import packet_len as _packet_len

TM_SECONDARY_HEADER_LEN = 7 + CUC_LEN
PUS_C = 2  # the PUS version field of ECSS-E-ST-70-41C
# a TM packet's primary header and its PUS-C secondary header up to the time stamp: packet id, sequence control,
# length; PUS version and time reference status, service, subtype, message type counter, destination id
_TM_HEADER = struct.Struct(">HHHBBBHH")
SEQ_COUNT_MODULO = MAX_SEQ_COUNT + 1
MAX_PACKET_LEN = PRIMARY_HEADER_LEN + 0x10000
HK_SIZE = sum(it.wire.octets or 0 for it in Housekeeping.LAYOUT)  # a fixed layout: 221 octets

# Unions of the declared classes, for annotations and isinstance checks.
TcCommand: TypeAlias = Union[tuple(p for p in DICTIONARY.packets if p.KIND == "TC")]  # type: ignore[valid-type]
Event: TypeAlias = Union[tuple(DICTIONARY.events.values())]  # type: ignore[valid-type]
TmReport: TypeAlias = Union[tuple(p for p in DICTIONARY.packets if p.KIND == "TM")]  # type: ignore[valid-type]


def _declared(value: object, kind: str) -> bool:
    """Whether ``value`` is a packet of the dictionary of ``kind`` ('TC' or 'TM')."""
    declared = isinstance(value, Packet) and DICTIONARY.by_name.get(type(value).__name__) is type(value)
    return declared and value.KIND == kind  # type: ignore[union-attr]


class TcHeader(Frozen):
    """What the headers of a decoded TC say."""

    apid: int
    seq_count: int
    service: int
    subservice: int
    source_id: int
    ack_flags: int = Field(
        description="PUS acknowledgement flags: bit3 acceptance, bit2 start, bit1 progress, bit0 completion"
    )

    @property
    def request_id(self) -> RequestId:
        """The TC's request id."""
        return RequestId(apid=self.apid, seq_count=self.seq_count)


class TmHeader(Frozen):
    """What the headers of a decoded TM say."""

    apid: int
    seq_count: int
    service: int
    subservice: int
    obt_s: float = Field(description="OBT time stamp of the packet, s")
    msg_counter: int = Field(description="PUS message type counter (16 bit, one per message type and destination)")
    destination_id: int
    time_status: int = Field(description="spacecraft time reference status (4 bit, ``TimeReferenceStatus``)")


# -------------------------------------------------------------------------------------------- encode/decode


def _check_ids(apid: int, seq: int) -> None:
    """Reject an APID or sequence count that does not fit the primary header."""
    if not 0 <= apid <= MAX_APID:
        raise BadArgument("apid", f"{apid} is outside [0, {MAX_APID}]")
    if not 0 <= seq <= MAX_SEQ_COUNT:
        raise BadArgument("seq", f"{seq} is outside [0, {MAX_SEQ_COUNT}] (wrap it modulo {SEQ_COUNT_MODULO})")


def encode_tc(cmd: TcCommand, apid: int, seq: int, *, source_id: int = 0, ack_flags: int = ALL_ACKS) -> bytes:
    """Build the TC packet of ``cmd`` addressed to ``apid`` with sequence count ``seq``."""
    if not _declared(cmd, "TC"):
        raise TypeError(f"{type(cmd).__name__} is not a telecommand of this mission")
    _check_ids(apid, seq)
    data = cmd.app_data()
    if PRIMARY_HEADER_LEN + TC_SECONDARY_HEADER_LEN + len(data) + CRC_LEN > MAX_PACKET_LEN:
        raise BadArgument(type(cmd).__name__, f"{len(data)} octets of application data do not fit one packet")
    tc = PusTc(
        service=cmd.SERVICE,
        message_subtype=cmd.subservice(),
        apid=apid,
        seq_count=seq,
        app_data=data,
        source_id=source_id,
        ack_flags=ack_flags,
    )
    return bytes(tc.pack())


def encode_tm(
    report: TmReport, apid: int, seq: int, obt_s: float, msg_counter: int, *, destination_id: int = 0,
    time_status: int = TimeReferenceStatus.FREE_RUNNING,
) -> bytes:
    """Build the TM packet of ``report`` from ``apid`` to ``destination_id``, stamped ``obt_s`` (OBT, s) as CUC with
    the spacecraft time reference status ``time_status``."""
    if not _declared(report, "TM"):
        raise TypeError(f"{type(report).__name__} is not a telemetry report of this mission")
    _check_ids(apid, seq)
    if not 0 <= msg_counter <= 0xFFFF:
        raise BadArgument("msg_counter", f"{msg_counter} is outside [0, 65535] (wrap it modulo 65536)")
    if not 0 <= destination_id <= 0xFFFF:
        raise BadArgument("destination_id", f"{destination_id} is outside [0, 65535]")
    if not 0 <= time_status <= 0xF:
        raise BadArgument("time_status", f"{time_status} does not fit the 4-bit time reference status")
    data = report.app_data()
    if PRIMARY_HEADER_LEN + TM_SECONDARY_HEADER_LEN + len(data) + CRC_LEN > MAX_PACKET_LEN:
        raise BadArgument(type(report).__name__, f"{len(data)} octets of source data do not fit one packet")
    # framed here rather than by spacepackets' PusTm, which builds and packs five objects a packet (16 us to encode
    # and 41 to decode, against 7.5 and 16 here); tests/contracts check the octets with PusTm.unpack and with a reader
    # written from the standard
    total = PRIMARY_HEADER_LEN + TM_SECONDARY_HEADER_LEN + len(data) + CRC_LEN
    head = _TM_HEADER.pack(0x0800 | apid, 0xC000 | seq, total - PRIMARY_HEADER_LEN - 1,
                           PUS_C << 4 | time_status, report.SERVICE, report.subservice(), msg_counter,
                           destination_id) + cuc_encode(obt_s) + data
    return head + binascii.crc_hqx(head, 0xFFFF).to_bytes(2, "big")


def _check_frame(data: bytes, want_tc: bool) -> tuple[int, int, RequestId | None]:
    """Check the primary header and length of one packet; return (apid, seq count, request id if TC)."""
    kind = "TC" if want_tc else "TM"
    if len(data) < 4:
        raise TruncatedPacket(f"{kind} of {len(data)} octets is shorter than the 6-octet primary header")
    w0, w1 = struct.unpack_from(">HH", data)
    apid, seq = w0 & MAX_APID, w1 & MAX_SEQ_COUNT
    rid = RequestId(apid=apid, seq_count=seq) if want_tc else None
    if len(data) < PRIMARY_HEADER_LEN:
        raise TruncatedPacket(f"{kind} of {len(data)} octets is shorter than the 6-octet primary header", rid)
    total = _packet_len(data)
    if len(data) < total:
        raise TruncatedPacket(f"{kind} length field announces {total} octets but only {len(data)} arrived", rid)
    if len(data) > total:
        raise LengthMismatch(f"{kind} length field announces {total} octets but {len(data)} arrived", rid)
    if w0 >> 13 != 0:
        raise MalformedPacket(f"{kind} packet version {w0 >> 13}, expected 0", rid)
    if bool(w0 & 0x1000) != want_tc:
        raise MalformedPacket(f"packet type bit says {'TC' if w0 & 0x1000 else 'TM'}, a {kind} was expected", rid)
    if not w0 & 0x0800:
        raise MalformedPacket(f"{kind} has no secondary header (flag clear), PUS needs one", rid)
    if w1 >> 14 != 0b11:
        raise MalformedPacket(f"{kind} sequence flags {w1 >> 14:02b}, only unsegmented (11) is used", rid)
    least = PRIMARY_HEADER_LEN + (TC_SECONDARY_HEADER_LEN if want_tc else TM_SECONDARY_HEADER_LEN) + CRC_LEN
    if total < least:
        raise MalformedPacket(f"{kind} of {total} octets is shorter than its headers and CRC ({least})", rid)
    # CRC-16/CCITT-FALSE over the whole packet including the trailer is zero when intact.
    if binascii.crc_hqx(data, 0xFFFF) != 0:
        raise CrcMismatch(f"{kind} CRC-16 mismatch (trailer 0x{data[-2:].hex()})", rid)
    return apid, seq, rid


def _payload(kind: str, service: int, sub: int, data: bytes, rid: RequestId | None) -> Packet:
    """Decode application data of a known (service, subtype); TM service 5 is dispatched on its event id."""
    cls: type[Packet] | None
    if kind == "TM" and service == 5:
        if sub not in Severity._value2member_map_:
            raise UnknownService(service, sub, True, rid)
        event_id = Reader(data, "Event").one("H", "event_id")
        cls = DICTIONARY.events.get(event_id)
        if cls is None:
            raise BadArgument("Event.event_id", f"unknown event id {event_id}", rid)
    else:
        types = DICTIONARY.telecommands if kind == "TC" else DICTIONARY.reports
        cls = types.get((service, sub))
        if cls is None:
            raise UnknownService(service, sub, service in DICTIONARY.services(kind), rid)
    r = Reader(data, cls.__name__)
    try:
        value = cls.from_app_data(sub, r)
        r.end()
    except PacketError as exc:
        exc.request_id = rid
        raise
    return value


def decode_tc(data: bytes, *, expected_apid: int | None = None) -> tuple[TcHeader, TcCommand]:
    """Parse and check a TC packet; raise a PacketError subclass (with its request id when readable)."""
    data = bytes(data)
    apid, seq, rid = _check_frame(data, want_tc=True)
    try:
        tc = PusTc.unpack(data)
    except InvalidTcCrc16Error:
        raise CrcMismatch("TC CRC-16 mismatch", rid) from None
    except ValueError as exc:
        raise MalformedPacket(f"TC secondary header: {exc}", rid) from None
    if expected_apid is not None and apid != expected_apid:
        raise WrongApid(f"TC addressed to APID 0x{apid:03X}, this is APID 0x{expected_apid:03X}", rid)
    header = TcHeader(
        apid=apid,
        seq_count=seq,
        service=tc.service,
        subservice=tc.message_subtype,
        source_id=tc.source_id,
        ack_flags=tc.pus_tc_sec_header.ack_flags,
    )
    return header, _payload("TC", header.service, header.subservice, bytes(tc.app_data), rid)


def decode_tm(data: bytes) -> tuple[TmHeader, TmReport]:
    """Parse and check a TM packet; raise a PacketError subclass."""
    data = bytes(data)
    apid, seq, _ = _check_frame(data, want_tc=False)  # the primary header, the length and the CRC
    _, _, _, version_status, service, sub, counter, destination = _TM_HEADER.unpack_from(data)
    if version_status >> 4 != PUS_C:
        raise MalformedPacket(f"TM secondary header: PUS version field value {version_status >> 4} found where PUS C "
                              f"{PUS_C} was expected")
    stamp_at = _TM_HEADER.size
    try:
        obt_s = cuc_decode(data[stamp_at : stamp_at + CUC_LEN])
    except CucError as exc:
        raise MalformedPacket(f"TM time stamp: {exc}") from None
    header = TmHeader(  # validated: pydantic-core's checks (1.8 us) are quicker than model_construct (3.1 us)
        apid=apid,
        seq_count=seq,
        service=service,
        subservice=sub,
        obt_s=obt_s,
        msg_counter=counter,
        destination_id=destination,
        time_status=version_status & 0x0F,
    )
    return header, _payload("TM", service, sub, data[stamp_at + CUC_LEN : -CRC_LEN], None)


def split_packets(stream: bytes) -> list[bytes]:
    """Cut a byte stream of concatenated space packets into packets, using each primary header's length field."""
    out = []
    pos = 0
    n = len(stream)
    while pos < n:
        if n - pos < PRIMARY_HEADER_LEN:
            raise TruncatedPacket(f"stream ends {n - pos} octets into the primary header of a packet at octet {pos}")
        size = _packet_len(stream, pos)
        if pos + size > n:
            raise TruncatedPacket(f"packet at octet {pos} announces {size} octets but only {n - pos} remain")
        out.append(bytes(stream[pos : pos + size]))
        pos += size
    return out


def complete_packets(stream: bytes) -> tuple[list[bytes], int]:
    """Cut a stream of concatenated space packets; return the packets and the octets of an incomplete last one.

    Like ``split_packets``, but a stream cut short (a node killed mid-write) keeps every complete packet.
    """
    out: list[bytes] = []
    pos, n = 0, len(stream)
    while n - pos >= PRIMARY_HEADER_LEN:
        size = _packet_len(stream, pos)
        if pos + size > n:
            break
        out.append(bytes(stream[pos : pos + size]))
        pos += size
    return out, n - pos


def request_id_of(packet: bytes) -> RequestId:
    """The request id (APID and sequence count) of a TC packet, from its first 4 octets."""
    if len(packet) < 4:
        raise TruncatedPacket(f"{len(packet)} octets hold no request id (4 needed)")
    w0, w1 = struct.unpack_from(">HH", packet)
    return RequestId(apid=w0 & MAX_APID, seq_count=w1 & MAX_SEQ_COUNT)
