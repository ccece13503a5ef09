"""Two runs of the flight software on the same inputs, compared reply by reply: the commanded torques, frame requests
and clock adjustments, and every telemetry packet by packet type, parameter and time (``flyby replay``).

Within a control period the k-th packet of a type is compared with the k-th packet of that type; a packet one side
sent and the other did not counts against the parameter ``(packet)``. Numbers differ by their absolute difference,
anything else (modes, flags, embedded telecommands, a value against none) by inequality.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum
from typing import Any

from pydantic import BaseModel

from contracts import pus
from contracts.messages import StepReply

COMMANDS = "commands (StepReply)"
"""The packet name under which the reply's own fields (torques, frame request, clock adjustment) are compared."""
ABSENT = "absent"
"""The value shown for a parameter or packet one side does not have."""


def flatten(value: Any, prefix: str = "", out: dict[str, Any] | None = None) -> dict[str, Any]:
    """``value`` as dotted parameter names and leaf values: ``q[0]``, ``request_id.seq_count``, ``frame_request``."""
    out = {} if out is None else out
    if isinstance(value, BaseModel):
        for name in type(value).model_fields:
            flatten(getattr(value, name), f"{prefix}.{name}" if prefix else name, out)
    elif isinstance(value, (tuple, list)) and value:
        for i, v in enumerate(value):
            flatten(v, f"{prefix}[{i}]", out)
    else:
        out[prefix] = value
    return out


def _numeric(a: Any, b: Any) -> float | None:
    """|a - b| if both are numbers (not flags or enumerations), else None."""
    def num(x: Any) -> bool:
        return isinstance(x, (int, float)) and not isinstance(x, (bool, Enum))

    return abs(float(a) - float(b)) if num(a) and num(b) else None


def _same(a: Any, b: Any) -> bool:
    """Equal values of the same type; NaN equals NaN (the same software computes the same NaN)."""
    if type(a) is not type(b):
        return False
    if isinstance(a, float) and a != a:
        return b != b
    return bool(a == b)


def shown(x: Any) -> str:
    """A parameter value as the replay prints it."""
    if isinstance(x, Enum):
        return x.name
    if isinstance(x, float):
        return repr(x)  # every digit: a replay's first divergence is often in the last bits
    if isinstance(x, bytes):
        return f"<{len(x)} octets {x[:6].hex()}...>"
    return str(x)


@dataclass
class ParameterDiff:
    """Where one parameter of one packet type differed: how often, first, and by the most (numbers only)."""

    packet: str
    parameter: str
    count: int = 0
    first_step: int = -1
    first_obt_s: float = 0.0
    first_recorded: Any = None
    first_replayed: Any = None
    largest: float | None = None
    largest_step: int = -1
    largest_obt_s: float = 0.0
    largest_recorded: Any = None
    largest_replayed: Any = None

    def add(self, step: int, obt_s: float, recorded: Any, replayed: Any) -> None:
        """Count one differing sample."""
        if self.count == 0:
            self.first_step, self.first_obt_s = step, obt_s
            self.first_recorded, self.first_replayed = recorded, replayed
        self.count += 1
        d = _numeric(recorded, replayed)
        if d is not None and (self.largest is None or d > self.largest):
            self.largest, self.largest_step, self.largest_obt_s = d, step, obt_s
            self.largest_recorded, self.largest_replayed = recorded, replayed

    def first_text(self) -> str:
        """The first divergence: step, OBT and the two values."""
        return (f"step {self.first_step}, OBT {self.first_obt_s:.3f} s: "
                f"{shown(self.first_recorded)} -> {shown(self.first_replayed)}")

    def largest_text(self) -> str:
        """The largest difference, its time and the two values ("-" if the parameter is not a number)."""
        if self.largest is None:
            return "-"
        return (f"{self.largest:.6g} at step {self.largest_step}, OBT {self.largest_obt_s:.3f} s "
                f"({shown(self.largest_recorded)} -> {shown(self.largest_replayed)})")


def packet_name(header: pus.TmHeader | None, report: Any) -> str:
    """A telemetry packet's type as the diff names it: report class and PUS service/subtype."""
    if header is None:
        return "undecodable packet"
    return f"{type(report).__name__} [{header.service},{header.subservice}]"


def _packets(downlink: tuple[bytes, ...]) -> dict[str, list[dict[str, Any]]]:
    """The period's packets by type, in order, each as its flattened parameters."""
    out: dict[str, list[dict[str, Any]]] = {}
    for raw in downlink:
        try:
            header, report = pus.decode_tm(raw)
        except pus.PacketError:
            out.setdefault(packet_name(None, None), []).append({"raw": raw})
            continue
        params = {"time stamp (OBT s)": header.obt_s, "sequence count": header.seq_count}
        out.setdefault(packet_name(header, report), []).append(flatten(report, "", params))
    return out


@dataclass
class StepDiff:
    """The comparison of a replay with its recording, period by period."""

    steps: int = 0
    differing_steps: int = 0
    params: dict[tuple[str, str], ParameterDiff] = field(default_factory=dict)

    @property
    def identical(self) -> bool:
        """Every compared reply was the same."""
        return self.differing_steps == 0

    def _add(self, packet: str, parameter: str, step: int, obt_s: float, recorded: Any, replayed: Any) -> None:
        key = (packet, parameter)
        if key not in self.params:
            self.params[key] = ParameterDiff(packet, parameter)
        self.params[key].add(step, obt_s, recorded, replayed)

    def _compare_params(self, packet: str, rec: dict[str, Any], rep: dict[str, Any], step: int, obt_s: float) -> None:
        for name in list(rec) + [k for k in rep if k not in rec]:
            a, b = rec.get(name, ABSENT), rep.get(name, ABSENT)
            if not _same(a, b):
                self._add(packet, name, step, obt_s, a, b)

    def compare(self, step: int, obt_s: float, recorded: StepReply, replayed: StepReply) -> bool:
        """Compare one period's replies; return whether they were the same."""
        self.steps += 1
        if recorded == replayed:
            return True
        before = sum(p.count for p in self.params.values())
        self._compare_params(COMMANDS, flatten(recorded.model_copy(update={"downlink": ()})),
                             flatten(replayed.model_copy(update={"downlink": ()})), step, obt_s)
        rec, rep = _packets(recorded.downlink), _packets(replayed.downlink)
        for name in list(rec) + [k for k in rep if k not in rec]:
            a, b = rec.get(name, []), rep.get(name, [])
            for i in range(max(len(a), len(b))):
                if i < len(a) and i < len(b):
                    self._compare_params(name, a[i], b[i], step, obt_s)
                else:
                    self._add(name, "(packet)", step, obt_s, "sent" if i < len(a) else ABSENT,
                              "sent" if i < len(b) else ABSENT)
        if sum(p.count for p in self.params.values()) == before:
            return True  # equal but for NaN values, which equal themselves here
        self.differing_steps += 1
        return False

    def rows(self) -> list[ParameterDiff]:
        """The differing parameters, earliest first divergence first."""
        return sorted(self.params.values(), key=lambda p: (p.first_step, p.packet != COMMANDS, p.packet, p.parameter))

    def first(self) -> ParameterDiff | None:
        """The parameter that diverged first (commanded torques before telemetry within a period)."""
        rows = self.rows()
        return rows[0] if rows else None
