"""Zero latencies reproduce the zero-time flight software: the executive with ``timing.modelled`` false gives the
telemetry (housekeeping by its zero-time fields), torques, frames, uplink and truth recorded from the flight
software before the executive (commit a3c702c; recorded again at 30b1117, after the PUS-C and TC authentication
changes, with the in-process keys fixed by the seed; and again with the attitude estimator, a multiplicative EKF
that filters the star tracker and removes the estimated gyro bias, and on-board FDIR: same uplink, new torques),
for the same seed.

The window covers acquisition, tracking and the hand-over to autonomous tracking with frames every 0.5 s and time
reports. A change of flight behaviour must record the digest again: ``telemetry_digest`` of ``WINDOW``/``TIMELINE``
(``tests/obsw/zero_time.py``); the full nominal, worst-late-far and clock-drift runs are compared with its ``main``.
"""

from __future__ import annotations

from scenario.model import scenario_from_dict
from tests.obsw.test_software import SHORT_FLYBY
from tests.obsw.zero_time import telemetry_digest
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
RECORDED = {
    "tm": "dcb2964fe9d295d769a4b8b5c8eaa19fea80ee4b94a3af270960f06d5b0dce70",
    "replies": "50b4f35be93b708346f109bc4bcc4f797116ab63a0d35702ca7e7defd745a9f9",
    "tc": "0cdd6408d0e9c0ba32da9ef6691b41ea3a5ccf7ec6316c717b474e3b8294e077",
    "truth": "3fb817cce0b5add15589e9b914b33768168d04c4fef06a6284313179cb01e891",
    "n_tm": 119,
    "n_hk": 30,
    "frames": 40,
}


def test_zero_latencies_reproduce_the_zero_time_telemetry() -> None:
    """Every packet (housekeeping by its zero-time fields), torque, frame request, uplinked TC and truth sample of
    the window is the zero-time flight software's, for the same seed."""
    assert telemetry_digest(scenario_from_dict(WINDOW), timeline_from_data(TIMELINE)) == RECORDED
