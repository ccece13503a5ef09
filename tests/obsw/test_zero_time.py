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
ground's nominal until the hand-over, a change of flight behaviour on purpose), for the same seed.

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
    "tm": "a12585f830177873352da151a307825a74bbcc155382e84afff86cc342286931",
    "replies": "5cde5225691cd6ad366970b6ea5c1b7f2c9fd7bab765c6843dbfd4a95eafacea",
    "tc": "4ae2f0620faca055f1c6f0b1a13a5cbe6b79f2c2f489ba93e32d0c73a3ca5064",
    "truth": "420d53996a72d957f232b55d5bb05c42e3678bc6c902be58a0b9079be3388c87",
    "n_tm": 122,
    "n_hk": 30,
    "frames": 40,
}


def test_zero_latencies_reproduce_the_zero_time_telemetry() -> None:
    """Every packet (housekeeping by its zero-time fields), torque, frame request, uplinked TC and truth sample of
    the window is the zero-time flight software's, for the same seed."""
    assert telemetry_digest(scenario_from_dict(WINDOW), timeline_from_data(TIMELINE)) == RECORDED
