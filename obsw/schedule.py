"""The on-board time-based schedule (PUS service 11): time-tagged commands released exactly once, in order.

Rules, all in on-board time (OBT):

- An entry is keyed on (tag, priority, sequence): lower priority values go first on equal tags, and the
  sequence (the order of acceptance) breaks the remaining ties, so the order is the same on every run.
- ``release_due(now)`` returns every pending entry with ``tag <= now`` in key order and forgets it: a released
  entry can never be released again, whatever time-shift, re-anchoring or clock jump follows. Called once per
  scheduler tick, an entry is released at the first tick at or after its tag: never early, at most one tick late
  (unless the clock jumps forward or the tag is moved into the past).
- ``insert`` checks each request on its own and returns one ``Rejection`` (with a ``RejectReason``) per refused
  request: malformed, refused by the command dictionary, duplicate request id, tag in the past, tag within
  ``margin_s`` of now, schedule full. The others are accepted.
- ``delete`` and ``time_shift`` are atomic: if a selection names a request that is not pending, or a shift
  would bring a tag before ``now + margin_s``, nothing changes and ``CommandRejected`` is raised.
- C/A-relative entries carry ``ca_offset_s``. Once the board holds a C/A estimate (``reanchor_ca``), their tag is
  always ``ca + ca_offset_s``; before that, the tag the ground computed is used. Time-shifting such an entry moves
  its offset too, so a later re-anchoring keeps the shift. Re-anchoring may move a tag into the past: the entry
  is then released at the next tick (late, never dropped, never twice). A C/A-relative entry whose tag is already
  past (or within the margin) when it is inserted was meant for before now: it is accepted and released at the next
  tick, late, like a re-anchored one (an absolute tag in the past is refused).
- ``enabled`` false (ECSS-E-ST-70-41C: the release function disabled, TC[11,2]; the flight software disables it in
  SAFE) releases nothing; the entries stay and those past their tag go at the first tick after enabling.
- ``shift_clock`` moves every tag and the C/A anchor by an on-board time step, so each entry keeps the physical time
  it stands for.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, replace

from obsw.errors import CommandRejected, InternalFault, RejectReason


@dataclass(frozen=True, slots=True)
class ScheduleRequest:
    """One activity of a PUS 11 insert request, as the ground sent it."""

    request_id: int
    tag_obt_s: float
    payload: object
    priority: int = 0
    ca_offset_s: float | None = None


@dataclass(frozen=True, slots=True)
class ScheduledCommand:
    """An accepted entry of the schedule; ``payload`` is opaque to the schedule."""

    request_id: int
    tag_obt_s: float
    payload: object
    priority: int
    sequence: int
    ca_offset_s: float | None = None

    @property
    def key(self) -> tuple[float, int, int]:
        """Release order: (tag, priority, sequence)."""
        return (self.tag_obt_s, self.priority, self.sequence)

    @property
    def ca_relative(self) -> bool:
        """Whether the tag follows the on-board C/A estimate."""
        return self.ca_offset_s is not None


@dataclass(frozen=True, slots=True)
class Rejection:
    """Why the request at ``index`` of an insert was refused."""

    index: int
    request_id: int | None
    reason: RejectReason
    text: str


@dataclass(frozen=True, slots=True)
class Selection:
    """Which entries a delete, time-shift or listing applies to: all given criteria must match (None: any)."""

    request_ids: frozenset[int] | None = None
    from_obt_s: float | None = None
    to_obt_s: float | None = None
    ca_relative: bool | None = None

    def matches(self, entry: ScheduledCommand) -> bool:
        """Whether ``entry`` is selected (the time window is inclusive at both ends)."""
        return (
            (self.request_ids is None or entry.request_id in self.request_ids)
            and (self.from_obt_s is None or entry.tag_obt_s >= self.from_obt_s)
            and (self.to_obt_s is None or entry.tag_obt_s <= self.to_obt_s)
            and (self.ca_relative is None or entry.ca_relative == self.ca_relative)
        )


@dataclass(frozen=True, slots=True)
class ScheduleSummary:
    """The schedule at a glance (the content of a PUS 11 summary report)."""

    pending: int
    capacity: int
    released: int
    first_tag_obt_s: float | None
    last_tag_obt_s: float | None
    ca_anchor_obt_s: float | None
    ca_relative_pending: int


PayloadCheck = Callable[[object], None]


def _is_int(x: object) -> bool:
    return isinstance(x, int) and not isinstance(x, bool)


def _is_real(x: object) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


class TimeBasedSchedule:
    """PUS service 11 time-based schedule of at most ``capacity`` pending entries, refusing tags within ``margin_s``."""

    def __init__(self, capacity: int, margin_s: float, payload_check: PayloadCheck | None = None) -> None:
        """``payload_check`` raises ``CommandRejected`` for an unknown command or a bad argument."""
        if not _is_int(capacity) or capacity < 1:
            raise ValueError(f"capacity must be a positive integer, got {capacity!r}")
        if not _is_real(margin_s) or margin_s < 0:
            raise ValueError(f"margin_s must be a finite number >= 0, got {margin_s!r}")
        self.capacity = capacity
        self.margin_s = float(margin_s)
        self._check = payload_check
        self._entries: list[ScheduledCommand] = []  # always sorted by key
        self._next_sequence = 0
        self._released_ids: set[int] = set()
        self._released = 0
        self._ca_obt_s: float | None = None
        self.enabled = True

    # --- queries -----------------------------------------------------------------------------------

    def __len__(self) -> int:
        return len(self._entries)

    @property
    def ca_anchor_obt_s(self) -> float | None:
        """The on-board C/A estimate the C/A-relative entries follow, OBT s (None until one is accepted)."""
        return self._ca_obt_s

    @property
    def next_tag_obt_s(self) -> float | None:
        """Tag of the next entry to release, OBT s (None when empty or disabled)."""
        return self._entries[0].tag_obt_s if self._entries and self.enabled else None

    def listing(self, selection: Selection | None = None) -> list[ScheduledCommand]:
        """The pending entries (all, or the selected ones) in release order (PUS 11 detail report)."""
        return [e for e in self._entries if selection is None or selection.matches(e)]

    def summary(self) -> ScheduleSummary:
        """Counts, the first and last tags and the C/A anchor (PUS 11 summary report)."""
        return ScheduleSummary(
            pending=len(self._entries),
            capacity=self.capacity,
            released=self._released,
            first_tag_obt_s=self._entries[0].tag_obt_s if self._entries else None,
            last_tag_obt_s=self._entries[-1].tag_obt_s if self._entries else None,
            ca_anchor_obt_s=self._ca_obt_s,
            ca_relative_pending=sum(e.ca_relative for e in self._entries),
        )

    # --- telecommands ------------------------------------------------------------------------------

    def insert(self, now_obt_s: float, requests: Iterable[ScheduleRequest]) -> list[Rejection]:
        """Insert each request that passes every check; return one Rejection per refused request."""
        _require_time(now_obt_s, "now_obt_s")
        rejections: list[Rejection] = []
        pending_ids = {e.request_id for e in self._entries}
        for index, req in enumerate(requests):
            try:
                entry = self._accepted(now_obt_s, req, pending_ids)
            except CommandRejected as err:
                rid = getattr(req, "request_id", None)
                rejections.append(Rejection(index, rid if _is_int(rid) else None, err.reason, err.text))
                continue
            pending_ids.add(entry.request_id)
            bisect.insort(self._entries, entry, key=_key)
        return rejections

    def delete(self, selection: Selection) -> list[ScheduledCommand]:
        """Remove the selected entries (atomically) and return them; naming a non-pending request is refused."""
        self._require_pending(selection)
        gone = [e for e in self._entries if selection.matches(e)]
        self._entries = [e for e in self._entries if not selection.matches(e)]
        return gone

    def time_shift(
        self, now_obt_s: float, delta_s: float, selection: Selection | None = None
    ) -> list[ScheduledCommand]:
        """Move the selected entries (all if None) by ``delta_s``, atomically; return them as shifted."""
        _require_time(now_obt_s, "now_obt_s")
        if not _is_real(delta_s):
            raise CommandRejected(RejectReason.MALFORMED, f"time shift delta_s must be finite, got {delta_s!r}")
        if selection is not None:
            self._require_pending(selection)
        chosen = [e for e in self._entries if selection is None or selection.matches(e)]
        for e in chosen:
            self._refuse_early(now_obt_s, e.tag_obt_s + delta_s, e.request_id, f"shifted by {delta_s} s")
        shifted = {
            e.sequence: replace(
                e,
                tag_obt_s=e.tag_obt_s + delta_s,
                ca_offset_s=None if e.ca_offset_s is None else e.ca_offset_s + delta_s,
            )
            for e in chosen
        }
        self._entries = sorted((shifted.get(e.sequence, e) for e in self._entries), key=_key)
        return [e for e in self._entries if e.sequence in shifted]

    # --- on-board calls ----------------------------------------------------------------------------

    def release_due(self, now_obt_s: float) -> list[ScheduledCommand]:
        """Every pending entry with tag <= now, in (tag, priority, sequence) order, each released exactly once."""
        _require_time(now_obt_s, "release_due: now_obt_s")
        if not self.enabled:
            return []
        n = 0
        while n < len(self._entries) and self._entries[n].tag_obt_s <= now_obt_s:
            n += 1
        due, self._entries = self._entries[:n], self._entries[n:]
        self._released += n
        self._released_ids.update(e.request_id for e in due)
        return due

    def reanchor_ca(self, new_ca_obt_s: float) -> list[ScheduledCommand]:
        """Accept a new on-board C/A estimate: every pending C/A-relative entry moves to ca + offset; return them."""
        _require_time(new_ca_obt_s, "reanchor_ca: the C/A estimate new_ca_obt_s")
        self._ca_obt_s = float(new_ca_obt_s)
        moved = {
            e.sequence: replace(e, tag_obt_s=self._ca_obt_s + e.ca_offset_s)
            for e in self._entries
            if e.ca_offset_s is not None
        }
        self._entries = sorted((moved.get(e.sequence, e) for e in self._entries), key=_key)
        return [e for e in self._entries if e.sequence in moved]

    def shift_clock(self, step_s: float) -> int:
        """On-board time stepped by ``step_s``: move every tag and the C/A anchor with it; return the entries moved."""
        _require_time(step_s, "shift_clock: step_s")
        if self._ca_obt_s is not None:
            self._ca_obt_s += step_s
        self._entries = [replace(e, tag_obt_s=e.tag_obt_s + step_s) for e in self._entries]
        return len(self._entries)

    # --- checks ------------------------------------------------------------------------------------

    def _accepted(self, now_obt_s: float, req: object, pending_ids: set[int]) -> ScheduledCommand:
        """The entry ``req`` becomes, or CommandRejected naming the first check it fails."""
        if not isinstance(req, ScheduleRequest):
            raise CommandRejected(RejectReason.MALFORMED, f"expected a ScheduleRequest, got {type(req).__name__}")
        rid = req.request_id
        if not _is_int(rid) or rid < 0:
            raise CommandRejected(RejectReason.MALFORMED, f"request_id must be an integer >= 0, got {rid!r}")
        if not _is_real(req.tag_obt_s):
            raise CommandRejected(
                RejectReason.MALFORMED, f"request {rid}: tag_obt_s must be finite, got {req.tag_obt_s!r}"
            )
        if not _is_int(req.priority):
            raise CommandRejected(
                RejectReason.MALFORMED, f"request {rid}: priority must be an integer, got {req.priority!r}"
            )
        if req.ca_offset_s is not None and not _is_real(req.ca_offset_s):
            raise CommandRejected(
                RejectReason.MALFORMED, f"request {rid}: ca_offset_s must be finite or absent, got {req.ca_offset_s!r}"
            )
        if self._check is not None:
            try:
                self._check(req.payload)
            except CommandRejected as err:
                raise CommandRejected(err.reason, f"request {rid}: {err.text}") from err
        if rid in pending_ids:
            raise CommandRejected(RejectReason.DUPLICATE_REQUEST, f"request {rid} is already scheduled")
        tag = float(req.tag_obt_s)
        if req.ca_offset_s is not None and self._ca_obt_s is not None:
            tag = self._ca_obt_s + req.ca_offset_s
        if req.ca_offset_s is None:  # a C/A-relative tag already past is released at once, late
            self._refuse_early(now_obt_s, tag, rid, "")
        if len(self._entries) >= self.capacity:
            raise CommandRejected(
                RejectReason.SCHEDULE_FULL, f"request {rid}: the schedule is full ({self.capacity} entries)"
            )
        entry = ScheduledCommand(
            request_id=rid,
            tag_obt_s=tag,
            payload=req.payload,
            priority=req.priority,
            sequence=self._next_sequence,
            ca_offset_s=None if req.ca_offset_s is None else float(req.ca_offset_s),
        )
        self._next_sequence += 1
        return entry

    def _refuse_early(self, now_obt_s: float, tag: float, rid: int, how: str) -> None:
        what = f"request {rid}" + (f" {how}" if how else "")
        if tag < now_obt_s:
            raise CommandRejected(RejectReason.TAG_IN_PAST, f"{what}: tag {tag} s is before now ({now_obt_s} s)")
        if tag < now_obt_s + self.margin_s:
            raise CommandRejected(
                RejectReason.TAG_WITHIN_MARGIN,
                f"{what}: tag {tag} s is within the {self.margin_s} s margin of now ({now_obt_s} s)",
            )

    def _require_pending(self, selection: Selection) -> None:
        if selection.request_ids is None:
            return
        pending = {e.request_id for e in self._entries}
        for rid in sorted(selection.request_ids):
            if rid in pending:
                continue
            if rid in self._released_ids:
                raise CommandRejected(RejectReason.ALREADY_RELEASED, f"request {rid} has already been released")
            raise CommandRejected(RejectReason.UNKNOWN_REQUEST, f"request {rid} is not in the schedule")


def _key(e: ScheduledCommand) -> tuple[float, int, int]:
    return e.key


def _require_time(now_obt_s: object, name: str) -> None:
    if not _is_real(now_obt_s):
        raise InternalFault(f"{name} must be a finite OBT, got {now_obt_s!r}")


__all__: Sequence[str] = (
    "PayloadCheck",
    "Rejection",
    "ScheduleRequest",
    "ScheduleSummary",
    "ScheduledCommand",
    "Selection",
    "TimeBasedSchedule",
)
