"""Operator requests to a running ground segment (``flyby ground``): a single command, a timeline, a trajectory.

Pure: each request becomes the telecommands ground will radiate at its next step, or an ``OperatorError``
naming what was wrong, so nothing reaches the spacecraft that ground itself would refuse.
"""

from __future__ import annotations

from typing import Any

from pydantic import Field, ValidationError

from contracts import pus
from contracts.errors import FlybyError
from contracts.textfile import TextFileError, decode_text, load_yaml
from contracts.model import Frozen
from ground.config import FlybyBelief
from ground.segment import GroundSegment
from ground.uplink import UplinkError, telecommand_of
from timeline.convert import utc_seconds
from timeline.model import CommandError, TimelineError, default_registry
from timeline.parse import timeline_from_csv_text, timeline_from_yaml_text


class OperatorError(FlybyError):
    """An operator request ground refuses; the message says why."""


class TrajectoryUpload(Frozen):
    """A trajectory file: the new C/A (UTC or s from the epoch) and distance; other fields keep ground's values."""

    ca_time_utc: str | None = Field(None, description="UTC of C/A, ISO 8601 with its zone")
    ca_time_s: float | None = Field(None, description="C/A time, s after the scenario epoch")
    ca_distance_km: float = Field(gt=0, description="C/A distance, km")
    ca_time_sigma_s: float | None = Field(None, ge=0, description="one-sigma of the C/A time, s")
    ca_distance_sigma_km: float | None = Field(None, ge=0, description="one-sigma of the C/A distance, km")


def _yaml(payload: bytes, what: str) -> Any:
    try:
        return load_yaml(decode_text(payload))
    except TextFileError as exc:
        raise OperatorError(f"{what}: {exc}") from None


def _request_ids(args: dict[str, Any], apid: int, required: bool) -> tuple[pus.RequestId, ...] | None:
    ids = args.get("request_ids")
    if ids is None:
        if required:
            raise OperatorError("request_ids: required (the sequence counts of the scheduled telecommands)")
        return None
    if not isinstance(ids, list) or not ids or not all(isinstance(i, int) and 0 <= i <= pus.MAX_SEQ_COUNT for i in ids):
        raise OperatorError(f"request_ids: must be a non-empty list of sequence counts 0..{pus.MAX_SEQ_COUNT}, "
                            f"got {ids!r}")
    return tuple(pus.RequestId(apid=apid, seq_count=i) for i in ids)


def _schedule_command(name: str, args: dict[str, Any], apid: int) -> pus.TcCommand:
    """PUS 11 and 17 requests that act on the on-board schedule or link, not on the timeline dictionary."""
    known = {"schedule_time_shift": {"delta_s", "request_ids"}, "schedule_delete": {"request_ids"},
             "schedule_report": {"detail", "request_ids"}, "ping": set()}
    extra = set(args) - known[name]
    if extra:
        raise OperatorError(f"command '{name}': unknown argument(s) {sorted(extra)} (known: {sorted(known[name])})")
    if name == "ping":
        return pus.Ping()
    if name == "schedule_delete":
        return pus.DeleteActivities(request_ids=_request_ids(args, apid, required=True))
    if name == "schedule_time_shift":
        delta = args.get("delta_s")
        if not isinstance(delta, int | float) or isinstance(delta, bool):
            raise OperatorError(f"command 'schedule_time_shift': delta_s must be a number of seconds, got {delta!r}")
        return pus.TimeShiftActivities(delta_s=float(delta), request_ids=_request_ids(args, apid, required=False))
    ids = _request_ids(args, apid, required=False)
    return pus.DetailReportRequest(request_ids=ids) if args.get("detail") else pus.SummaryReportRequest(request_ids=ids)


SCHEDULE_COMMANDS = ("schedule_time_shift", "schedule_delete", "schedule_report", "ping")


def command_request(payload: bytes, apid: int = 0x0C1) -> pus.TcCommand:
    """A single command ``{command: NAME, args: {...}}``: one of the timeline dictionary, checked against the
    registry, or a schedule/link request (``SCHEDULE_COMMANDS``) addressed to ``apid``."""
    data = _yaml(payload, "command")
    if not isinstance(data, dict) or "command" not in data:
        raise OperatorError("command: expected a mapping with 'command' and optional 'args'")
    extra = set(data) - {"command", "args"}
    if extra:
        raise OperatorError(f"command: unknown field(s) {sorted(extra)}")
    name, args = str(data["command"]), data.get("args") or {}
    if not isinstance(args, dict):
        raise OperatorError(f"command '{name}': args must be a mapping of argument names")
    if name in SCHEDULE_COMMANDS:
        return _schedule_command(name, args, apid)
    try:
        cmd = default_registry().command(name, args)
        return telecommand_of(cmd)
    except CommandError as exc:
        raise OperatorError(str(exc)) from None
    except UplinkError as exc:
        raise OperatorError(str(exc)) from None


def believed_trajectory(payload: bytes, belief: FlybyBelief, epoch_utc: str) -> FlybyBelief:
    """Ground's belief of the flyby with a trajectory file's C/A time, distance and sigmas (the rest kept)."""
    data = _yaml(payload, "trajectory")
    try:
        t = TrajectoryUpload.model_validate(data)
    except ValidationError as exc:
        e = exc.errors()[0]
        raise OperatorError(f"trajectory: {'.'.join(map(str, e['loc']))}: {e['msg']}") from None
    if (t.ca_time_utc is None) == (t.ca_time_s is None):
        raise OperatorError("trajectory: give exactly one of ca_time_utc and ca_time_s")
    if t.ca_time_utc is not None:
        from datetime import datetime

        try:
            ca_s = utc_seconds(datetime.fromisoformat(t.ca_time_utc.replace("Z", "+00:00")), epoch_utc)
        except (ValueError, TypeError) as exc:
            raise OperatorError(f"trajectory: ca_time_utc: {exc}") from None
    else:
        ca_s = float(t.ca_time_s)  # type: ignore[arg-type]
    update: dict[str, Any] = {"ca_utc_s": ca_s, "ca_distance_km": t.ca_distance_km}
    if t.ca_time_sigma_s is not None:
        update["ca_time_sigma_s"] = t.ca_time_sigma_s
    if t.ca_distance_sigma_km is not None:
        update["ca_distance_sigma_km"] = t.ca_distance_sigma_km
    return belief.model_copy(update=update)


def trajectory_request(payload: bytes, segment: GroundSegment) -> pus.UploadNominalTrajectory:
    """A new nominal trajectory, its C/A time turned into OBT with ground's current correlation."""
    b = believed_trajectory(payload, segment.belief, segment.epoch_utc)
    base = segment.nominal_trajectory_tc()
    update: dict[str, Any] = {"ca_obt_s": segment.correlation.to_obt(b.ca_utc_s), "ca_distance_km": b.ca_distance_km,
                              "sigma_ca_time_s": b.ca_time_sigma_s, "sigma_ca_distance_km": b.ca_distance_sigma_km}
    return pus.UploadNominalTrajectory.model_validate({**base.model_dump(), **update})


def timeline_request(payload: bytes, name: str, segment: GroundSegment,
                     utc_s: float) -> tuple[list[pus.InsertActivities | pus.InsertCaRelativeActivities], list[str]]:
    """A timeline file (YAML, or CSV when ``name`` ends in .csv) as schedule inserts, tags in OBT, and the
    commands refused because they would arrive too late."""
    try:
        text = payload.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise OperatorError(f"{name or 'timeline'}: not UTF-8 text: {exc}") from None
    try:
        if name.lower().endswith(".csv"):
            timeline = timeline_from_csv_text(text, name)
        else:
            timeline = timeline_from_yaml_text(text, name or "<timeline>")
    except TimelineError as exc:
        raise OperatorError("; ".join(exc.problems)) from None
    log: list[str] = []
    inserts = segment.timeline_upload(utc_s, segment.nominal_trajectory_tc(), log, timeline)
    if not inserts:
        raise OperatorError("timeline: " + ("; ".join(log) or "no command left to upload"))
    return inserts, log
