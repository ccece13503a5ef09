"""Where a three-process loop's time goes: time marks of each node's lock-step traffic and work, and the table of
the hops between them.

With ``--trace FILE`` a node marks, on the host's monotonic clock (the same in every process of a host, so marks of
different nodes compare), each step-numbered message it publishes (before and after the bus's ``put``), each one it
receives (when the bus's thread hands it over, once decoded, and when its main loop takes it), and its own work on a
period (``work``: the flight software's step, the universe's advance). ``hop_table`` follows one period's chain
through the universe and the flight software:

    universe publishes the request -> the flight software's bus thread receives it, decodes it, its loop takes it ->
    its step -> it publishes the reply -> the universe receives, decodes and takes it -> its advance -> the next
    request

and gives each link's median, 90th percentile and total over the run. Marks are kept in memory until the node
ends (about 100 bytes each, some 20 a period): a diagnostic for runs of minutes, not a flight recorder.
"""

from __future__ import annotations

import statistics
from collections import defaultdict
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

from contracts.clock import monotonic_ns

# what is marked; a message's marks add its key's last two parts (obsw/step, obsw/reply, ground/step, ...)
PUBLISH, PUBLISHED, ARRIVED, DECODED, TAKEN = "publish", "published", "arrived", "decoded", "taken"
WORK_START, WORK_END = "work", "worked"


class TraceError(ValueError):
    """A trace file that is not one ``HopTrace`` wrote."""


@dataclass(frozen=True)
class Mark:
    """One time mark: host monotonic ns, the node, what happened, the step number it concerns."""

    t_ns: int
    node: str
    what: str
    step: int


class HopTrace:
    """A node's time marks, written to ``path`` by ``write``."""

    def __init__(self, node: str, path: Path) -> None:
        self.node = node
        self.path = Path(path)
        self._marks: list[tuple[int, str, int]] = []

    def mark(self, what: str, step: int) -> None:
        """Mark ``what`` for ``step`` now."""
        self._marks.append((monotonic_ns(), what, step))

    def mark_at(self, t_ns: int, what: str, step: int) -> None:
        """Mark ``what`` for ``step`` at ``t_ns``, a time read earlier with ``contracts.clock.monotonic_ns``."""
        self._marks.append((t_ns, what, step))

    def write(self) -> None:
        """Write every mark, one line each: ns, node, what, step."""
        with open(self.path, "w", encoding="ascii") as f:
            f.write("t_ns,node,what,step\n")
            f.writelines(f"{t},{self.node},{w},{s}\n" for t, w, s in self._marks)


def message_mark(what: str, key: str) -> str:
    """The mark of ``what`` (publish, arrived, ...) for a message on ``key``: ``what:node/kind``."""
    return f"{what}:{'/'.join(key.rsplit('/', 2)[-2:])}"


def read_traces(paths: Iterable[Path]) -> list[Mark]:
    """Every mark of the trace files ``paths``, in time order; TraceError naming the file and line that is wrong."""
    marks = []
    for path in paths:
        lines = Path(path).read_text(encoding="ascii").splitlines()
        if not lines or lines[0] != "t_ns,node,what,step":
            raise TraceError(f"{path}: not a hop trace (its first line is not 't_ns,node,what,step')")
        for n, line in enumerate(lines[1:], start=2):
            parts = line.split(",")
            try:
                if len(parts) != 4:
                    raise ValueError(f"{len(parts)} fields, expected 4")
                marks.append(Mark(int(parts[0]), parts[1], parts[2], int(parts[3])))
            except ValueError as exc:
                raise TraceError(f"{path}: line {n}: {exc}") from None
    return sorted(marks, key=lambda m: m.t_ns)


# one period's chain, as (node, mark); the request and reply marks name the key of each
STEP, REPLY = "obsw/step", "obsw/reply"
CHAIN: tuple[tuple[str, str], ...] = (
    ("universe", message_mark(PUBLISH, STEP)), ("universe", message_mark(PUBLISHED, STEP)),
    ("obsw", message_mark(ARRIVED, STEP)), ("obsw", message_mark(DECODED, STEP)), ("obsw", message_mark(TAKEN, STEP)),
    ("obsw", WORK_START), ("obsw", WORK_END),
    ("obsw", message_mark(PUBLISH, REPLY)), ("obsw", message_mark(PUBLISHED, REPLY)),
    ("universe", message_mark(ARRIVED, REPLY)), ("universe", message_mark(DECODED, REPLY)),
    ("universe", message_mark(TAKEN, REPLY)),
    ("universe", WORK_START), ("universe", WORK_END),
)
NEXT_REQUEST = "universe: worked -> next publish:obsw/step"


@dataclass(frozen=True)
class Segment:
    """One link of the chain over a run: its name and durations, s (one per period that has both marks)."""

    name: str
    durations_s: tuple[float, ...]

    @property
    def median_us(self) -> float:
        """Median duration, us."""
        return 1e6 * statistics.median(self.durations_s)

    @property
    def p90_us(self) -> float:
        """90th percentile duration, us."""
        d = sorted(self.durations_s)
        return 1e6 * d[min(len(d) - 1, int(0.9 * len(d)))]

    @property
    def total_s(self) -> float:
        """Sum over the run, s."""
        return sum(self.durations_s)


def hop_table(marks: Sequence[Mark]) -> list[Segment]:
    """The chain's links over every period that has all of its marks (the first of each mark per step: a resent
    request counts from its first sending), then the universe's time from its advance to the next request (the
    ground step and the frame's hand-over happen there)."""
    first: dict[int, dict[tuple[str, str], int]] = defaultdict(dict)
    for m in marks:
        first[m.step].setdefault((m.node, m.what), m.t_ns)
    links: dict[str, list[float]] = {f"{a[0]}: {a[1]} -> {b[0] + ': ' if b[0] != a[0] else ''}{b[1]}": []
                                     for a, b in zip(CHAIN, CHAIN[1:])}
    links[NEXT_REQUEST] = []
    names = list(links)
    # the universe's work on period k is marked with the step number of the request it answers (k)
    for step in sorted(first):
        seen = first[step]
        if not all(c in seen for c in CHAIN):
            continue
        for name, a, b in zip(names, CHAIN, CHAIN[1:]):
            links[name].append((seen[b] - seen[a]) * 1e-9)
        nxt = first.get(step + 1, {}).get(("universe", message_mark(PUBLISH, STEP)))
        if nxt is not None:
            links[NEXT_REQUEST].append((nxt - seen[("universe", WORK_END)]) * 1e-9)
    return [Segment(name, tuple(d)) for name, d in links.items() if d]
