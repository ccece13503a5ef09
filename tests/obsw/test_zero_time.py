"""Zero latencies reproduce the zero-time flight software: the executive with ``timing.modelled`` false gives the
telemetry (housekeeping by its zero-time fields), torques, frames, uplink and truth recorded from the flight
software before the executive (commit a3c702c; recorded again at 30b1117, after the PUS-C and TC authentication
changes, with the in-process keys fixed by the seed), for the same seed.

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
    "tm": "2e54ed00698112915440c9f58dccfbd250a16df1558fbd3e8c734214bb47d85b",
    "replies": "db8646b58d3c047ab3134094707f9b0b1d863ac2782feb5408c9b96058cbc22d",
    "tc": "0cdd6408d0e9c0ba32da9ef6691b41ea3a5ccf7ec6316c717b474e3b8294e077",
    "truth": "1afccd584357346e38230f147a6a476303578532b48e56e0a5c90894b785fd14",
    "n_tm": 119,
    "n_hk": 30,
    "frames": 40,
}


def test_zero_latencies_reproduce_the_zero_time_telemetry() -> None:
    """Every packet (housekeeping by its zero-time fields), torque, frame request, uplinked TC and truth sample of
    the window is the zero-time flight software's, for the same seed."""
    assert telemetry_digest(scenario_from_dict(WINDOW), timeline_from_data(TIMELINE)) == RECORDED
