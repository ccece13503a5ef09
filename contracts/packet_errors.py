"""Why a packet cannot be decoded or built: typed errors carrying the PUS service 1 failure code and the request id.

A request id is the first 4 octets of a TC (its APID and sequence count); verification reports and rejection events
quote it, and an error raised while decoding a TC carries it when the primary header could be read, so the OBSW can
answer with a failure report.
"""

from __future__ import annotations

import struct
from enum import IntEnum

from pydantic import Field

from contracts.errors import FlybyError
from contracts.model import Frozen

MAX_APID = 0x7FF
MAX_SEQ_COUNT = 0x3FFF


class FailureCode(IntEnum):
    """Service 1 failure codes for packets that cannot be accepted.

    Codes from 0x0100 up are left to the OBSW for execution failures (illegal transition, schedule full, ...).
    """

    TRUNCATED = 0x0001
    BAD_LENGTH = 0x0002
    BAD_CRC = 0x0003
    BAD_HEADER = 0x0004
    UNKNOWN_SERVICE = 0x0005
    UNKNOWN_SUBSERVICE = 0x0006
    BAD_ARGUMENT = 0x0007
    WRONG_APID = 0x0008
    UNAUTHENTICATED = 0x0009  # no security header and trailer, or a MAC that does not verify
    UNKNOWN_SPI = 0x000A  # a security parameter index with no security association on board
    REPLAYED = 0x000B  # an anti-replay sequence number at or below the last one accepted


class RequestId(Frozen):
    """PUS request identifier of a TC: its APID and sequence count (the first 4 octets of the packet)."""

    apid: int = Field(ge=0, le=MAX_APID, description="APID the TC was addressed to")
    seq_count: int = Field(ge=0, le=MAX_SEQ_COUNT, description="packet sequence count of the TC")

    def packed(self) -> bytes:
        """The 4 octets: version 0, type TC, secondary header flag, APID, unsegmented flags, sequence count."""
        return struct.pack(">HH", 0x1800 | self.apid, 0xC000 | self.seq_count)

    @classmethod
    def from_packed(cls, raw: bytes) -> RequestId:
        """Read the 4 octets written by ``packed`` (the type and flag bits are checked)."""
        word0, word1 = struct.unpack(">HH", raw)
        if word0 & 0xF800 != 0x1800 or word1 & 0xC000 != 0xC000:
            raise BadArgument("request_id", f"0x{raw.hex()} is not the id of an unsegmented PUS TC")
        return cls(apid=word0 & MAX_APID, seq_count=word1 & MAX_SEQ_COUNT)


class PacketError(FlybyError):
    """A packet that cannot be decoded; ``failure_code`` is the service 1 code to report it with.

    ``request_id`` is the id read from the primary header (None if fewer than 4 octets arrived).
    """

    failure_code: FailureCode = FailureCode.BAD_HEADER

    def __init__(self, message: str, request_id: RequestId | None = None) -> None:
        self.request_id = request_id
        super().__init__(message)


class MalformedPacket(PacketError):
    """The packet's structure is wrong (header fields, PUS version, too short for its headers)."""

    failure_code = FailureCode.BAD_HEADER


class TruncatedPacket(MalformedPacket):
    """Fewer octets than the primary header's length field announces."""

    failure_code = FailureCode.TRUNCATED


class LengthMismatch(MalformedPacket):
    """More octets than the primary header's length field announces."""

    failure_code = FailureCode.BAD_LENGTH


class CrcMismatch(MalformedPacket):
    """The CRC-16 trailer does not match the packet."""

    failure_code = FailureCode.BAD_CRC


class UnknownService(PacketError):
    """A service, or a subtype of a known service, that this mission does not define."""

    def __init__(self, service: int, subservice: int, known_service: bool, request_id: RequestId | None = None):
        self.service = service
        self.subservice = subservice
        self.failure_code = FailureCode.UNKNOWN_SUBSERVICE if known_service else FailureCode.UNKNOWN_SERVICE
        what = f"subtype {subservice} of service {service}" if known_service else f"service {service}"
        super().__init__(f"unknown {what} (packet [{service},{subservice}])", request_id)


class BadArgument(PacketError):
    """An application-data field that is missing, out of range or inconsistent; ``field`` names it."""

    failure_code = FailureCode.BAD_ARGUMENT

    def __init__(self, field: str, why: str, request_id: RequestId | None = None) -> None:
        self.field = field
        self.why = why
        super().__init__(f"{field}: {why}", request_id)


class WrongApid(PacketError):
    """A TC addressed to another APID than the receiver's."""

    failure_code = FailureCode.WRONG_APID
