"""Zero latencies reproduce the zero-time flight software: the executive with ``timing.modelled`` false gives the
telemetry (housekeeping by its zero-time fields), torques, frames, uplink and truth recorded from the flight
software before the executive (commit a3c702c; recorded again at 30b1117, after the PUS-C and TC authentication
changes, with the in-process keys fixed by the seed; recorded again with the camera's detector on and the imaging
chain robust to it, and with the attitude estimator (a multiplicative EKF that filters the star tracker and removes
the estimated gyro bias) and on-board FDIR, both changes of flight behaviour on purpose; recorded again when the MEKF's
covariance steps were compiled and the universe's truth geometry vectorised, the same equations rounded in another
order; recorded again when the control path (tracking loop, PD law, wheel split) was compiled, the same equations
rounded in another order: torques within 3e-16 N m of the previous record; and with the filter's 3x3 inverse by
its adjugate; recorded again when the recognition's continuous estimate was compiled, its 2x2 systems solved in
closed form: over the nominal flyby the C/A estimates moved by at most 1.7e-6 s and 4e-7 km, within the solver's
stopping tolerance, and the pointing error by 6e-11 rad; recorded again when the continuous estimate solved a
constant offset of the line of sight and EstimateReport carried it, a change of flight behaviour on purpose; recorded
again when the imaging chain's prediction took the recognised trajectory as soon as it is trusted rather than the
ground's nominal until the hand-over, a change of flight behaviour on purpose; recorded again when ACQUISITION
entered from STANDBY waited for the slew onto the target before its first frame, a change of flight behaviour on
purpose; recorded again when ground uploaded Dimorphos's trajectory rather than the barycentre's, a change of
ground's behaviour on purpose), for the same seed. Since
2026-12-02 the record keeps the numbers, compared to rounding, not a digest: the digest recorded on one processor
failed on another (AMD EPYC with AVX2, after Intel runs) with the same code, as Numba and NumPy round by the host's
vector units. Since 2026-12-07 the uplinked telecommands are kept decoded too (recorded again on an AMD EPYC): their
digest, taken for exact on any machine, differed there, ground's trajectory upload and C/A-relative release times
being floating-point results as well.

The window covers acquisition, tracking and the hand-over to autonomous tracking with frames every 0.5 s and time
reports. A change of flight behaviour must record the digest again: ``telemetry_digest`` of ``WINDOW``/``TIMELINE``
(``tests/obsw/zero_time.py``); the full nominal, worst-late-far and clock-drift runs are compared with its ``main``.
"""

from __future__ import annotations

import json
from pathlib import Path

from scenario.model import scenario_from_dict
from tests.obsw.test_software import SHORT_FLYBY
from tests.obsw.zero_time import differences, load_record, save_record, telemetry_record
from timeline.parse import timeline_from_data

# the short flyby of test_software, C/A-58 s to C/A-28 s, with the processing times off
WINDOW = {**SHORT_FLYBY, "name": "zero-time-window", "obsw": {"timing": {"modelled": False}},
          "universe": {**SHORT_FLYBY["universe"], "end_s": 140.0}}
TIMELINE = {
    "description": "acquisition at C/A-44 s, frames every 0.5 s, two time reports",
    "commands": [
        {"time": "CA-44s", "command": "set_mode", "args": {"mode": "ACQUISITION"}},
        {"time": "+0s", "command": "start_imaging", "args": {"period_s": 0.5}},
        {"time": "CA-34s", "command": "report_time", "args": {"count": 2}},
    ],
}
# recorded on this build with the processing times off (``python -m tests.obsw.test_zero_time`` writes it again)
RECORD = Path(__file__).parent / "data" / "zero_time_window.json.gz"


def test_zero_latencies_reproduce_the_zero_time_telemetry() -> None:
    """Every packet (housekeeping by its zero-time fields), torque, frame request, uplinked TC and truth sample of
    the window is the zero-time flight software's, for the same seed, to rounding (``zero_time.differences``)."""
    got = telemetry_record(scenario_from_dict(WINDOW), timeline_from_data(TIMELINE))
    want = load_record(RECORD)
    assert (len(got["replies"]), len(got["tm"]), got["frames"]) == (len(want["replies"]), len(want["tm"]),
                                                                     want["frames"])
    assert differences(got, want) == []


def test_the_comparison_sees_a_change_of_behaviour() -> None:
    """A torque moved by a part in a million, or a mode or frame id changed, is a difference; rounding is not."""
    want = load_record(RECORD)
    step = next(i for i, r in enumerate(want["replies"]) if any(r[1]))
    nudged = json.loads(json.dumps(want))
    nudged["replies"][step][1][0] *= 1 + 1e-12
    assert differences(nudged, want) == []
    nudged["replies"][step][1][0] *= 1 + 1e-5
    assert differences(nudged, want) == [f".replies[{step}][1][0]: {nudged['replies'][step][1][0]!r} != "
                                         f"{want['replies'][step][1][0]!r}"]
    framed = next(i for i, t in enumerate(want["truth"]) if t[3] is not None)
    moved = json.loads(json.dumps(want))
    moved["truth"][framed][3] += 1
    assert differences(moved, want) != []


if __name__ == "__main__":
    RECORD.parent.mkdir(exist_ok=True)
    save_record(telemetry_record(scenario_from_dict(WINDOW), timeline_from_data(TIMELINE)), RECORD)
    print(f"wrote {RECORD}")
