"""The campaign's judge: an expected event's detection latency is that of its earliest report by on-board time,
whatever order the archive lists the reports in."""

from __future__ import annotations

from pathlib import Path

import pytest

from analysis.expectations import judge
from analysis.runfolder import RunData
from analysis.telemetry import Telemetry
from analysis.truth import Truth
from contracts import pus
from contracts.messages import TruthRecord
from scenario.model import scenario_from_dict

OBT_OFFSET_S = 1000.0  # on-board time runs this far ahead of true time in the run below


def _truth(times_s: list[float]) -> Truth:
    """A truth at rest, on-board time the true time plus OBT_OFFSET_S."""
    return Truth.from_records([TruthRecord(
        t_s=t, obt_s=t + OBT_OFFSET_S, q=(0.0, 0.0, 0.0, 1.0), omega_rad_s=(0.0, 0.0, 0.0),
        wheel_momentum_nms=(0.0, 0.0, 0.0), wheel_torque_nm=(0.0, 0.0, 0.0), pointing_error_rad=0.0,
        target_in_fov=True, range_m=5.5e4, theta_rad=1.0, phase_angle_deg=60.0) for t in times_s])


@pytest.mark.parametrize("reported_true_s", [[150.0, 120.0, 135.0], [120.0, 150.0], [135.0, 120.0]])
def test_latency_is_from_the_earliest_report(reported_true_s: list[float]) -> None:
    """Reports listed late-first give the latency of the earliest one (fault at 100 s, first report at 120 s)."""
    sc = scenario_from_dict({
        "name": "late-first", "universe": {"faults": [{"kind": "plume_brightening", "start_s": 100.0,
                                                       "end_s": 200.0, "magnitude": 100.0}]},
        "expect": {"events": [{"event": "FalseLockEvent", "within_s": 25.0}]}})
    tm = Telemetry(source="test", packets=len(reported_true_s))
    tm.events = [(t + OBT_OFFSET_S, pus.FalseLockEvent(frame_id=k, offset_rad=0.01, gate_rad=0.005))
                 for k, t in enumerate(reported_true_s)]
    data = RunData(Path("<test>"), sc, _truth([0.0, 300.0]), tm)
    verdict = judge(data, None, None, None, [])  # type: ignore[arg-type]  # no figure is expected
    assert verdict.latencies["FalseLockEvent"] == pytest.approx(20.0)
    assert verdict.passed
