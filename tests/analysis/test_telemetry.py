"""Telemetry of a run: a cut stream keeps every whole packet; undecodable packets are counted, not fatal."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from analysis.telemetry import decoded_telemetry
from contracts.pus import complete_packets
from contracts import pus

APID = 0x0C1


@settings(max_examples=40, deadline=None)
@given(n=st.integers(0, 8), cut=st.integers(0, 400))
def test_complete_packets_keeps_every_whole_packet(n: int, cut: int) -> None:
    """A stream cut anywhere yields exactly the packets wholly before the cut, and the rest as the tail."""
    packets = [pus.encode_tm(pus.TimeReport(obt_s=100.0 + i), APID, i, 100.0 + i, i) for i in range(n)]
    stream = b"".join(packets)
    cut = min(cut, len(stream))
    got, tail = complete_packets(stream[:cut])
    whole = []
    pos = 0
    for p in packets:
        if pos + len(p) <= cut:
            whole.append(p)
        pos += len(p)
    assert got == whole
    assert tail == cut - sum(len(p) for p in whole)
    assert got == (pus.split_packets(stream[: cut - tail]) if cut - tail else [])


def test_undecodable_packets_are_counted() -> None:
    """A garbled packet counts as undecodable; the others land in their kind with their OBT."""
    ev = pus.ModeChangedEvent(from_mode=pus.Mode.STANDBY, to_mode=pus.Mode.ACQUISITION, cause="test")
    good = pus.encode_tm(ev, APID, 0, 12.5, 0)
    bad = good[:6] + bytes(len(good) - 6)  # header kept, data field zeroed: no such report
    tm = decoded_telemetry([good, bad], "test")
    assert (tm.packets, tm.undecodable) == (2, 1)
    assert tm.mode_changes == [(12.5, ev)] and tm.events == [(12.5, ev)]
