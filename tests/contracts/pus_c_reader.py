"""An independent reader of the mission's packets, written from the standards, for the conformance tests.

It imports nothing of the project and nothing of spacepackets: every field is cut by hand from
- CCSDS 133.0-B-2 (Space Packet Protocol): the 6-octet primary header;
- ECSS-E-ST-70-41C (PUS-C): the TM secondary header (PUS version, spacecraft time reference status, service type,
  subtype, message type counter, destination id, time), the TC secondary header (PUS version, acknowledgement flags,
  service type, subtype, source id), the packet error control (CRC-16 of clause 7.4.4 / CCSDS 131.0 annex: polynomial
  x^16 + x^12 + x^5 + 1, all ones preset), TC[11,4] insert activities (N, then N times a release time and a
  request), and the request id (the first 4 octets of a TC);
- CCSDS 301.0-B-4 (Time Code Formats): the CUC with its P-field.
The mission's own choices it needs are stated here as constants: its time stamp is a CUC of 4 coarse and 2 fine
octets with an explicit P-field, and a count N is 16 bits.
"""

from __future__ import annotations

from dataclasses import dataclass

PRIMARY_LEN = 6
PUS_VERSION = 2  # ECSS-E-ST-70-41C
CUC_P_FIELD = 0x2E  # no extension, time code id 010 (agency-defined epoch), 4 coarse octets, 2 fine octets
CUC_LEN = 1 + 4 + 2
TM_SECONDARY_LEN = 1 + 1 + 1 + 2 + 2 + CUC_LEN
TC_SECONDARY_LEN = 1 + 1 + 1 + 2
N_OCTETS = 2


class NonConforming(AssertionError):
    """A packet that breaks the standard; the message says which field."""


def crc16(data: bytes) -> int:
    """CRC-16 of the packet error control: polynomial 0x1021, preset 0xFFFF, no reflection, no final XOR."""
    crc = 0xFFFF
    for byte in data:
        crc ^= byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) if crc & 0x8000 else crc << 1
            crc &= 0xFFFF
    return crc


def u(data: bytes, at: int, n: int) -> int:
    """The big-endian unsigned integer of ``n`` octets at ``at``."""
    if at + n > len(data):
        raise NonConforming(f"field at octet {at} of {n} octets runs past the {len(data)}-octet data")
    return int.from_bytes(data[at:at + n], "big")


@dataclass(frozen=True)
class Primary:
    """CCSDS primary header."""

    version: int
    is_tc: bool
    has_secondary: bool
    apid: int
    seq_flags: int
    seq_count: int
    length: int  # the whole packet, octets


def primary(packet: bytes) -> Primary:
    """The primary header of ``packet``, checked against its length."""
    if len(packet) < PRIMARY_LEN:
        raise NonConforming(f"{len(packet)} octets hold no primary header")
    w0, w1, w2 = u(packet, 0, 2), u(packet, 2, 2), u(packet, 4, 2)
    p = Primary(version=w0 >> 13, is_tc=bool(w0 >> 12 & 1), has_secondary=bool(w0 >> 11 & 1), apid=w0 & 0x7FF,
                seq_flags=w1 >> 14, seq_count=w1 & 0x3FFF, length=w2 + 1 + PRIMARY_LEN)
    if p.length != len(packet):
        raise NonConforming(f"packet data length field says {p.length} octets, the packet has {len(packet)}")
    if p.version != 0:
        raise NonConforming(f"packet version number {p.version}, CCSDS 133.0 says 0")
    if not p.has_secondary:
        raise NonConforming("secondary header flag clear: a PUS packet has a secondary header")
    if p.seq_flags != 0b11:
        raise NonConforming(f"sequence flags {p.seq_flags:02b}: a PUS packet is unsegmented (11)")
    if crc16(packet[:-2]) != u(packet, len(packet) - 2, 2):
        raise NonConforming(f"packet error control 0x{u(packet, len(packet) - 2, 2):04X} is not the CRC-16 "
                            f"0x{crc16(packet[:-2]):04X}")
    return p


def split(stream: bytes) -> list[bytes]:
    """A stream of concatenated packets cut by each primary header's length field."""
    out, at = [], 0
    while at < len(stream):
        if len(stream) - at < PRIMARY_LEN:
            raise NonConforming(f"stream ends inside a primary header at octet {at}")
        n = u(stream, at + 4, 2) + 1 + PRIMARY_LEN
        if at + n > len(stream):
            raise NonConforming(f"packet at octet {at} runs past the end of the stream")
        out.append(stream[at:at + n])
        at += n
    return out


def cuc_seconds(data: bytes, at: int) -> float:
    """The CUC time code at ``at`` (P-field, 4 coarse, 2 fine octets), s from its epoch."""
    if u(data, at, 1) != CUC_P_FIELD:
        raise NonConforming(f"CUC P-field 0x{u(data, at, 1):02X}, the mission's is 0x{CUC_P_FIELD:02X}")
    return u(data, at + 1, 4) + u(data, at + 5, 2) / 65536.0


@dataclass(frozen=True)
class Tm:
    """A TM packet: primary header, PUS-C TM secondary header, source data."""

    primary: Primary
    time_status: int
    service: int
    subtype: int
    message_counter: int
    destination_id: int
    time_s: float
    data: bytes


def _pus(packet: bytes, is_tc: bool) -> Primary:
    """The primary header of a PUS packet of the kind wanted, its secondary header's room and PUS version checked."""
    kind, secondary = ("TC", TC_SECONDARY_LEN) if is_tc else ("TM", TM_SECONDARY_LEN)
    p = primary(packet)
    if p.is_tc != is_tc:
        raise NonConforming(f"packet type says {'TC' if p.is_tc else 'TM'}, {kind} expected")
    if p.length < PRIMARY_LEN + secondary + 2:
        raise NonConforming(f"{p.length} octets cannot hold the {kind} secondary header and CRC")
    version = u(packet, PRIMARY_LEN, 1) >> 4
    if version != PUS_VERSION:
        raise NonConforming(f"{kind} PUS version {version}, ECSS-E-ST-70-41C says {PUS_VERSION}")
    return p


def tm(packet: bytes) -> Tm:
    """Read a TM packet."""
    p, h = _pus(packet, is_tc=False), PRIMARY_LEN
    return Tm(primary=p, time_status=u(packet, h, 1) & 0xF, service=u(packet, h + 1, 1), subtype=u(packet, h + 2, 1),
              message_counter=u(packet, h + 3, 2), destination_id=u(packet, h + 5, 2),
              time_s=cuc_seconds(packet, h + 7), data=packet[h + TM_SECONDARY_LEN:-2])


@dataclass(frozen=True)
class Tc:
    """A TC packet: primary header, PUS-C TC secondary header, application data."""

    primary: Primary
    ack_flags: int
    service: int
    subtype: int
    source_id: int
    data: bytes
    request_id: bytes


def tc(packet: bytes) -> Tc:
    """Read a TC packet."""
    p, h = _pus(packet, is_tc=True), PRIMARY_LEN
    return Tc(primary=p, ack_flags=u(packet, h, 1) & 0xF, service=u(packet, h + 1, 1), subtype=u(packet, h + 2, 1),
              source_id=u(packet, h + 3, 2), data=packet[h + TC_SECONDARY_LEN:-2], request_id=packet[:4])


def insert_activities(data: bytes) -> list[tuple[float, Tc]]:
    """TC[11,4] application data: N, then N times (release time, request), and nothing after."""
    n, at, out = u(data, 0, N_OCTETS), N_OCTETS, []
    for _ in range(n):
        release = cuc_seconds(data, at)
        at += CUC_LEN
        size = u(data, at + 4, 2) + 1 + PRIMARY_LEN
        out.append((release, tc(data[at:at + size])))
        at += size
    if at != len(data):
        raise NonConforming(f"TC[11,4] has {len(data) - at} octets after its {n} activities")
    return out


def ca_relative_activities(data: bytes) -> list[tuple[float, float, Tc]]:
    """The mission's TC[200,8]: N, then N times (f64 offset from C/A, release time, request)."""
    import struct

    n, at, out = u(data, 0, N_OCTETS), N_OCTETS, []
    for _ in range(n):
        (offset,) = struct.unpack_from(">d", data, at)
        release = cuc_seconds(data, at + 8)
        at += 8 + CUC_LEN
        size = u(data, at + 4, 2) + 1 + PRIMARY_LEN
        out.append((offset, release, tc(data[at:at + size])))
        at += size
    if at != len(data):
        raise NonConforming(f"TC[200,8] has {len(data) - at} octets after its {n} activities")
    return out
