"""Hypothesis strategies for every packet of the TM/TC dictionary, generated from its declarations.

Each field's values come from its wire type and declared checks (bounds, lengths); fields that share a validity bit
are present together, padded arrays share their count, a packet with subtype variants draws one variant. Packets
with a cross-field rule the declarations cannot express register an override in ``OVERRIDES``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from enum import IntEnum
from typing import Any

from hypothesis import assume
from hypothesis import strategies as st

from contracts import pus
from contracts.dictionary import DICTIONARY, CheckType, MonitoringDefinition, SetCameraCadence, UploadNominalTrajectory
from contracts.packet import Item, Packet, Record, RecordWire
from contracts.packet_errors import MAX_APID, MAX_SEQ_COUNT, RequestId
from contracts.wire import (
    CountedList,
    CucWire,
    EmbeddedPacket,
    EnumCode,
    Number,
    OctetString,
    Padded,
    RequestIdWire,
    TextWire,
    Vector,
    WireType,
)

apids = st.integers(0, MAX_APID)
seqs = st.integers(0, MAX_SEQ_COUNT)
counters = st.integers(0, 0xFFFF)
# OBTs on the 2^-16 s CUC grid, which the packets carry exactly.
grid_obt = st.builds(lambda c, f: c + f / 65536, st.integers(0, 2**32 - 1), st.integers(0, 0xFFFF))
request_ids = st.builds(RequestId, apid=apids, seq_count=seqs)
texts = st.text(alphabet=st.characters(codec="utf-8"), max_size=60)  # at most 240 octets of UTF-8
MAX_ITEMS = 3  # list lengths drawn (the wire allows 65535)


def _bounds(checks: dict[str, Any]) -> tuple[Any, Any, bool, bool]:
    """(low, high, exclude low, exclude high) of the declared checks."""
    low = max([v for k, v in checks.items() if k in ("ge", "gt")], default=None)
    high = min([v for k, v in checks.items() if k in ("le", "lt")], default=None)
    return low, high, "gt" in checks, "lt" in checks


def _checks(it: Item) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for k, v in it.checks:  # the tightest of repeated checks (a U16 declared ge=1 has ge=0 and ge=1)
        out[k] = max(out.get(k, v), v) if k in ("ge", "gt", "min_length") else min(out.get(k, v), v)
    return out


def wire_strategy(wire: WireType, checks: dict[str, Any]) -> st.SearchStrategy[Any]:
    """Values of one wire type within the declared checks."""
    low, high, excl_low, excl_high = _bounds(checks)
    if isinstance(wire, Number) and wire.is_float:
        return st.floats(min_value=low, max_value=high, exclude_min=excl_low and low is not None,
                         exclude_max=excl_high and high is not None, allow_nan=False, allow_infinity=False,
                         width=8 * wire.octets)  # type: ignore[arg-type]
    if isinstance(wire, Number):
        top = (1 << (8 * wire.octets)) - 1
        return st.integers(max(0, low or 0) + excl_low, min(top, top if high is None else high) - excl_high)
    if isinstance(wire, EnumCode):
        return st.sampled_from(list(wire.enum))
    if isinstance(wire, TextWire):
        return texts
    if isinstance(wire, CucWire):
        return grid_obt
    if isinstance(wire, RequestIdWire):
        return request_ids
    if isinstance(wire, OctetString):
        return st.binary(min_size=wire.n, max_size=wire.n)
    if isinstance(wire, EmbeddedPacket):
        return tc_packets
    if isinstance(wire, Vector):
        return st.tuples(*[wire_strategy(wire.element, {})] * wire.n)
    if isinstance(wire, CountedList):
        lo = checks.get("min_length", 0)
        return st.lists(wire_strategy(wire.element, {}), min_size=lo, max_size=max(lo, MAX_ITEMS)).map(tuple)
    if isinstance(wire, RecordWire):
        return record_strategy(wire.model)
    raise TypeError(f"no strategy for a {wire.label} field")


@st.composite
def _fields(draw: st.DrawFn, cls: type[Record]) -> dict[str, Any]:
    """The keyword arguments of one value of ``cls``."""
    items = [it for it in cls.LAYOUT if it.is_field]
    variants: dict[int, tuple[str, ...]] = getattr(cls, "VARIANTS", {})
    left_out = variants[draw(st.sampled_from(sorted(variants)))] if variants else ()
    present = {b: draw(st.booleans()) for b in {it.bit for it in items if it.bit is not None}}
    used = draw(st.integers(1, max((it.wire.slots for it in items if isinstance(it.wire, Padded)), default=1)))
    out: dict[str, Any] = {}
    for it in items:
        if it.name in left_out or (it.bit is not None and not present[it.bit]):
            continue
        if isinstance(it.wire, Padded):
            out[it.name] = tuple(draw(wire_strategy(it.wire.element, {})) for _ in range(used))
        else:
            out[it.name] = draw(wire_strategy(it.wire, _checks(it)))
    for name in getattr(cls, "OFF_WIRE", ()):
        enum = cls.model_fields[name].annotation
        assert isinstance(enum, type) and issubclass(enum, IntEnum), f"{cls.__name__}.{name}: no strategy"
        out[name] = draw(st.sampled_from(list(enum)))
    return out


def record_strategy(cls: type[Record]) -> st.SearchStrategy[Any]:
    """Values of a record or packet: its override if it has one, else from its declaration."""
    if cls in OVERRIDES:
        return OVERRIDES[cls]()
    return _fields(cls).map(lambda kw: cls(**kw))


@st.composite
def orthonormal_pairs(draw: st.DrawFn) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """Two perpendicular unit vectors (Gram-Schmidt on well-conditioned draws)."""
    comp = st.floats(-1.0, 1.0)
    a = [draw(comp) for _ in range(3)]
    b = [draw(comp) for _ in range(3)]
    na = math.sqrt(sum(x * x for x in a))
    assume(na > 0.1)
    a = [x / na for x in a]
    d = sum(x * y for x, y in zip(a, b, strict=True))
    b = [y - d * x for x, y in zip(a, b, strict=True)]
    nb = math.sqrt(sum(x * x for x in b))
    assume(nb > 0.1)
    b = [x / nb for x in b]
    # One more projection so the dot product is at rounding level.
    d = sum(x * y for x, y in zip(a, b, strict=True))
    b = [y - d * x for x, y in zip(a, b, strict=True)]
    nb = math.sqrt(sum(x * x for x in b))
    return tuple(a), tuple(x / nb for x in b)


@st.composite
def _trajectories(draw: st.DrawFn) -> UploadNominalTrajectory:
    """A nominal trajectory: the declared fields, with perpendicular unit directions."""
    kw = draw(_fields(UploadNominalTrajectory))
    kw["approach_direction"], kw["ca_direction"] = draw(orthonormal_pairs())
    return UploadNominalTrajectory(**kw)


def _cadences() -> st.SearchStrategy[SetCameraCadence]:
    """A cadence whose exposure fits its period."""
    return _fields(SetCameraCadence).filter(lambda kw: kw["exposure_s"] <= kw["period_s"]).map(
        lambda kw: SetCameraCadence(**kw))


@st.composite
def _monitoring_definitions(draw: st.DrawFn) -> MonitoringDefinition:
    """A monitoring definition whose limits are ordered (an expected-value check repeats its value)."""
    kw = draw(_fields(MonitoringDefinition))
    low, high = sorted((kw["low"], kw["high"]))
    kw["low"], kw["high"] = (low, low) if kw["check_type"] == CheckType.EXPECTED_VALUE else (low, high)
    return MonitoringDefinition(**kw)


OVERRIDES: dict[type, Callable[[], st.SearchStrategy[Any]]] = {
    UploadNominalTrajectory: _trajectories,
    SetCameraCadence: _cadences,
    MonitoringDefinition: _monitoring_definitions,
}

# TC packets to schedule: any telecommand that does not itself carry packets
_FLAT_TCS = [p for p in DICTIONARY.packets if p.KIND == "TC"
             and not any(isinstance(getattr(it.wire, "element", None), RecordWire) for it in p.LAYOUT)]
tc_packets = st.builds(lambda c, a, s: pus.encode_tc(c, a, s),
                       st.one_of([st.deferred(lambda p=p: record_strategy(p)) for p in _FLAT_TCS]), apids, seqs)


def packet_strategy(cls: type[Packet]) -> st.SearchStrategy[Any]:
    """Values of one packet of the dictionary."""
    return record_strategy(cls)


telecommands = st.one_of([packet_strategy(p) for p in DICTIONARY.packets if p.KIND == "TC"])
reports = st.one_of([packet_strategy(p) for p in DICTIONARY.packets if p.KIND == "TM"])
