"""Digest of a run's telemetry, replies, frames and truth that ignores what the timing model adds to housekeeping.

The executive with every cost, readout and delay at zero must reproduce the zero-time flight software's telemetry
for the same seed. Housekeeping gained timing fields, so its packets are compared by their header and the fields
the zero-time software had (``ZERO_TIME_HK_FIELDS``); every other packet byte for byte, and the wheel torques,
frame requests, clock adjustments, uplinked telecommands and the truth.

    PYTHONPATH=. python tests/obsw/zero_time.py OUT.json SCENARIO.yaml...   (full runs, for the three scenarios)
"""

from __future__ import annotations

import hashlib
import json
import sys
from pathlib import Path
from typing import Any

from contracts import pus
from flyby.inprocess import run_in_process
from scenario.model import Scenario, load_run_inputs
from timeline.model import Timeline

ZERO_TIME_HK_FIELDS = ("mode", "q", "rate_rad_s", "wheel_speed_rad_s", "wheel_momentum_nms", "pointing_error_rad",
                       "best_ca_obt_s", "best_ca_distance_km", "best_mse_rad2")


def telemetry_digest(scenario: Scenario, timeline: Timeline | None, max_steps: int | None = None) -> dict[str, Any]:
    """SHA-256 of the telemetry (housekeeping by its zero-time fields), of the replies, uplink and truth of a run."""
    h_rep, h_tc, h_tm = hashlib.sha256(), hashlib.sha256(), hashlib.sha256()

    def on_step(req: Any, rep: Any, frame: Any) -> None:
        h_rep.update(repr((rep.step, rep.wheel_torque_nm, rep.frame_request, rep.clock_adjust_s)).encode())
        for raw in req.uplink:
            h_tc.update(raw)

    run = run_in_process(scenario, timeline, on_step=on_step, max_steps=max_steps)
    n_hk = 0
    for p in run.received:
        if isinstance(p.report, pus.Housekeeping):
            n_hk += 1
            h_tm.update(repr((p.header, [getattr(p.report, f) for f in ZERO_TIME_HK_FIELDS])).encode())
        else:
            h_tm.update(p.raw)
    truth = hashlib.sha256(repr([(t.t_s, t.q, t.pointing_error_rad, t.frame_id) for t in run.truth]).encode())
    return dict(tm=h_tm.hexdigest(), replies=h_rep.hexdigest(), tc=h_tc.hexdigest(), truth=truth.hexdigest(),
                n_tm=len(run.received), n_hk=n_hk, frames=run.frames)


def main(argv: list[str]) -> int:
    """Write the digests of full runs of the scenarios to argv[0] (keyed on the scenario's name)."""
    out = {}
    for path in argv[1:]:
        sc, tl = load_run_inputs(path)
        out[sc.name] = telemetry_digest(sc, tl)
        print(sc.name, out[sc.name], flush=True)
    Path(argv[0]).write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
