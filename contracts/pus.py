"""The mission's packets: PUS-C telecommands and telemetry on CCSDS space packets, built with spacepackets.

Every packet is a CCSDS space packet (unsegmented, secondary header present) with a PUS-C secondary header and a
CRC-16/CCITT (ibm-3740) trailer. Telemetry is stamped with OBT as a 7-octet CUC (``contracts.cuc``: P-field 0x2E,
4 coarse + 2 fine octets), so a TM header is 6 + 7 + 7 = 20 octets. All fields are big-endian.

Services (TC = ground to spacecraft, TM = spacecraft to ground):

====  ========  ======================================================================================
svc   subtype   content
====  ========  ======================================================================================
1     TM 1..8   verification: acceptance (1 ok, 2 fail), start (3, 4), completion (7, 8) of a TC,
                ``Verification``: request id (4 octets), then on failure u16 code + u8 length + UTF-8 reason
3     TM 25     housekeeping parameter report, ``Housekeeping``, fixed layout below (``HK_SIZE`` octets)
5     TM 1..4   event report, subtype = severity (1 info, 2 low, 3 medium, 4 high); u16 event id + parameters
9     TC 1      ``SetTimeReportRate``: u8 rate exponent (one report every 2^n s)
9     TM 2      ``TimeReport``: u8 rate exponent + OBT as CUC (7 octets)
11    TC 1..17  time-based schedule: 1 enable, 2 disable, 3 reset, 4 insert, 5 delete by request id,
                7 / 15 time-shift selected / all, 9 / 16 detail report selected / all, 12 / 17 summary
                report selected / all (``InsertActivities``, ``DeleteActivities``, ``TimeShiftActivities``,
                ``DetailReportRequest``, ``SummaryReportRequest``, ...)
11    TM 10,13  ``ScheduleDetailReport`` (each activity with its TC), ``ScheduleSummaryReport``
17    TC 1/TM 2 ``Ping`` / ``PingReply`` (are-you-alive)
200   TC 1..6   mission commands: set mode, upload nominal trajectory, set camera cadence, start imaging,
                stop imaging, request time reports
200   TM 130    ``NavigationReport``: what the imaging chain made of one frame (fixed 49 octets)
====  ========  ======================================================================================

The filter-based subtypes of service 11 (6, 8, 11, 14) are not implemented: ground always names activities by
request id. A scheduled activity carries, as a mission extension, an optional offset from closest approach so the
OBSW can re-anchor it when a new C/A estimate is accepted; its absolute release OBT is always present.
A time shift is an IEEE float64 in seconds (exact, unlike a CUC relative time on the 2^-16 s grid).

Housekeeping layout (``HK_SIZE`` = 85 octets, float32 unless noted; absent values are NaN with their flag cleared)::

    offset  size  field
    0       2     structure id (u16, = HK_SID)
    2       1     mode (u8, ``Mode``)
    3       1     validity flags: bit0 pointing error, bit1 best trajectory, bit2 best-grid MSE
    4       1     number of wheels in use (u8, 1..4)
    5       16    attitude quaternion body->inertial, x y z w
    21      12    body rate, rad/s, x y z
    33      16    wheel speeds, rad/s, 4 slots (unused slots 0)
    49      16    wheel angular momentum, N m s, 4 slots (unused slots 0)
    65      4     pointing error estimate, rad
    69      8     best trajectory C/A time, OBT s (float64: float32 would only resolve 256 s at 2^32 s)
    77      4     best trajectory C/A distance, km
    81      4     best-grid mean square error of the line-of-sight angle, rad^2

Decoding errors are ``PacketError`` subclasses carrying a PUS service-1 ``failure_code`` and, when the primary
header could be read, the ``request_id`` of the offending TC, so the OBSW can answer with a failure report.
"""

from __future__ import annotations

import binascii
import math
import struct
from enum import IntEnum
from typing import Annotated, Any, ClassVar, Literal, Self, TypeAlias

from pydantic import AfterValidator, BeforeValidator, Field, ValidationError, field_validator, model_validator
from spacepackets.ecss.tc import InvalidTcCrc16Error, PusTc
from spacepackets.ecss.tm import InvalidTmCrc16Error, PusTm

from contracts.cuc import CUC_LEN, MAX_OBT_S, CucError, cuc_decode, cuc_encode
from contracts.errors import FlybyError
from contracts.model import Frozen

PRIMARY_HEADER_LEN = 6
TC_SECONDARY_HEADER_LEN = 5
TM_SECONDARY_HEADER_LEN = 7 + CUC_LEN
CRC_LEN = 2
MAX_APID = 0x7FF
MAX_SEQ_COUNT = 0x3FFF
SEQ_COUNT_MODULO = MAX_SEQ_COUNT + 1
MAX_PACKET_LEN = PRIMARY_HEADER_LEN + 0x10000
MAX_TEXT_OCTETS = 255
F32_MAX = 3.4028234663852886e38
HK_SID = 1
HK_WHEEL_SLOTS = 4
MISSION_SERVICE = 200


class Mode(IntEnum):
    """On-board modes and their wire codes (names as in the mode manager and the timeline)."""

    SAFE = 0
    STANDBY = 1
    ACQUISITION = 2
    NOMINAL_TRACKING = 3
    AUTONOMOUS_TRACKING = 4


class Severity(IntEnum):
    """Event severity, which is also the service 5 subtype."""

    INFO = 1
    LOW = 2
    MEDIUM = 3
    HIGH = 4


class Stage(IntEnum):
    """Verification stage; the value is the service 1 success subtype, failure is value + 1."""

    ACCEPTANCE = 1
    START = 3
    COMPLETION = 7


class EventId(IntEnum):
    """Event identifiers of service 5 (the u16 that opens an event report)."""

    MODE_CHANGED = 1
    TARGET_ACQUIRED = 2
    TARGET_LOST = 3
    WHEEL_SATURATION = 4
    FAULT = 5
    COMMAND_REJECTED = 6
    CLOCK_JUMP = 7


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


# ----------------------------------------------------------------------------------------------------- errors


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


# ----------------------------------------------------------------------------------------------- field types


def _fits_f32(x: float) -> float:
    """Accept a float that a float32 can carry (finite values up to F32_MAX, NaN and infinities)."""
    if math.isfinite(x) and abs(x) > F32_MAX:
        raise ValueError(f"{x!r} exceeds the float32 range of this field (|x| <= {F32_MAX:.4g})")
    return x


def _finite(x: float) -> float:
    """Accept a finite float only."""
    if not math.isfinite(x):
        raise ValueError(f"must be finite, got {x!r}")
    return x


def _fits_text(s: str) -> str:
    """Accept a string whose UTF-8 form fits the u8 length prefix."""
    n = len(s.encode("utf-8"))
    if n > MAX_TEXT_OCTETS:
        raise ValueError(f"is {n} octets of UTF-8, at most {MAX_TEXT_OCTETS} fit")
    return s


def _mode_by_name(v: Any) -> Any:
    """Let a mode be given by name ('STANDBY') as well as by code."""
    if isinstance(v, str) and v in Mode.__members__:
        return Mode[v]
    return v


F32 = Annotated[float, AfterValidator(_fits_f32)]
Finite = Annotated[float, AfterValidator(_finite)]
Text = Annotated[str, AfterValidator(_fits_text)]
ModeValue = Annotated[Mode, BeforeValidator(_mode_by_name)]
U8 = Annotated[int, Field(ge=0, le=0xFF)]
U16 = Annotated[int, Field(ge=0, le=0xFFFF)]
U32 = Annotated[int, Field(ge=0, le=0xFFFFFFFF)]
ObtS = Annotated[float, Field(ge=0.0, le=MAX_OBT_S)]
UnitVector = tuple[Finite, Finite, Finite]


# --------------------------------------------------------------------------------------------- wire helpers


class _Reader:
    """Reads the application data of one packet, naming the field at fault when it runs short."""

    def __init__(self, data: bytes, kind: str) -> None:
        self.data = data
        self.kind = kind
        self.pos = 0

    def take(self, fmt: str, field: str) -> tuple[Any, ...]:
        """Unpack the big-endian struct ``fmt`` for ``field``."""
        s = struct.Struct(">" + fmt)
        end = self.pos + s.size
        if end > len(self.data):
            raise BadArgument(
                f"{self.kind}.{field}",
                f"missing: application data ends at octet {len(self.data)}, field needs octets {self.pos}..{end - 1}",
            )
        values = s.unpack_from(self.data, self.pos)
        self.pos = end
        return values

    def one(self, fmt: str, field: str) -> Any:
        """Unpack a single value."""
        return self.take(fmt, field)[0]

    def raw(self, n: int, field: str) -> bytes:
        """Take ``n`` octets."""
        if self.pos + n > len(self.data):
            raise BadArgument(f"{self.kind}.{field}", f"missing: needs {n} octets, {len(self.data) - self.pos} left")
        out = self.data[self.pos : self.pos + n]
        self.pos += n
        return out

    def text(self, field: str) -> str:
        """A u8-length-prefixed UTF-8 string."""
        n = self.one("B", field + ".length")
        try:
            return self.raw(n, field).decode("utf-8")
        except UnicodeDecodeError as exc:
            raise BadArgument(f"{self.kind}.{field}", f"not UTF-8 ({exc.reason} at octet {exc.start})") from None

    def obt(self, field: str) -> float:
        """An OBT as a 7-octet CUC."""
        try:
            return cuc_decode(self.raw(CUC_LEN, field))
        except CucError as exc:
            raise BadArgument(f"{self.kind}.{field}", str(exc)) from None

    def request_id(self, field: str) -> RequestId:
        """A 4-octet request id."""
        raw = self.raw(4, field)
        try:
            return RequestId.from_packed(raw)
        except BadArgument as exc:
            raise BadArgument(f"{self.kind}.{field}", exc.why) from None

    def request_ids(self, field: str) -> tuple[RequestId, ...]:
        """A u16 count then that many request ids."""
        n = self.one("H", field + ".count")
        return tuple(self.request_id(f"{field}[{i}]") for i in range(n))

    def packet(self, field: str) -> bytes:
        """A complete embedded space packet, delimited by its own length field."""
        if self.pos + PRIMARY_HEADER_LEN > len(self.data):
            raise BadArgument(f"{self.kind}.{field}", "missing: no room for an embedded packet's primary header")
        n = _packet_len(self.data, self.pos)
        return self.raw(n, field)

    def end(self) -> None:
        """Check that every octet was consumed."""
        if self.pos != len(self.data):
            raise BadArgument(self.kind, f"{len(self.data) - self.pos} unexpected octets after the last field")


def _text(s: str) -> bytes:
    """u8 length + UTF-8."""
    b = s.encode("utf-8")
    return bytes((len(b),)) + b


def _request_ids(ids: tuple[RequestId, ...]) -> bytes:
    """u16 count + 4 octets each."""
    return struct.pack(">H", len(ids)) + b"".join(r.packed() for r in ids)


def _packet_len(data: bytes, offset: int = 0) -> int:
    """Total length of the space packet starting at ``offset``, from its length field."""
    return struct.unpack_from(">H", data, offset + 4)[0] + PRIMARY_HEADER_LEN + 1


def _opt(x: float | None) -> float:
    """The wire value of an optional float: NaN when absent."""
    return math.nan if x is None else x


def _built(cls: type[Frozen], kind: str, **fields: Any) -> Any:
    """Construct ``cls`` from decoded fields, turning a validation error into BadArgument naming the field."""
    try:
        return cls(**fields)
    except ValidationError as exc:
        err = exc.errors()[0]
        loc = ".".join(str(p) for p in err["loc"])
        raise BadArgument(f"{kind}.{loc}" if loc else kind, f"{err['msg']} (got {err.get('input')!r})") from None


# ------------------------------------------------------------------------------------------ payload classes


class _Payload(Frozen):
    """A TC command or TM report: knows its service, subtype and application-data layout."""

    SERVICE: ClassVar[int]
    SUBSERVICE: ClassVar[int] = -1

    def subservice(self) -> int:
        """The PUS subtype this value travels with."""
        return self.SUBSERVICE

    def app_data(self) -> bytes:
        """The application data (TC) or source data (TM) octets."""
        return b""

    @classmethod
    def from_app_data(cls, subservice: int, r: _Reader) -> Self:
        """Parse application data written by ``app_data``; raise BadArgument naming the field."""
        return _built(cls, cls.__name__)


# Service 17 ---------------------------------------------------------------------------------------------


class Ping(_Payload):
    """TC[17,1] are-you-alive."""

    SERVICE: ClassVar[int] = 17
    SUBSERVICE: ClassVar[int] = 1


class PingReply(_Payload):
    """TM[17,2] are-you-alive connection report."""

    SERVICE: ClassVar[int] = 17
    SUBSERVICE: ClassVar[int] = 2


# Service 1 ----------------------------------------------------------------------------------------------


_STAGE_OF_SUBTYPE = {1: Stage.ACCEPTANCE, 2: Stage.ACCEPTANCE, 3: Stage.START, 4: Stage.START}
_STAGE_OF_SUBTYPE |= {7: Stage.COMPLETION, 8: Stage.COMPLETION}


class Verification(_Payload):
    """TM[1,x] verification report of one TC at one stage; a failure carries a code and a reason."""

    SERVICE: ClassVar[int] = 1
    stage: Stage = Field(description="acceptance, start or completion")
    request_id: RequestId = Field(description="the TC this report is about")
    failure_code: U16 | None = Field(None, description="service 1 failure code; None for a success report")
    reason: Text = Field("", description="human-readable failure reason (UTF-8, at most 255 octets)")

    @model_validator(mode="after")
    def _reason_only_on_failure(self) -> Verification:
        if self.failure_code is None and self.reason:
            raise ValueError("reason: a success report carries no reason")
        return self

    @property
    def success(self) -> bool:
        """Whether this is a success report."""
        return self.failure_code is None

    def subservice(self) -> int:
        """Success subtype of the stage, +1 for failure."""
        return int(self.stage) + (0 if self.success else 1)

    def app_data(self) -> bytes:
        """Request id, then on failure code and reason."""
        out = self.request_id.packed()
        if self.failure_code is not None:
            out += struct.pack(">H", self.failure_code) + _text(self.reason)
        return out

    @classmethod
    def from_app_data(cls, subservice: int, r: _Reader) -> Self:
        """Stage and success from the subtype, then the fields."""
        stage = _STAGE_OF_SUBTYPE[subservice]
        rid = r.request_id("request_id")
        if subservice == int(stage):
            return _built(cls, cls.__name__, stage=stage, request_id=rid)
        code = r.one("H", "failure_code")
        return _built(cls, cls.__name__, stage=stage, request_id=rid, failure_code=code, reason=r.text("reason"))

    @classmethod
    def failure_for(cls, error: PacketError, stage: Stage = Stage.ACCEPTANCE) -> Verification | None:
        """The failure report answering a TC that raised ``error``; None if its request id could not be read."""
        if error.request_id is None:
            return None
        reason = str(error).encode("utf-8")[:MAX_TEXT_OCTETS].decode("utf-8", errors="ignore")
        return cls(stage=stage, request_id=error.request_id, failure_code=int(error.failure_code), reason=reason)


# Service 3 ----------------------------------------------------------------------------------------------

_HK = struct.Struct(">HBBB4f3f4f4ffdff")
HK_SIZE = _HK.size


class Housekeeping(_Payload):
    """TM[3,25] housekeeping report of the navigation chain (layout in the module docstring)."""

    SERVICE: ClassVar[int] = 3
    SUBSERVICE: ClassVar[int] = 25
    mode: ModeValue = Field(description="current on-board mode")
    q: tuple[F32, F32, F32, F32] = Field(description="estimated attitude body->inertial, scalar-last x y z w")
    rate_rad_s: tuple[F32, F32, F32] = Field(description="estimated body rate, rad/s")
    wheel_speed_rad_s: tuple[F32, ...] = Field(min_length=1, max_length=HK_WHEEL_SLOTS, description="rad/s")
    wheel_momentum_nms: tuple[F32, ...] = Field(min_length=1, max_length=HK_WHEEL_SLOTS, description="N m s")
    pointing_error_rad: F32 | None = Field(None, description="estimated boresight-to-target angle, rad")
    best_ca_obt_s: float | None = Field(None, description="C/A time of the best trajectory, OBT s")
    best_ca_distance_km: F32 | None = Field(None, description="C/A distance of the best trajectory, km")
    best_mse_rad2: F32 | None = Field(None, description="best-grid mean square line-of-sight error, rad^2")

    @model_validator(mode="after")
    def _consistent(self) -> Housekeeping:
        if len(self.wheel_speed_rad_s) != len(self.wheel_momentum_nms):
            raise ValueError(
                f"wheel_momentum_nms: {len(self.wheel_momentum_nms)} wheels but wheel_speed_rad_s has "
                f"{len(self.wheel_speed_rad_s)}"
            )
        if (self.best_ca_obt_s is None) != (self.best_ca_distance_km is None):
            raise ValueError("best_ca_distance_km: the best trajectory needs both C/A time and distance, or neither")
        return self

    def app_data(self) -> bytes:
        """The fixed 85-octet layout."""
        n = len(self.wheel_speed_rad_s)
        pad = (0.0,) * (HK_WHEEL_SLOTS - n)
        flags = (
            (self.pointing_error_rad is not None)
            | (self.best_ca_obt_s is not None) << 1
            | (self.best_mse_rad2 is not None) << 2
        )
        return _HK.pack(
            HK_SID,
            int(self.mode),
            flags,
            n,
            *self.q,
            *self.rate_rad_s,
            *self.wheel_speed_rad_s,
            *pad,
            *self.wheel_momentum_nms,
            *pad,
            _opt(self.pointing_error_rad),
            _opt(self.best_ca_obt_s),
            _opt(self.best_ca_distance_km),
            _opt(self.best_mse_rad2),
        )

    @classmethod
    def from_app_data(cls, subservice: int, r: _Reader) -> Self:
        """Parse the fixed layout; absent values come back as None."""
        v = r.take(_HK.format[1:], "housekeeping")
        sid, mode, flags, n = v[0:4]
        if sid != HK_SID:
            raise BadArgument(f"{cls.__name__}.sid", f"structure id {sid}, expected {HK_SID}")
        if not 1 <= n <= HK_WHEEL_SLOTS:
            raise BadArgument(f"{cls.__name__}.wheel_count", f"{n} wheels, expected 1..{HK_WHEEL_SLOTS}")
        if flags & ~0b111:
            raise BadArgument(f"{cls.__name__}.flags", f"unknown validity bits 0x{flags:02X}")
        if mode not in Mode._value2member_map_:
            raise BadArgument(f"{cls.__name__}.mode", f"unknown mode code {mode}")
        has_traj = bool(flags & 2)
        return _built(
            cls,
            cls.__name__,
            mode=Mode(mode),
            q=v[4:8],
            rate_rad_s=v[8:11],
            wheel_speed_rad_s=v[11 : 11 + n],
            wheel_momentum_nms=v[15 : 15 + n],
            pointing_error_rad=v[19] if flags & 1 else None,
            best_ca_obt_s=v[20] if has_traj else None,
            best_ca_distance_km=v[21] if has_traj else None,
            best_mse_rad2=v[22] if flags & 4 else None,
        )


# Service 5 ----------------------------------------------------------------------------------------------


class EventReport(_Payload):
    """Base of the event reports; the subtype is its severity, the first u16 of its data its event id."""

    SERVICE: ClassVar[int] = 5
    EVENT_ID: ClassVar[EventId]
    severity: Severity

    def subservice(self) -> int:
        """The severity."""
        return int(self.severity)

    def app_data(self) -> bytes:
        """Event id then the event's parameters."""
        return struct.pack(">H", self.EVENT_ID) + self.parameters()

    def parameters(self) -> bytes:
        """The event's parameters."""
        return b""


class ModeChangedEvent(EventReport):
    """The mode manager made a transition: from, to, and why."""

    EVENT_ID: ClassVar[EventId] = EventId.MODE_CHANGED
    severity: Severity = Severity.INFO
    from_mode: ModeValue
    to_mode: ModeValue
    cause: Text = Field("", description="what triggered the transition (command, event, time)")

    def parameters(self) -> bytes:
        """u8 from, u8 to, cause text."""
        return struct.pack(">BB", self.from_mode, self.to_mode) + _text(self.cause)

    @classmethod
    def from_app_data(cls, subservice: int, r: _Reader) -> Self:
        """Parse the parameters."""
        a, b = r.take("BB", "modes")
        return _built(cls, cls.__name__, severity=subservice, from_mode=a, to_mode=b, cause=r.text("cause"))


class TargetAcquiredEvent(EventReport):
    """The imaging chain found the target: centroid and area in the processed (binned) image."""

    EVENT_ID: ClassVar[EventId] = EventId.TARGET_ACQUIRED
    severity: Severity = Severity.INFO
    centroid_x_px: F32 = Field(description="centroid column in the processed image, px")
    centroid_y_px: F32 = Field(description="centroid row in the processed image, px")
    area_px: U32 = Field(description="area of the target region, px")

    def parameters(self) -> bytes:
        """f32 x, f32 y, u32 area."""
        return struct.pack(">ffI", self.centroid_x_px, self.centroid_y_px, self.area_px)

    @classmethod
    def from_app_data(cls, subservice: int, r: _Reader) -> Self:
        """Parse the parameters."""
        x, y, a = r.take("ffI", "centroid")
        return _built(cls, cls.__name__, severity=subservice, centroid_x_px=x, centroid_y_px=y, area_px=a)


class TargetLostEvent(EventReport):
    """The target has not been seen for longer than the timeout."""

    EVENT_ID: ClassVar[EventId] = EventId.TARGET_LOST
    severity: Severity = Severity.MEDIUM
    unseen_s: F32 = Field(ge=0, description="time since the target was last seen, OBT s")

    def parameters(self) -> bytes:
        """f32 unseen time."""
        return struct.pack(">f", self.unseen_s)

    @classmethod
    def from_app_data(cls, subservice: int, r: _Reader) -> Self:
        """Parse the parameters."""
        return _built(cls, cls.__name__, severity=subservice, unseen_s=r.one("f", "unseen_s"))


class WheelSaturationEvent(EventReport):
    """A reaction wheel reached its momentum limit."""

    EVENT_ID: ClassVar[EventId] = EventId.WHEEL_SATURATION
    severity: Severity = Severity.MEDIUM
    wheel: U8 = Field(description="wheel index")
    momentum_nms: F32 = Field(description="wheel momentum at saturation, N m s")

    def parameters(self) -> bytes:
        """u8 wheel, f32 momentum."""
        return struct.pack(">Bf", self.wheel, self.momentum_nms)

    @classmethod
    def from_app_data(cls, subservice: int, r: _Reader) -> Self:
        """Parse the parameters."""
        w, h = r.take("Bf", "wheel")
        return _built(cls, cls.__name__, severity=subservice, wheel=w, momentum_nms=h)


class FaultEvent(EventReport):
    """An on-board fault was detected."""

    EVENT_ID: ClassVar[EventId] = EventId.FAULT
    severity: Severity = Severity.HIGH
    fault_code: U16 = Field(description="OBSW-defined fault code")
    reason: Text = Field("", description="what failed")

    def parameters(self) -> bytes:
        """u16 code, reason text."""
        return struct.pack(">H", self.fault_code) + _text(self.reason)

    @classmethod
    def from_app_data(cls, subservice: int, r: _Reader) -> Self:
        """Parse the parameters."""
        code = r.one("H", "fault_code")
        return _built(cls, cls.__name__, severity=subservice, fault_code=code, reason=r.text("reason"))


class ClockJumpEvent(EventReport):
    """On-board time stepped between two control periods by more than the jump threshold."""

    EVENT_ID: ClassVar[EventId] = EventId.CLOCK_JUMP
    severity: Severity = Severity.MEDIUM
    step_s: Finite = Field(description="OBT step beyond the control period, s (negative: backwards)")

    def parameters(self) -> bytes:
        """f64 step."""
        return struct.pack(">d", self.step_s)

    @classmethod
    def from_app_data(cls, subservice: int, r: _Reader) -> Self:
        """Parse the step."""
        return _built(cls, cls.__name__, severity=subservice, step_s=r.one("d", "step_s"))


class CommandRejectedEvent(EventReport):
    """A TC was rejected (its service 1 failure report carries the reason text)."""

    EVENT_ID: ClassVar[EventId] = EventId.COMMAND_REJECTED
    severity: Severity = Severity.LOW
    request_id: RequestId
    failure_code: U16

    def parameters(self) -> bytes:
        """Request id, u16 failure code."""
        return self.request_id.packed() + struct.pack(">H", self.failure_code)

    @classmethod
    def from_app_data(cls, subservice: int, r: _Reader) -> Self:
        """Parse the parameters."""
        rid = r.request_id("request_id")
        code = r.one("H", "failure_code")
        return _built(cls, cls.__name__, severity=subservice, request_id=rid, failure_code=code)


# Service 9 ----------------------------------------------------------------------------------------------


class SetTimeReportRate(_Payload):
    """TC[9,1] set the time report generation rate: one report every 2^rate_exponent s."""

    SERVICE: ClassVar[int] = 9
    SUBSERVICE: ClassVar[int] = 1
    rate_exponent: U8

    def app_data(self) -> bytes:
        """u8 exponent."""
        return bytes((self.rate_exponent,))

    @classmethod
    def from_app_data(cls, subservice: int, r: _Reader) -> Self:
        """Parse the exponent."""
        return _built(cls, cls.__name__, rate_exponent=r.one("B", "rate_exponent"))


class TimeReport(_Payload):
    """TM[9,2] CUC time report: the OBT latched at the time reference instant."""

    SERVICE: ClassVar[int] = 9
    SUBSERVICE: ClassVar[int] = 2
    obt_s: ObtS = Field(description="on-board time of the report, s (carried on the 2^-16 s CUC grid)")
    rate_exponent: U8 = Field(0, description="current generation rate, one report every 2^n s")

    def app_data(self) -> bytes:
        """u8 exponent + CUC."""
        return bytes((self.rate_exponent,)) + cuc_encode(self.obt_s)

    @classmethod
    def from_app_data(cls, subservice: int, r: _Reader) -> Self:
        """Parse exponent and time."""
        n = r.one("B", "rate_exponent")
        return _built(cls, cls.__name__, rate_exponent=n, obt_s=r.obt("obt_s"))


# Service 11 ---------------------------------------------------------------------------------------------


def _check_tc_packet(packet: bytes) -> bytes:
    """Accept one complete space packet of type TC (its contents are decoded when it is released)."""
    if len(packet) < PRIMARY_HEADER_LEN + TC_SECONDARY_HEADER_LEN + CRC_LEN:
        raise ValueError(f"{len(packet)} octets is shorter than the smallest PUS TC")
    if not packet[0] & 0x10:
        raise ValueError("is a telemetry packet, a telecommand is needed")
    if _packet_len(packet) != len(packet):
        raise ValueError(f"length field says {_packet_len(packet)} octets, {len(packet)} given")
    return packet


class ScheduledActivity(Frozen):
    """One entry of the time-based schedule: a complete TC packet and its release OBT."""

    release_obt_s: ObtS = Field(description="release time, OBT s (carried on the 2^-16 s CUC grid)")
    tc_packet: Annotated[bytes, AfterValidator(_check_tc_packet)] = Field(description="the complete TC packet")
    ca_offset_s: Finite | None = Field(
        None, description="offset of the release from closest approach, s, if the activity follows the C/A estimate"
    )

    @property
    def request_id(self) -> RequestId:
        """The request id of the wrapped TC."""
        w0, w1 = struct.unpack_from(">HH", self.tc_packet)
        return RequestId(apid=w0 & MAX_APID, seq_count=w1 & MAX_SEQ_COUNT)

    def packed(self) -> bytes:
        """u8 tag kind (0 absolute, 1 C/A-relative), CUC release, [f64 C/A offset], the TC packet."""
        if self.ca_offset_s is None:
            return b"\x00" + cuc_encode(self.release_obt_s) + self.tc_packet
        return b"\x01" + cuc_encode(self.release_obt_s) + struct.pack(">d", self.ca_offset_s) + self.tc_packet

    @classmethod
    def read(cls, r: _Reader, field: str) -> ScheduledActivity:
        """Parse what ``packed`` wrote."""
        kind = r.one("B", field + ".tag_kind")
        if kind not in (0, 1):
            raise BadArgument(f"{r.kind}.{field}.tag_kind", f"{kind}, expected 0 (absolute) or 1 (C/A-relative)")
        release = r.obt(field + ".release_obt_s")
        offset = r.one("d", field + ".ca_offset_s") if kind else None
        packet = r.packet(field + ".tc_packet")
        return _built(cls, f"{r.kind}.{field}", release_obt_s=release, tc_packet=packet, ca_offset_s=offset)


class ScheduleSummaryEntry(Frozen):
    """One line of a schedule summary: release OBT and the request id of the scheduled TC."""

    release_obt_s: ObtS
    request_id: RequestId


class EnableSchedule(_Payload):
    """TC[11,1] enable the release of scheduled activities."""

    SERVICE: ClassVar[int] = 11
    SUBSERVICE: ClassVar[int] = 1


class DisableSchedule(_Payload):
    """TC[11,2] disable the release of scheduled activities (they stay in the schedule)."""

    SERVICE: ClassVar[int] = 11
    SUBSERVICE: ClassVar[int] = 2


class ResetSchedule(_Payload):
    """TC[11,3] delete every scheduled activity."""

    SERVICE: ClassVar[int] = 11
    SUBSERVICE: ClassVar[int] = 3


class InsertActivities(_Payload):
    """TC[11,4] insert activities into the time-based schedule."""

    SERVICE: ClassVar[int] = 11
    SUBSERVICE: ClassVar[int] = 4
    activities: tuple[ScheduledActivity, ...] = Field(min_length=1, max_length=0xFFFF)

    def app_data(self) -> bytes:
        """u16 count then each activity."""
        return struct.pack(">H", len(self.activities)) + b"".join(a.packed() for a in self.activities)

    @classmethod
    def from_app_data(cls, subservice: int, r: _Reader) -> Self:
        """Parse the activities."""
        n = r.one("H", "activities.count")
        acts = tuple(ScheduledActivity.read(r, f"activities[{i}]") for i in range(n))
        return _built(cls, cls.__name__, activities=acts)


class DeleteActivities(_Payload):
    """TC[11,5] delete the activities whose TCs have these request ids."""

    SERVICE: ClassVar[int] = 11
    SUBSERVICE: ClassVar[int] = 5
    request_ids: tuple[RequestId, ...] = Field(min_length=1, max_length=0xFFFF)

    def app_data(self) -> bytes:
        """u16 count then the ids."""
        return _request_ids(self.request_ids)

    @classmethod
    def from_app_data(cls, subservice: int, r: _Reader) -> Self:
        """Parse the ids."""
        return _built(cls, cls.__name__, request_ids=r.request_ids("request_ids"))


class TimeShiftActivities(_Payload):
    """TC[11,7] time-shift the named activities, or TC[11,15] all of them when ``request_ids`` is None."""

    SERVICE: ClassVar[int] = 11
    delta_s: Finite = Field(description="shift added to each release time, s (negative: earlier)")
    request_ids: tuple[RequestId, ...] | None = Field(None, min_length=1, max_length=0xFFFF)

    def subservice(self) -> int:
        """15 for all, 7 for selected."""
        return 15 if self.request_ids is None else 7

    def app_data(self) -> bytes:
        """f64 shift, then for 11,7 the ids."""
        out = struct.pack(">d", self.delta_s)
        return out if self.request_ids is None else out + _request_ids(self.request_ids)

    @classmethod
    def from_app_data(cls, subservice: int, r: _Reader) -> Self:
        """Parse shift and ids."""
        delta = r.one("d", "delta_s")
        ids = r.request_ids("request_ids") if subservice == 7 else None
        return _built(cls, cls.__name__, delta_s=delta, request_ids=ids)


class DetailReportRequest(_Payload):
    """TC[11,9] detail-report the named activities, or TC[11,16] all when ``request_ids`` is None."""

    SERVICE: ClassVar[int] = 11
    request_ids: tuple[RequestId, ...] | None = Field(None, min_length=1, max_length=0xFFFF)

    def subservice(self) -> int:
        """16 for all, 9 for selected."""
        return 16 if self.request_ids is None else 9

    def app_data(self) -> bytes:
        """The ids, for 11,9."""
        return b"" if self.request_ids is None else _request_ids(self.request_ids)

    @classmethod
    def from_app_data(cls, subservice: int, r: _Reader) -> Self:
        """Parse the ids."""
        ids = r.request_ids("request_ids") if subservice == 9 else None
        return _built(cls, cls.__name__, request_ids=ids)


class SummaryReportRequest(_Payload):
    """TC[11,12] summary-report the named activities, or TC[11,17] all when ``request_ids`` is None."""

    SERVICE: ClassVar[int] = 11
    request_ids: tuple[RequestId, ...] | None = Field(None, min_length=1, max_length=0xFFFF)

    def subservice(self) -> int:
        """17 for all, 12 for selected."""
        return 17 if self.request_ids is None else 12

    def app_data(self) -> bytes:
        """The ids, for 11,12."""
        return b"" if self.request_ids is None else _request_ids(self.request_ids)

    @classmethod
    def from_app_data(cls, subservice: int, r: _Reader) -> Self:
        """Parse the ids."""
        ids = r.request_ids("request_ids") if subservice == 12 else None
        return _built(cls, cls.__name__, request_ids=ids)


class ScheduleDetailReport(_Payload):
    """TM[11,10] the scheduled activities in full, in release order."""

    SERVICE: ClassVar[int] = 11
    SUBSERVICE: ClassVar[int] = 10
    activities: tuple[ScheduledActivity, ...] = Field((), max_length=0xFFFF)

    def app_data(self) -> bytes:
        """u16 count then each activity."""
        return struct.pack(">H", len(self.activities)) + b"".join(a.packed() for a in self.activities)

    @classmethod
    def from_app_data(cls, subservice: int, r: _Reader) -> Self:
        """Parse the activities."""
        n = r.one("H", "activities.count")
        acts = tuple(ScheduledActivity.read(r, f"activities[{i}]") for i in range(n))
        return _built(cls, cls.__name__, activities=acts)


class ScheduleSummaryReport(_Payload):
    """TM[11,13] release time and request id of the scheduled activities, in release order."""

    SERVICE: ClassVar[int] = 11
    SUBSERVICE: ClassVar[int] = 13
    entries: tuple[ScheduleSummaryEntry, ...] = Field((), max_length=0xFFFF)

    def app_data(self) -> bytes:
        """u16 count then CUC + request id each."""
        body = b"".join(cuc_encode(e.release_obt_s) + e.request_id.packed() for e in self.entries)
        return struct.pack(">H", len(self.entries)) + body

    @classmethod
    def from_app_data(cls, subservice: int, r: _Reader) -> Self:
        """Parse the entries."""
        n = r.one("H", "entries.count")
        entries = []
        for i in range(n):
            t = r.obt(f"entries[{i}].release_obt_s")
            entries.append(ScheduleSummaryEntry(release_obt_s=t, request_id=r.request_id(f"entries[{i}].request_id")))
        return _built(cls, cls.__name__, entries=tuple(entries))


# Service 200 (mission) ----------------------------------------------------------------------------------


class SetMode(_Payload):
    """TC[200,1] request an on-board mode."""

    SERVICE: ClassVar[int] = MISSION_SERVICE
    SUBSERVICE: ClassVar[int] = 1
    mode: ModeValue

    def app_data(self) -> bytes:
        """u8 mode."""
        return bytes((int(self.mode),))

    @classmethod
    def from_app_data(cls, subservice: int, r: _Reader) -> Self:
        """Parse the mode."""
        return _built(cls, cls.__name__, mode=r.one("B", "mode"))


_UNIT_TOL = 1e-9
_ORTHO_TOL = 1e-6


class UploadNominalTrajectory(_Payload):
    """TC[200,2] the nominal flyby the recognition grid is built around (all float64)."""

    SERVICE: ClassVar[int] = MISSION_SERVICE
    SUBSERVICE: ClassVar[int] = 2
    ca_obt_s: Finite = Field(ge=0, description="nominal closest approach time, OBT s")
    ca_distance_km: Finite = Field(gt=0, description="nominal distance at closest approach, km")
    speed_km_s: Finite = Field(gt=0, description="relative speed, km/s")
    approach_direction: UnitVector = Field(description="unit vector of the relative velocity, inertial frame")
    ca_direction: UnitVector = Field(description="unit vector target -> spacecraft at closest approach, inertial")
    sigma_ca_time_s: Finite = Field(ge=0, description="one-sigma uncertainty of the C/A time, s")
    sigma_ca_distance_km: Finite = Field(ge=0, description="one-sigma uncertainty of the C/A distance, km")

    @model_validator(mode="after")
    def _geometry(self) -> UploadNominalTrajectory:
        for name in ("approach_direction", "ca_direction"):
            v = getattr(self, name)
            norm = math.sqrt(sum(c * c for c in v))
            if abs(norm - 1.0) > _UNIT_TOL:
                raise ValueError(f"{name}: norm {norm!r} is not 1 within {_UNIT_TOL:g}")
        dot = sum(a * b for a, b in zip(self.approach_direction, self.ca_direction, strict=True))
        if abs(dot) > _ORTHO_TOL:
            raise ValueError(
                f"ca_direction: must be perpendicular to approach_direction at closest approach, dot = {dot:.3g}"
            )
        return self

    def app_data(self) -> bytes:
        """11 float64."""
        return struct.pack(
            ">11d",
            self.ca_obt_s,
            self.ca_distance_km,
            self.speed_km_s,
            *self.approach_direction,
            *self.ca_direction,
            self.sigma_ca_time_s,
            self.sigma_ca_distance_km,
        )

    @classmethod
    def from_app_data(cls, subservice: int, r: _Reader) -> Self:
        """Parse the 11 float64."""
        v = r.take("11d", "trajectory")
        return _built(
            cls,
            cls.__name__,
            ca_obt_s=v[0],
            ca_distance_km=v[1],
            speed_km_s=v[2],
            approach_direction=v[3:6],
            ca_direction=v[6:9],
            sigma_ca_time_s=v[9],
            sigma_ca_distance_km=v[10],
        )


class SetCameraCadence(_Payload):
    """TC[200,3] change the frame period and exposure."""

    SERVICE: ClassVar[int] = MISSION_SERVICE
    SUBSERVICE: ClassVar[int] = 3
    period_s: Finite = Field(gt=0, description="time between frames, OBT s")
    exposure_s: Finite = Field(gt=0, description="exposure time, s")

    @model_validator(mode="after")
    def _exposure_fits(self) -> SetCameraCadence:
        if self.exposure_s > self.period_s:
            raise ValueError(f"exposure_s: {self.exposure_s} s is longer than the period {self.period_s} s")
        return self

    def app_data(self) -> bytes:
        """f64 period, f64 exposure."""
        return struct.pack(">dd", self.period_s, self.exposure_s)

    @classmethod
    def from_app_data(cls, subservice: int, r: _Reader) -> Self:
        """Parse period and exposure."""
        p, e = r.take("dd", "cadence")
        return _built(cls, cls.__name__, period_s=p, exposure_s=e)


class StartImaging(_Payload):
    """TC[200,4] start taking frames, at ``period_s`` or at the current cadence when None."""

    SERVICE: ClassVar[int] = MISSION_SERVICE
    SUBSERVICE: ClassVar[int] = 4
    period_s: Finite | None = Field(None, gt=0, description="time between frames, OBT s")

    def app_data(self) -> bytes:
        """u8 present flag, f64 period."""
        return struct.pack(">Bd", self.period_s is not None, _opt(self.period_s))

    @classmethod
    def from_app_data(cls, subservice: int, r: _Reader) -> Self:
        """Parse flag and period."""
        present, period = r.take("Bd", "period_s")
        if present not in (0, 1):
            raise BadArgument(f"{cls.__name__}.period_s.present", f"flag {present}, expected 0 or 1")
        return _built(cls, cls.__name__, period_s=period if present else None)


class StopImaging(_Payload):
    """TC[200,5] stop taking frames."""

    SERVICE: ClassVar[int] = MISSION_SERVICE
    SUBSERVICE: ClassVar[int] = 5


class AdjustObt(_Payload):
    """TC[200,7] step the on-board clock by ``delta_s`` (a commanded time correction; reported as a clock jump)."""

    SERVICE: ClassVar[int] = MISSION_SERVICE
    SUBSERVICE: ClassVar[int] = 7
    delta_s: Finite = Field(ge=-86400.0, le=86400.0, description="OBT step, s (negative: backwards)")

    def app_data(self) -> bytes:
        """f64 step."""
        return struct.pack(">d", self.delta_s)

    @classmethod
    def from_app_data(cls, subservice: int, r: _Reader) -> Self:
        """Parse the step."""
        return _built(cls, cls.__name__, delta_s=r.one("d", "delta_s"))


class RequestTimeReports(_Payload):
    """TC[200,6] send ``count`` service 9 time reports, one per second, for ground time correlation."""

    SERVICE: ClassVar[int] = MISSION_SERVICE
    SUBSERVICE: ClassVar[int] = 6
    count: int = Field(ge=1, le=0xFFFF, description="number of time reports")

    def app_data(self) -> bytes:
        """u16 count."""
        return struct.pack(">H", self.count)

    @classmethod
    def from_app_data(cls, subservice: int, r: _Reader) -> Self:
        """Parse the count."""
        return _built(cls, cls.__name__, count=r.one("H", "count"))


_NAV = struct.Struct(">IBffffIddd")


class NavigationReport(_Payload):
    """TM[200,130] what the imaging chain made of one frame: centroids (binned px), area, measured line of sight.

    Layout: u32 frame id, u8 validity flags (bit0 Dimorphos centroid, bit1 Didymos centroid, bit2 line of sight),
    f32 Dimorphos col, row, f32 Didymos col, row, u32 Dimorphos area px, f64 line of sight x y z (inertial).
    """

    SERVICE: ClassVar[int] = MISSION_SERVICE
    SUBSERVICE: ClassVar[int] = 130
    frame_id: U32
    dimorphos_col_row: tuple[F32, F32] | None = Field(None, description="Dimorphos centroid, binned px")
    didymos_col_row: tuple[F32, F32] | None = Field(None, description="Didymos centroid, binned px")
    dimorphos_area_px: U32 = Field(0, description="Dimorphos area, binned px")
    los_inertial: UnitVector | None = Field(None, description="measured line of sight to Dimorphos, inertial")

    def app_data(self) -> bytes:
        """The fixed 49-octet layout."""
        flags = (
            (self.dimorphos_col_row is not None)
            | (self.didymos_col_row is not None) << 1
            | (self.los_inertial is not None) << 2
        )
        dm = self.dimorphos_col_row or (0.0, 0.0)
        dd = self.didymos_col_row or (0.0, 0.0)
        los = self.los_inertial or (0.0, 0.0, 0.0)
        return _NAV.pack(self.frame_id, flags, *dm, *dd, self.dimorphos_area_px, *los)

    @classmethod
    def from_app_data(cls, subservice: int, r: _Reader) -> Self:
        """Parse the fixed layout; absent values come back as None."""
        v = r.take(_NAV.format[1:], "navigation")
        flags = v[1]
        if flags & ~0b111:
            raise BadArgument(f"{cls.__name__}.flags", f"unknown validity bits 0x{flags:02X}")
        return _built(
            cls,
            cls.__name__,
            frame_id=v[0],
            dimorphos_col_row=v[2:4] if flags & 1 else None,
            didymos_col_row=v[4:6] if flags & 2 else None,
            dimorphos_area_px=v[6],
            los_inertial=v[7:10] if flags & 4 else None,
        )


_EST = struct.Struct(">IB7d")


class EstimateReport(_Payload):
    """TM[200,131] the on-board C/A estimates: best grid candidate and the continuous (least-squares) estimate.

    Layout: u32 line-of-sight measurements used, u8 validity flags (bit0 grid, bit1 continuous), f64 grid C/A OBT s,
    grid C/A distance km, grid mean square error rad^2, continuous C/A OBT s, continuous C/A distance km, and the
    continuous estimate's one-sigma C/A time s and distance km.
    """

    SERVICE: ClassVar[int] = MISSION_SERVICE
    SUBSERVICE: ClassVar[int] = 131
    n_measurements: U32
    grid_ca_obt_s: Finite | None = None
    grid_ca_distance_km: Finite | None = None
    grid_mse_rad2: Finite | None = None
    continuous_ca_obt_s: Finite | None = None
    continuous_ca_distance_km: Finite | None = None
    continuous_sigma_time_s: Finite | None = None
    continuous_sigma_distance_km: Finite | None = None

    @model_validator(mode="after")
    def _complete(self) -> EstimateReport:
        grid = (self.grid_ca_obt_s, self.grid_ca_distance_km, self.grid_mse_rad2)
        cont = (self.continuous_ca_obt_s, self.continuous_ca_distance_km, self.continuous_sigma_time_s,
                self.continuous_sigma_distance_km)
        for name, group in (("grid_ca_obt_s", grid), ("continuous_ca_obt_s", cont)):
            if any(v is None for v in group) and any(v is not None for v in group):
                raise ValueError(f"{name}: an estimate needs all of its values, or none")
        return self

    def app_data(self) -> bytes:
        """The fixed 61-octet layout; absent values are sent as 0 with their validity bit clear."""
        flags = (self.grid_ca_obt_s is not None) | (self.continuous_ca_obt_s is not None) << 1
        return _EST.pack(self.n_measurements, flags, _opt(self.grid_ca_obt_s), _opt(self.grid_ca_distance_km),
                         _opt(self.grid_mse_rad2), _opt(self.continuous_ca_obt_s),
                         _opt(self.continuous_ca_distance_km), _opt(self.continuous_sigma_time_s),
                         _opt(self.continuous_sigma_distance_km))

    @classmethod
    def from_app_data(cls, subservice: int, r: _Reader) -> Self:
        """Parse the fixed layout."""
        v = r.take(_EST.format[1:], "estimate")
        flags = v[1]
        if flags & ~0b11:
            raise BadArgument(f"{cls.__name__}.flags", f"unknown validity bits 0x{flags:02X}")
        g, c = bool(flags & 1), bool(flags & 2)
        return _built(cls, cls.__name__, n_measurements=v[0],
                      grid_ca_obt_s=v[2] if g else None, grid_ca_distance_km=v[3] if g else None,
                      grid_mse_rad2=v[4] if g else None, continuous_ca_obt_s=v[5] if c else None,
                      continuous_ca_distance_km=v[6] if c else None, continuous_sigma_time_s=v[7] if c else None,
                      continuous_sigma_distance_km=v[8] if c else None)


# ---------------------------------------------------------------------------------------------- registries

TcCommand: TypeAlias = (
    Ping
    | SetTimeReportRate
    | EnableSchedule
    | DisableSchedule
    | ResetSchedule
    | InsertActivities
    | DeleteActivities
    | TimeShiftActivities
    | DetailReportRequest
    | SummaryReportRequest
    | SetMode
    | UploadNominalTrajectory
    | SetCameraCadence
    | StartImaging
    | StopImaging
    | RequestTimeReports
    | AdjustObt
)
Event: TypeAlias = (
    ModeChangedEvent | TargetAcquiredEvent | TargetLostEvent | WheelSaturationEvent | FaultEvent | CommandRejectedEvent
    | ClockJumpEvent
)
TmReport: TypeAlias = (
    PingReply
    | Verification
    | Housekeeping
    | Event
    | TimeReport
    | ScheduleDetailReport
    | ScheduleSummaryReport
    | NavigationReport
    | EstimateReport
)

_TC_TYPES: dict[tuple[int, int], type[_Payload]] = {
    (17, 1): Ping,
    (9, 1): SetTimeReportRate,
    (11, 1): EnableSchedule,
    (11, 2): DisableSchedule,
    (11, 3): ResetSchedule,
    (11, 4): InsertActivities,
    (11, 5): DeleteActivities,
    (11, 7): TimeShiftActivities,
    (11, 15): TimeShiftActivities,
    (11, 9): DetailReportRequest,
    (11, 16): DetailReportRequest,
    (11, 12): SummaryReportRequest,
    (11, 17): SummaryReportRequest,
    (MISSION_SERVICE, 1): SetMode,
    (MISSION_SERVICE, 2): UploadNominalTrajectory,
    (MISSION_SERVICE, 3): SetCameraCadence,
    (MISSION_SERVICE, 4): StartImaging,
    (MISSION_SERVICE, 5): StopImaging,
    (MISSION_SERVICE, 6): RequestTimeReports,
    (MISSION_SERVICE, 7): AdjustObt,
}
_TM_TYPES: dict[tuple[int, int], type[_Payload]] = {
    (17, 2): PingReply,
    **{(1, sub): Verification for sub in (1, 2, 3, 4, 7, 8)},
    (3, 25): Housekeeping,
    (9, 2): TimeReport,
    (11, 10): ScheduleDetailReport,
    (11, 13): ScheduleSummaryReport,
    (MISSION_SERVICE, 130): NavigationReport,
    (MISSION_SERVICE, 131): EstimateReport,
}
_EVENT_TYPES: dict[int, type[EventReport]] = {
    int(c.EVENT_ID): c
    for c in (
        ModeChangedEvent,
        TargetAcquiredEvent,
        TargetLostEvent,
        WheelSaturationEvent,
        FaultEvent,
        CommandRejectedEvent,
        ClockJumpEvent,
    )
}


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
    msg_counter: int = Field(description="PUS message type counter (16 bit)")
    destination_id: int


# -------------------------------------------------------------------------------------------- encode/decode


def _check_ids(apid: int, seq: int) -> None:
    """Reject an APID or sequence count that does not fit the primary header."""
    if not 0 <= apid <= MAX_APID:
        raise BadArgument("apid", f"{apid} is outside [0, {MAX_APID}]")
    if not 0 <= seq <= MAX_SEQ_COUNT:
        raise BadArgument("seq", f"{seq} is outside [0, {MAX_SEQ_COUNT}] (wrap it modulo {SEQ_COUNT_MODULO})")


def encode_tc(cmd: TcCommand, apid: int, seq: int, *, source_id: int = 0, ack_flags: int = 0b1111) -> bytes:
    """Build the TC packet of ``cmd`` addressed to ``apid`` with sequence count ``seq``."""
    if type(cmd) not in _TC_TYPES.values():
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
    report: TmReport, apid: int, seq: int, obt_s: float, msg_counter: int, *, destination_id: int = 0
) -> bytes:
    """Build the TM packet of ``report`` from ``apid``, stamped ``obt_s`` (OBT, s) as CUC."""
    if not isinstance(report, EventReport) and type(report) not in _TM_TYPES.values():
        raise TypeError(f"{type(report).__name__} is not a telemetry report of this mission")
    _check_ids(apid, seq)
    if not 0 <= msg_counter <= 0xFFFF:
        raise BadArgument("msg_counter", f"{msg_counter} is outside [0, 65535] (wrap it modulo 65536)")
    data = report.app_data()
    if PRIMARY_HEADER_LEN + TM_SECONDARY_HEADER_LEN + len(data) + CRC_LEN > MAX_PACKET_LEN:
        raise BadArgument(type(report).__name__, f"{len(data)} octets of source data do not fit one packet")
    tm = PusTm(
        service=report.SERVICE,
        message_subtype=report.subservice(),
        timestamp=cuc_encode(obt_s),
        source_data=data,
        apid=apid,
        seq_count=seq,
        message_counter=msg_counter,
        destination_id=destination_id,
    )
    return bytes(tm.pack())


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


def _payload(
    types: dict[tuple[int, int], type[_Payload]], service: int, sub: int, data: bytes, rid: RequestId | None
) -> Any:
    """Decode application data of a known (service, subtype); TM service 5 is dispatched on its event id."""
    if service == 5 and types is _TM_TYPES:
        if sub not in Severity._value2member_map_:
            raise UnknownService(service, sub, True, rid)
        r = _Reader(data, "Event")
        event_id = r.one("H", "event_id")
        cls: type[_Payload] | None = _EVENT_TYPES.get(event_id)
        if cls is None:
            raise BadArgument("Event.event_id", f"unknown event id {event_id}", rid)
        r.kind = cls.__name__
    else:
        cls = types.get((service, sub))
        if cls is None:
            raise UnknownService(service, sub, any(s == service for s, _ in types), rid)
        r = _Reader(data, cls.__name__)
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
    return header, _payload(_TC_TYPES, header.service, header.subservice, bytes(tc.app_data), rid)


def decode_tm(data: bytes) -> tuple[TmHeader, TmReport]:
    """Parse and check a TM packet; raise a PacketError subclass."""
    data = bytes(data)
    apid, seq, _ = _check_frame(data, want_tc=False)
    try:
        tm = PusTm.unpack(data, timestamp_len=CUC_LEN)
    except InvalidTmCrc16Error:
        raise CrcMismatch("TM CRC-16 mismatch") from None
    except ValueError as exc:
        raise MalformedPacket(f"TM secondary header: {exc}") from None
    try:
        obt_s = cuc_decode(tm.timestamp)
    except CucError as exc:
        raise MalformedPacket(f"TM time stamp: {exc}") from None
    sec = tm.pus_tm_sec_header
    header = TmHeader(
        apid=apid,
        seq_count=seq,
        service=sec.service,
        subservice=sec.message_subtype,
        obt_s=obt_s,
        msg_counter=sec.message_counter,
        destination_id=sec.dest_id,
    )
    return header, _payload(_TM_TYPES, header.service, header.subservice, bytes(tm.source_data), None)


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


def request_id_of(packet: bytes) -> RequestId:
    """The request id (APID and sequence count) of a TC packet, from its first 4 octets."""
    if len(packet) < 4:
        raise TruncatedPacket(f"{len(packet)} octets hold no request id (4 needed)")
    w0, w1 = struct.unpack_from(">HH", packet)
    return RequestId(apid=w0 & MAX_APID, seq_count=w1 & MAX_SEQ_COUNT)
