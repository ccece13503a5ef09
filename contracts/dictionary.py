"""The mission's TM/TC dictionary: every packet, once, with its fields in wire order.

Each declaration gives the packet's kind (``Telecommand`` or ``Report``), PUS service and subtype(s), name and
description (the docstring), its fields with wire type (the annotation, ``contracts.wire``), unit, range and
description (``field``), and for a telecommand the timeline command that sends it. Everything else is derived from
here: the codec (``contracts.packet``, framed by ``contracts.pus``), the registries (``DICTIONARY``), the timeline
commands and their argument models, ground's uplink, the on-board dispatch, the test strategies, the Markdown
table and the XTCE export (``flyby dictionary``).

Mission choices that are not a flat table: a verification report's subtype is its stage (+1 on failure) and only
a failure carries a code and a reason; an event report's subtype is its severity and its first u16 the event id;
the selected/all pairs of service 11 (7/15, 9/16, 12/17) differ by the request ids alone. TC[11,4] has the layout
of ECSS-E-ST-70-41C (N, then N times a release time and a complete TC packet; no sub-schedule or group ids, and N
is a u16 as the mission chooses); an activity that follows the on-board C/A estimate travels in the mission
subservice TC[200,8], which adds its offset from closest approach so the OBSW can re-anchor it when a new C/A
estimate is accepted. The filter-based subtypes of service 11 (6, 8, 11, 14) are not implemented: ground always
names activities by request id. A time shift is an IEEE float64 in seconds (exact, unlike a CUC relative time on
the 2^-16 s grid). A radiated TC travels inside a security envelope (``contracts.sdls``) that is no part of the
packet.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Iterable
from enum import IntEnum
from typing import Annotated, Any, ClassVar

from pydantic import AfterValidator, model_validator

from contracts.mode import Mode  # noqa: F401  (re-exported: the packets' mode field)
from contracts.model import named_enum
from contracts.packet import (
    Constant,
    Count,
    Packet,
    Record,
    Report,
    Telecommand,
    TimelineCommand,
    Validity,
    declared,
    field,
)
from contracts.packet_errors import MAX_APID, MAX_SEQ_COUNT, PacketError, RequestId
from contracts.task import TASK_COUNT, Task
from contracts.wire import (
    F32,
    F64,
    MAX_TEXT_OCTETS,
    PRIMARY_HEADER_LEN,
    U8,
    U16,
    U32,
    UINT16,
    UINT8,
    EnumCode,
    EmbeddedPacket,
    Finite,
    OctetString,
    Mode8,
    ObtS,
    Rid,
    Task8,
    Text,
    UnitVector,
    packet_len,
)

SERVICE_NAMES = {1: "request verification", 3: "housekeeping", 5: "event reporting", 9: "time management",
                 11: "time-based scheduling", 12: "on-board monitoring", 17: "test", 19: "event-action",
                 200: "mission: flyby navigation"}
"""The PUS services of the mission (ECSS-E-ST-70-41C names; 200 is the mission's own)."""
HK_SID = 1
HK_WHEEL_SLOTS = 4
MISSION_SERVICE = 200
TC_SECONDARY_HEADER_LEN = 5
WRAPPED_KEY_LEN = 40  # a 256-bit key wrapped by AES key wrap (RFC 3394): 8 octets longer
CRC_LEN = 2
MAX_LIST = 0xFFFF
UNIT_TOLERANCE = 1e-9
ORTHOGONAL_TOLERANCE = 1e-6


class AckFlag(IntEnum):
    """The acknowledgement flags of a TC secondary header (ECSS-E-ST-70-41C: bit 3, the lowest, asks for the
    acceptance success report, bit 2 for start, bit 1 for progress, bit 0, the highest, for completion)."""

    ACCEPTANCE = 0b0001
    START = 0b0010
    PROGRESS = 0b0100
    COMPLETION = 0b1000


ALL_ACKS = 0b1111


class TimeReferenceStatus(IntEnum):
    """The 4-bit spacecraft time reference status of a TM secondary header, as this mission defines it."""

    UNKNOWN = 0  # never sent by this OBSW: the value of a field left unset
    FREE_RUNNING = 1  # OBT counts the on-board oscillator, continuous with the previous control period
    STEPPED = 2  # OBT stepped (a commanded adjustment or a detected jump) at this control period


class Severity(IntEnum):
    """Event severity, which is also the service 5 subtype."""

    INFO = 1
    LOW = 2
    MEDIUM = 3
    HIGH = 4


class Stage(IntEnum):
    """Verification stage; the value is the service 1 success subtype, failure is value + 1."""

    ACCEPTANCE = 1
    START = 3
    COMPLETION = 7


class EventId(IntEnum):
    """Event identifiers of service 5 (the u16 that opens an event report)."""

    MODE_CHANGED = 1
    TARGET_ACQUIRED = 2
    TARGET_LOST = 3
    WHEEL_SATURATION = 4
    FAULT = 5
    COMMAND_REJECTED = 6
    CLOCK_JUMP = 7
    SECURITY_REJECTION = 8
    TASK_OVERRUN = 9
    FRAME_OVERRUN = 10
    PARAMETER_CHECK = 11
    WHEEL_FAILED = 12
    WHEEL_SET = 13
    STAR_TRACKER = 14
    FRAME_ANOMALY = 15
    FALSE_LOCK = 16
    UPLINK_GAP = 17
    LATE_RELEASE = 18
    TIME_SHIFTED = 19


class Parameter(IntEnum):
    """The on-board parameters that service 12 can monitor, each a housekeeping value (norms of vectors)."""

    MODE = 1  # mode code
    BODY_RATE = 2  # |estimated body rate|, rad/s
    WHEEL_MOMENTUM_0 = 3  # wheel angular momentum, N m s
    WHEEL_MOMENTUM_1 = 4
    WHEEL_MOMENTUM_2 = 5
    WHEEL_MOMENTUM_3 = 6
    WHEEL_SPEED_0 = 7  # wheel speed, rad/s
    WHEEL_SPEED_1 = 8
    WHEEL_SPEED_2 = 9
    WHEEL_SPEED_3 = 10
    GYRO_BIAS = 11  # |estimated gyro bias|, rad/s
    ATTITUDE_SIGMA = 12  # one-sigma attitude uncertainty of the estimator, rad
    POINTING_ERROR = 13  # estimated boresight-to-target angle, rad (not checked while unknown)
    TASK_OVERRUNS = 14  # count
    FRAME_OVERRUNS = 15  # count
    SKIPPED_RELEASES = 16  # count
    TC_REJECTED_AUTH = 17  # count
    FRAMES_DISCARDED = 18  # count
    MEASUREMENTS_REJECTED = 19  # count
    EXPOSURE_TO_CENTROID = 20  # from the exposure of the last frame used to its line of sight on board, s


class CheckType(IntEnum):
    """Service 12 check types (ECSS-E-ST-70-41C: limit, expected-value and delta checks)."""

    LIMIT = 1  # low <= value <= high
    EXPECTED_VALUE = 2  # value == low (high repeats it)
    DELTA = 3  # low <= value - previous sample <= high


class CheckStatus(IntEnum):
    """The checking status of a monitored parameter (ECSS-E-ST-70-41C service 12)."""

    UNCHECKED = 0  # not yet checked, or the parameter has no value
    WITHIN = 1  # within limits, as expected, or within the delta thresholds
    BELOW_LOW = 2  # limit or delta check: below the low limit or threshold
    ABOVE_HIGH = 3  # limit or delta check: above the high limit or threshold
    UNEXPECTED = 4  # expected-value check: another value


class FaultCode(IntEnum):
    """The on-board faults a FaultEvent reports (each sends the spacecraft to SAFE)."""

    WHEELS_CANNOT_CONTROL = 1  # the wheels in use cannot torque an axis the mode's attitude control needs


class FrameAnomaly(IntEnum):
    """What is wrong with a camera frame, as image statistics show it (or a frame that never came)."""

    MISSING = 1  # requested, never delivered
    BLANK = 2  # no light from the scene: nothing above the noise
    SATURATED = 3  # most of the frame at full scale


Parameter16 = Annotated[named_enum(Parameter), EnumCode(Parameter, UINT16)]
CheckType8 = Annotated[named_enum(CheckType), EnumCode(CheckType, UINT8)]
CheckStatus8 = Annotated[named_enum(CheckStatus), EnumCode(CheckStatus, UINT8)]
Severity8 = Annotated[named_enum(Severity), EnumCode(Severity, UINT8)]
EventId16 = Annotated[named_enum(EventId), EnumCode(EventId, UINT16)]
FrameAnomaly8 = Annotated[named_enum(FrameAnomaly), EnumCode(FrameAnomaly, UINT8)]
FaultCode16 = Annotated[named_enum(FaultCode), EnumCode(FaultCode, UINT16)]


# Service 17 ---------------------------------------------------------------------------------------------


class Ping(Telecommand, service=17, subtype=1):
    """Are-you-alive."""


class PingReply(Report, service=17, subtype=2):
    """Are-you-alive connection report."""


# Service 1 ----------------------------------------------------------------------------------------------

_FAILURE = ("failure_code", "reason")


class Verification(Report, service=1, subtypes={1: _FAILURE, 2: (), 3: _FAILURE, 4: (), 7: _FAILURE, 8: ()}):
    """Verification report of one TC at one stage (acceptance, start or completion: subtype 1, 3, 7 on success,
    2, 4, 8 on failure); a failure carries a code and a reason."""

    OFF_WIRE: ClassVar[tuple[str, ...]] = ("stage",)
    stage: Stage = field("acceptance, start or completion (the subtype)")
    request_id: Rid = field("the TC this report is about")
    failure_code: U16 | None = field("service 1 failure code (failure reports only)", default=None)
    reason: Text = field("human-readable failure reason, UTF-8 (failure reports only)", default="")

    @model_validator(mode="after")
    def _reason_only_on_failure(self) -> Verification:
        if self.failure_code is None and self.reason:
            raise ValueError("reason: a success report carries no reason")
        return self

    @property
    def success(self) -> bool:
        """Whether this is a success report."""
        return self.failure_code is None

    def subservice(self) -> int:
        """Success subtype of the stage, +1 for failure."""
        return int(self.stage) + (0 if self.success else 1)

    @classmethod
    def implied(cls, subservice: int) -> dict[str, Any]:
        """The stage is the subtype, rounded down to its success subtype."""
        return {"stage": Stage(subservice - (subservice % 2 == 0))}

    @classmethod
    def failure_for(cls, error: PacketError, stage: Stage = Stage.ACCEPTANCE) -> Verification | None:
        """The failure report answering a TC that raised ``error``; None if its request id could not be read."""
        if error.request_id is None:
            return None
        reason = str(error).encode("utf-8")[:MAX_TEXT_OCTETS].decode("utf-8", errors="ignore")
        return cls(stage=stage, request_id=error.request_id, failure_code=int(error.failure_code), reason=reason)


# Service 3 ----------------------------------------------------------------------------------------------

_NAN = math.nan


_PER_TASK = tuple[(F32,) * TASK_COUNT]  # type: ignore[misc]
_NO_TIMES = (0.0,) * TASK_COUNT
_TASKS = " ".join(t.name for t in Task)


class Housekeeping(Report, service=3, subtype=25):
    """Housekeeping parameter report of the navigation chain; absent values are NaN with their flag cleared."""

    sid: ClassVar[Constant] = Constant(UINT16, HK_SID, "structure id")
    mode: Mode8 = field("current on-board mode")
    flags: ClassVar[Validity] = Validity("validity: bit0 pointing error, bit1 best trajectory, bit2 best-grid MSE, "
                                         "bit3 exposure-to-centroid latency, bit4 centroid-to-torque latency")
    wheel_count: ClassVar[Count] = Count(UINT8, 1, HK_WHEEL_SLOTS, "number of wheels in use")
    q: tuple[F32, F32, F32, F32] = field("estimated attitude body->inertial, scalar-last x y z w")
    rate_rad_s: tuple[F32, F32, F32] = field("estimated body rate, x y z", "rad/s")
    wheel_speed_rad_s: tuple[F32, ...] = field("wheel speeds", "rad/s", slots=HK_WHEEL_SLOTS, min_length=1,
                                               max_length=HK_WHEEL_SLOTS)
    wheel_momentum_nms: tuple[F32, ...] = field("wheel angular momenta", "N m s", slots=HK_WHEEL_SLOTS,
                                                min_length=1, max_length=HK_WHEEL_SLOTS)
    pointing_error_rad: F32 | None = field("estimated boresight-to-target angle", "rad", default=None, bit=0)
    # float64: a float32 would only resolve 256 s at 2^32 s
    best_ca_obt_s: F64 | None = field("C/A time of the best trajectory, OBT", "s", default=None, bit=1)
    best_ca_distance_km: F32 | None = field("C/A distance of the best trajectory", "km", default=None, bit=1)
    best_mse_rad2: F32 | None = field("best-grid mean square line-of-sight error", "rad^2", default=None, bit=2)
    tc_rejected_auth: U16 = field("uplinked TCs refused for a missing or wrong MAC (saturates)", default=0)
    tc_rejected_spi: U16 = field("uplinked TCs refused for an unknown security parameter index (saturates)",
                                 default=0)
    tc_rejected_replay: U16 = field("uplinked TCs refused for an anti-replay sequence number at or below the last "
                                    "accepted one (saturates)", default=0)
    task_time_last_s: _PER_TASK = field("execution time of each task's last run, in task order: " + _TASKS, "s",
                                        default=_NO_TIMES)
    task_time_max_s: _PER_TASK = field("longest execution time of each task since start, in task order: " + _TASKS,
                                       "s", default=_NO_TIMES)
    exposure_to_centroid_s: F32 | None = field("from the exposure of the last frame the control used to its line of "
                                               "sight being available on board", "s", default=None, bit=3)
    centroid_to_torque_s: F32 | None = field("from that line of sight being available to the end of the control "
                                             "task that used it (the torques' update)", "s", default=None, bit=4)
    task_overruns: U32 = field("task runs that finished after their slot's deadline, since start", default=0)
    frame_overruns: U32 = field("minor frames whose work was still running at the next tick, since start",
                                default=0)
    skipped_releases: U32 = field("task releases skipped because the processor was busy past the slot's deadline, "
                                  "since start", default=0)
    gyro_bias_rad_s: tuple[F32, F32, F32] = field("gyro bias estimated by the attitude estimator, body x y z",
                                                   "rad/s", default=(0.0, 0.0, 0.0))
    attitude_sigma_rad: F32 = field("one-sigma attitude uncertainty of the estimator (largest axis)", "rad",
                                    default=0.0, ge=0)
    wheels_in_use: U8 = field("mask of the wheels the control allocates torque to (bit k: wheel k)", default=0)
    wheels_failed: U8 = field("mask of the wheels FDIR has found failed (bit k: wheel k)", default=0)
    frames_discarded: U16 = field("camera frames missing, blank or saturated, since start (saturates)", default=0)
    measurements_rejected: U16 = field("lines of sight refused by the gate against the recognised trajectory, since "
                                       "start (saturates)", default=0)

    @model_validator(mode="after")
    def _consistent(self) -> Housekeeping:
        if len(self.wheel_speed_rad_s) != len(self.wheel_momentum_nms):
            raise ValueError(
                f"wheel_momentum_nms: {len(self.wheel_momentum_nms)} wheels but wheel_speed_rad_s has "
                f"{len(self.wheel_speed_rad_s)}"
            )
        if (self.best_ca_obt_s is None) != (self.best_ca_distance_km is None):
            raise ValueError("best_ca_distance_km: the best trajectory needs both C/A time and distance, or neither")
        return self


# Service 5 ----------------------------------------------------------------------------------------------


def _severity(default: Severity) -> Any:
    """The severity field of an event, with the event's usual severity."""
    return field("event severity (the subtype)", default=default)


class EventReport(Report):
    """Base of the event reports: the subtype is the severity, the first u16 of the data the event id."""

    OFF_WIRE: ClassVar[tuple[str, ...]] = ("severity",)
    EVENT_ID: ClassVar[EventId]
    severity: Severity = field("event severity (the subtype)")
    event_id: ClassVar[Constant] = Constant(UINT16, None, "event identifier")

    @classmethod
    def __pydantic_init_subclass__(cls, **kwargs: Any) -> None:
        super().__pydantic_init_subclass__(service=5, subtypes=tuple(int(s) for s in Severity), **kwargs)

    def subservice(self) -> int:
        """The severity."""
        return int(self.severity)

    @classmethod
    def implied(cls, subservice: int) -> dict[str, Any]:
        """The severity is the subtype."""
        return {"severity": subservice}


class ModeChangedEvent(EventReport):
    """The mode manager made a transition: from, to, and why."""

    EVENT_ID: ClassVar[EventId] = EventId.MODE_CHANGED
    severity: Severity = _severity(Severity.INFO)
    from_mode: Mode8 = field("mode before the transition")
    to_mode: Mode8 = field("mode after the transition")
    cause: Text = field("what triggered the transition (command, event, time)", default="")


class TargetAcquiredEvent(EventReport):
    """The imaging chain found the target: centroid and area in the processed (binned) image."""

    EVENT_ID: ClassVar[EventId] = EventId.TARGET_ACQUIRED
    severity: Severity = _severity(Severity.INFO)
    centroid_x_px: F32 = field("centroid column in the processed image", "px")
    centroid_y_px: F32 = field("centroid row in the processed image", "px")
    area_px: U32 = field("area of the target region", "px")


class TargetLostEvent(EventReport):
    """The target has not been seen for longer than the timeout."""

    EVENT_ID: ClassVar[EventId] = EventId.TARGET_LOST
    severity: Severity = _severity(Severity.MEDIUM)
    unseen_s: F32 = field("time since the target was last seen, OBT", "s", ge=0)


class WheelSaturationEvent(EventReport):
    """A reaction wheel reached its momentum limit."""

    EVENT_ID: ClassVar[EventId] = EventId.WHEEL_SATURATION
    severity: Severity = _severity(Severity.MEDIUM)
    wheel: U8 = field("wheel index")
    momentum_nms: F32 = field("wheel momentum at saturation", "N m s")


class FaultEvent(EventReport):
    """An on-board fault was detected; the spacecraft goes to SAFE."""

    EVENT_ID: ClassVar[EventId] = EventId.FAULT
    severity: Severity = _severity(Severity.HIGH)
    fault_code: FaultCode16 = field("what failed (the fault code)")
    reason: Text = field("what failed", default="")


class ClockJumpEvent(EventReport):
    """On-board time stepped between two control periods by more than the jump threshold."""

    EVENT_ID: ClassVar[EventId] = EventId.CLOCK_JUMP
    severity: Severity = _severity(Severity.MEDIUM)
    step_s: Finite = field("OBT step beyond the control period (negative: backwards)", "s")


class TaskOverrunEvent(EventReport):
    """A task finished after its slot's deadline; raised on the first of a run of overruns of that task (the
    housekeeping counts every one)."""

    EVENT_ID: ClassVar[EventId] = EventId.TASK_OVERRUN
    severity: Severity = _severity(Severity.MEDIUM)
    task: Task8 = field("the task that overran")
    minor_frame: U8 = field("its minor frame in the major frame")
    execution_s: F32 = field("its execution time", "s", ge=0)
    late_s: F32 = field("how long after its deadline it finished", "s", ge=0)


class FrameOverrunEvent(EventReport):
    """The work of a minor frame was still running at the next tick; raised on the first of a run of such frames
    (the housekeeping counts every one)."""

    EVENT_ID: ClassVar[EventId] = EventId.FRAME_OVERRUN
    severity: Severity = _severity(Severity.MEDIUM)
    minor_frame: U8 = field("the minor frame in the major frame")
    late_s: F32 = field("how long after the next tick its work ended", "s", ge=0)


class CommandRejectedEvent(EventReport):
    """A TC was rejected (its service 1 failure report carries the reason text)."""

    EVENT_ID: ClassVar[EventId] = EventId.COMMAND_REJECTED
    severity: Severity = _severity(Severity.LOW)
    request_id: Rid = field("the rejected TC")
    failure_code: U16 = field("service 1 failure code of the rejection")


class TcSecurityRejectedEvent(EventReport):
    """An uplinked TC failed the space data link security check (CCSDS 355.0-B authentication) and was dropped."""

    EVENT_ID: ClassVar[EventId] = EventId.SECURITY_REJECTION
    severity: Severity = _severity(Severity.HIGH)
    spi: U16 = field("security parameter index the TC named (0 when too short to hold one)")
    arsn: U32 = field("anti-replay sequence number the TC carried (0 when too short to hold one)")
    failure_code: U16 = field("service 1 failure code of the rejection")


class ParameterCheckEvent(EventReport):
    """A monitored parameter changed its checking status (service 12 check transition); the severity is the
    monitoring definition's."""

    EVENT_ID: ClassVar[EventId] = EventId.PARAMETER_CHECK
    severity: Severity = _severity(Severity.MEDIUM)
    pmon_id: U16 = field("the parameter monitoring definition")
    parameter: Parameter16 = field("the monitored parameter")
    previous_status: CheckStatus8 = field("checking status before the transition")
    status: CheckStatus8 = field("checking status after the transition")
    value: Finite = field("the parameter's value (its change since the previous sample, for a delta check)")
    limit: Finite = field("the limit, threshold or expected value crossed (the one left, back within)")


class WheelFailedEvent(EventReport):
    """A reaction wheel does not follow its torque commands: its measured momentum change is far from the commanded
    impulse over the detection window (a failed or stuck wheel)."""

    EVENT_ID: ClassVar[EventId] = EventId.WHEEL_FAILED
    severity: Severity = _severity(Severity.HIGH)
    wheel: U8 = field("wheel index")
    commanded_nms: F32 = field("impulse commanded to the wheel over the window", "N m s")
    measured_nms: F32 = field("measured change of the wheel's momentum over the window", "N m s")


class WheelSetEvent(EventReport):
    """The control changed the set of wheels it allocates torque to."""

    EVENT_ID: ClassVar[EventId] = EventId.WHEEL_SET
    severity: Severity = _severity(Severity.MEDIUM)
    wheels_in_use: U8 = field("mask of the wheels now in use (bit k: wheel k)")
    wheels_failed: U8 = field("mask of the wheels FDIR has found failed")
    controllable_axes: U8 = field("body axes the wheels in use can torque (bit 0 x, 1 y, 2 z)")


class StarTrackerEvent(EventReport):
    """The star tracker stopped giving attitudes (outage declared: the attitude is propagated with the gyro and the
    estimated bias), or gave them again."""

    EVENT_ID: ClassVar[EventId] = EventId.STAR_TRACKER
    severity: Severity = _severity(Severity.MEDIUM)
    available: U8 = field("0: outage declared, 1: attitudes again", le=1)
    outage_s: F32 = field("how long the outage has lasted (0 when declared)", "s", ge=0)
    attitude_sigma_rad: F32 = field("one-sigma attitude uncertainty of the estimator now", "rad", ge=0)


class FrameAnomalyEvent(EventReport):
    """A camera frame was missing, blank or saturated and was discarded; raised on the first of a run of such frames
    (the housekeeping counts every one)."""

    EVENT_ID: ClassVar[EventId] = EventId.FRAME_ANOMALY
    severity: Severity = _severity(Severity.MEDIUM)
    anomaly: FrameAnomaly8 = field("what was wrong")
    frame_id: U32 = field("the frame (for a missing one: the last frame received)")
    statistic: F32 = field("what showed it: the saturated fraction, the peak above the background in 8-bit DN, or "
                           "how long the frame is overdue in s")


class FalseLockEvent(EventReport):
    """The imaging chain's Dimorphos is farther from the recognised trajectory's prediction than the gate: a false
    lock (plume, a star, a fragment) is suspected and its lines of sight are refused; raised on the first of a run
    of refusals."""

    EVENT_ID: ClassVar[EventId] = EventId.FALSE_LOCK
    severity: Severity = _severity(Severity.MEDIUM)
    frame_id: U32 = field("the frame")
    offset_rad: F32 = field("angle between the measured and the predicted line of sight", "rad", ge=0)
    gate_rad: F32 = field("the gate it exceeded", "rad", ge=0)


class UplinkGapEvent(EventReport):
    """Uplinked telecommands were lost: the sequence count of the TC received skips counts of the ground's
    sequence."""

    EVENT_ID: ClassVar[EventId] = EventId.UPLINK_GAP
    severity: Severity = _severity(Severity.MEDIUM)
    expected_seq: U16 = field("sequence count expected next")
    received_seq: U16 = field("sequence count received")
    lost: U16 = field("telecommands missing in between")


class LateReleaseEvent(EventReport):
    """A scheduled command was released later than its tag: a C/A-relative command that arrived, or was re-anchored,
    after its time (it is released at once, not dropped)."""

    EVENT_ID: ClassVar[EventId] = EventId.LATE_RELEASE
    severity: Severity = _severity(Severity.LOW)
    request_id: Rid = field("the released TC")
    late_s: F32 = field("release time minus the tag", "s", ge=0)


class TimeShiftedEvent(EventReport):
    """After an on-board time step, everything held in OBT (schedule tags, trajectories, measurements, histories)
    was moved by the step, so the physical times they stand for do not move."""

    EVENT_ID: ClassVar[EventId] = EventId.TIME_SHIFTED
    severity: Severity = _severity(Severity.INFO)
    step_s: Finite = field("the step applied", "s")
    schedule_entries: U16 = field("schedule entries moved")


# Service 9 ----------------------------------------------------------------------------------------------


class SetTimeReportRate(Telecommand, service=9, subtype=1):
    """Set the time report generation rate: one report every 2^rate_exponent s."""

    rate_exponent: U8 = field("one report every 2^n s")


class TimeReport(Report, service=9, subtype=2):
    """CUC time report: the OBT latched at the time reference instant."""

    rate_exponent: U8 = field("current generation rate, one report every 2^n s", default=0)
    obt_s: ObtS = field("on-board time of the report (carried on the 2^-16 s CUC grid)", "s")


# Service 11 ---------------------------------------------------------------------------------------------


def _check_tc_packet(packet: bytes) -> bytes:
    """Accept one complete space packet of type TC (its contents are decoded when it is released)."""
    if len(packet) < PRIMARY_HEADER_LEN + TC_SECONDARY_HEADER_LEN + CRC_LEN:
        raise ValueError(f"{len(packet)} octets is shorter than the smallest PUS TC")
    if not packet[0] & 0x10:
        raise ValueError("is a telemetry packet, a telecommand is needed")
    if packet_len(packet) != len(packet):
        raise ValueError(f"length field says {packet_len(packet)} octets, {len(packet)} given")
    return packet


TcPacket = Annotated[bytes, AfterValidator(_check_tc_packet), EmbeddedPacket()]


def _request_id(packet: bytes) -> RequestId:
    """The request id of a TC packet: APID and sequence count from its first 4 octets."""
    w0, w1 = struct.unpack_from(">HH", packet)
    return RequestId(apid=w0 & MAX_APID, seq_count=w1 & MAX_SEQ_COUNT)


class ScheduledActivity(Record):
    """One entry of the time-based schedule (ECSS-E-ST-70-41C): its release OBT and a complete TC packet."""

    release_obt_s: ObtS = field("release time, OBT (carried on the 2^-16 s CUC grid)", "s")
    tc_packet: TcPacket = field("the complete TC packet")

    @property
    def request_id(self) -> RequestId:
        """The request id of the wrapped TC."""
        return _request_id(self.tc_packet)


class CaRelativeActivity(Record):
    """A schedule entry that follows the on-board C/A estimate: its offset from closest approach, the release OBT
    ground computed (used until the board holds a C/A estimate), and a complete TC packet."""

    ca_offset_s: Finite = field("offset of the release from closest approach", "s")
    release_obt_s: ObtS = field("release time by ground's C/A, OBT (carried on the 2^-16 s CUC grid)", "s")
    tc_packet: TcPacket = field("the complete TC packet")

    @property
    def request_id(self) -> RequestId:
        """The request id of the wrapped TC."""
        return _request_id(self.tc_packet)


class ScheduleSummaryEntry(Record):
    """One line of a schedule summary: release OBT and the request id of the scheduled TC."""

    release_obt_s: ObtS = field("release time, OBT", "s")
    request_id: Rid = field("request id of the scheduled TC")


_IDS = "request ids of the scheduled TCs"


class EnableSchedule(Telecommand, service=11, subtype=1):
    """Enable the release of scheduled activities."""


class DisableSchedule(Telecommand, service=11, subtype=2):
    """Disable the release of scheduled activities (they stay in the schedule)."""


class ResetSchedule(Telecommand, service=11, subtype=3):
    """Delete every scheduled activity and disable the release until TC[11,1] (ECSS-E-ST-70-41C 6.11.4)."""


class InsertActivities(Telecommand, service=11, subtype=4):
    """Insert activities into the time-based schedule."""

    activities: tuple[ScheduledActivity, ...] = field("the activities", min_length=1, max_length=MAX_LIST)


class DeleteActivities(Telecommand, service=11, subtype=5):
    """Delete the activities whose TCs have these request ids."""

    request_ids: tuple[Rid, ...] = field(_IDS, min_length=1, max_length=MAX_LIST)


class TimeShiftActivities(Telecommand, service=11, subtypes={7: (), 15: ("request_ids",)}):
    """Time-shift the named activities (subtype 7), or all of them (15, no request ids)."""

    delta_s: Finite = field("shift added to each release time (negative: earlier)", "s")
    request_ids: tuple[Rid, ...] | None = field(_IDS + " (subtype 7 only)", default=None, min_length=1,
                                               max_length=MAX_LIST)


class DetailReportRequest(Telecommand, service=11, subtypes={9: (), 16: ("request_ids",)}):
    """Detail-report the named activities (subtype 9), or all of them (16, no request ids)."""

    request_ids: tuple[Rid, ...] | None = field(_IDS + " (subtype 9 only)", default=None, min_length=1,
                                               max_length=MAX_LIST)


class SummaryReportRequest(Telecommand, service=11, subtypes={12: (), 17: ("request_ids",)}):
    """Summary-report the named activities (subtype 12), or all of them (17, no request ids)."""

    request_ids: tuple[Rid, ...] | None = field(_IDS + " (subtype 12 only)", default=None, min_length=1,
                                               max_length=MAX_LIST)


class ScheduleDetailReport(Report, service=11, subtype=10):
    """The scheduled activities in full, in release order."""

    activities: tuple[ScheduledActivity, ...] = field("the activities", default=(), max_length=MAX_LIST)


class ScheduleSummaryReport(Report, service=11, subtype=13):
    """Release time and request id of the scheduled activities, in release order."""

    entries: tuple[ScheduleSummaryEntry, ...] = field("the activities", default=(), max_length=MAX_LIST)


# Service 12 ---------------------------------------------------------------------------------------------


class MonitoringDefinition(Record):
    """A parameter monitoring definition (ECSS-E-ST-70-41C service 12): which parameter, which check, its limits,
    how many consecutive samples confirm a new status, and the severity of the event a transition raises."""

    pmon_id: U16 = field("identifier of the definition", ge=1)
    parameter: Parameter16 = field("the monitored parameter")
    check_type: CheckType8 = field("limit, expected-value or delta check")
    repetition: U8 = field("consecutive samples with the same new status that confirm it", ge=1)
    low: Finite = field("low limit, expected value, or low delta threshold (per sample)")
    high: Finite = field("high limit, the expected value again, or high delta threshold (per sample)")
    severity: Severity8 = field("severity of the check transition event")

    @model_validator(mode="after")
    def _limits(self) -> MonitoringDefinition:
        if self.check_type == CheckType.EXPECTED_VALUE and self.high != self.low:
            raise ValueError(f"high: an expected-value check repeats the expected value {self.low!r} in high, got "
                             f"{self.high!r}")
        if self.high < self.low:
            raise ValueError(f"high: {self.high!r} is below low {self.low!r}")
        return self


_PMON_IDS = "identifiers of parameter monitoring definitions"


class EnableParameterMonitoring(Telecommand, service=12, subtype=1):
    """Enable the named parameter monitoring definitions (their checks start again from UNCHECKED)."""

    pmon_ids: tuple[U16, ...] = field(_PMON_IDS, min_length=1, max_length=MAX_LIST)


class DisableParameterMonitoring(Telecommand, service=12, subtype=2):
    """Disable the named parameter monitoring definitions."""

    pmon_ids: tuple[U16, ...] = field(_PMON_IDS, min_length=1, max_length=MAX_LIST)


class AddParameterMonitoringDefinitions(Telecommand, service=12, subtype=5):
    """Add parameter monitoring definitions (enabled); an identifier already defined is refused."""

    definitions: tuple[MonitoringDefinition, ...] = field("the definitions", min_length=1, max_length=MAX_LIST)


class DeleteParameterMonitoringDefinitions(Telecommand, service=12, subtype=6):
    """Delete the named parameter monitoring definitions."""

    pmon_ids: tuple[U16, ...] = field(_PMON_IDS, min_length=1, max_length=MAX_LIST)


class ModifyParameterMonitoringDefinitions(Telecommand, service=12, subtype=7):
    """Replace existing parameter monitoring definitions (same identifiers); their checks start again."""

    definitions: tuple[MonitoringDefinition, ...] = field("the definitions", min_length=1, max_length=MAX_LIST)


# Service 19 ---------------------------------------------------------------------------------------------


class EventActionDefinition(Record):
    """An event-action definition (ECSS-E-ST-70-41C service 19): the telecommand run when an event is reported."""

    event_id: EventId16 = field("the event that triggers the action")
    tc_packet: TcPacket = field("the complete TC packet run as the action")


_EVENT_IDS = "events whose actions are named"


class AddEventActions(Telecommand, service=19, subtype=1):
    """Add event-action definitions (disabled until enabled; one per event)."""

    definitions: tuple[EventActionDefinition, ...] = field("the definitions", min_length=1, max_length=MAX_LIST)


class DeleteEventActions(Telecommand, service=19, subtype=2):
    """Delete the event-action definitions of the named events."""

    event_ids: tuple[EventId16, ...] = field(_EVENT_IDS, min_length=1, max_length=MAX_LIST)


class EnableEventActions(Telecommand, service=19, subtype=4):
    """Enable the event-action definitions of the named events."""

    event_ids: tuple[EventId16, ...] = field(_EVENT_IDS, min_length=1, max_length=MAX_LIST)


class DisableEventActions(Telecommand, service=19, subtype=5):
    """Disable the event-action definitions of the named events."""

    event_ids: tuple[EventId16, ...] = field(_EVENT_IDS, min_length=1, max_length=MAX_LIST)


# Service 200 (mission) ----------------------------------------------------------------------------------


class SetMode(Telecommand, service=MISSION_SERVICE, subtype=1,
              command=TimelineCommand("set_mode", "request an on-board mode")):
    """Request an on-board mode."""

    mode: Mode8 = field("mode to enter")


class UploadNominalTrajectory(
    Telecommand, service=MISSION_SERVICE, subtype=2,
    command=TimelineCommand(
        "upload_nominal_trajectory", "set the nominal C/A the recognition grid is built on",
        ground_fills=("speed_km_s", "approach_direction", "ca_direction", "sigma_ca_time_s", "sigma_ca_distance_km"),
    ),
):
    """The nominal flyby the recognition grid is built around."""

    ca_obt_s: Finite = field("nominal closest approach time, OBT", "s", ge=0)
    ca_distance_km: Finite = field("nominal distance at closest approach", "km", gt=0)
    speed_km_s: Finite = field("relative speed", "km/s", gt=0)
    approach_direction: UnitVector = field("unit vector of the relative velocity, inertial frame")
    ca_direction: UnitVector = field("unit vector target -> spacecraft at closest approach, inertial frame")
    sigma_ca_time_s: Finite = field("one-sigma uncertainty of the C/A time", "s", ge=0)
    sigma_ca_distance_km: Finite = field("one-sigma uncertainty of the C/A distance", "km", ge=0)

    @model_validator(mode="after")
    def _geometry(self) -> UploadNominalTrajectory:
        for name in ("approach_direction", "ca_direction"):
            v = getattr(self, name)
            norm = math.sqrt(sum(c * c for c in v))
            if abs(norm - 1.0) > UNIT_TOLERANCE:
                raise ValueError(f"{name}: norm {norm!r} is not 1 within {UNIT_TOLERANCE:g}")
        dot = sum(a * b for a, b in zip(self.approach_direction, self.ca_direction, strict=True))
        if abs(dot) > ORTHOGONAL_TOLERANCE:
            raise ValueError(
                f"ca_direction: must be perpendicular to approach_direction at closest approach, dot = {dot:.3g}"
            )
        return self


class SetCameraCadence(Telecommand, service=MISSION_SERVICE, subtype=3,
                       command=TimelineCommand("set_camera_cadence", "change frame period and exposure")):
    """Change the frame period and exposure."""

    period_s: Finite = field("time between frames, OBT", "s", gt=0)
    exposure_s: Finite = field("exposure time", "s", gt=0)

    @model_validator(mode="after")
    def _exposure_fits(self) -> SetCameraCadence:
        if self.exposure_s > self.period_s:
            raise ValueError(f"exposure_s ({self.exposure_s:g} s) must not exceed period_s ({self.period_s:g} s)")
        return self


class StartImaging(Telecommand, service=MISSION_SERVICE, subtype=4,
                   command=TimelineCommand("start_imaging", "start taking frames at a fixed period")):
    """Start taking frames, at ``period_s`` or at the current cadence when it is absent."""

    flags: ClassVar[Validity] = Validity("bit0: period_s present")
    period_s: Finite | None = field("time between frames, OBT", "s", default=None, gt=0, bit=0)


class StopImaging(Telecommand, service=MISSION_SERVICE, subtype=5,
                  command=TimelineCommand("stop_imaging", "stop taking frames")):
    """Stop taking frames."""


class RequestTimeReports(
    Telecommand, service=MISSION_SERVICE, subtype=6,
    command=TimelineCommand("report_time", "send PUS 9 time reports for ground time correlation",
                            defaults=(("count", 1),)),
):
    """Send ``count`` service 9 time reports, one per second, for ground time correlation."""

    count: U16 = field("number of time reports", ge=1)


class AdjustObt(Telecommand, service=MISSION_SERVICE, subtype=7,
                command=TimelineCommand("adjust_obt", "step the on-board clock (a commanded time correction)")):
    """Step the on-board clock by ``delta_s`` (a commanded time correction; reported as a clock jump)."""

    delta_s: Finite = field("OBT step (negative: backwards)", "s", ge=-86400.0, le=86400.0)


class InsertCaRelativeActivities(Telecommand, service=MISSION_SERVICE, subtype=8):
    """Insert activities that follow the on-board C/A estimate into the time-based schedule (the mission's
    extension of TC[11,4]: each entry adds its offset from closest approach)."""

    activities: tuple[CaRelativeActivity, ...] = field("the activities", min_length=1, max_length=MAX_LIST)


class RekeySecurityAssociation(Telecommand, service=MISSION_SERVICE, subtype=9):
    """Load a new TC authentication key (CCSDS 355.0-B over-the-air rekeying): a new security association, its key
    wrapped (AES key wrap, RFC 3394) under a key derived from the association that authenticates this TC. The board
    accepts both until the first TC under the new one, then retires the old one."""

    spi: U16 = field("security parameter index of the new association", ge=1)
    wrapped_key: Annotated[bytes, OctetString(WRAPPED_KEY_LEN)] = field(
        "the new 256-bit key, wrapped", min_length=WRAPPED_KEY_LEN, max_length=WRAPPED_KEY_LEN)


class BadPixel(Record):
    """One pixel of the camera's bad-pixel map, at full resolution."""

    col: U16 = field("column", "px")
    row: U16 = field("row", "px")


class LoadBadPixelMap(Telecommand, service=MISSION_SERVICE, subtype=10):
    """Replace the on-board map of the camera's bad pixels with ground's calibration (hot and warm pixels of dark
    frames, dead pixels and columns of flat fields): before binning, the imaging chain replaces each listed pixel,
    and every pixel of each listed column, by the mean of its nearest good neighbours in its row. Refused when a
    pixel or a column is outside the camera's frame; an empty map clears it."""

    columns: tuple[U16, ...] = field("dead columns", default=(), max_length=MAX_LIST)
    pixels: tuple[BadPixel, ...] = field("bad pixels (column, row)", default=(), max_length=MAX_LIST)


class SetWheelSet(Telecommand, service=MISSION_SERVICE, subtype=11,
                  command=TimelineCommand("set_wheel_set", "choose the reaction wheels the control uses")):
    """Choose the reaction wheels the control allocates torque to: a mask (bit k: wheel k), or 0 for every wheel FDIR
    has not found failed. If the mode's attitude control needs an axis the set cannot torque, the spacecraft goes to
    SAFE."""

    wheels: U8 = field("mask of the wheels to use (bit k: wheel k); 0: every wheel not found failed", le=0x0F)


class NavigationReport(Report, service=MISSION_SERVICE, subtype=130):
    """What the imaging chain made of one frame: centroids (binned px), area, measured line of sight; absent values
    are 0 with their flag cleared."""

    frame_id: U32 = field("frame counter")
    flags: ClassVar[Validity] = Validity("validity: bit0 Dimorphos centroid, bit1 Didymos centroid, bit2 line of "
                                         "sight", fill=0.0)
    dimorphos_col_row: tuple[F32, F32] | None = field("Dimorphos centroid, column row", "binned px", default=None,
                                                      bit=0)
    didymos_col_row: tuple[F32, F32] | None = field("Didymos centroid, column row", "binned px", default=None, bit=1)
    dimorphos_area_px: U32 = field("Dimorphos area", "binned px", default=0)
    los_inertial: UnitVector | None = field("measured line of sight to Dimorphos, inertial (without a Dimorphos "
                                            "centroid: Didymos's, standing in for it)", default=None, bit=2)


class EstimateReport(Report, service=MISSION_SERVICE, subtype=131):
    """The on-board C/A estimates: best grid candidate and the continuous (least-squares) estimate; absent values
    are NaN with their flag cleared."""

    n_measurements: U32 = field("line-of-sight measurements used")
    flags: ClassVar[Validity] = Validity("validity: bit0 grid estimate, bit1 continuous estimate, bit2 its "
                                         "line-of-sight offsets")
    grid_ca_obt_s: Finite | None = field("grid C/A time, OBT", "s", default=None, bit=0)
    grid_ca_distance_km: Finite | None = field("grid C/A distance", "km", default=None, bit=0)
    grid_mse_rad2: Finite | None = field("grid mean square line-of-sight error", "rad^2", default=None, bit=0)
    continuous_ca_obt_s: Finite | None = field("continuous C/A time, OBT", "s", default=None, bit=1)
    continuous_ca_distance_km: Finite | None = field("continuous C/A distance", "km", default=None, bit=1)
    continuous_sigma_time_s: Finite | None = field("one-sigma of the continuous C/A time", "s", default=None, bit=1)
    continuous_sigma_distance_km: Finite | None = field("one-sigma of the continuous C/A distance", "km",
                                                        default=None, bit=1)
    los_offset_in_plane_rad: Finite | None = field(
        "constant offset of the measured line of sight in the flyby plane (a misaligned camera's)", "rad", default=None,
        bit=2)
    los_offset_out_of_plane_rad: Finite | None = field(
        "constant offset of the measured line of sight out of the flyby plane", "rad", default=None, bit=2)

    @model_validator(mode="after")
    def _complete(self) -> EstimateReport:
        grid = (self.grid_ca_obt_s, self.grid_ca_distance_km, self.grid_mse_rad2)
        cont = (self.continuous_ca_obt_s, self.continuous_ca_distance_km, self.continuous_sigma_time_s,
                self.continuous_sigma_distance_km)
        offsets = (self.los_offset_in_plane_rad, self.los_offset_out_of_plane_rad)
        for name, group in (("grid_ca_obt_s", grid), ("continuous_ca_obt_s", cont),
                            ("los_offset_in_plane_rad", offsets)):
            if any(v is None for v in group) and any(v is not None for v in group):
                raise ValueError(f"{name}: an estimate needs all of its values, or none")
        return self


# ---------------------------------------------------------------------------------------------- registries


class Dictionary:
    """The declared packets and the look-ups derived from them."""

    def __init__(self, packets: Iterable[type[Packet]]) -> None:
        self.packets = tuple(packets)
        self.by_name = {p.__name__: p for p in self.packets}
        self.telecommands = {(p.SERVICE, s): p for p in self.packets if p.KIND == "TC" for s in p.SUBTYPES}
        self.reports = {(p.SERVICE, s): p for p in self.packets
                        if p.KIND == "TM" and not issubclass(p, EventReport) for s in p.SUBTYPES}
        self.events = {int(p.EVENT_ID): p for p in self.packets if issubclass(p, EventReport)}
        self.commands = {p.COMMAND.name: p for p in self.packets if p.COMMAND is not None}
        if len(self.by_name) != len(self.packets):
            raise ValueError("two packets of the dictionary share a name")

    def services(self, kind: str) -> frozenset[int]:
        """The services that have packets of ``kind`` ('TC' or 'TM')."""
        return frozenset(p.SERVICE for p in self.packets if p.KIND == kind)


DICTIONARY = Dictionary(declared())
"""Every packet of the mission, in declaration order."""
