"""Lost uplink: a gap in the sequence counts of the radiated telecommands received."""

from __future__ import annotations

from obsw.uplink_watch import UplinkGap, UplinkWatch


def test_gaps_are_counted_modulo_and_duplicates_are_no_loss() -> None:
    """0, 1 then 4 lose 2 and 3; a repeated 4 is no loss; counts wrap at the modulo; scheduled counts are ignored."""
    w = UplinkWatch(first_seq_count=0, modulo=0x2000)
    assert w.received(0) is None and w.received(1) is None
    assert w.received(4) == UplinkGap(expected_seq=2, received_seq=4, lost=2)
    assert w.received(4) is None and w.received(3) is None and w.expected == 5
    assert w.received(0x2005) is None  # a count of the schedule's range
    w.expected = 0x1FFF
    assert w.received(1) == UplinkGap(expected_seq=0x1FFF, received_seq=1, lost=2)
    assert w.lost_total == 4


def test_the_first_telecommands_lost_show_at_the_first_received() -> None:
    """The whole upload lost and re-sent with new counts: the first TC received reveals the loss."""
    w = UplinkWatch(first_seq_count=0, modulo=0x2000)
    assert w.received(3) == UplinkGap(expected_seq=0, received_seq=3, lost=3)
