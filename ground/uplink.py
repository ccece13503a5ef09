"""Turning a validated timeline into PUS telecommands: each command becomes its TC, wrapped in one
service 11 insert with its release OBT (and its C/A offset, so the spacecraft can re-anchor it on board)."""

from __future__ import annotations

from collections.abc import Callable

from contracts import pus
from timeline.convert import ResolvedCommand
from timeline.model import Command


class UplinkError(ValueError):
    """A timeline command has no telecommand (a registry entry without a PUS mapping)."""


def telecommand_of(command: Command, nominal: pus.UploadNominalTrajectory | None = None) -> pus.TcCommand:
    """The telecommand that carries out one timeline command."""
    a = command.args
    match command.name:
        case "set_mode":
            return pus.SetMode(mode=pus.Mode[str(a["mode"])])
        case "start_imaging":
            return pus.StartImaging(period_s=a.get("period_s"))
        case "stop_imaging":
            return pus.StopImaging()
        case "set_camera_cadence":
            return pus.SetCameraCadence(period_s=a["period_s"], exposure_s=a["exposure_s"])
        case "adjust_obt":
            return pus.AdjustObt(delta_s=a["delta_s"])
        case "report_time":
            return pus.RequestTimeReports(count=a.get("count", 1))
        case "upload_nominal_trajectory":
            if nominal is None:
                raise UplinkError("upload_nominal_trajectory: ground has no nominal trajectory to complete it from")
            return nominal.model_copy(update={"ca_obt_s": a["ca_obt_s"], "ca_distance_km": a["ca_distance_km"]})
    raise UplinkError(f"timeline command '{command.name}' has no telecommand mapping")


def schedule_insert(resolved: list[ResolvedCommand], apid: int, next_seq: Callable[[], int],
                    nominal: pus.UploadNominalTrajectory | None = None) -> pus.InsertActivities:
    """One TC[11,4] inserting every resolved command, each as a complete TC with its own sequence count."""
    activities = tuple(
        pus.ScheduledActivity(release_obt_s=r.obt_s, ca_offset_s=r.ca_offset_s,
                              tc_packet=pus.encode_tc(telecommand_of(r.command, nominal=nominal), apid, next_seq()))
        for r in resolved
    )
    return pus.InsertActivities(activities=activities)
