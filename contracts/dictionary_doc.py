"""The TM/TC dictionary as Markdown, generated from the declarations (``flyby dictionary`` prints it)."""

from __future__ import annotations

from typing import Any

from contracts.cuc import CUC_LEN
from contracts.dictionary import DICTIONARY, SERVICE_NAMES, Dictionary, EventReport, Verification
from contracts.packet import Constant, Count, Item, Packet, Record, RecordWire, Validity
from contracts.pus import CRC_LEN, PRIMARY_HEADER_LEN, TC_SECONDARY_HEADER_LEN, TM_SECONDARY_HEADER_LEN
from contracts.wire import MAX_TEXT_OCTETS, CountedList, EnumCode, TextWire


def packet_id(p: type[Packet]) -> str:
    """E.g. ``TM[3,25]``, ``TC[11,7/15]``, ``TM[5,1..4]``."""
    subs = p.SUBTYPES
    if issubclass(p, EventReport):
        text = f"{subs[0]}..{subs[-1]}"
    else:
        text = "/".join(str(s) for s in subs)
    return f"{p.KIND}[{p.SERVICE},{text}]"


def _number(x: Any) -> str:
    return f"{x:g}" if isinstance(x, float) else str(x)


def value_range(it: Item) -> str:
    """The accepted values of an item: bounds, enumeration codes, lengths or the constant."""
    x = it.extra
    if isinstance(x, Constant):
        return f"= {x.value}"
    if isinstance(x, Count):
        return f"{x.low} .. {x.high}"
    if isinstance(x, Validity):
        return "0 or 1" if x.omit else "flags"
    if isinstance(it.wire, EnumCode):
        return ", ".join(f"{m.value} {m.name}" for m in it.wire.enum)
    checks = dict(it.checks)
    lows = [(v, ">=") for k, v in it.checks if k == "ge"] + [(v, ">") for k, v in it.checks if k == "gt"]
    highs = [(v, "<=") for k, v in it.checks if k == "le"] + [(v, "<") for k, v in it.checks if k == "lt"]
    low = max(lows, key=lambda b: (b[0], b[1] == ">"), default=None)
    high = min(highs, key=lambda b: (b[0], b[1] == "<"), default=None)
    parts = []
    if low is not None and high is not None and low[1] == ">=" and high[1] == "<=":
        parts.append(f"{_number(low[0])} .. {_number(high[0])}")
    else:
        parts += [f"{b[1]} {_number(b[0])}" for b in (low, high) if b is not None]
    if "min_length" in checks or "max_length" in checks:
        parts.append(f"{checks.get('min_length', 0)} .. {checks.get('max_length')} items")
    if isinstance(it.wire, TextWire):
        parts.append(f"<= {MAX_TEXT_OCTETS} octets")
    return ", ".join(parts)


def _presence(it: Item, p: type[Record]) -> str:
    notes = []
    if it.bit is not None:
        notes.append(f"present when flag bit {it.bit} is set")
    variants = getattr(p, "VARIANTS", {})
    leaving = [str(s) for s, absent in variants.items() if it.name in absent]
    if leaving:
        notes.append(f"absent in subtype {', '.join(leaving)}")
    return "; ".join(notes)


def _rows(p: type[Record]) -> list[str]:
    rows = ["| offset | field | wire type | unit | range | description |", "|---|---|---|---|---|---|"]
    offset: int | None = 0
    for it in p.LAYOUT:
        where = "-" if offset is None else str(offset)
        desc = it.description + (f" ({_presence(it, p)})" if _presence(it, p) else "")
        name = it.name if it.is_field else f"*{it.name}*"
        rows.append(f"| {where} | {name} | {it.wire.label} | {it.unit} | {value_range(it)} | {desc} |")
        size = it.wire.octets
        conditional = it.bit is not None and any(isinstance(i.extra, Validity) and i.extra.omit for i in p.LAYOUT)
        offset = None if offset is None or size is None or conditional or _presence(it, p).startswith("absent") \
            else offset + size
    return rows


def _records(d: Dictionary) -> list[type[Record]]:
    seen: list[type[Record]] = []
    for p in d.packets:
        for it in p.LAYOUT:
            w = it.wire.element if isinstance(it.wire, CountedList) else it.wire
            if isinstance(w, RecordWire) and w.model not in seen:
                seen.append(w.model)
    return seen


def markdown(d: Dictionary = DICTIONARY) -> str:
    """Every packet of the dictionary: a summary table, then each packet's fields in wire order."""
    tm_header = PRIMARY_HEADER_LEN + TM_SECONDARY_HEADER_LEN
    out = [
        "# TM/TC dictionary",
        "",
        "Generated from `contracts/dictionary.py` by `flyby dictionary`. Every packet is a CCSDS space packet with a "
        f"PUS-C secondary header and a CRC-16 trailer ({CRC_LEN} octets). A TC's application data follows "
        f"{PRIMARY_HEADER_LEN + TC_SECONDARY_HEADER_LEN} octets of headers; a TM's source data follows {tm_header} "
        f"octets of headers, whose time stamp is the OBT as a {CUC_LEN}-octet CUC (P-field 0x2E, 4 coarse + 2 fine "
        "octets of 2^-16 s). All numbers are big-endian. Offsets are in octets from the start of the application "
        "(TC) or source (TM) data; italic items are octets of the packet, not fields of its value.",
        "",
        "| kind | packet | name | description |",
        "|---|---|---|---|",
    ]
    for p in d.packets:
        out.append(f"| {p.KIND} | {packet_id(p)} | {p.__name__} | {_first_line(p)} |")
    out += ["", "## Services", "", "| service | name | TC subtypes | TM subtypes |", "|---|---|---|---|"]
    for service in sorted(d.services("TC") | d.services("TM")):
        subtypes = [", ".join(str(k) for k in sorted({s for p in d.packets if p.KIND == kind and p.SERVICE == service
                                                     for s in p.SUBTYPES})) for kind in ("TC", "TM")]
        out.append(f"| {service} | {SERVICE_NAMES.get(service, '')} | {subtypes[0]} | {subtypes[1]} |")
    for p in d.packets:
        out += ["", f"## {packet_id(p)} {p.__name__}", "", _doc(p)]
        notes = []
        if issubclass(p, EventReport):
            notes.append(f"Event id {int(p.EVENT_ID)} ({p.EVENT_ID.name}); the subtype is the severity "
                         f"(default {p.model_fields['severity'].default.name}).")
        if p is Verification:
            notes.append("Subtype 1/3/7: success of acceptance/start/completion; 2/4/8: failure, which alone "
                         "carries the failure code and reason.")
        if p.COMMAND is not None:
            c = p.COMMAND
            fills = f"; ground fills {', '.join(c.ground_fills)}" if c.ground_fills else ""
            defaults = "".join(f"; {k} defaults to {v}" for k, v in c.defaults)
            notes.append(f"Timeline command `{c.name}`: {c.description}{fills}{defaults}.")
        if notes:
            out += [""] + notes
        out += [""] + (_rows(p) if p.LAYOUT else ["No application data."])
    for r in _records(d):
        out += ["", f"## {r.__name__} (record)", "", _doc(r), ""] + _rows(r)
    return "\n".join(out) + "\n"


def _doc(p: type) -> str:
    return " ".join((p.__doc__ or "").split())


def _first_line(p: type) -> str:
    text = _doc(p)
    return text.split(". ")[0].rstrip(".") if text else ""
