"""The telemetry of the dictionary as XTCE 1.2 for Yamcs, built with yamcs-pymdb from the declarations.

One SpaceSystem holds the CCSDS primary header (abstract root container), the PUS-C TM secondary header (abstract
container restricted to TM packets) and one container per TM packet, restricted on its service and subtype(s);
event reports derive from an abstract event container and are told apart by their event id. Every field becomes
parameters named ``<Container>_<field>`` (a vector's elements ``_0``, ``_1``...): a CUC time is its P-field, coarse
seconds and fine ticks, a request id its six bit fields, an embedded TC packet its primary header, first
secondary-header octet and the remaining octets. Optional fields behind a validity octet are always on the wire
(filled), so they are plain entries; fields a subtype leaves out, or a flag omits, have an include condition.
The CRC-16 trailer (2 octets) follows the last entry.
"""

from __future__ import annotations

from typing import Any

from yamcs.pymdb import (
    AndExpression,
    ArrayParameter,
    Charset,
    Container,
    ContainerEntry,
    EnumeratedParameter,
    EqExpression,
    Expression,
    FloatEncoding,
    FloatParameter,
    IntegerDataType,
    IntegerEncoding,
    IntegerParameter,
    OrExpression,
    Parameter,
    ParameterEntry,
    ParameterValue,
    StringEncoding,
    StringParameter,
    System,
)

from contracts.cuc import COARSE_OCTETS, FINE_OCTETS, P_FIELD
from contracts.dictionary import DICTIONARY, Dictionary, EventReport, TimeReferenceStatus
from contracts.packet import Constant, Item, Packet, Record, RecordWire, Validity
from contracts.wire import (
    MAX_TEXT_OCTETS,
    CountedList,
    CucWire,
    EmbeddedPacket,
    EnumCode,
    Number,
    Padded,
    RequestIdWire,
    TextWire,
    Vector,
    WireType,
)

# (name, bits, description) of the fields of a CCSDS primary header and of a request id (its first 4 octets)
PRIMARY_HEADER = (
    ("version", 3, "packet version number (0)"),
    ("type", 1, "packet type: 0 TM, 1 TC"),
    ("secondary_header", 1, "secondary header flag (1: PUS)"),
    ("apid", 11, "application process identifier"),
    ("sequence_flags", 2, "sequence flags (3: unsegmented)"),
    ("sequence_count", 14, "packet sequence count"),
    ("length", 16, "packet data length: octets after the primary header, minus 1"),
)
PUS_TM_HEADER = (
    ("pus_version", 4, "PUS version number (2: PUS-C)"),
    ("time_reference_status", 4, "spacecraft time reference status: "
     + ", ".join(f"{m.value} {m.name}" for m in TimeReferenceStatus)),
    ("service", 8, "service type"),
    ("subtype", 8, "message subtype"),
    ("message_counter", 16, "message type counter"),
    ("destination_id", 16, "destination identifier: the source id of the TC a report answers, else the ground's"),
)


class _Builder:
    """Adds the parameters and entries of the declared items to one system."""

    def __init__(self, system: System, obt_epoch: str) -> None:
        self.system = system
        self.obt_epoch = obt_epoch

    def integer(self, name: str, bits: int, description: str, units: str | None = None) -> IntegerParameter:
        """An unsigned big-endian integer parameter."""
        return IntegerParameter(self.system, name, signed=False, bits=64 if bits > 32 else 32,
                                short_description=description or None, units=units or None,
                                encoding=IntegerEncoding(bits=bits))

    def time(self, name: str, description: str) -> list[ParameterEntry]:
        """An OBT as the mission's CUC: P-field, coarse seconds, fine ticks of 2^-16 s."""
        epoch = (f"CUC level 2 (P-field 0x{P_FIELD:02X}, agency-defined epoch): OBT counts seconds from the on-board "
                 f"clock's zero. {self.obt_epoch}")
        coarse = self.integer(f"{name}_coarse", 8 * COARSE_OCTETS, f"{description}: whole seconds of OBT", "s")
        coarse.long_description = epoch
        fine = self.integer(f"{name}_fine", 8 * FINE_OCTETS, f"{description}: fraction of a second", "2^-16 s")
        fine.long_description = epoch
        return [ParameterEntry(self.integer(f"{name}_p_field", 8, f"{description}: CUC P-field (0x{P_FIELD:02X})")),
                ParameterEntry(coarse), ParameterEntry(fine)]

    def entries(self, name: str, wire: WireType, description: str, units: str,
                condition: Expression | None = None) -> list[ParameterEntry | ContainerEntry]:
        """The entries of one item laid out by ``wire``."""
        out: list[ParameterEntry | ContainerEntry]
        if isinstance(wire, Number):
            out = [ParameterEntry(self.scalar(name, wire, description, units))]
        elif isinstance(wire, EnumCode):
            choices = [(int(m.value), m.name) for m in wire.enum]
            out = [ParameterEntry(EnumeratedParameter(
                self.system, name, choices, short_description=description or None,
                encoding=IntegerEncoding(bits=8 * wire.wire.octets)))]
        elif isinstance(wire, TextWire):
            out = [ParameterEntry(StringParameter(
                self.system, name, short_description=description or None,
                encoding=StringEncoding(length_bits=8, max_bits=8 * MAX_TEXT_OCTETS, charset=Charset.UTF_8,
                                        termination=None)))]
        elif isinstance(wire, CucWire):
            out = list(self.time(name, description))
        elif isinstance(wire, RequestIdWire):
            out = [ParameterEntry(self.integer(f"{name}_{f}", bits, f"{description}: {d}"))
                   for f, bits, d in PRIMARY_HEADER[:6]]
        elif isinstance(wire, Vector | Padded):
            n = wire.n if isinstance(wire, Vector) else wire.slots
            out = []
            for i in range(n):
                out += self.entries(f"{name}_{i}", wire.element, f"{description} [{i}]", units)
        elif isinstance(wire, CountedList) and isinstance(wire.element, RecordWire):
            count = self.integer(f"{name}_count", 16, f"{description}: number of items")
            item = self.record(f"{name}_item", wire.element.model)
            out = [ParameterEntry(count), ContainerEntry(item, repeat=ParameterValue(count))]
        elif isinstance(wire, EmbeddedPacket):
            out = [ParameterEntry(self.integer(f"{name}_{f}", bits, f"{description}: {d}"))
                   for f, bits, d in PRIMARY_HEADER]
            length = out[-1].parameter  # type: ignore[union-attr]
            out.append(ParameterEntry(self.integer(f"{name}_pus_version_ack", 8,
                                                   "PUS version (4 bits) and acknowledgement flags (4 bits)")))
            out.append(ParameterEntry(ArrayParameter(
                self.system, f"{name}_rest", IntegerDataType(signed=False, bits=8, encoding=IntegerEncoding(bits=8)),
                length=ParameterValue(length), short_description="the packet's remaining octets (length field of "
                "them), from the service type to the CRC")))
        else:
            raise TypeError(f"{name}: no XTCE form for a {wire.label} field")
        if condition is not None:
            for e in out:
                e.condition = condition
        return out

    def scalar(self, name: str, wire: Number, description: str, units: str) -> Parameter:
        """An unsigned integer or an IEEE float."""
        bits = 8 * wire.octets
        if wire.is_float:
            return FloatParameter(self.system, name, bits=bits,  # type: ignore[arg-type]
                                  short_description=description or None, units=units or None,
                                  encoding=FloatEncoding(bits=bits))
        return self.integer(name, bits, description, units)

    def items(self, prefix: str, owner: type[Record], skip: tuple[str, ...] = (),
              subtype: Parameter | None = None) -> list[ParameterEntry | ContainerEntry]:
        """The entries of a record's or packet's layout, with conditions where a field may be left out."""
        out: list[ParameterEntry | ContainerEntry] = []
        flags: dict[int, Parameter] = {}
        omitting: Validity | None = None
        for it in owner.LAYOUT:
            if it.name in skip:
                continue
            name = f"{prefix}_{it.name}"
            desc = it.description
            if isinstance(it.extra, Validity):
                omitting = it.extra if it.extra.omit else None
                p = self.integer(name, 8, desc)
                flags = {0: p}
                out.append(ParameterEntry(p))
                continue
            if isinstance(it.extra, Constant):
                desc = f"{desc} (= {it.extra.value})"
            out += self.entries(name, it.wire, desc, it.unit, self._condition(it, owner, omitting, flags, subtype))
        return out

    @staticmethod
    def _condition(it: Item, owner: type[Record], omitting: Validity | None, flags: dict[int, Parameter],
                   subtype: Parameter | None) -> Expression | None:
        if it.bit is not None and omitting is not None:
            return EqExpression(flags[0], 1 << it.bit)
        variants = getattr(owner, "VARIANTS", {})
        if subtype is not None and any(it.name in absent for absent in variants.values()):
            present = [EqExpression(subtype, s) for s, absent in variants.items() if it.name not in absent]
            return present[0] if len(present) == 1 else OrExpression(*present)
        return None

    def record(self, name: str, model: type[Record]) -> Container:
        """An abstract container for one item of a repeated record."""
        c = Container(self.system, name, abstract=True, short_description=model.__doc__.split("\n")[0]
                      if model.__doc__ else None)
        c.entries = self.items(name, model)
        return c


def _restriction(checks: list[tuple[Parameter, tuple[int, ...]]]) -> Expression:
    parts: list[Expression] = []
    for param, values in checks:
        eqs: list[Expression] = [EqExpression(param, v) for v in values]
        parts.append(eqs[0] if len(eqs) == 1 else OrExpression(*eqs))
    return parts[0] if len(parts) == 1 else AndExpression(*parts)


def xtce_system(obt_epoch: str, d: Dictionary = DICTIONARY, name: str = "flyby") -> System:
    """The SpaceSystem of the dictionary's telemetry; ``obt_epoch`` says what OBT 0 is (in the time descriptions)."""
    system = System(name, short_description="LICIACube flyby emulator telemetry (PUS-C on CCSDS space packets)",
                    long_description=__doc__)
    b = _Builder(system, obt_epoch)
    header = {f: b.integer(f"ccsds_{f}", bits, d_) for f, bits, d_ in PRIMARY_HEADER}
    root = Container(system, "ccsds_space_packet", abstract=True,
                     short_description="CCSDS 133.0-B space packet primary header (6 octets)",
                     entries=[ParameterEntry(p) for p in header.values()])
    pus = {f: b.integer(f"pus_{f}", bits, d_) for f, bits, d_ in PUS_TM_HEADER}
    tm = Container(system, "pus_tm", abstract=True, base=root,
                   condition=_restriction([(header["type"], (0,)), (header["secondary_header"], (1,))]),
                   short_description="PUS-C TM secondary header (ECSS-E-ST-70-41C), time stamped with OBT as CUC",
                   entries=[ParameterEntry(p) for p in pus.values()] + b.time("pus_obt", "TM time stamp"))
    event_id = b.integer("event_id", 16, "event identifier (service 5)")
    events = Container(system, "pus_event", abstract=True, base=tm, entries=[ParameterEntry(event_id)],
                       condition=_restriction([(pus["service"], (5,))]),
                       short_description="PUS-C event report: subtype = severity, first u16 = event id")
    for p in d.packets:
        if p.KIND != "TM":
            continue
        _packet_container(b, p, tm, events, pus, event_id)
    return system


def _packet_container(b: _Builder, p: type[Packet], tm: Container, events: Container,
                      pus: dict[str, Parameter], event_id: Parameter) -> Container:
    doc = " ".join((p.__doc__ or "").split())
    if issubclass(p, EventReport):
        base, checks = events, [(event_id, (int(p.EVENT_ID),))]
        skip: tuple[str, ...] = ("event_id",)
    else:
        base, checks, skip = tm, [(pus["service"], (p.SERVICE,)), (pus["subtype"], p.SUBTYPES)], ()
    c = Container(b.system, p.__name__, base=base, condition=_restriction(checks), short_description=doc or None)
    c.entries = b.items(p.__name__, p, skip, pus["subtype"])
    return c


def xtce_text(obt_epoch: str, d: Dictionary = DICTIONARY) -> str:
    """The XTCE 1.2 document of ``xtce_system``."""
    text: Any = xtce_system(obt_epoch, d).dumps(format="xtce-1.2")
    return str(text)
