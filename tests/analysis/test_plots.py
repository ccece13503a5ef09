"""The charts' helpers: mode intervals from events or housekeeping; the on-board timing chart."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

from analysis.plots import mode_intervals, timing_section
from analysis.runfolder import RunData
from analysis.telemetry import decoded_telemetry
from contracts import pus
from contracts.task import Task
from ground.config import ReportConfig
from scenario.model import Scenario


def test_mode_intervals_from_events() -> None:
    """Mode intervals run from each change to the next, the last to the end of the telemetry."""
    ch = [(10.0, pus.ModeChangedEvent(from_mode=pus.Mode.STANDBY, to_mode=pus.Mode.ACQUISITION)),
          (50.0, pus.ModeChangedEvent(from_mode=pus.Mode.ACQUISITION, to_mode=pus.Mode.NOMINAL_TRACKING))]
    hk = [(0.0, int(pus.Mode.STANDBY)), (99.0, int(pus.Mode.NOMINAL_TRACKING))]
    assert mode_intervals(ch, hk, 99.0) == [(0.0, 10.0, 1), (10.0, 50.0, 2), (50.0, 99.0, 3)]
    assert mode_intervals([], [(0.0, 1), (1.0, 1), (2.0, 2)], 3.0) == [(0.0, 2.0, 1), (2.0, 3.0, 2)]


def test_timing_section_draws_the_housekeeping_timing_and_states_the_last_counters() -> None:
    """The timing chart is drawn from housekeeping, its note gives the last report's overrun counters; without
    housekeeping it says so."""
    hk = [pus.Housekeeping(mode=pus.Mode.NOMINAL_TRACKING, q=(0.0, 0.0, 0.0, 1.0), rate_rad_s=(0.0, 0.0, 0.0),
                           wheel_speed_rad_s=(0.0,) * 3, wheel_momentum_nms=(0.0,) * 3,
                           task_time_max_s=tuple(1e-4 * (i + 1) for i in range(len(Task))),
                           exposure_to_centroid_s=0.2 + 0.1 * k, centroid_to_torque_s=0.003, task_overruns=k,
                           frame_overruns=2 * k, skipped_releases=3 * k) for k in range(3)]
    tm = decoded_telemetry([pus.encode_tm(h, 0xC1, k, 100.0 + k, k) for k, h in enumerate(hk)], "test")
    data = RunData(Path("<test>"), Scenario(name="t"), None, tm)
    figs = SimpleNamespace(true_ca_obt_s=101.0)
    s = timing_section(data, figs, ReportConfig())  # type: ignore[arg-type]
    assert s.png is not None and s.png.startswith(b"\x89PNG") and not s.missing
    assert s.notes == ["task overruns 2, minor frame overruns 4, skipped releases 6 (to the last housekeeping)"]
    empty = timing_section(RunData(Path("<test>"), Scenario(name="t"), None, decoded_telemetry([], "test")), figs,
                           ReportConfig())  # type: ignore[arg-type]
    assert empty.png is None and empty.missing == ["no housekeeping in the telemetry"]
