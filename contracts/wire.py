"""Wire types of the TM/TC dictionary: how one field's value becomes octets and back.

A packet field declares its wire type in its annotation (``q: tuple[F32, F32, F32, F32]``); the generic codec
(``contracts.packet``), the documentation and the XTCE export read it from there. All numbers are big-endian.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass
from enum import IntEnum
from typing import Annotated, Any

from pydantic import AfterValidator, Field

from contracts.cuc import CUC_LEN, MAX_OBT_S, CucError, cuc_decode, cuc_encode
from contracts.mode import Mode, ModeValue
from contracts.packet_errors import BadArgument, RequestId
from contracts.task import Task, TaskValue

PRIMARY_HEADER_LEN = 6
MAX_TEXT_OCTETS = 255
F32_MAX = 3.4028234663852886e38


def packet_len(data: bytes, offset: int = 0) -> int:
    """Total length of the space packet starting at ``offset``, from its length field."""
    return struct.unpack_from(">H", data, offset + 4)[0] + PRIMARY_HEADER_LEN + 1


_STRUCTS: dict[str, struct.Struct] = {}  # each format Reader.take was asked for, compiled once (the fields' few)


class Reader:
    """Reads the application data of one packet, naming the field at fault when it runs short."""

    def __init__(self, data: bytes, kind: str) -> None:
        self.data = data
        self.kind = kind
        self.pos = 0

    def fault(self, field: str, why: str) -> BadArgument:
        """The error naming ``field`` of the packet being read."""
        return BadArgument(f"{self.kind}.{field}" if field else self.kind, why)

    def take(self, fmt: str, field: str) -> tuple[Any, ...]:
        """Unpack the big-endian struct ``fmt`` for ``field``."""
        s = _STRUCTS.get(fmt)
        if s is None:
            s = _STRUCTS[fmt] = struct.Struct(">" + fmt)
        end = self.pos + s.size
        if end > len(self.data):
            raise self.fault(field, f"missing: application data ends at octet {len(self.data)}, "
                                    f"field needs octets {self.pos}..{end - 1}")
        values = s.unpack_from(self.data, self.pos)
        self.pos = end
        return values

    def one(self, fmt: str, field: str) -> Any:
        """Unpack a single value."""
        return self.take(fmt, field)[0]

    def raw(self, n: int, field: str) -> bytes:
        """Take ``n`` octets."""
        if self.pos + n > len(self.data):
            raise self.fault(field, f"missing: needs {n} octets, {len(self.data) - self.pos} left")
        out = self.data[self.pos : self.pos + n]
        self.pos += n
        return out

    def packet(self, field: str) -> bytes:
        """A complete embedded space packet, delimited by its own length field."""
        if self.pos + PRIMARY_HEADER_LEN > len(self.data):
            raise self.fault(field, "missing: no room for an embedded packet's primary header")
        return self.raw(packet_len(self.data, self.pos), field)

    def end(self) -> None:
        """Check that every octet was consumed."""
        if self.pos != len(self.data):
            raise BadArgument(self.kind, f"{len(self.data) - self.pos} unexpected octets after the last field")


class WireType:
    """How a value travels: ``label`` names it in the documentation, ``octets`` is its size when fixed."""

    label: str

    @property
    def octets(self) -> int | None:
        """Size in octets when fixed, else None."""
        return None

    def encode(self, value: Any) -> bytes:
        """The octets of ``value``."""
        raise NotImplementedError

    def decode(self, r: Reader, field: str) -> Any:
        """Read a value for ``field``."""
        raise NotImplementedError

    def filler(self, fill: float) -> Any:
        """The value sent in place of an absent one (its validity flag clear)."""
        raise TypeError(f"a {self.label} field cannot be absent behind a validity flag")


@dataclass(frozen=True)
class Number(WireType):
    """An unsigned integer or an IEEE 754 float of fixed size."""

    label: str
    fmt: str
    is_float: bool

    @property
    def octets(self) -> int:  # type: ignore[override]
        """Size in octets."""
        return struct.calcsize(">" + self.fmt)

    def encode(self, value: Any) -> bytes:
        """Big-endian."""
        return struct.pack(">" + self.fmt, value)

    def decode(self, r: Reader, field: str) -> Any:
        """Big-endian."""
        return r.one(self.fmt, field)

    def filler(self, fill: float) -> Any:
        """``fill`` for a float, 0 for an integer."""
        return fill if self.is_float else 0


UINT8 = Number("u8", "B", False)
UINT16 = Number("u16", "H", False)
UINT32 = Number("u32", "I", False)
FLOAT32 = Number("f32", "f", True)
FLOAT64 = Number("f64", "d", True)


@dataclass(frozen=True)
class EnumCode(WireType):
    """An enumeration sent as its integer code (``wire`` gives the size)."""

    enum: type[IntEnum]
    wire: Number

    @property
    def label(self) -> str:  # type: ignore[override]
        """The code's integer type."""
        return self.wire.label

    @property
    def octets(self) -> int:  # type: ignore[override]
        """Size in octets."""
        return self.wire.octets

    def encode(self, value: Any) -> bytes:
        """The code."""
        return self.wire.encode(int(value))

    def decode(self, r: Reader, field: str) -> Any:
        """The member, or BadArgument naming the field for an unknown code."""
        code = self.wire.decode(r, field)
        if code not in self.enum._value2member_map_:
            raise r.fault(field, f"unknown {self.enum.__name__} code {code}")
        return self.enum(code)


@dataclass(frozen=True)
class TextWire(WireType):
    """A u8 length then that many octets of UTF-8."""

    label: str = "text"

    def encode(self, value: Any) -> bytes:
        """Length then UTF-8."""
        b = value.encode("utf-8")
        return bytes((len(b),)) + b

    def decode(self, r: Reader, field: str) -> Any:
        """Length then UTF-8."""
        n = r.one("B", field + ".length")
        try:
            return r.raw(n, field).decode("utf-8")
        except UnicodeDecodeError as exc:
            raise r.fault(field, f"not UTF-8 ({exc.reason} at octet {exc.start})") from None


@dataclass(frozen=True)
class CucWire(WireType):
    """An on-board time as the mission's 7-octet CUC (``contracts.cuc``)."""

    label: str = "cuc"
    octets: int = CUC_LEN

    def encode(self, value: Any) -> bytes:
        """P-field, 4 coarse and 2 fine octets."""
        return cuc_encode(value)

    def decode(self, r: Reader, field: str) -> Any:
        """OBT, s."""
        try:
            return cuc_decode(r.raw(CUC_LEN, field))
        except CucError as exc:
            raise r.fault(field, str(exc)) from None


@dataclass(frozen=True)
class RequestIdWire(WireType):
    """A TC's request id: its first 4 octets (``RequestId.packed``)."""

    label: str = "request id"
    octets: int = 4

    def encode(self, value: Any) -> bytes:
        """The 4 octets."""
        return value.packed()

    def decode(self, r: Reader, field: str) -> Any:
        """The 4 octets, checked."""
        raw = r.raw(4, field)
        try:
            return RequestId.from_packed(raw)
        except BadArgument as exc:
            raise r.fault(field, exc.why) from None


@dataclass(frozen=True)
class EmbeddedPacket(WireType):
    """A complete space packet carried inside another, delimited by its own length field."""

    label: str = "space packet"

    def encode(self, value: Any) -> bytes:
        """The packet as it is."""
        return bytes(value)

    def decode(self, r: Reader, field: str) -> Any:
        """As many octets as the embedded primary header announces."""
        return r.packet(field)


@dataclass(frozen=True)
class OctetString(WireType):
    """A fixed number of octets, carried as they are (a wrapped key)."""

    n: int

    @property
    def label(self) -> str:  # type: ignore[override]
        """E.g. 40 octets."""
        return f"{self.n} octets"

    @property
    def octets(self) -> int:  # type: ignore[override]
        """Size in octets."""
        return self.n

    def encode(self, value: Any) -> bytes:
        """The octets."""
        return bytes(value)

    def decode(self, r: Reader, field: str) -> Any:
        """``n`` octets."""
        return r.raw(self.n, field)


@dataclass(frozen=True)
class Vector(WireType):
    """A fixed number of values of one wire type (a tuple)."""

    element: WireType
    n: int

    @property
    def label(self) -> str:  # type: ignore[override]
        """E.g. 3 x f64."""
        return f"{self.n} x {self.element.label}"

    @property
    def octets(self) -> int | None:  # type: ignore[override]
        """Size in octets."""
        return None if self.element.octets is None else self.n * self.element.octets

    def encode(self, value: Any) -> bytes:
        """Each element."""
        return b"".join(self.element.encode(v) for v in value)

    def decode(self, r: Reader, field: str) -> Any:
        """Each element."""
        return tuple(self.element.decode(r, f"{field}[{i}]") for i in range(self.n))

    def filler(self, fill: float) -> Any:
        """Every element filled."""
        return (self.element.filler(fill),) * self.n


@dataclass(frozen=True)
class CountedList(WireType):
    """A u16 count then that many values (a tuple)."""

    element: WireType

    @property
    def label(self) -> str:  # type: ignore[override]
        """E.g. u16 count + n x request id."""
        return f"u16 count + n x {self.element.label}"

    def encode(self, value: Any) -> bytes:
        """Count then each element."""
        return struct.pack(">H", len(value)) + b"".join(self.element.encode(v) for v in value)

    def decode(self, r: Reader, field: str) -> Any:
        """Count then each element."""
        n = r.one("H", field + ".count")
        return tuple(self.element.decode(r, f"{field}[{i}]") for i in range(n))


@dataclass(frozen=True)
class Padded(WireType):
    """``slots`` values of which the first ``count`` are used (the count is a separate item); unused slots are 0."""

    element: WireType
    slots: int

    @property
    def label(self) -> str:  # type: ignore[override]
        """E.g. 4 x f32 (first count used)."""
        return f"{self.slots} x {self.element.label}, the first 'count' used, the rest 0"

    @property
    def octets(self) -> int | None:  # type: ignore[override]
        """Size in octets."""
        return None if self.element.octets is None else self.slots * self.element.octets

    def encode(self, value: Any) -> bytes:
        """The values then zeros."""
        pad = (self.element.filler(0.0),) * (self.slots - len(value))
        return b"".join(self.element.encode(v) for v in (*value, *pad))

    def decode_used(self, r: Reader, field: str, used: int) -> Any:
        """All slots; the first ``used`` are kept."""
        values = tuple(self.element.decode(r, f"{field}[{i}]") for i in range(self.slots))
        return values[:used]


# --------------------------------------------------------------------------------------- field value checks


def _fits_f32(x: float) -> float:
    """Accept a float that a float32 can carry (finite values up to F32_MAX, NaN and infinities)."""
    if -F32_MAX <= x <= F32_MAX:  # nearly every value: two comparisons, no call (a packet has dozens of them)
        return x
    if math.isfinite(x):
        raise ValueError(f"{x!r} exceeds the float32 range of this field (|x| <= {F32_MAX:.4g})")
    return x


def _finite(x: float) -> float:
    """Accept a finite float only."""
    if -math.inf < x < math.inf:  # finite: two comparisons, no call (NaN compares false)
        return x
    raise ValueError(f"must be finite, got {x!r}")


def _fits_text(s: str) -> str:
    """Accept a string whose UTF-8 form fits the u8 length prefix."""
    n = len(s.encode("utf-8"))
    if n > MAX_TEXT_OCTETS:
        raise ValueError(f"is {n} octets of UTF-8, at most {MAX_TEXT_OCTETS} fit")
    return s


# The annotations a packet field is declared with: a Python type, its value checks, and its wire type.
U8 = Annotated[int, Field(ge=0, le=0xFF), UINT8]
U16 = Annotated[int, Field(ge=0, le=0xFFFF), UINT16]
U32 = Annotated[int, Field(ge=0, le=0xFFFFFFFF), UINT32]
F32 = Annotated[float, AfterValidator(_fits_f32), FLOAT32]
F64 = Annotated[float, FLOAT64]
Finite = Annotated[float, AfterValidator(_finite), FLOAT64]
Text = Annotated[str, AfterValidator(_fits_text), TextWire()]
ObtS = Annotated[float, Field(ge=0.0, le=MAX_OBT_S), CucWire()]
Rid = Annotated[RequestId, RequestIdWire()]
UnitVector = tuple[Finite, Finite, Finite]
Mode8 = Annotated[ModeValue, EnumCode(Mode, UINT8)]
Task8 = Annotated[TaskValue, EnumCode(Task, UINT8)]
