"""An XTCE 1.2 telemetry reader written from the standard with xml.etree, independent of the project's codec.

It walks SpaceSystem / TelemetryMetaData / ParameterTypeSet, ParameterSet and ContainerSet, starts each packet at
the root SequenceContainer and descends into the containers whose BaseContainer is the current one and whose
RestrictionCriteria hold, decoding entries bit by bit: integer (unsigned, two's complement), IEEE float, string
(fixed, or with a leading size tag) and binary encodings with their size in bits and byte order; enumerations;
arrays with a fixed or dynamic dimension; include conditions and repeated container entries. It does not import the
project's ``contracts``.
"""

from __future__ import annotations

import struct
import xml.etree.ElementTree as ET
from collections.abc import Callable
from pathlib import Path
from typing import Any

NS = "{http://www.omg.org/spec/XTCE/20180204}"


def _tag(el: ET.Element) -> str:
    return el.tag.removeprefix(NS)


class Bits:
    """A packet read as a bit string, most significant bit first."""

    def __init__(self, data: bytes) -> None:
        self.data = data
        self.pos = 0

    def take(self, n: int) -> int:
        """The next ``n`` bits as an unsigned integer."""
        if self.pos + n > 8 * len(self.data):
            raise ValueError(f"packet of {len(self.data)} octets ends before bit {self.pos + n}")
        value = int.from_bytes(self.data, "big") >> (8 * len(self.data) - self.pos - n) & ((1 << n) - 1)
        self.pos += n
        return value

    def octets(self, n: int) -> bytes:
        """The next ``n`` octets (byte aligned)."""
        if self.pos % 8:
            raise ValueError(f"octets asked at bit {self.pos}, not on an octet boundary")
        start = self.pos // 8
        if start + n > len(self.data):
            raise ValueError(f"packet of {len(self.data)} octets ends before octet {start + n}")
        self.pos += 8 * n
        return self.data[start : start + n]


class XtceReader:
    """Decodes packets with the containers of one XTCE document."""

    def __init__(self, path: Path) -> None:
        root = ET.parse(path).getroot()
        if _tag(root) != "SpaceSystem":
            raise ValueError(f"root element is {root.tag}, not an XTCE 1.2 SpaceSystem")
        tm = root.find(NS + "TelemetryMetaData")
        assert tm is not None, "no TelemetryMetaData"
        self.types = {el.get("name"): el for el in tm.find(NS + "ParameterTypeSet")}  # type: ignore[union-attr]
        self.parameters = {el.get("name"): el.get("parameterTypeRef")
                           for el in tm.find(NS + "ParameterSet")}  # type: ignore[union-attr]
        self.containers = {el.get("name"): el for el in tm.find(NS + "ContainerSet")}  # type: ignore[union-attr]
        self.children: dict[str | None, list[ET.Element]] = {}
        for el in self.containers.values():
            base = el.find(NS + "BaseContainer")
            self.children.setdefault(None if base is None else base.get("containerRef"), []).append(el)

    # -------------------------------------------------------------------------------------------- packets
    def decode(self, packet: bytes) -> tuple[str, dict[str, list[Any]]]:
        """(name of the most derived container, every parameter's values in order of appearance)."""
        bits = Bits(packet)
        values: dict[str, list[Any]] = {}
        roots = self.children[None]
        current = next(c for c in roots if not any(c is x for x in self._repeated_containers()))
        while True:
            self._entries(current, bits, values)
            matching = [c for c in self.children.get(current.get("name"), []) if self._restricts(c, values)]
            if not matching:
                break
            if len(matching) > 1:
                raise ValueError(f"{[c.get('name') for c in matching]} all match after {current.get('name')}")
            current = matching[0]
        if current.get("abstract") == "true":
            raise ValueError(f"no concrete container matches; stopped at abstract {current.get('name')}")
        return str(current.get("name")), values

    def _repeated_containers(self) -> list[ET.Element]:
        refs = {e.get("containerRef") for c in self.containers.values() for e in c.iter(NS + "ContainerRefEntry")}
        return [self.containers[r] for r in refs if r in self.containers]

    def _restricts(self, container: ET.Element, values: dict[str, list[Any]]) -> bool:
        crit = container.find(f"{NS}BaseContainer/{NS}RestrictionCriteria")
        if crit is None:
            return True
        return self._holds(crit[0], values)

    def _entries(self, container: ET.Element, bits: Bits, values: dict[str, list[Any]]) -> None:
        for entry in container.find(NS + "EntryList"):  # type: ignore[union-attr]
            loc = entry.find(NS + "LocationInContainerInBits")
            if loc is not None:
                if loc.get("referenceLocation", "previousEntry") != "previousEntry":
                    raise ValueError("only locations relative to the previous entry are read")
                bits.pos += int(loc.findtext(NS + "FixedValue", "0"))
            cond = entry.find(f"{NS}IncludeCondition")
            if cond is not None and not self._holds(cond[0], values):
                continue
            if _tag(entry) == "ParameterRefEntry":
                name = str(entry.get("parameterRef"))
                values.setdefault(name, []).append(self._value(self.types[self.parameters[name]], bits, values))
            elif _tag(entry) == "ContainerRefEntry":
                count = 1
                repeat = entry.find(f"{NS}RepeatEntry/{NS}Count")
                if repeat is not None:
                    count = self._integer_value(repeat, values)
                for _ in range(count):
                    self._entries(self.containers[str(entry.get("containerRef"))], bits, values)
            else:
                raise ValueError(f"entry {_tag(entry)} is not read")

    # -------------------------------------------------------------------------------------------- values
    def _value(self, ptype: ET.Element, bits: Bits, values: dict[str, list[Any]]) -> Any:
        kind = _tag(ptype)
        if kind in ("IntegerParameterType", "EnumeratedParameterType"):
            return _integer(ptype.find(NS + "IntegerDataEncoding"), bits)  # type: ignore[arg-type]
        if kind == "FloatParameterType":
            enc = ptype.find(NS + "FloatDataEncoding")
            assert enc is not None and enc.get("encoding", "IEEE754_1985") == "IEEE754_1985"
            size = int(enc.get("sizeInBits", "32"))
            order = "<" if enc.get("byteOrder") == "leastSignificantByteFirst" else ">"
            return struct.unpack(order + {32: "f", 64: "d"}[size], bits.octets(size // 8))[0]
        if kind == "StringParameterType":
            return _string(ptype.find(NS + "StringDataEncoding"), bits)  # type: ignore[arg-type]
        if kind == "BinaryParameterType":
            enc = ptype.find(NS + "BinaryDataEncoding")
            size = enc.findtext(f"{NS}SizeInBits/{NS}FixedValue")  # type: ignore[union-attr]
            return bits.octets(int(size) // 8)  # type: ignore[arg-type]
        if kind == "ArrayParameterType":
            element = self.types[ptype.get("arrayTypeRef")]
            dim = ptype.find(f"{NS}DimensionList/{NS}Dimension")
            start = int(dim.findtext(f"{NS}StartingIndex/{NS}FixedValue"))  # type: ignore[union-attr,arg-type]
            end = self._integer_value(dim.find(NS + "EndingIndex"), values)  # type: ignore[union-attr,arg-type]
            return [self._value(element, bits, values) for _ in range(end - start + 1)]
        raise ValueError(f"parameter type {kind} is not read")

    def _integer_value(self, holder: ET.Element, values: dict[str, list[Any]]) -> int:
        """A FixedValue, or a DynamicValue: the last value of a parameter, linearly adjusted."""
        fixed = holder.findtext(NS + "FixedValue")
        if fixed is not None:
            return int(fixed)
        dyn = holder.find(NS + "DynamicValue")
        ref = dyn.find(NS + "ParameterInstanceRef")  # type: ignore[union-attr]
        value = values[str(ref.get("parameterRef"))][-1]  # type: ignore[union-attr]
        adj = dyn.find(NS + "LinearAdjustment")  # type: ignore[union-attr]
        if adj is not None:
            value = float(adj.get("slope", "1")) * value + float(adj.get("intercept", "0"))
        return int(value)

    # ---------------------------------------------------------------------------------------- conditions
    def _holds(self, expr: ET.Element, values: dict[str, list[Any]]) -> bool:
        kind = _tag(expr)
        if kind == "BooleanExpression":
            return self._holds(expr[0], values)
        if kind == "ANDedConditions":
            return all(self._holds(e, values) for e in expr)
        if kind == "ORedConditions":
            return any(self._holds(e, values) for e in expr)
        if kind == "Condition":
            ref = expr.find(NS + "ParameterInstanceRef")
            seen = values.get(str(ref.get("parameterRef")))  # type: ignore[union-attr]
            if not seen:
                return False
            op = expr.findtext(NS + "ComparisonOperator")
            return _COMPARE[str(op)](seen[-1], int(expr.findtext(NS + "Value")))  # type: ignore[arg-type]
        raise ValueError(f"condition {kind} is not read")


_COMPARE: dict[str, Callable[[Any, Any], bool]] = {
    "==": lambda a, b: a == b, "!=": lambda a, b: a != b, "<": lambda a, b: a < b, "<=": lambda a, b: a <= b,
    ">": lambda a, b: a > b, ">=": lambda a, b: a >= b,
}


def _integer(enc: ET.Element, bits: Bits) -> int:
    size = int(enc.get("sizeInBits", "8"))
    raw = bits.take(size)
    if enc.get("byteOrder") == "leastSignificantByteFirst":
        raw = int.from_bytes(raw.to_bytes(size // 8, "big"), "little")
    scheme = enc.get("encoding", "unsigned")
    if scheme == "twosComplement" and raw >> (size - 1):
        raw -= 1 << size
    elif scheme != "unsigned" and scheme != "twosComplement":
        raise ValueError(f"integer encoding {scheme} is not read")
    return raw


def _string(enc: ET.Element, bits: Bits) -> str:
    charset = enc.get("encoding", "UTF-8")
    variable = enc.find(NS + "Variable")
    holder = variable if variable is not None else enc.find(NS + "SizeInBits")
    lead = holder.find(NS + "LeadingSize")  # type: ignore[union-attr]
    if lead is not None:
        n = bits.take(int(lead.get("sizeInBitsOfSizeTag", "16")))
        return bits.octets(n).decode(charset)
    fixed = enc.findtext(f"{NS}SizeInBits/{NS}Fixed/{NS}FixedValue")
    if fixed is None:
        raise ValueError("a variable string needs a leading size to be read")
    return bits.octets(int(fixed) // 8).decode(charset)
