"""Lost uplink: telecommands that never arrived show as a gap in the sequence counts of those that did.

Ground radiates its telecommands with consecutive sequence counts from ``uplink_first_seq_count``, modulo
``uplink_seq_modulo`` (the counts above are those of the TCs it puts in the schedule, which are not radiated on their
own), and re-sends a TC whose acceptance is overdue with a new count: so a TC lost on the way, or the whole uplink
lost for a while, leaves a gap the next one reveals. Pure.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class UplinkGap:
    """Telecommands missing before the one received."""

    expected_seq: int
    received_seq: int
    lost: int


class UplinkWatch:
    """The next sequence count expected of ground's radiated telecommands."""

    def __init__(self, first_seq_count: int, modulo: int) -> None:
        self.expected = first_seq_count
        self.modulo = modulo
        self.lost_total = 0

    def received(self, seq_count: int) -> UplinkGap | None:
        """Take the sequence count of a radiated TC that passed the security check; the gap before it, if any."""
        if seq_count >= self.modulo:
            return None  # not a radiated TC's count
        lost = (seq_count - self.expected) % self.modulo
        if lost >= self.modulo // 2:
            return None  # behind the expected count (a duplicate): no loss, and the expectation stays
        expected, self.expected = self.expected, (seq_count + 1) % self.modulo
        if lost == 0:
            return None
        self.lost_total += lost
        return UplinkGap(expected, seq_count, lost)
