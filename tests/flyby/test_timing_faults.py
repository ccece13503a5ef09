"""Timing faults end to end: the universe's cpu_overload and imaging_latency reach the OBSW's processor model as
hardware readings, and the flight software reports what they do in its telemetry."""

from __future__ import annotations

import math

from contracts import pus
from flyby.inprocess import run_in_process
from scenario.model import scenario_from_dict
from tests.obsw.test_zero_time import TIMELINE, WINDOW
from timeline.parse import timeline_from_data

FRAME_LATENCY_S = 0.005 + 1024 * 1024 * 12 / 80e6 + 512 * 512 * 60e-9  # the default timing model's, closed form


def _packets(run) -> list[tuple[float, object]]:  # noqa: ANN001
    return [(p.header.obt_s, p.report) for p in run.received if p.report is not None]


def test_a_processor_overload_is_reported_by_events_and_counters_inside_its_window_only() -> None:
    """A 200x slow-down for 2 s: no overrun before it; inside it task and minor frame overruns are raised as events
    and counted by housekeeping; the torques keep coming every period."""
    # 200x the attitude (MEKF, 0.6 ms) and control tasks leaves 3.6 s of work queued: the run goes on until it is done
    sc = scenario_from_dict({"name": "overload", "universe": {
        "start_s": -50.0, "end_s": -38.0, "save_frames_every": 0,
        "faults": [{"kind": "cpu_overload", "start_s": -47.0, "end_s": -45.0, "magnitude": 200.0}]}})
    run = run_in_process(sc)
    tm = _packets(run)
    obt_at = {round(r.t_s, 6): r.obt_s for r in run.truth}
    start, end = obt_at[-47.0], obt_at[-45.0]
    events = [(t, r) for t, r in tm if isinstance(r, pus.TaskOverrunEvent | pus.FrameOverrunEvent)]
    assert {type(r) for _, r in events} == {pus.TaskOverrunEvent, pus.FrameOverrunEvent}
    assert all(start <= t < end + 0.2 for t, _ in events)  # the last overrun frame ends after the window
    hk = [(t, r) for t, r in tm if isinstance(r, pus.Housekeeping)]
    assert all(r.task_overruns == r.frame_overruns == 0 for t, r in hk if t < start)
    after = [r for t, r in hk if t > end + 1.0]
    assert after and all(r.task_overruns > 0 and r.frame_overruns > 0 for r in after)
    assert len({r.task_overruns for r in after}) == 1  # nothing more once the processor is back to speed
    assert len(run.truth) > 80 and all(all(map(math.isfinite, r.wheel_torque_nm)) for r in run.truth)


def test_an_imaging_latency_delays_every_line_of_sight_by_it() -> None:
    """Frames 0.5 s late at the interface: housekeeping's exposure-to-centroid latency is the readout and FPGA
    stages plus 0.5 s, rounded up to the next tick where the imaging task picks the frame up."""
    data = {**WINDOW, "obsw": {}, "universe": {**WINDOW["universe"], "faults": [
        {"kind": "imaging_latency", "start_s": WINDOW["universe"]["start_s"], "end_s": WINDOW["universe"]["end_s"],
         "magnitude": 0.5}]}}
    run = run_in_process(scenario_from_dict(data), timeline_from_data(TIMELINE))
    latencies = [r.exposure_to_centroid_s for _, r in _packets(run)
                 if isinstance(r, pus.Housekeeping) and r.exposure_to_centroid_s is not None]
    assert len(latencies) > 10
    assert all(0.5 + FRAME_LATENCY_S <= x < 0.5 + FRAME_LATENCY_S + 0.1 + 0.01 for x in latencies)
