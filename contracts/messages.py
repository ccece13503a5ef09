"""Messages between the nodes: one definition each, with a version field.

A message travels as ``[u32 header length][header JSON][blob]``: the header is the pydantic model as JSON,
the blob carries bulk data (camera pixels) untouched, so a 2 MB frame is never base64-encoded.
A receiver that cannot decode a message gets a ``DecodeError`` naming the message type and what was wrong.
"""

from __future__ import annotations

import struct
from typing import Literal, TypeVar

from pydantic import ConfigDict, Field, ValidationError

from contracts.errors import DecodeError
from contracts.model import Frozen

BUS_VERSION = 1
_HEADER = struct.Struct(">I")


class Message(Frozen):
    """Base of every bus message; bytes fields travel as base64 inside the JSON header."""

    model_config = ConfigDict(frozen=True, extra="forbid", ser_json_bytes="base64", val_json_bytes="base64")
    version: Literal[1] = BUS_VERSION


class SensorData(Frozen):
    """Sensor readings of one control period, as the on-board hardware sees them."""

    star_tracker_q: tuple[float, float, float, float] | None = Field(
        description="attitude body->inertial, scalar-last; None during an outage"
    )
    gyro_rad_s: tuple[float, float, float]
    wheel_speed_rad_s: tuple[float, ...]


class CentroidMeasurement(Frozen):
    """Centroid-level fidelity: what the imaging chain would report of a frame, sent instead of its pixels.

    Positions are (col, row) at the camera's full resolution, pixel centres at integer coordinates (the on-board
    software bins them as it bins pixels); None where the chain would not report the body.
    """

    dimorphos_col_row: tuple[float, float] | None = Field(description="Dimorphos centroid, full-resolution px")
    dimorphos_area_px: float = Field(ge=0, description="lit area of Dimorphos, full-resolution px (0: not reported)")
    didymos_col_row: tuple[float, float] | None = Field(description="Didymos centroid, full-resolution px")
    didymos_area_px: float = Field(ge=0, description="lit area of Didymos, full-resolution px (0: not reported)")


class FrameMeta(Frozen):
    """Metadata of a camera frame whose pixels travel in the message blob (uint16, row-major); at centroid-level
    fidelity ``measurement`` replaces the pixels and the blob is empty."""

    frame_id: int = Field(ge=0)
    obt_s: float = Field(description="on-board time of the middle of the exposure, s")
    width: int = Field(gt=0)
    height: int = Field(gt=0)
    bit_depth: int = Field(ge=8, le=16)
    exposure_s: float = Field(gt=0)
    measurement: CentroidMeasurement | None = Field(
        None, description="centroid-level fidelity: the imaging chain's output modelled by the universe, no pixels")


class FrameRequest(Frozen):
    """The OBSW asks for a frame to be exposed at the start of the next control period."""

    exposure_s: float = Field(gt=0)


class StepRequest(Message):
    """Universe -> OBSW: one control period begins; here is what the hardware reads."""

    step: int = Field(ge=0)
    obt_s: float
    sensors: SensorData
    uplink: tuple[bytes, ...] = Field(default=(), description="telecommand packets received this period")
    frame: FrameMeta | None = None
    cpu_slowdown: float = Field(
        1.0, ge=1.0, allow_inf_nan=False, description="hardware reading for the OBSW node's processor model: the "
        "processor runs this many times slower than nominal over this period (1: nominal); flight logic never "
        "reads it"
    )
    imaging_delay_s: float = Field(
        0.0, ge=0.0, allow_inf_nan=False, description="hardware reading for the OBSW node's processor model: extra "
        "delay, s, before this period's frame reaches the processor (the camera interface); flight logic never "
        "reads it"
    )


class StepReply(Message):
    """OBSW -> universe: actuator commands for the period that began with ``step``."""

    step: int = Field(ge=0)
    wheel_torque_nm: tuple[float, ...]
    frame_request: FrameRequest | None = None
    downlink: tuple[bytes, ...] = Field(default=(), description="telemetry packets sent this period")
    clock_adjust_s: float | None = Field(None, description="commanded step of the on-board clock, from next period")
    actuation_delay_s: float = Field(
        0.0, ge=0.0, allow_inf_nan=False, description="the wheels take the new torques this long after the start of "
        "the period (the control task's modelled finish), s; the previous torques act until then"
    )


class TruthRecord(Frozen):
    """Simulation truth at one control period, sent to ground for the report (never to the OBSW)."""

    t_s: float
    obt_s: float
    q: tuple[float, float, float, float]
    omega_rad_s: tuple[float, float, float]
    wheel_momentum_nms: tuple[float, ...]
    wheel_torque_nm: tuple[float, ...]
    pointing_error_rad: float
    target_in_fov: bool
    range_m: float
    theta_rad: float
    phase_angle_deg: float
    los_dimorphos_inertial: tuple[float, float, float] | None = Field(None, description="unit LOS to Dimorphos")
    los_didymos_inertial: tuple[float, float, float] | None = Field(None, description="unit LOS to Didymos")
    dimorphos_camera: tuple[float, float, float] | None = Field(
        None, description="unit vector to Dimorphos in camera axes (x columns, y rows, z boresight)"
    )
    range_didymos_m: float | None = Field(None, description="range to the Didymos centre, m")
    frame_id: int | None = Field(None, description="camera frame exposed at this period, if any")
    dimorphos_px: tuple[float, float] | None = Field(None, description="true (col, row) of Dimorphos in that frame")
    didymos_px: tuple[float, float] | None = Field(None, description="true (col, row) of Didymos in that frame")


class GroundStep(Message):
    """Universe -> ground: UTC has advanced; here is the telemetry the antenna received."""

    step: int = Field(ge=0)
    utc_s: float = Field(description="true time, s after the scenario epoch")
    downlink: tuple[bytes, ...] = ()
    downlink_utc_s: tuple[float, ...] = Field(default=(), description="arrival time of each downlink packet, s")
    truth: tuple[TruthRecord, ...] = ()


class GroundReply(Message):
    """Ground -> universe: telecommands radiated during this ground step."""

    step: int = Field(ge=0)
    uplink: tuple[bytes, ...] = ()


class Status(Message):
    """Progress of a node, for people watching a run."""

    node: str
    sim_time_s: float
    real_time_factor: float | None = None
    mode: str | None = None
    text: str = ""


class Shutdown(Message):
    """A node is stopping the run; ``failed`` says whether it ended in error."""

    node: str
    reason: str
    sim_time_s: float | None = None
    failed: bool = False


class OperatorCommand(Message):
    """An operator's request to the ground node (``flyby ground``)."""

    request: int = Field(ge=0, description="the operator's request number, echoed in the reply")
    action: Literal["send", "upload_trajectory", "upload_timeline"]
    payload: bytes = Field(description="YAML: a command {command, args}, a trajectory, or a timeline file's content")
    name: str = Field("", description="file name of an upload (its suffix tells YAML from CSV)")


class OperatorReply(Message):
    """Ground's answer to an operator request: accepted for uplink, or refused with the reason."""

    request: int = Field(ge=0)
    ok: bool
    text: str


class TmLine(Message):
    """One received telemetry packet of interest (housekeeping, event, verification), as a line for people."""

    utc_s: float
    obt_s: float
    kind: str
    text: str


M = TypeVar("M", bound=Message)


def encode(msg: Message, blob: bytes = b"") -> bytes:
    """Serialise a message and its optional blob."""
    header = msg.model_dump_json().encode()
    return _HEADER.pack(len(header)) + header + blob


def decode(kind: type[M], data: bytes) -> tuple[M, bytes]:
    """Parse bytes into a message of type ``kind`` and its blob, or raise DecodeError."""
    if len(data) < _HEADER.size:
        raise DecodeError(f"{kind.__name__}: {len(data)} bytes is shorter than the {_HEADER.size}-byte header")
    (n,) = _HEADER.unpack_from(data)
    if _HEADER.size + n > len(data):
        raise DecodeError(f"{kind.__name__}: header says {n} bytes but only {len(data) - _HEADER.size} follow")
    try:
        msg = kind.model_validate_json(data[_HEADER.size : _HEADER.size + n])
    except ValidationError as exc:
        first = exc.errors()[0]
        where = ".".join(str(p) for p in first["loc"]) or "(message)"
        raise DecodeError(f"{kind.__name__}: {where}: {first['msg']} ({exc.error_count()} error(s))") from None
    return msg, data[_HEADER.size + n :]
