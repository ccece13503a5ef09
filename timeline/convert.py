"""Resolve a timeline's tags to on-board time (OBT), as ground does before uploading it.

Rules (each the closed form the tests check):

- UTC tag: ``obt = correlation.to_obt(utc_s)``, with ``utc_s`` the seconds from the scenario epoch;
- OBT tag: ``obt = obt_s``;
- C/A tag: ``obt = correlation.to_obt(ca_utc_s) + ca_offset_s``; the offset is kept so the on-board scheduler can
  re-anchor the command (``obt = new_ca_obt + ca_offset_s``) when it accepts a new C/A estimate. Offsets are in
  on-board seconds, the same rule the scheduler applies, so re-anchoring on an unchanged estimate moves nothing;
- delay after the previous entry (file order): ``obt = previous_obt + delay_s``; if the previous entry is tied to
  C/A, so is this one, with ``ca_offset_s = previous_ca_offset_s + delay_s`` (a burst moves as one block).

The result is sorted by OBT; entries with equal OBT keep their file order.
"""

from __future__ import annotations

import math
from datetime import datetime, timezone
from typing import NamedTuple, Protocol

from timeline.model import AfterPreviousTag, CaTag, Command, ObtTag, Timeline, TimelineError, UtcTag


class UtcToObt(Protocol):
    """A time correlation: maps UTC (s from the scenario epoch) to OBT (s). ground.correlation.Correlation is one."""

    def to_obt(self, utc_s: float) -> float:
        """On-board time at ``utc_s``, s."""
        ...


class ResolvedCommand(NamedTuple):
    """A command ready for the on-board schedule: its OBT tag, its C/A offset if tied to C/A, the command, and its
    row in the timeline (1-based, file order)."""

    obt_s: float
    ca_offset_s: float | None
    command: Command
    row: int = 0


def epoch_datetime(epoch_utc: str | datetime) -> datetime:
    """The scenario epoch as an aware UTC datetime (text in ISO 8601 with its zone, as Scenario.epoch_utc)."""
    if isinstance(epoch_utc, str):
        try:
            dt = datetime.fromisoformat(epoch_utc)
        except ValueError:
            raise ValueError(f"epoch_utc: cannot read {epoch_utc!r} as an ISO 8601 UTC time") from None
    else:
        dt = epoch_utc
    if dt.tzinfo is None or dt.utcoffset() is None:
        raise ValueError(f"epoch_utc: {epoch_utc!r} must carry its zone (end it in 'Z')")
    return dt.astimezone(timezone.utc)


def utc_seconds(utc: datetime, epoch_utc: str | datetime) -> float:
    """Seconds from the epoch to ``utc`` (exact to the microsecond before rounding to float)."""
    return (utc - epoch_datetime(epoch_utc)).total_seconds()


def resolved_commands(
    timeline: Timeline,
    correlation: UtcToObt,
    *,
    epoch_utc: str | datetime,
    ca_utc_s: float | None = None,
    not_before_obt_s: float | None = None,
    source: str = "<timeline>",
) -> list[ResolvedCommand]:
    """Resolve every tag to OBT and return the commands in tag order.

    ``ca_utc_s`` is ground's C/A estimate (s from the epoch), needed only if a tag is C/A-relative.
    ``not_before_obt_s``: if given, every command whose OBT is earlier is refused (ground uses now + light time +
    a margin, so nothing reaches the spacecraft already late). Raises TimelineError naming each row at fault.
    """
    epoch = epoch_datetime(epoch_utc)
    ca_obt_s: float | None = None
    if ca_utc_s is not None:
        if not math.isfinite(ca_utc_s):
            raise TimelineError(source, [f"ca_utc_s: must be a finite number, got {ca_utc_s}"])
        ca_obt_s = correlation.to_obt(ca_utc_s)
    problems: list[str] = []
    resolved: list[ResolvedCommand] = []
    previous: ResolvedCommand | None = None
    for row, entry in enumerate(timeline.entries, start=1):
        tag = entry.tag
        current: ResolvedCommand | None = None
        if isinstance(tag, UtcTag):
            current = ResolvedCommand(correlation.to_obt(utc_seconds(tag.utc, epoch)), None, entry.command, row)
        elif isinstance(tag, ObtTag):
            current = ResolvedCommand(tag.obt_s, None, entry.command, row)
        elif isinstance(tag, CaTag):
            if ca_obt_s is None:
                problems.append(f"row {row}, field 'time': tied to C/A but no C/A estimate (ca_utc_s) was given")
            else:
                current = ResolvedCommand(ca_obt_s + tag.ca_offset_s, tag.ca_offset_s, entry.command, row)
        elif isinstance(tag, AfterPreviousTag):
            if previous is None:
                # The previous row failed (reported already) or there is none (Timeline refuses that).
                problems.append(f"row {row}, field 'time': relative to row {row - 1}, which could not be resolved")
            elif previous.ca_offset_s is not None and ca_obt_s is not None:
                offset = previous.ca_offset_s + tag.delay_s
                current = ResolvedCommand(ca_obt_s + offset, offset, entry.command, row)
            else:
                current = ResolvedCommand(previous.obt_s + tag.delay_s, None, entry.command, row)
        if current is not None and not math.isfinite(current.obt_s):
            problems.append(f"row {row}, field 'time': resolves to a non-finite OBT ({current.obt_s})")
            current = None
        if current is not None and not_before_obt_s is not None and current.obt_s < not_before_obt_s:
            problems.append(
                f"row {row}, field 'time': resolves to OBT {current.obt_s:.3f} s, "
                f"before the earliest allowed OBT {not_before_obt_s:.3f} s"
            )
        previous = current
        if current is not None:
            resolved.append(current)
    if problems:
        raise TimelineError(source, problems)
    # sorted() is stable: equal tags keep their file order.
    return sorted(resolved, key=lambda r: r.obt_s)
