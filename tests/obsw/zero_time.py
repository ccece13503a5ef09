"""Record of a run's telemetry, replies, frames and truth that ignores what the timing model adds to housekeeping,
and its digest.

The executive with every cost, readout and delay at zero must reproduce the zero-time flight software's telemetry
for the same seed. Housekeeping gained timing fields, so its packets are compared by their header and the fields
the zero-time software had (``ZERO_TIME_HK_FIELDS``); every other packet by its header and decoded fields, and the
wheel torques, frame requests, clock adjustments, uplinked telecommands and the truth.

``telemetry_record`` keeps the numbers, and ``differences`` compares two records: integers, strings and enumerations
exactly, floating-point values (the uplinked telecommands' among them) to a relative 1e-6 (and 1e-12 absolute).
Floating point is not bit-identical across processors: Numba compiles for the host's vector units (AVX2 or AVX-512,
with or without fused multiply-add) and NumPy dispatches its loops by CPU, so the same code rounds differently on
another machine; a change of flight behaviour moves the figures far beyond that tolerance or changes a discrete field.
The digest (SHA-256, exact) compares builds on one machine.

    PYTHONPATH=. python tests/obsw/zero_time.py OUT.json SCENARIO.yaml...   (full runs, for the three scenarios)
"""

from __future__ import annotations

import gzip
import hashlib
import json
import math
import sys
from pathlib import Path
from typing import Any

from contracts import pus, sdls
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


def telemetry_record(scenario: Scenario, timeline: Timeline | None, max_steps: int | None = None) -> dict[str, Any]:
    """The run's replies, telemetry (housekeeping by its zero-time fields; every other packet by its decoded fields),
    uplinked telecommands (each by its decoded header and fields: ground's trajectory upload is computed in floating
    point too, and rounds by the processor; its MAC follows from them) and truth as JSON values."""
    replies: list[Any] = []
    tc: list[Any] = []

    def on_step(req: Any, rep: Any, frame: Any) -> None:
        request = None if rep.frame_request is None else rep.frame_request.model_dump(mode="json")
        replies.append([rep.step, list(rep.wheel_torque_nm), request, rep.clock_adjust_s])
        for raw in req.uplink:
            header, command = pus.decode_tc(sdls.packet_of(raw))
            tc.append([req.step, header.model_dump(mode="json"), {"type": type(command).__name__,
                                                                  **_json(command.model_dump())}])

    run = run_in_process(scenario, timeline, on_step=on_step, max_steps=max_steps)
    tm: list[Any] = []
    for p in run.received:
        header = None if p.header is None else p.header.model_dump(mode="json")
        if isinstance(p.report, pus.Housekeeping):
            body: Any = {f: _json(getattr(p.report, f)) for f in ZERO_TIME_HK_FIELDS}
        elif p.report is not None:
            body = {"type": type(p.report).__name__, **p.report.model_dump(mode="json")}
        else:
            body = {"undecoded": p.raw.hex()}
        tm.append([header, body])
    truth = [[t.t_s, list(t.q), t.pointing_error_rad, t.frame_id] for t in run.truth]
    return dict(replies=replies, tm=tm, truth=truth, tc=tc, frames=run.frames)


def _json(value: Any) -> Any:
    """A value as JSON would hold it (tuples as lists, enumerations by value)."""
    return json.loads(json.dumps(value, default=lambda v: getattr(v, "value", str(v))))


def differences(got: Any, want: Any, path: str = "", rtol: float = 1e-6, atol: float = 1e-12,
                limit: int = 10) -> list[str]:
    """Where two records differ (at most ``limit``): a path and both values; floats within ``rtol`` or ``atol``."""
    out: list[str] = []

    def walk(a: Any, b: Any, at: str) -> None:
        if len(out) >= limit:
            return
        if isinstance(a, float) or isinstance(b, float):
            if isinstance(a, (int, float)) and isinstance(b, (int, float)) and not isinstance(a, bool) \
                    and (a == b or math.isclose(a, b, rel_tol=rtol, abs_tol=atol) or math.isnan(a) and math.isnan(b)):
                return
            out.append(f"{at}: {a!r} != {b!r}")
        elif isinstance(a, dict) and isinstance(b, dict):
            if a.keys() != b.keys():
                out.append(f"{at}: keys {sorted(a)} != {sorted(b)}")
                return
            for k in a:
                walk(a[k], b[k], f"{at}.{k}")
        elif isinstance(a, list) and isinstance(b, list):
            if len(a) != len(b):
                out.append(f"{at}: {len(a)} items != {len(b)}")
            for i, (x, y) in enumerate(zip(a, b)):
                walk(x, y, f"{at}[{i}]")
        elif a != b:
            out.append(f"{at}: {a!r} != {b!r}")

    walk(got, want, path)
    return out


def save_record(record: dict[str, Any], path: Path) -> None:
    """Write a record, gzipped JSON (floats kept exactly: JSON writes the shortest repr that reads back)."""
    path.write_bytes(gzip.compress(json.dumps(record, separators=(",", ":")).encode(), mtime=0))


def load_record(path: Path) -> dict[str, Any]:
    """Read a record written by ``save_record``."""
    return json.loads(gzip.decompress(path.read_bytes()))


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
