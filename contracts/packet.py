"""How a packet of the dictionary is declared, and the generic codec its declaration gives.

A packet is a frozen model declared with its kind, service and subtype(s) as class keywords; its fields, in wire
order, carry their wire type in their annotation (``contracts.wire``) and their unit, range and description in
``field(...)``. Octets that are no field of the value sit between the fields as class variables:

- ``Constant``: a fixed value (a structure id, an event id), checked on decoding;
- ``Validity``: one octet of validity flags: bit k is set when the optional fields declared with ``bit=k`` are
  present; absent ones are sent as ``fill`` (or left out of the packet, with ``omit=True``);
- ``Count``: how many slots of the ``Padded`` arrays that follow are used.

Every packet declared with a ``service`` is collected, in declaration order, by ``declared()``: that list is the
dictionary. A packet whose layout is no flat sequence overrides ``subservice``, ``app_data`` and ``from_app_data``.
"""

from __future__ import annotations

import math
import struct
import types
import typing
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Annotated, Any, ClassVar, Literal, Self, get_args, get_origin

from pydantic import Field, ValidationError
from pydantic.fields import FieldInfo

from contracts.model import Frozen
from contracts.packet_errors import BadArgument
from contracts.wire import UINT8, CountedList, EnumCode, Number, Padded, Reader, Vector, WireType

Kind = Literal["TC", "TM"]
_UNSET: Any = ...


def field(description: str, unit: str = "", *, default: Any = _UNSET, bit: int | None = None,
          slots: int | None = None, **checks: Any) -> Any:
    """A packet field: its description, unit and value checks (``ge``, ``gt``, ``le``, ``lt``, lengths).

    ``bit``: the validity flag of an optional field; ``slots``: the wire size of a ``Padded`` array.
    """
    extra = {"unit": unit, "bit": bit, "slots": slots}
    return Field(default, description=description, json_schema_extra=extra, **checks)


@dataclass(frozen=True)
class Constant:
    """Octets of fixed value between the fields (``value`` None: the packet's ``EVENT_ID``)."""

    wire: Number
    value: int | None
    description: str


@dataclass(frozen=True)
class Validity:
    """One octet of validity flags for the optional fields declared with ``bit=``."""

    description: str = "validity flags: bit k set when the fields of bit k are present"
    fill: float = math.nan
    omit: bool = False


@dataclass(frozen=True)
class Count:
    """The number of used slots of the ``Padded`` arrays that follow."""

    wire: Number
    low: int
    high: int
    description: str


WireOnly = Constant | Validity | Count


@dataclass(frozen=True)
class Item:
    """One element of a packet's layout: a field of the value, or octets of its own (``extra`` then says which)."""

    name: str
    wire: WireType
    description: str
    unit: str = ""
    extra: WireOnly | None = None
    bit: int | None = None
    optional: bool = False
    checks: tuple[tuple[str, Any], ...] = ()

    @property
    def is_field(self) -> bool:
        """Whether this item is a field of the value."""
        return self.extra is None


@dataclass(frozen=True)
class TimelineCommand:
    """The timeline command that sends a telecommand: its name, what it does, and the fields ground completes
    from its own knowledge (the timeline gives the others)."""

    name: str
    description: str
    ground_fills: tuple[str, ...] = ()
    defaults: tuple[tuple[str, Any], ...] = ()


# -------------------------------------------------------------------------------------- wire type of a field


def _wire_in(metadata: typing.Iterable[Any]) -> WireType | None:
    return next((m for m in metadata if isinstance(m, WireType)), None)


def wire_of(annotation: Any, metadata: typing.Iterable[Any] = ()) -> WireType:
    """The wire type a field annotation declares (an optional's inner type; a tuple's vector or counted list)."""
    found = _wire_in(metadata)
    if found is not None:
        return found
    origin = get_origin(annotation)
    if origin is Annotated:
        inner, *meta = get_args(annotation)
        return wire_of(inner, meta)
    if origin in (typing.Union, types.UnionType):
        present = [a for a in get_args(annotation) if a is not type(None)]
        if len(present) != 1:
            raise TypeError(f"{annotation}: a packet field is one type, or one type or None")
        return wire_of(present[0])
    if origin is tuple:
        args = get_args(annotation)
        if len(args) == 2 and args[1] is Ellipsis:
            return CountedList(wire_of(args[0]))
        elements = [wire_of(a) for a in args]
        if any(e != elements[0] for e in elements):
            raise TypeError(f"{annotation}: a vector's elements must share one wire type")
        return Vector(elements[0], len(elements))
    if isinstance(annotation, type) and issubclass(annotation, Record):
        return RecordWire(annotation)
    raise TypeError(f"{annotation}: no wire type declared")


def _is_optional(annotation: Any) -> bool:
    return get_origin(annotation) in (typing.Union, types.UnionType) and type(None) in get_args(annotation)


_CHECKS = ("ge", "gt", "le", "lt", "min_length", "max_length")


def _checks_of(info: FieldInfo) -> tuple[tuple[str, Any], ...]:
    out = []
    for m in info.metadata:
        for name in _CHECKS:
            value = getattr(m, name, None)
            if value is not None:
                out.append((name, value))
    return tuple(out)


def _field_item(name: str, info: FieldInfo) -> Item:
    extra = info.json_schema_extra if isinstance(info.json_schema_extra, Mapping) else {}
    wire = wire_of(info.annotation, info.metadata)
    slots = extra.get("slots")
    if slots is not None:
        if not isinstance(wire, CountedList):
            raise TypeError(f"{name}: slots= needs a tuple[X, ...] field")
        wire = Padded(wire.element, int(slots))  # type: ignore[call-overload]
    bit = extra.get("bit")
    return Item(name=name, wire=wire, description=info.description or "", unit=str(extra.get("unit") or ""),
                bit=None if bit is None else int(bit),  # type: ignore[call-overload]
                optional=_is_optional(info.annotation), checks=_checks_of(info))


def _extra_item(name: str, extra: WireOnly, owner: type) -> Item:
    if isinstance(extra, Constant):
        if extra.value is None and hasattr(owner, "EVENT_ID"):
            extra = Constant(extra.wire, int(owner.EVENT_ID), extra.description)  # type: ignore[attr-defined]
        return Item(name=name, wire=extra.wire, description=extra.description, extra=extra)
    if isinstance(extra, Count):
        return Item(name=name, wire=extra.wire, description=extra.description, extra=extra)
    return Item(name=name, wire=UINT8, description=extra.description, extra=extra)


def layout_of(cls: type[Record]) -> tuple[Item, ...]:
    """The items of ``cls`` in wire order: its fields and the octets declared between them, base classes first."""
    items: list[Item] = []
    seen: set[str] = set()
    for klass in reversed(cls.__mro__):
        for name in vars(klass).get("__annotations__", {}):
            if name in seen:
                continue
            if name in cls.model_fields and name not in cls.OFF_WIRE:
                seen.add(name)
                items.append(_field_item(name, cls.model_fields[name]))
            elif isinstance(getattr(cls, name, None), Constant | Validity | Count):
                seen.add(name)
                items.append(_extra_item(name, getattr(cls, name), cls))
    return tuple(items)


# --------------------------------------------------------------------------------------------------- codec


def built(cls: type[Frozen], kind: str, **fields: Any) -> Any:
    """Construct ``cls`` from decoded fields, turning a validation error into BadArgument naming the field."""
    try:
        return cls.__pydantic_validator__.validate_python(fields)  # cls(**fields), without repacking the fields
    except ValidationError as exc:
        err = exc.errors()[0]
        loc = ".".join(str(p) for p in err["loc"])
        raise BadArgument(f"{kind}.{loc}" if loc else kind, f"{err['msg']} (got {err.get('input')!r})") from None


# A layout of numbers only (scalars, enumeration codes, vectors, padded arrays, constants, validity flags kept in
# place, counts) has one size: it is read and written with one struct, the items' checks made on the values after.
# Anything the fast path does not take as it is (a short packet, a failed check, a value struct refuses) goes the
# item-by-item way below, which names the field at fault: both ways give the same octets and values.
_SCALAR, _ENUM, _VECTOR, _PADDED, _CONSTANT, _VALIDITY, _COUNT = range(7)


_UNFILLABLE: Any = object()  # an absent value the wire type cannot fill: the item-by-item way raises its error


@dataclass(frozen=True)
class _FixedPlan:
    """One struct for a whole layout: per item, what it is, where its values start and how many it has."""

    codec: struct.Struct
    # per item: kind, name, first value, values, validity bit, the value sent when absent (a field's filler), and
    # what the kind checks or adds (a constant's value, a count's bounds, an enumeration's members by code, a padded
    # array's filler); plain tuples, unpacked at each packet
    steps: tuple[tuple[int, str, int, int, int | None, Any, Any], ...]
    mask: int  # every validity bit the layout declares
    counted: str | None  # the padded array the count counts
    layout: tuple[Item, ...]  # kept, so the id keying the plan cache is never reused


_PLANS: dict[tuple[int, tuple[str, ...]], _FixedPlan | None] = {}
_BITS: dict[int, tuple[tuple[Item, ...], tuple[tuple[str, int], ...]]] = {}  # the layout kept, as in _FixedPlan


def _filler(wire: WireType, fill: float) -> Any:
    """What ``wire`` sends for an absent value, or _UNFILLABLE."""
    try:
        return wire.filler(fill)
    except TypeError:
        return _UNFILLABLE


def _fixed_plan(layout: tuple[Item, ...], left_out: tuple[str, ...]) -> _FixedPlan | None:
    """The layout as one struct, or None when it has an item of variable size."""
    key = (id(layout), left_out)
    if key in _PLANS:
        return _PLANS[key]
    fmt, steps, n, fill = [], [], 0, math.nan
    counted = next((i.name for i in layout if isinstance(i.wire, Padded)), None)
    plan: _FixedPlan | None = None
    for it in layout:
        if it.name in left_out:
            continue
        w, x = it.wire, it.extra
        aux: Any = None
        if isinstance(x, Validity):
            if x.omit:
                break
            kind, f, k, fill = _VALIDITY, "B", 1, x.fill
        elif isinstance(x, Constant):
            kind, f, k, aux = _CONSTANT, x.wire.fmt, 1, x.value
        elif isinstance(x, Count):
            kind, f, k, aux = _COUNT, x.wire.fmt, 1, (x.low, x.high)
        elif isinstance(w, Number):
            kind, f, k = _SCALAR, w.fmt, 1
        elif isinstance(w, EnumCode):
            kind, f, k, aux = _ENUM, w.wire.fmt, 1, w.enum._value2member_map_
        elif isinstance(w, Vector | Padded) and isinstance(w.element, Number):
            k = w.n if isinstance(w, Vector) else w.slots
            kind, f = (_VECTOR if isinstance(w, Vector) else _PADDED), w.element.fmt * k
            aux = w.element.filler(0.0) if isinstance(w, Padded) else None
        else:
            break
        fmt.append(f)
        absent = _filler(w, fill) if x is None else None
        steps.append((kind, it.name, n, k, it.bit, absent, aux))
        n += k
    else:
        plan = _FixedPlan(struct.Struct(">" + "".join(fmt)), tuple(steps),
                          sum(1 << b for b in {it.bit for it in layout if it.bit is not None}), counted, layout)
    _PLANS[key] = plan
    return plan


def _encode_fixed(plan: _FixedPlan, value: Any, flags: int) -> bytes | None:
    """The octets of ``value`` in one struct, or None for the item-by-item way."""
    flat: list[Any] = []
    for kind, name, _, k, _, absent, aux in plan.steps:
        if kind == _CONSTANT:
            flat.append(aux)
        elif kind == _VALIDITY:
            flat.append(flags)
        elif kind == _COUNT:
            if plan.counted is None:
                return None
            flat.append(len(getattr(value, plan.counted)))
        else:
            v = getattr(value, name)
            if v is None:
                if absent is _UNFILLABLE:
                    return None
                v = absent
            if kind == _SCALAR:
                flat.append(v)
            elif kind == _ENUM:
                flat.append(int(v))
            elif kind == _VECTOR:
                if len(v) != k:
                    return None
                flat.extend(v)
            else:
                if len(v) > k:
                    return None
                flat.extend(v)
                flat.extend((aux,) * (k - len(v)))
    try:
        return plan.codec.pack(*flat)
    except (struct.error, TypeError, ValueError, OverflowError):
        return None


def _decode_fixed(plan: _FixedPlan, r: Reader) -> dict[str, Any] | None:
    """The field values read in one struct, or None (nothing consumed) for the item-by-item way."""
    end = r.pos + plan.codec.size
    if end > len(r.data):
        return None
    raw = plan.codec.unpack_from(r.data, r.pos)
    values: dict[str, Any] = {}
    flags = used = 0
    for kind, name, i, k, bit, _, aux in plan.steps:
        if kind == _SCALAR:
            v = raw[i]
        elif kind == _VECTOR:
            v = raw[i:i + k]
        elif kind == _CONSTANT:
            if raw[i] != aux:
                return None
            continue
        elif kind == _VALIDITY:
            flags = raw[i]
            if flags & ~plan.mask:
                return None
            continue
        elif kind == _COUNT:
            used = raw[i]
            if not aux[0] <= used <= aux[1]:
                return None
            continue
        elif kind == _ENUM:
            v = aux.get(raw[i])  # the member, as enum(code) gives it
            if v is None:
                return None
        else:
            v = raw[i:i + min(used, k)]
        values[name] = v if bit is None or flags >> bit & 1 else None
    r.pos = end
    return values


def _flags(layout: tuple[Item, ...], value: Any) -> int:
    """The validity flags of ``value``: the bit of each optional field present."""
    bits = _BITS.get(id(layout))
    if bits is None:
        bits = _BITS[id(layout)] = layout, tuple((it.name, it.bit) for it in layout if it.bit is not None)
    flags = 0
    for name, bit in bits[1]:
        if getattr(value, name) is not None:
            flags |= 1 << bit
    return flags


def encode_items(layout: tuple[Item, ...], value: Any, left_out: tuple[str, ...] = ()) -> bytes:
    """The octets of ``value`` laid out by ``layout``, without the fields ``left_out``."""
    flags = _flags(layout, value)
    plan = _fixed_plan(layout, left_out)
    if plan is not None and (octets := _encode_fixed(plan, value, flags)) is not None:
        return octets
    out = []
    fill = math.nan
    omit = False
    for it in layout:
        if it.name in left_out:
            continue
        x = it.extra
        if isinstance(x, Constant):
            out.append(x.wire.encode(x.value))
        elif isinstance(x, Validity):
            out.append(UINT8.encode(flags))
            fill, omit = x.fill, x.omit
        elif isinstance(x, Count):
            counted = next(i for i in layout if isinstance(i.wire, Padded))
            out.append(x.wire.encode(len(getattr(value, counted.name))))
        else:
            v = getattr(value, it.name)
            if v is None:
                if omit:
                    continue
                v = it.wire.filler(fill)
            out.append(it.wire.encode(v))
    return b"".join(out)


def decode_items(layout: tuple[Item, ...], r: Reader, prefix: str = "",
                 left_out: tuple[str, ...] = ()) -> dict[str, Any]:
    """The field values read by ``layout`` (naming each field ``prefix + name`` in errors)."""
    plan = _fixed_plan(layout, left_out)
    if plan is not None and (fast := _decode_fixed(plan, r)) is not None:
        return fast
    values: dict[str, Any] = {}
    flags = 0
    omit = False
    used = 0
    mask = sum(1 << b for b in {it.bit for it in layout if it.bit is not None})
    for it in layout:
        name = prefix + it.name
        x = it.extra
        if it.name in left_out:
            continue  # the model's default stands for a field the subtype leaves out
        if isinstance(x, Constant):
            got = x.wire.decode(r, name)
            if got != x.value:
                raise r.fault(name, f"{got}, expected {x.value}")
        elif isinstance(x, Validity):
            flags, omit = r.one("B", name), x.omit
            if flags & ~mask:
                raise r.fault(name, f"unknown validity bits 0x{flags:02X}")
        elif isinstance(x, Count):
            used = x.wire.decode(r, name)
            if not x.low <= used <= x.high:
                raise r.fault(name, f"{used}, expected {x.low}..{x.high}")
        else:
            present = it.bit is None or bool(flags >> it.bit & 1)
            if not present and omit:
                values[it.name] = None
                continue
            wire = it.wire
            v = wire.decode_used(r, name, used) if isinstance(wire, Padded) else wire.decode(r, name)
            values[it.name] = v if present else None
    return values


# ------------------------------------------------------------------------------------------- declarations


class Record(Frozen):
    """A frozen model laid out on the wire by its declaration (``LAYOUT``, computed once per class)."""

    LAYOUT: ClassVar[tuple[Item, ...]] = ()
    OFF_WIRE: ClassVar[tuple[str, ...]] = ()  # fields that are no octets (the subtype carries them)
    VARIANT_FIELDS: ClassVar[tuple[str, ...]] = ()

    @classmethod
    def __pydantic_init_subclass__(cls, **kwargs: Any) -> None:
        super().__pydantic_init_subclass__(**kwargs)
        cls.LAYOUT = layout_of(cls)


@dataclass(frozen=True)
class RecordWire(WireType):
    """A nested record laid out by its own declaration."""

    model: type[Record]

    @property
    def label(self) -> str:  # type: ignore[override]
        """The record's name."""
        return self.model.__name__

    def encode(self, value: Any) -> bytes:
        """The record's items."""
        return encode_items(self.model.LAYOUT, value)

    def decode(self, r: Reader, field: str) -> Any:
        """The record's items, then the record checked."""
        return built(self.model, f"{r.kind}.{field}", **decode_items(self.model.LAYOUT, r, field + "."))


_DECLARED: list[type[Packet]] = []


class Packet(Record):
    """A telecommand or a telemetry report of the dictionary (declare it with ``service=`` and ``subtype=``)."""

    KIND: ClassVar[Kind]
    SERVICE: ClassVar[int]
    SUBTYPES: ClassVar[tuple[int, ...]]
    VARIANTS: ClassVar[dict[int, tuple[str, ...]]] = {}  # subtype -> the optional fields it leaves out
    COMMAND: ClassVar[TimelineCommand | None] = None

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__()  # the declaration's keywords are read once the fields are complete, below

    @classmethod
    def __pydantic_init_subclass__(cls, service: int | None = None, subtype: int | None = None,
                                   subtypes: tuple[int, ...] | dict[int, tuple[str, ...]] | None = None,
                                   command: TimelineCommand | None = None, **kwargs: Any) -> None:
        if isinstance(subtypes, dict):
            cls.VARIANTS = subtypes
            cls.VARIANT_FIELDS = tuple(sorted({f for absent in subtypes.values() for f in absent}))
        super().__pydantic_init_subclass__(**kwargs)
        if service is None:
            return
        cls.SERVICE = service
        cls.SUBTYPES = (subtype,) if subtype is not None else tuple(subtypes or ())
        if not cls.SUBTYPES:
            raise TypeError(f"{cls.__name__}: declare subtype= or subtypes=")
        cls.COMMAND = command
        for it in cls.LAYOUT:
            if it.optional and it.bit is None and it.name not in cls.VARIANT_FIELDS and not cls.custom_codec():
                raise TypeError(f"{cls.__name__}.{it.name}: an optional field needs a validity bit or a subtype")
        _DECLARED.append(cls)

    @classmethod
    def custom_codec(cls) -> bool:
        """Whether this packet's application data is written by hand (it overrides ``app_data``)."""
        return cls.app_data is not Packet.app_data

    def subservice(self) -> int:
        """The PUS subtype this value travels with."""
        for sub, absent in self.VARIANTS.items():
            if all((getattr(self, f) is None) == (f in absent) for f in self.VARIANT_FIELDS):
                return sub
        return self.SUBTYPES[0]

    def app_data(self) -> bytes:
        """The application data (TC) or source data (TM) octets."""
        return encode_items(self.LAYOUT, self, self.VARIANTS.get(self.subservice(), ()))

    @classmethod
    def implied(cls, subservice: int) -> dict[str, Any]:
        """Field values the subtype carries (none unless a packet says so)."""
        return {}

    @classmethod
    def from_app_data(cls, subservice: int, r: Reader) -> Self:
        """Parse application data written by ``app_data``; raise BadArgument naming the field."""
        values = decode_items(cls.LAYOUT, r, left_out=cls.VARIANTS.get(subservice, ()))
        return built(cls, r.kind, **values, **cls.implied(subservice))

    @classmethod
    def fields(cls) -> tuple[Item, ...]:
        """The layout items that are fields of the value."""
        return tuple(it for it in cls.LAYOUT if it.is_field)


class Telecommand(Packet):
    """A telecommand (ground to spacecraft)."""

    KIND: ClassVar[Kind] = "TC"


class Report(Packet):
    """A telemetry report (spacecraft to ground)."""

    KIND: ClassVar[Kind] = "TM"


def declared() -> tuple[type[Packet], ...]:
    """Every packet declared so far, in declaration order."""
    return tuple(_DECLARED)
