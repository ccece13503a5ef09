"""Zero latencies reproduce the zero-time flight software: the executive with ``timing.modelled`` false gives the
telemetry (housekeeping by its zero-time fields), torques, frames, uplink and truth recorded from the flight
software before the executive (commit a3c702c; recorded again at 30b1117, after the PUS-C and TC authentication
changes, with the in-process keys fixed by the seed; recorded again with the camera's detector on and the imaging
chain robust to it: telemetry, replies and truth from the zero-time flight software of branch img before it took the
executive, the uplink's MACs from the in-process keys fixed by the seed), for the same seed.

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
    "tm": "2ebbb94965f4f02f76fa30c13532b03547373548007ab83217a3213e762611b1",
    "replies": "95624c626b450d562fa7dda9bb008251239422cfb6ef96530322f32ce61151c0",
    "tc": "4ae2f0620faca055f1c6f0b1a13a5cbe6b79f2c2f489ba93e32d0c73a3ca5064",
    "truth": "055f0f19abc90df74e96ee38aa6431a3b100cddba4d63cb8d133514f49a33b3f",
    "n_tm": 122,
    "n_hk": 30,
    "frames": 40,
}


def test_zero_latencies_reproduce_the_zero_time_telemetry() -> None:
    """Every packet (housekeeping by its zero-time fields), torque, frame request, uplinked TC and truth sample of
    the window is the zero-time flight software's, for the same seed."""
    assert telemetry_digest(scenario_from_dict(WINDOW), timeline_from_data(TIMELINE)) == RECORDED
