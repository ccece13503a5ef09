"""The charts' helpers: mode intervals from events or housekeeping."""

from __future__ import annotations

from analysis.plots import mode_intervals
from contracts import pus


def test_mode_intervals_from_events() -> None:
    """Mode intervals run from each change to the next, the last to the end of the telemetry."""
    ch = [(10.0, pus.ModeChangedEvent(from_mode=pus.Mode.STANDBY, to_mode=pus.Mode.ACQUISITION)),
          (50.0, pus.ModeChangedEvent(from_mode=pus.Mode.ACQUISITION, to_mode=pus.Mode.NOMINAL_TRACKING))]
    hk = [(0.0, int(pus.Mode.STANDBY)), (99.0, int(pus.Mode.NOMINAL_TRACKING))]
    assert mode_intervals(ch, hk, 99.0) == [(0.0, 10.0, 1), (10.0, 50.0, 2), (50.0, 99.0, 3)]
    assert mode_intervals([], [(0.0, 1), (1.0, 1), (2.0, 2)], 3.0) == [(0.0, 2.0, 1), (2.0, 3.0, 2)]
