"""The flight software core: one call per control period (a minor frame of the executive), on on-board time only.

``FlightSoftware.step`` takes what the hardware read during the period (OBT, sensors, received telecommands, a
camera frame, the processor's speed) and returns what the software commands (wheel torques and when they take
effect, a frame request, telemetry packets). Inside, the executive (``obsw.executive``) releases the tasks in the
slots of the schedule table (``obsw.table``; by default all of them, in this order, every minor frame):

1. TIME: an OBT jump is reported, and everything held in OBT is moved by it so the physical times it stands for do
   not move; a service 9 time report goes out when due;
2. TELECOMMANDS: telecommands received are decoded, verified (PUS service 1) and executed; a bad one is answered
   with a failure report and nothing else is lost; a gap in their sequence counts reports a lost uplink
   (``obsw.uplink_watch``);
3. SCHEDULE: scheduled commands whose tag has come (PUS service 11) are released and executed (late ones with an
   event);
4. ATTITUDE: the attitude and the gyro bias are estimated (``obsw.attitude``: a multiplicative EKF on the star
   tracker and the gyro; an outage is declared and the attitude propagated with the estimated bias);
5. IMAGING: a frame whose readout and FPGA stages are over goes through the software stage of the imaging chain
   (a saturated or blank frame is discarded, ``obsw.frame_quality``); Dimorphos's line of sight, turned inertial with
   the attitude at its exposure and accepted by the false-lock gate (``obsw.lock_gate``), is a measurement from the
   task's finish on; a line of sight refused in NOMINAL_TRACKING hands over to AUTONOMOUS_TRACKING; while
   Dimorphos is not found and its trajectory not yet recognised, Didymos's line of sight stands in for its own
   where the trajectory knows less than Didymos tells (``_stand_in_los``); Didymos's line of sight, whenever found,
   is a sighting of its own;
6. RECOGNITION: the measurements feed the trajectory recognition, stamped with their exposure time; Didymos's
   standing in feed a recognition of their own, whose trajectory, its uncertainty widened by the orbit's radius,
   is pointed on and predicts the frames until Dimorphos's own is recognised (``_stand_in_trajectory``); Didymos's
   sightings feed a third, against which Dimorphos's is cross-checked before it is trusted (``_contradicted``);
7. MODES: the mode manager reacts to time and events (acquisition window, target acquired or lost, C/A-30 s by the
   on-board estimate, end of flyby);
8. CONTROL: the tracking loop (with the latest measurement, taken at its exposure) and the PD controller give the
   wheel torques over the wheels in use (SAFE holds the attitude of its entry); a wheel reaching its momentum limit
   fails a parameter check; the loop follows ground's nominal until AUTONOMOUS_TRACKING, except while Dimorphos, its
   trajectory recognised, goes unseen (``_unseen_since_recognised``): then the recognised trajectory, and while
   Didymos's stands in for a Dimorphos not yet recognised, or Dimorphos goes unseen (or is not found in
   ACQUISITION) before its trajectory is recognised (``_unseen_unrecognised``): then Didymos's
   (``pointing_trajectory``);
9. FDIR: a failed parameter check is reported and recovered (SAFE); failed wheels are found
   (``obsw.wheel_health``); the service 12 definitions are checked (``obsw.monitoring``); the service 19 actions of
   the events raised are run (``obsw.event_action``);
10. CAMERA: a frame is requested at the imaging cadence; a frame overdue is reported missing;
11. TELEMETRY: housekeeping, with the executive's timing, and the estimate report go into the downlink.

Each task takes the execution time of the timing model (``obsw.timing``); what a task produces exists on board
from its modelled finish, so a line of sight is used only once the frame's readout, FPGA stages and software stage
are over, and the torques take effect when the control task ends. With ``timing.modelled`` false every task takes
no time and the order above is the zero-time flight software's. The processor's slow-down and the camera
interface's delay are hardware readings for the processor model; flight logic never reads them.

It never reads the clock, the bus or the disk: the node feeds it.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from contracts import pus, sdls
from contracts.messages import FrameMeta, FrameRequest, StepReply, StepRequest
from contracts.mode import Mode
from contracts.task import Task
from obsw.attitude import AttitudeEstimator
from obsw.attitude_history import AttitudeHistory
from obsw.config import ObswConfig
from obsw.control import boresight_error_rad, pd_torque_nm, wheel_torques_nm
from obsw.errors import CommandRejected, InternalFault, RejectReason
from obsw.event_action import EventActions
from obsw.executive import Activation, EventKind, Executive, FrameReport, Run, TaskSpec
from obsw.frame_quality import FrameWatch, saturated_fraction
from obsw.imaging import BadPixelMap, Detections, los_body, measured_detections, predict_frame, process_frame
from obsw.imaging_geometry import FramePrediction, LosKnowledge, matrix_of_quaternion
from obsw.lock_gate import Estimate, LockGate, Prediction
from obsw.modes import (CaEstimate, Cause, FalseLock, Fault, ModeEvent, ModeManager, TargetDetected, Tick,
                        WheelSaturation)
from obsw.modes import SetMode as SetModeTrigger
from obsw.monitoring import ParameterMonitor
from obsw.recognition import TrajectoryRecognizer, estimates_agree, predicted_los
from obsw.schedule import ScheduleRequest, Selection, TimeBasedSchedule
from obsw.tc_security import TcSecurity
from obsw.timing import NO_WORK, TimingModel, Work
from obsw.tm_counters import TmCounters
from obsw.tracking import Reference, TrackingLoop
from obsw.trajectory import NominalTrajectory
from obsw.uplink_watch import UplinkWatch
from obsw.verification import TcVerification
from obsw.wheel_health import WheelHealth

TRACKING_MODES = (Mode.NOMINAL_TRACKING, Mode.AUTONOMOUS_TRACKING)
# attitude estimates kept to turn a frame's LOS with the attitude at its exposure: 6.4 s at 10 Hz, past the 1 s
# latencies of bench/latency.py with room for a backlog of frames
ATTITUDE_HISTORY_PERIODS = 64
POINTING_MODES = (Mode.ACQUISITION, *TRACKING_MODES)
ACTION_SEQ_BASE = 0x3F00  # sequence counts of the TCs the software builds for its own event actions
AXIS_TOLERANCE = 1e-6  # a body axis farther than this from the wheels' span cannot be torqued


@dataclass(frozen=True, slots=True)
class Measurement:
    """Dimorphos's line of sight measured in one frame: inertial unit vector, and the frame's exposure time (OBT);
    ``stand_in``: Didymos's, Dimorphos not found (``_stand_in_los``): pointed on, and recognised apart (the payload
    of a DIDYMOS_SIGHTED event is Didymos's too)."""

    exposure_obt_s: float
    los_inertial: np.ndarray
    frame_id: int
    stand_in: bool = False


@dataclass(frozen=True, slots=True)
class WheelLimit:
    """A failed parameter check: a wheel at its momentum limit."""

    wheel: int
    momentum_nms: float


def controllable_axes(axes: np.ndarray) -> int:
    """Mask of the body axes (bit 0 x, 1 y, 2 z) the wheels of ``axes`` (3 x N, N may be 0) can torque."""
    if axes.shape[1] == 0:
        return 0
    basis, sv, _ = np.linalg.svd(axes, full_matrices=False)
    span = basis[:, sv > AXIS_TOLERANCE * max(float(sv[0]), 1.0)]
    return sum(1 << i for i in range(3) if np.linalg.norm(np.eye(3)[i] - span @ (span.T @ np.eye(3)[i])) < 1e-6)


def spans(axes: np.ndarray, vector: np.ndarray) -> bool:
    """Whether the wheels of ``axes`` (3 x N) can torque the body about ``vector``."""
    if axes.shape[1] == 0:
        return False
    v = vector / np.linalg.norm(vector)
    coef = np.linalg.lstsq(axes, v, rcond=None)[0]
    return bool(np.linalg.norm(axes @ coef - v) < AXIS_TOLERANCE)


def wheel_axes_body(layout: str, pyramid_angle_deg: float) -> np.ndarray:
    """Wheel spin axes in body axes, 3 x N: identity, or four at ``pyramid_angle_deg`` elevation about +Z."""
    if layout == "orthogonal":
        return np.eye(3)
    el = math.radians(pyramid_angle_deg)
    az = np.radians([45.0, 135.0, 225.0, 315.0])
    return np.vstack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.full(4, np.sin(el))])


class _LiveParameters(Mapping):
    """The monitorable parameters as a mapping whose values are read when looked up."""

    __slots__ = ("_readers",)

    def __init__(self, readers: dict[pus.Parameter, Callable[[], float | None]]) -> None:
        self._readers = readers

    def __getitem__(self, parameter: pus.Parameter) -> float | None:
        return self._readers[parameter]()

    def get(self, parameter: pus.Parameter, default: float | None = None) -> float | None:  # type: ignore[override]
        """The parameter's value now, ``default`` for a parameter it does not hold (a reader's own error raises)."""
        reader = self._readers.get(parameter)
        return default if reader is None else reader()

    def __iter__(self) -> Iterator[pus.Parameter]:
        return iter(self._readers)

    def __len__(self) -> int:
        return len(self._readers)


class FlightSoftware:
    """The on-board software of the flyby, advanced one control period per ``step``."""

    def __init__(self, cfg: ObswConfig, keys: sdls.KeyRing | None = None) -> None:
        """``keys``: the on-board security associations that authenticate uplinked TCs (none: all are refused)."""
        self.cfg = cfg
        self.security = TcSecurity(keys)
        self.camera = cfg.camera
        w = cfg.wheels
        self.axes = wheel_axes_body(w.layout, w.pyramid_angle_deg)
        # each wheel's monitored parameters, looked up once (service 12 samples them every period)
        self._wheel_parameters = tuple((pus.Parameter[f"WHEEL_MOMENTUM_{k}"], pus.Parameter[f"WHEEL_SPEED_{k}"])
                                       for k in range(self.axes.shape[1]))
        self.max_torque_nm = w.max_torque_nm
        self.max_momentum_nms = w.max_momentum_nms
        self.wheel_inertia_kgm2 = w.inertia_kgm2
        self.inertia = np.asarray(cfg.inertia_kgm2, dtype=float)
        self.modes = ModeManager(cfg.modes)
        self.schedule = TimeBasedSchedule(cfg.schedule_capacity, cfg.schedule_margin_s, payload_check=self._check_tc)
        self.tracking = TrackingLoop(cfg.tracking, cfg.camera.boresight_body)
        self.trajectory: NominalTrajectory | None = None
        self.recognizer: TrajectoryRecognizer | None = None
        # the same recognition on Didymos's lines of sight standing in for Dimorphos's (``_stand_in_trajectory``)
        self.stand_in_recognizer: TrajectoryRecognizer | None = None
        # Didymos's every line of sight recognised apart, to cross-check Dimorphos's (``_recognition_trusted``)
        self.didymos_recognizer: TrajectoryRecognizer | None = None
        # ((whether Didymos's every line of sight stands in, their count), the trajectory)
        self._stand_in_cache: tuple[tuple[bool, int], NominalTrajectory] | None = None
        # the cross-check's verdict for (Dimorphos's measurements, Didymos's measurements)
        self._cross_check: tuple[tuple[int, int], bool] | None = None
        # whether Didymos's recognition fits its recent lines of sight, for its measurement count (``_didymos_fits``)
        self._didymos_fit: tuple[int, bool] | None = None
        self.detections: Detections | None = None
        self.bad_pixels: BadPixelMap | None = None  # the camera's bad-pixel map, uploaded by ground
        self.imaging = False
        self.frame_period_s = cfg.camera.frame_period_s
        self.exposure_s = cfg.camera.exposure_s
        self._next_frame_obt: float | None = None
        # OBT of an entry into ACQUISITION from rest: no frame is exposed before the slew onto the target is done
        self._settle_since_obt: float | None = None
        self._reference_obt: float | None = None  # OBT the pointing reference (last_reference) was computed for
        self._counters = TmCounters()
        self.attitude = AttitudeEstimator(cfg.attitude)
        self.monitor = ParameterMonitor(cfg.monitoring)
        self.actions = EventActions()
        for i, a in enumerate(cfg.event_actions):
            packet = pus.encode_tc(a.telecommand(), cfg.apid, ACTION_SEQ_BASE + i, source_id=cfg.onboard_source_id,
                                   ack_flags=0)
            self.actions.add([(pus.EventId[a.event], packet)], enabled=a.enabled)
        self._actions_due: list[tuple[pus.EventId, bytes]] = []
        self._in_action = False
        self.frame_watch = FrameWatch(cfg.fdir)
        self.lock_gate = LockGate(cfg.fdir)
        self.uplink_watch = UplinkWatch(cfg.fdir.uplink_first_seq_count, cfg.fdir.uplink_seq_modulo)
        self._safe_q: np.ndarray | None = None
        self._last_frame_id = 0
        self._time_status = pus.TimeReferenceStatus.FREE_RUNNING
        self._requester: int | None = None  # source id of the TC being executed: its responses go there
        self._attitude_history = AttitudeHistory(ATTITUDE_HISTORY_PERIODS)
        self._exposure_rotation: tuple[np.ndarray, np.ndarray] | None = None  # (an attitude of the history, its matrix)
        self.autonomous_trajectory: NominalTrajectory | None = None
        self._autonomous_count = -1
        self._hk_next: float | None = None
        self._estimate_next = float("-inf")
        self._time_report_period: float | None = None
        self._time_rate_exponent = 0
        self._time_report_next: float | None = None
        self._time_reports_left = 0
        self._last_seen_obt: float | None = None
        self._wheel_saturated = False
        self._log: list[str] = []
        self._tm: list[bytes] = []
        self._prev_obt: float | None = None
        self._prev_time_frame = 0  # the executive's minor frame count when the time task last ran
        self._clock_adjust_s: float | None = None
        self.last_reference: Reference | None = None
        self.pointing_error_est_rad: float | None = None
        n_wheels = self.axes.shape[1]
        self.wheel_health = WheelHealth(cfg.fdir, n_wheels, w.max_momentum_nms)
        self.wheels_in_use = (1 << n_wheels) - 1
        self._in_use_of: tuple[int, np.ndarray] = (-1, np.zeros(0, dtype=bool))  # (wheel set, its booleans)
        # what the attitude task determined this period, for the tasks after it
        self._q = np.array([0.0, 0.0, 0.0, 1.0])
        self._omega = np.zeros(3)
        self._bias = np.zeros(3)
        self._attitude_sigma_rad = 0.0
        self._star_tracker_out = False
        self._outage_start: float | None = None
        # the torques of the last reply and of the one before, and when the last took effect: what the wheels got
        # (Python floats: per wheel, the same arithmetic as NumPy's at a fifth of the cost on three or four values)
        self._applied: tuple[tuple[float, ...], tuple[float, ...], float] = ((0.0,) * n_wheels, (0.0,) * n_wheels, 0.0)
        self._no_impulse = (0.0,) * n_wheels  # the impulse reset at each measurement
        self._impulse = self._no_impulse  # impulse commanded to each wheel since the last momentum measured, N m s
        self._impulse_s = 0.0  # the time it spans, s
        self._measured_h = False  # the attitude task measured the wheel momenta this period
        self._step_sequence = 0
        self._wheel_speed = np.zeros(n_wheels)
        self._wheel_h = np.zeros(n_wheels)
        self._torque = np.zeros(n_wheels)
        self._req: StepRequest | None = None
        self._frame_request_out: FrameRequest | None = None
        # timing, for the reply and the housekeeping
        self.timing = TimingModel(cfg.timing)
        self._actuation_delay_s = 0.0
        self._exposure_to_centroid_s: float | None = None
        self._centroid_to_torque_s: float | None = None
        self._overrunning = {t: False for t in Task}
        self._frame_overrunning = False
        self.last_frame: FrameReport | None = None
        self.executive = self._executive()
        self._live_parameters = _LiveParameters(self._readers())  # read as service 12 looks
        # what each telecommand does on board; a TC of the dictionary without an entry is refused
        self._handlers: dict[type, Callable[[Any, float], None]] = {
            pus.Ping: self._ping,
            pus.UploadNominalTrajectory: self._load_trajectory,
            pus.SetMode: self._set_mode,
            pus.SetCameraCadence: self._set_cadence,
            pus.StartImaging: self._start_imaging,
            pus.StopImaging: self._stop_imaging,
            pus.SetTimeReportRate: self._set_time_report_rate,
            pus.AdjustObt: self._adjust_obt,
            pus.RekeySecurityAssociation: self._rekey,
            pus.LoadBadPixelMap: self._load_bad_pixels,
            pus.RequestTimeReports: self._request_time_reports,
            pus.InsertActivities: self._insert_activities,
            pus.InsertCaRelativeActivities: self._insert_ca_relative,
            pus.DeleteActivities: self._delete_activities,
            pus.TimeShiftActivities: self._time_shift,
            pus.SummaryReportRequest: self._summary_report,
            pus.DetailReportRequest: self._detail_report,
            pus.EnableSchedule: self._enable_schedule,
            pus.DisableSchedule: self._disable_schedule,
            pus.ResetSchedule: self._reset_schedule,
            pus.SetWheelSet: self._set_wheel_set,
            pus.EnableParameterMonitoring: lambda c, o: self.monitor.set_enabled(c.pmon_ids, True),
            pus.DisableParameterMonitoring: lambda c, o: self.monitor.set_enabled(c.pmon_ids, False),
            pus.AddParameterMonitoringDefinitions: lambda c, o: self.monitor.add(c.definitions),
            pus.DeleteParameterMonitoringDefinitions: lambda c, o: self.monitor.delete(c.pmon_ids),
            pus.ModifyParameterMonitoringDefinitions: lambda c, o: self.monitor.modify(c.definitions),
            pus.AddEventActions: self._add_event_actions,
            pus.DeleteEventActions: lambda c, o: self.actions.delete(c.event_ids),
            pus.EnableEventActions: lambda c, o: self.actions.set_enabled(c.event_ids, True),
            pus.DisableEventActions: lambda c, o: self.actions.set_enabled(c.event_ids, False),
        }

    # -- public ------------------------------------------------------------------------------------------
    @property
    def mode_name(self) -> str:
        """Name of the current mode."""
        return self.modes.mode.name

    def take_log(self) -> list[str]:
        """Log lines since the last call."""
        out, self._log = self._log, []
        return out

    def step(self, req: StepRequest, frame: np.ndarray | None) -> StepReply:
        """One control period, one minor frame of the executive: see the module docstring for the order of work."""
        tick = req.obt_s
        self._tm = []
        self._time_status = pus.TimeReferenceStatus.FREE_RUNNING  # until the time task finds a step
        self._req = req
        self._frame_request_out = None
        self._step_sequence = self.executive.sequence  # events posted from here on are on this tick's time scale
        # the impulse of the period that ended at this tick: the torques before until the last reply's took effect
        before, after, d = self._applied
        rest = self.cfg.control_period_s - d
        self._impulse = tuple(i + b * d + a * rest for i, b, a in zip(self._impulse, before, after))
        self._impulse_s += self.cfg.control_period_s
        self._measured_h = False
        for raw in req.uplink:
            self.executive.post(EventKind.TC_ARRIVED, tick, raw)
        meta = req.frame
        if meta is not None:
            self.frame_watch.delivered(meta.obt_s)
        if meta is not None and (frame is not None or meta.measurement is not None):
            # a frame, or at centroid-level fidelity the modelled output of its imaging chain, which takes as long
            n = self.cfg.imaging.binned_size_px
            # the processor model: the frame leaves the FPGA after the rest of its exposure, its readout and the
            # FPGA stages, and whatever the camera interface adds (a hardware reading)
            delay = self.timing.frame_delay_s(meta.width, meta.height, meta.bit_depth, meta.exposure_s, n * n)
            self.executive.post(EventKind.FRAME_READY, meta.obt_s + delay + req.imaging_delay_s, (frame, meta))
        report = self.executive.minor_frame(tick, req.cpu_slowdown)
        self.last_frame = report
        if report.overrun and not self._frame_overrunning:
            next_tick = tick + self.cfg.control_period_s  # the tick that finds the work still running
            late = report.busy_until_s - next_tick
            self._event(pus.FrameOverrunEvent(minor_frame=report.minor_frame, late_s=late), next_tick,
                        f"minor frame {report.minor_frame} overran the next tick by {late * 1e3:.1f} ms")
        self._frame_overrunning = report.overrun
        torque = tuple(self._torque.tolist())
        self._applied = (self._applied[1], torque, self._actuation_delay_s)
        adjust, self._clock_adjust_s = self._clock_adjust_s, None
        # trusted, not validated: the software's own values, each of its field's type (the step's int, torques checked
        # finite as Python floats, a validated frame request, encoded packets, a delay clamped to the period)
        return StepReply.trusted(step=req.step, wheel_torque_nm=torque, clock_adjust_s=adjust,
                                 frame_request=self._frame_request_out, downlink=tuple(self._tm),
                                 actuation_delay_s=self._actuation_delay_s)

    # -- the executive's tasks -----------------------------------------------------------------------------
    def _executive(self) -> Executive:
        """The executive with this software's tasks, their subscriptions and the schedule's timer."""
        e = EventKind
        tasks = {
            Task.TIME: TaskSpec(self._task_time),
            Task.TELECOMMANDS: TaskSpec(self._task_telecommands, frozenset({e.TC_ARRIVED}), periodic=False),
            Task.SCHEDULE: TaskSpec(self._task_schedule, frozenset({e.TAG_DUE}), periodic=False),
            Task.ATTITUDE: TaskSpec(self._task_attitude),
            Task.IMAGING: TaskSpec(self._task_imaging, frozenset({e.FRAME_READY}), periodic=False),
            Task.RECOGNITION: TaskSpec(self._task_recognition, frozenset({e.MEASUREMENT, e.DIDYMOS_SIGHTED}),
                                       periodic=False),
            Task.MODES: TaskSpec(self._task_modes, frozenset({e.MEASUREMENT})),
            Task.CONTROL: TaskSpec(self._task_control, frozenset({e.MEASUREMENT})),
            Task.FDIR: TaskSpec(self._task_fdir, frozenset({e.PARAM_CHECK_FAILED})),
            Task.CAMERA: TaskSpec(self._task_camera),
            Task.TELEMETRY: TaskSpec(self._task_telemetry),
        }
        ex = Executive(self.cfg.executive, self.cfg.control_period_s, tasks, self.timing.execution_s, self._observe)
        ex.add_timer(e.TAG_DUE, lambda: self.schedule.next_tag_obt_s)
        return ex

    def _observe(self, run: Run) -> None:
        """After each run: the torques' actuation time, the latencies of the measurement used, overrun events."""
        if run.task is Task.CONTROL:
            tick = self._tick_s()
            self._actuation_delay_s = min(max(run.finish_s - tick, 0.0), self.cfg.control_period_s)
            used = [e for e in run.events if e.kind == EventKind.MEASUREMENT]
            if used:
                latest = used[-1]
                m: Measurement = latest.payload  # type: ignore[assignment]
                self._exposure_to_centroid_s = latest.time_s - m.exposure_obt_s
                self._centroid_to_torque_s = run.finish_s - latest.time_s
        if not run.ran:
            return
        overrun = run.overrun
        if overrun and not self._overrunning[run.task]:
            late = run.finish_s - run.deadline_s
            self._event(pus.TaskOverrunEvent(task=run.task, minor_frame=run.minor_frame, execution_s=run.execution_s,
                                             late_s=late), run.deadline_s,
                        f"{run.task.name} overran its slot by {late * 1e3:.1f} ms in minor frame {run.minor_frame}")
        self._overrunning[run.task] = overrun

    def _task_time(self, act: Activation) -> Work:
        """Time management: an OBT step beyond the control period is reported; a time report when due."""
        tick = act.tick_s
        # the periods since this task last ran (a release skipped under overload is no jump)
        dt = self.cfg.control_period_s * (self.executive.frames - self._prev_time_frame)
        if self._prev_obt is not None and abs(tick - self._prev_obt - dt) > self.cfg.clock_jump_threshold_s:
            jump = tick - self._prev_obt - dt
            self._time_status = pus.TimeReferenceStatus.STEPPED
            self._event(pus.ClockJumpEvent(step_s=jump), act.now_s, f"on-board time jumped by {jump:+.6f} s")
            moved = self._shift_time(jump)
            self._event(pus.TimeShiftedEvent(step_s=jump, schedule_entries=min(moved, 0xFFFF)), act.now_s,
                        f"everything held in OBT moved by {jump:+.6f} s ({moved} schedule entries)")
        self._prev_obt, self._prev_time_frame = tick, self.executive.frames
        self._time_report(tick)
        return NO_WORK

    def _task_telecommands(self, act: Activation) -> Work:
        """The telecommands received, in order of arrival, each authenticated first."""
        tcs = act.of(EventKind.TC_ARRIVED)
        for ev in tcs:
            packet = self._authenticated(ev.payload, act.now_s)  # type: ignore[arg-type]
            if packet is not None:
                gap = self.uplink_watch.received(pus.request_id_of(packet).seq_count)
                if gap is not None:
                    self._event(pus.UplinkGapEvent(expected_seq=gap.expected_seq, received_seq=gap.received_seq,
                                                   lost=min(gap.lost, 0xFFFF)), act.now_s,
                                f"uplink: {gap.lost} telecommand(s) lost before sequence count {gap.received_seq}")
                self._telecommand(packet, act.now_s, scheduled=False)
        return Work(commands=len(tcs))

    def _task_schedule(self, act: Activation) -> Work:
        """The scheduled commands whose tag has come, in release order."""
        due = self.schedule.release_due(act.now_s)
        for entry in due:
            late = act.now_s - entry.tag_obt_s
            if late > self.cfg.control_period_s:
                rid = pus.request_id_of(entry.payload)  # type: ignore[arg-type]
                self._event(pus.LateReleaseEvent(request_id=rid, late_s=late), act.now_s,
                            f"scheduled TC {rid.seq_count} released {late:.2f} s after its tag")
            self._telecommand(entry.payload, act.now_s, scheduled=True)  # type: ignore[arg-type]
        return Work(commands=len(due))

    def _task_attitude(self, act: Activation) -> Work:
        """The attitude, rate and wheel momenta of this period."""
        req = self._req
        assert req is not None
        st = req.sensors.star_tracker_q
        est = self.attitude.step(np.asarray(req.sensors.gyro_rad_s, dtype=float),
                                 None if st is None else np.asarray(st, dtype=float), self.cfg.control_period_s)
        self._q, self._omega, self._bias, self._attitude_sigma_rad = est.q, est.omega_rad_s, est.bias_rad_s, est.sigma_rad
        self._attitude_history.append(req.obt_s, est.q)
        if est.outage != self._star_tracker_out:
            self._star_tracker_out = est.outage
            if est.outage:
                self._outage_start = act.now_s - self.attitude.since_solution_s
                self._event(pus.StarTrackerEvent(available=0, outage_s=0.0, attitude_sigma_rad=est.sigma_rad),
                            act.now_s, "star tracker outage declared: attitude propagated with the gyro and the "
                            f"estimated bias {np.degrees(est.bias_rad_s).round(4).tolist()} deg/s")
            else:
                lasted = act.now_s - (self._outage_start or act.now_s)
                self._event(pus.StarTrackerEvent(severity=pus.Severity.INFO, available=1, outage_s=max(lasted, 0.0),
                                                 attitude_sigma_rad=est.sigma_rad), act.now_s,
                            f"star tracker solutions again after {lasted:.1f} s")
        self._wheel_speed = np.asarray(req.sensors.wheel_speed_rad_s, dtype=float)
        self._wheel_h = self.wheel_inertia_kgm2 * (self.axes.T @ self._omega + self._wheel_speed)
        self._measured_h = True
        return NO_WORK

    def _task_imaging(self, act: Activation) -> Work:
        """The software stage of the imaging chain for each frame out of the FPGA, oldest first."""
        frames = act.of(EventKind.FRAME_READY)
        regions = pixels = samples = 0
        for ev in frames:
            frame, meta = ev.payload  # type: ignore[misc]
            det = self._image(frame, meta, act)
            regions += len(det.blobs)
            pixels += sum(b.area_px for b in det.blobs)
            samples += det.limb_samples
        return Work(frames=len(frames), regions=regions, foreground_px=pixels, limb_samples=samples)

    def _task_recognition(self, act: Activation) -> Work:
        """The new measurements into the recognition, at their exposure time; the continuous estimate solved again."""
        new = act.of(EventKind.MEASUREMENT)
        rec = self.recognizer
        if rec is None:  # no nominal trajectory yet: nothing to recognise against
            return NO_WORK
        stand_ins = self.stand_in_recognizer
        for ev in new:
            m: Measurement = ev.payload  # type: ignore[assignment]
            if not m.stand_in:
                rec.add_measurement(m.exposure_obt_s, m.los_inertial)
            elif stand_ins is not None:  # Didymos's trajectory apart: it is up to the orbit's radius off Dimorphos's
                stand_ins.add_measurement(m.exposure_obt_s, m.los_inertial)
        didymos = self.didymos_recognizer
        if didymos is not None:
            for ev in act.of(EventKind.DIDYMOS_SIGHTED):
                m = ev.payload  # type: ignore[assignment]
                didymos.add_measurement(m.exposure_obt_s, m.los_inertial)
        rec.continuous()
        r = self.cfg.recognition
        return Work(candidates=r.grid_time_points * r.grid_distance_points * len(new),
                    measurements=rec.measurement_count)

    def _task_modes(self, act: Activation) -> Work:
        """The mode manager on this period's detections and time."""
        self._mode_by_events(act.now_s, bool(act.of(EventKind.MEASUREMENT)))
        return NO_WORK

    def _task_control(self, act: Activation) -> Work:
        """The wheel torques from the tracking loop and the PD law; the wheel momentum limit is checked."""
        used = act.of(EventKind.MEASUREMENT)
        seen = None if not used else used[-1].payload
        # the loops advance by the control period, not by OBT differences: a clock jump is not a long period
        tau = self._control(act.tick_s, self.cfg.control_period_s, self._q, self._omega, self._wheel_h,
                            seen)  # type: ignore[arg-type]
        self._torque = tau
        wheel_h = self._wheel_h
        saturated = any(abs(h) >= self.max_momentum_nms for h in wheel_h.tolist())
        if saturated and not self._wheel_saturated:
            worst = int(np.argmax(np.abs(wheel_h)))
            act.emit(EventKind.PARAM_CHECK_FAILED, WheelLimit(worst, float(wheel_h[worst])))
        self._wheel_saturated = saturated
        return NO_WORK

    def _task_fdir(self, act: Activation) -> Work:
        """Failure detection, isolation and recovery: each failed parameter check reported and recovered (a wheel at
        its limit sends the spacecraft to SAFE); failed wheels found; the service 12 definitions checked; the service
        19 actions of the events raised so far run."""
        now = act.now_s
        checks = act.of(EventKind.PARAM_CHECK_FAILED)
        for ev in checks:
            w: WheelLimit = ev.payload  # type: ignore[assignment]
            self._event(pus.WheelSaturationEvent(wheel=w.wheel, momentum_nms=w.momentum_nms), now,
                        f"wheel {w.wheel} saturated at {w.momentum_nms:+.4f} N m s")
            self._mode_event(self.modes.handle(WheelSaturation(w.wheel), now), now)
        failures = []
        if self._measured_h:  # over the periods since the momenta were last measured (a skipped attitude task)
            failures = self.wheel_health.update(self._wheel_h, self._impulse, self._impulse_s)
            self._impulse, self._impulse_s = self._no_impulse, 0.0
        for f in failures:
            self._event(pus.WheelFailedEvent(wheel=f.wheel, commanded_nms=f.commanded_nms, measured_nms=f.measured_nms),
                        now, f"wheel {f.wheel} failed: {f.commanded_nms:+.2e} N m s commanded over the window, "
                        f"{f.measured_nms:+.2e} N m s measured")
        transitions = self.monitor.check(self._parameters())
        for t in transitions:
            d = t.definition
            self._event(pus.ParameterCheckEvent(severity=d.severity, pmon_id=d.pmon_id, parameter=d.parameter,
                                                previous_status=t.previous, status=t.status, value=t.value,
                                                limit=t.limit), now,
                        f"monitoring {d.pmon_id} ({d.parameter.name}): {t.previous.name} -> {t.status.name}, value "
                        f"{t.value:.6g}, limit {t.limit:.6g}")
        actions = self._run_actions(now)
        if not (checks or transitions or actions):
            return NO_WORK  # the usual period: no Work to build
        return Work(checks=len(checks) + len(transitions), commands=actions)

    def _task_camera(self, act: Activation) -> Work:
        """A frame request when the imaging cadence is due; a frame requested and never delivered reported missing."""
        overdue = self.frame_watch.overdue(act.tick_s)
        if overdue is not None and self.frame_watch.anomaly(pus.FrameAnomaly.MISSING):
            last = -1 if self.detections is None else self._last_frame_id
            self._event(pus.FrameAnomalyEvent(anomaly=pus.FrameAnomaly.MISSING, frame_id=max(last, 0),
                                              statistic=overdue), act.now_s,
                        f"frame missing: requested {overdue:.2f} s ago, never delivered")
        self._frame_request_out = self._frame_request(act.tick_s)
        if self._frame_request_out is not None:
            self.frame_watch.requested(act.tick_s)
        return NO_WORK

    def _task_telemetry(self, act: Activation) -> Work:
        """Housekeeping and estimate reports when due."""
        packets = self._periodic_tm(act.now_s)
        return Work(packets=packets) if packets else NO_WORK

    # -- telemetry -----------------------------------------------------------------------------------------
    def _send(self, report: pus.TmReport, obt: float, destination_id: int | None = None) -> None:
        """Downlink ``report`` to ``destination_id`` (unsolicited reports: the configured ground id)."""
        dest = self.cfg.ground_id if destination_id is None else destination_id
        seq, counter = self._counters.stamp(report.SERVICE, report.subservice(), dest)
        self._tm.append(pus.encode_tm(report, self.cfg.apid, seq, obt, counter, destination_id=dest,
                                      time_status=self._time_status))

    def _event(self, event: pus.TmReport, obt: float, text: str) -> None:
        """Report an event; its service 19 action, if one is enabled, runs in the FDIR task (not for the events of an
        action itself)."""
        self._send(event, obt)
        self._log.append(f"OBT {obt:.2f} s: {text}")
        if isinstance(event, pus.EventReport) and not self._in_action:
            packet = self.actions.triggered(event.EVENT_ID)
            if packet is not None:
                self._actions_due.append((event.EVENT_ID, packet))

    def _run_actions(self, obt: float) -> int:
        """Run the service 19 actions of the events raised so far; the number run."""
        due, self._actions_due = self._actions_due, []
        self._in_action = True
        try:
            for event_id, packet in due:
                self._log.append(f"OBT {obt:.2f} s: event-action: {event_id.name} runs TC {pus.decode_tc(packet)[1]!r}")
                self._telecommand(packet, obt, scheduled=True)
        finally:
            self._in_action = False
        return len(due)

    def _parameters(self) -> Mapping[pus.Parameter, float | None]:
        """The values of the parameters service 12 can monitor, this period, each read when looked up (a period's
        checks look up a few of some thirty)."""
        return self._live_parameters

    def _readers(self) -> dict[pus.Parameter, Callable[[], float | None]]:
        """How to read each parameter service 12 can monitor."""
        P = pus.Parameter
        ex = self.executive
        readers: dict[pus.Parameter, Callable[[], float | None]] = {
            P.MODE: lambda: float(self.modes.mode),
            P.BODY_RATE: lambda: math.sqrt(float(self._omega.dot(self._omega))),
            P.GYRO_BIAS: lambda: math.sqrt(float(self._bias.dot(self._bias))) if self.attitude.bias_known else None,
            P.ATTITUDE_SIGMA: lambda: self._attitude_sigma_rad,
            P.POINTING_ERROR: lambda: self.pointing_error_est_rad, P.TASK_OVERRUNS: lambda: float(ex.task_overruns),
            P.FRAME_OVERRUNS: lambda: float(ex.frame_overruns), P.SKIPPED_RELEASES: lambda: float(ex.skipped),
            P.TC_REJECTED_AUTH: lambda: float(self.security.housekeeping()["tc_rejected_auth"]),
            P.FRAMES_DISCARDED: lambda: float(self.frame_watch.discarded),
            P.MEASUREMENTS_REJECTED: lambda: float(self.lock_gate.rejected),
            P.EXPOSURE_TO_CENTROID: lambda: self._exposure_to_centroid_s,
        }
        for k, (momentum, speed) in enumerate(self._wheel_parameters):
            readers[momentum] = lambda k=k: float(self._wheel_h[k])
            readers[speed] = lambda k=k: float(self._wheel_speed[k])
        return readers

    def _shift_time(self, step_s: float) -> int:
        """On-board time stepped by ``step_s``: move everything held in OBT with it (schedule tags and C/A anchor,
        trajectories, recognition measurements, tracking loop, mode manager, histories, cadences, queued events),
        so the physical times they stand for do not move; return the schedule entries moved."""
        moved = self.schedule.shift_clock(step_s)
        if self.trajectory is not None:
            self.trajectory = self.trajectory.with_ca(self.trajectory.ca_time_obt_s + step_s,
                                                      self.trajectory.ca_distance_km)
        if self.recognizer is not None:
            self.recognizer.shift_time(step_s)
        if self.stand_in_recognizer is not None:
            self.stand_in_recognizer.shift_time(step_s)
        if self.didymos_recognizer is not None:
            self.didymos_recognizer.shift_time(step_s)
        self._stand_in_cache = None
        self._cross_check = self._didymos_fit = None
        self.autonomous_trajectory, self._autonomous_count = None, -1
        self.tracking.shift_time(step_s)
        self.modes.shift_time(step_s)
        self.frame_watch.shift(step_s)
        self.lock_gate.shift(step_s)
        self._attitude_history = self._attitude_history.shifted(step_s)
        if self._last_seen_obt is not None:
            self._last_seen_obt += step_s
        if self._outage_start is not None:
            self._outage_start += step_s
        for name in ("_next_frame_obt", "_hk_next", "_time_report_next", "_settle_since_obt", "_reference_obt"):
            if getattr(self, name) is not None:
                setattr(self, name, getattr(self, name) + step_s)
        self._estimate_next += step_s

        def payload(kind: EventKind, p: object) -> object:
            if kind == EventKind.FRAME_READY:
                frame, meta = p  # type: ignore[misc]
                return frame, meta.model_copy(update={"obt_s": meta.obt_s + step_s})
            if kind in (EventKind.MEASUREMENT, EventKind.DIDYMOS_SIGHTED):
                return dataclasses.replace(p, exposure_obt_s=p.exposure_obt_s + step_s)  # type: ignore[type-var]
            return p

        self.executive.shift_time(step_s, self._step_sequence, payload)
        return moved

    # -- telecommands --------------------------------------------------------------------------------------
    def _check_tc(self, payload: object) -> None:
        """Schedule payload check: a complete TC packet of a known command with valid arguments."""
        if not isinstance(payload, bytes):
            raise CommandRejected(RejectReason.MALFORMED, f"scheduled payload is {type(payload).__name__}, not a TC")
        try:
            pus.decode_tc(payload, expected_apid=self.cfg.apid)
        except pus.PacketError as exc:
            raise CommandRejected(RejectReason.BAD_ARGUMENT, f"scheduled TC: {exc}") from None

    def _authenticated(self, unit: bytes, obt: float) -> bytes | None:
        """The TC packet of an uplinked unit that passes the security check; None (reported) otherwise."""
        try:
            return self.security.check(unit)
        except sdls.SecurityRejection as rej:
            self._log.append(f"OBT {obt:.2f} s: SECURITY: uplinked unit of {len(unit)} octets refused: {rej.why}")
            if rej.request_id is not None:
                self._send(pus.Verification(stage=pus.Stage.ACCEPTANCE, request_id=rej.request_id,
                                            failure_code=int(rej.failure_code), reason=rej.why), obt)
            self._send(pus.TcSecurityRejectedEvent(spi=rej.spi, arsn=rej.arsn, failure_code=int(rej.failure_code)),
                       obt)
            return None

    def _telecommand(self, raw: bytes, obt: float, scheduled: bool) -> None:
        """Decode, verify (service 1, as the TC's acknowledgement flags ask) and execute one TC; a scheduled one is
        verified at its release like one just received."""
        try:
            header, cmd = pus.decode_tc(raw, expected_apid=self.cfg.apid)
        except pus.PacketError as exc:
            self._log.append(f"OBT {obt:.2f} s: rejected {'scheduled ' if scheduled else ''}telecommand: {exc}")
            failure = pus.Verification.failure_for(exc)
            if failure is not None:  # the source id is unreadable: the report goes to the ground
                self._send(failure, obt)
            return
        if header.source_id == self.cfg.onboard_source_id:  # the software's own TC: its verification stays on board
            verification = TcVerification(header, lambda report, dest: None)
        else:
            verification = TcVerification(header, lambda report, dest: self._send(report, obt, dest))
        verification.accepted()
        verification.started()
        self._requester = header.source_id
        try:
            self._execute(cmd, obt)
        except CommandRejected as rej:
            self._log.append(f"OBT {obt:.2f} s: {type(cmd).__name__} refused: {rej.text}")
            code = 0x0100 + int(rej.reason)
            verification.failed(pus.Stage.COMPLETION, code, rej.text)
            self._event(pus.CommandRejectedEvent(request_id=header.request_id, failure_code=code), obt,
                        f"command rejected: {rej.text}")
            return
        finally:
            self._requester = None
        verification.completed()

    def _execute(self, cmd: pus.TcCommand, obt: float) -> None:
        handler = self._handlers.get(type(cmd))
        if handler is None:
            raise CommandRejected(RejectReason.UNKNOWN_COMMAND, f"{type(cmd).__name__} has no on-board handler")
        handler(cmd, obt)

    def _ping(self, cmd: pus.Ping, obt: float) -> None:
        self._send(pus.PingReply(), obt, self._requester)

    def _set_mode(self, cmd: pus.SetMode, obt: float) -> None:
        self._mode_event(self.modes.handle(SetModeTrigger(cmd.mode), obt), obt)

    def _set_cadence(self, cmd: pus.SetCameraCadence, obt: float) -> None:
        self.frame_period_s, self.exposure_s = cmd.period_s, cmd.exposure_s

    def _start_imaging(self, cmd: pus.StartImaging, obt: float) -> None:
        if cmd.period_s is not None:
            self.frame_period_s = cmd.period_s
        self.imaging = True
        self._next_frame_obt = self._tick_s()  # the cadence counts in ticks: frames are exposed at a tick

    def _stop_imaging(self, cmd: pus.StopImaging, obt: float) -> None:
        self.imaging = False

    def _set_time_report_rate(self, cmd: pus.SetTimeReportRate, obt: float) -> None:
        self._time_report_period = float(2**cmd.rate_exponent)
        self._time_rate_exponent = cmd.rate_exponent
        self._time_report_next = obt
        self._time_reports_left = -1

    def _adjust_obt(self, cmd: pus.AdjustObt, obt: float) -> None:
        # the oscillator hardware applies it before the next period; the jump is then seen and reported
        self._clock_adjust_s = (self._clock_adjust_s or 0.0) + cmd.delta_s
        self._log.append(f"OBT {obt:.3f} s: commanded clock adjustment of {cmd.delta_s:+.6f} s")

    def _rekey(self, cmd: pus.RekeySecurityAssociation, obt: float) -> None:
        try:
            self.security.install(cmd.spi, cmd.wrapped_key)
        except ValueError as exc:
            raise CommandRejected(RejectReason.BAD_ARGUMENT, f"rekey: {exc}") from None
        self._log.append(f"OBT {obt:.2f} s: TC authentication: security association {cmd.spi} loaded")

    def _load_bad_pixels(self, cmd: pus.LoadBadPixelMap, obt: float) -> None:
        try:
            bad = BadPixelMap.build(self.camera.resolution_px, [(p.col, p.row) for p in cmd.pixels], cmd.columns)
        except ValueError as exc:
            raise CommandRejected(RejectReason.BAD_ARGUMENT, f"bad-pixel map: {exc}") from None
        self.bad_pixels = bad if len(bad) else None
        self._log.append(f"OBT {obt:.2f} s: bad-pixel map loaded: {len(cmd.pixels)} pixel(s), "
                         f"{len(cmd.columns)} column(s)")

    def _request_time_reports(self, cmd: pus.RequestTimeReports, obt: float) -> None:
        self._time_report_period = 1.0
        self._time_rate_exponent = 0
        self._time_report_next = obt
        self._time_reports_left = cmd.count

    def _insert_activities(self, cmd: pus.InsertActivities, obt: float) -> None:
        self._schedule_insert([ScheduleRequest(request_id=pus.request_id_of(a.tc_packet).seq_count,
                                               tag_obt_s=a.release_obt_s, payload=a.tc_packet)
                               for a in cmd.activities], obt)

    def _insert_ca_relative(self, cmd: pus.InsertCaRelativeActivities, obt: float) -> None:
        self._schedule_insert([ScheduleRequest(request_id=pus.request_id_of(a.tc_packet).seq_count,
                                               tag_obt_s=a.release_obt_s, payload=a.tc_packet,
                                               ca_offset_s=a.ca_offset_s) for a in cmd.activities], obt)

    def _schedule_insert(self, reqs: list[ScheduleRequest], obt: float) -> None:
        if self.recognizer is not None and self.schedule.ca_anchor_obt_s is None:
            self.schedule.reanchor_ca(self.trajectory.ca_time_obt_s)  # type: ignore[union-attr]
        rejections = self.schedule.insert(obt, reqs)
        if rejections:
            raise CommandRejected(rejections[0].reason, "; ".join(
                f"activity {r.index}: {r.text}" for r in rejections))

    def _enable_schedule(self, cmd: pus.EnableSchedule, obt: float) -> None:
        self.schedule.enabled = True
        self._log.append(f"OBT {obt:.2f} s: time-based schedule enabled")

    def _disable_schedule(self, cmd: pus.DisableSchedule, obt: float) -> None:
        self.schedule.enabled = False
        self._log.append(f"OBT {obt:.2f} s: time-based schedule disabled")

    def _reset_schedule(self, cmd: pus.ResetSchedule, obt: float) -> None:
        # ECSS-E-ST-70-41C TC[11,3]: every activity deleted and the schedule's execution disabled until enabled again
        gone = self.schedule.delete(Selection())
        self.schedule.enabled = False
        self._log.append(f"OBT {obt:.2f} s: time-based schedule reset: {len(gone)} activities deleted, disabled")

    def _add_event_actions(self, cmd: pus.AddEventActions, obt: float) -> None:
        for d in cmd.definitions:
            self._check_tc(d.tc_packet)
        self.actions.add([(d.event_id, d.tc_packet) for d in cmd.definitions])

    def _set_wheel_set(self, cmd: pus.SetWheelSet, obt: float) -> None:
        n = self.axes.shape[1]
        full = (1 << n) - 1
        if cmd.wheels & ~full:
            raise CommandRejected(RejectReason.BAD_ARGUMENT, f"wheels: mask 0b{cmd.wheels:b} names a wheel beyond the "
                                  f"{n} wheels")
        mask = cmd.wheels or full & ~self.wheel_health.failed_mask
        self.wheels_in_use = mask
        in_use = self._in_use()
        axes = controllable_axes(self.axes[:, in_use])
        names = ", ".join(str(k) for k in range(n) if mask >> k & 1) or "none"
        self._event(pus.WheelSetEvent(wheels_in_use=mask, wheels_failed=self.wheel_health.failed_mask,
                                      controllable_axes=axes), obt,
                    f"wheel set: {names} (axes {''.join(c for i, c in enumerate('xyz') if axes >> i & 1) or 'none'} "
                    "controllable)")
        slew = np.asarray(self.cfg.tracking.plane_normal_axis_body, dtype=float)
        if self.modes.mode != Mode.SAFE and not spans(self.axes[:, in_use], slew):
            why = f"wheels {names} cannot torque the slew axis ({', '.join(f'{c:g}' for c in slew)}) in body axes"
            self._event(pus.FaultEvent(fault_code=pus.FaultCode.WHEELS_CANNOT_CONTROL, reason=why), obt,
                        f"fault: {why}")
            self._mode_event(self.modes.handle(Fault(why), obt), obt)

    def _in_use(self) -> np.ndarray:
        """Booleans of the wheels in use (read-only; built again only when the wheel set changes)."""
        if self._in_use_of[0] != self.wheels_in_use:
            mask = np.array([bool(self.wheels_in_use >> k & 1) for k in range(self.axes.shape[1])])
            mask.setflags(write=False)
            self._in_use_of = (self.wheels_in_use, mask)
        return self._in_use_of[1]

    def _delete_activities(self, cmd: pus.DeleteActivities, obt: float) -> None:
        self.schedule.delete(Selection(request_ids=frozenset(r.seq_count for r in cmd.request_ids)))

    def _time_shift(self, cmd: pus.TimeShiftActivities, obt: float) -> None:
        sel = None if not cmd.request_ids else Selection(request_ids=frozenset(r.seq_count for r in cmd.request_ids))
        self.schedule.time_shift(obt, cmd.delta_s, sel)

    def _summary_report(self, cmd: pus.SummaryReportRequest, obt: float) -> None:
        entries = tuple(pus.ScheduleSummaryEntry(release_obt_s=e.tag_obt_s,
                                                 request_id=pus.request_id_of(e.payload))  # type: ignore[arg-type]
                        for e in self.schedule.listing())
        self._send(pus.ScheduleSummaryReport(entries=entries), obt, self._requester)

    def _detail_report(self, cmd: pus.DetailReportRequest, obt: float) -> None:
        activities = tuple(pus.ScheduledActivity(release_obt_s=e.tag_obt_s, tc_packet=e.payload)  # type: ignore[arg-type]
                           for e in self.schedule.listing())
        self._send(pus.ScheduleDetailReport(activities=activities), obt, self._requester)

    def _load_trajectory(self, cmd: pus.UploadNominalTrajectory, obt: float) -> None:
        traj = NominalTrajectory(
            ca_time_obt_s=cmd.ca_obt_s, ca_distance_km=cmd.ca_distance_km, speed_km_s=cmd.speed_km_s,
            approach_direction=cmd.approach_direction, ca_direction=cmd.ca_direction,
            ca_time_sigma_s=cmd.sigma_ca_time_s, ca_distance_sigma_km=cmd.sigma_ca_distance_km,
        )
        if self.modes.mode in TRACKING_MODES:
            raise CommandRejected(RejectReason.BAD_ARGUMENT,
                                  f"nominal trajectory cannot be replaced in {self.modes.mode.name}")
        try:
            recognizer = TrajectoryRecognizer(traj, self.cfg.recognition)
        except ValueError as exc:  # a grid that does not fit the uploaded uncertainty: the ground's fault
            raise CommandRejected(RejectReason.BAD_ARGUMENT, f"nominal trajectory: {exc}") from None
        self.trajectory = traj
        self.recognizer = recognizer
        self.stand_in_recognizer, self._stand_in_cache = TrajectoryRecognizer(traj, self.cfg.recognition), None
        self.didymos_recognizer = TrajectoryRecognizer(traj, self.cfg.recognition)
        self._cross_check = self._didymos_fit = None
        self.schedule.reanchor_ca(traj.ca_time_obt_s)
        self.modes.handle(CaEstimate(traj.ca_time_obt_s), obt)
        self._log.append(f"OBT {obt:.2f} s: nominal trajectory loaded: C/A at OBT {traj.ca_time_obt_s:.2f} s, "
                         f"{traj.ca_distance_km:.2f} km")

    # -- attitude estimate ---------------------------------------------------------------------------------
    def _attitude_at(self, obt_s: float) -> np.ndarray:
        """The attitude estimate of the control period nearest ``obt_s`` (a frame's exposure time)."""
        return self._attitude_history.nearest(obt_s)

    # -- imaging -------------------------------------------------------------------------------------------
    def _image(self, frame: np.ndarray | None, meta: FrameMeta, act: Activation) -> Detections:
        """Process a frame (at centroid-level fidelity, take its modelled detections); if Dimorphos is seen, emit its
        measured inertial LOS stamped with the exposure."""
        obt = meta.obt_s
        self._last_frame_id = meta.frame_id
        fdir = self.cfg.fdir
        if frame is not None:
            saturated = saturated_fraction(frame, self.camera.bit_depth, fdir.frame_sample_stride)
            if saturated >= fdir.frame_saturated_fraction:  # nothing in it can be measured: not even processed
                self._frame_anomaly(pus.FrameAnomaly.SATURATED, meta.frame_id, saturated, act.now_s)
                return Detections(blobs=(), didymos=None, dimorphos=None, didymos_offset_px=None,
                                  dimorphos_offset_px=None, didymos_offset_rad=None, dimorphos_offset_rad=None,
                                  threshold_dn8=0, background_dn8=0, noise_sigma_dn8=0.0,
                                  binned_size_px=self.cfg.imaging.binned_size_px)
            # what the frame should show, from the attitude at the exposure and the best trajectory known on board:
            # the recognised one once trusted, even before it is flown, since the ground's nominal can be seconds
            # off in C/A time and then predicts Dimorphos hundreds of px from where it is
            recognised = self._recognised_trajectory()
            prediction = predict_frame(self._attitude_at(meta.obt_s), self.cfg.targets, self.camera,
                                       self.cfg.imaging,
                                       recognised or self._stand_in_trajectory() or self.pointing_trajectory(),
                                       meta.obt_s, self._los_knowledge(recognised, meta.obt_s))
            det = process_frame(frame, self.cfg.imaging, self.detections, self.camera, bad_pixels=self.bad_pixels,
                                prediction=prediction)
        else:
            assert meta.measurement is not None
            det = measured_detections(meta.measurement, self.cfg.imaging, self.camera)
            prediction = None
        seen_before = self.detections is not None and self.detections.dimorphos is not None
        if seen_before and not any(b.area_px >= self.cfg.imaging.min_body_area_px for b in det.blobs):
            peak = max((b.peak_dn8 - det.background_dn8 for b in det.blobs), default=0)
            self._frame_anomaly(pus.FrameAnomaly.BLANK, meta.frame_id, float(peak), act.now_s)
            return det  # the previous detections stay the reference of the chain's continuity
        self.frame_watch.good()
        self.detections = det
        didymos_los = None if det.didymos is None or det.didymos_offset_px is None \
            else self._inertial_los(det.didymos_offset_px, det.binned_size_px, obt)
        if self.cfg.tracking.didymos_cross_check and didymos_los is not None:
            act.emit(EventKind.DIDYMOS_SIGHTED, Measurement(obt, didymos_los, meta.frame_id, stand_in=True))
        if det.dimorphos is None or det.dimorphos_offset_px is None:
            stand_in = self._stand_in_los(det, prediction, didymos_los)
            if stand_in is not None:
                self._last_seen_obt = obt
                act.emit(EventKind.MEASUREMENT, Measurement(obt, stand_in, meta.frame_id, stand_in=True))
            self._send(pus.NavigationReport(frame_id=meta.frame_id, dimorphos_col_row=None,
                                            didymos_col_row=_col_row(det.didymos), dimorphos_area_px=0,
                                            los_inertial=None if stand_in is None else
                                            tuple(float(c) for c in stand_in)), obt)
            return det
        los_i = self._inertial_los(det.dimorphos_offset_px, det.binned_size_px, obt)
        gate = self.lock_gate.check(self._recognised_trajectory(), obt, los_i, self._prediction(obt))
        if not gate.accepted:
            if self.lock_gate.run == 1:
                self._event(pus.FalseLockEvent(frame_id=meta.frame_id, offset_rad=gate.innovation_rad,
                                               gate_rad=gate.gate_rad), act.now_s,
                            f"false lock: frame {meta.frame_id}'s target moved {np.degrees(gate.innovation_rad):.3f} "
                            f"deg from the recognised trajectory's prediction (gate {np.degrees(gate.gate_rad):.3f} "
                            "deg): its line of sight is refused")
            self.detections = None  # the chain identifies afresh rather than by continuity with the false target
            self._mode_event(self.modes.handle(FalseLock(meta.frame_id), act.now_s), act.now_s)
        else:
            self._last_seen_obt = obt
            act.emit(EventKind.MEASUREMENT, Measurement(obt, los_i, meta.frame_id))
        self._send(pus.NavigationReport(frame_id=meta.frame_id, dimorphos_col_row=det.dimorphos.centroid_col_row,
                                        didymos_col_row=_col_row(det.didymos), dimorphos_area_px=det.dimorphos.area_px,
                                        los_inertial=tuple(float(c) for c in los_i)), obt)
        return det

    def _stand_in_los(self, det: Detections, prediction: FramePrediction | None,
                      didymos_los: np.ndarray | None) -> np.ndarray | None:
        """Didymos's inertial line of sight (``didymos_los``, of ``det``'s Didymos), standing in for Dimorphos's while Dimorphos is not found and its
        trajectory not yet recognised on its own lines of sight: when Didymos is found, and the trajectory's
        uncertainty on Dimorphos's place is wider than the orbit's apparent radius (Didymos's centroid then bounds
        where Dimorphos is better than the trajectory does: hidden behind or in front of Didymos, or lost in its
        glow, Dimorphos is within that radius of it), and Didymos lies where that place and radius allow
        (``tracking.didymos_stands_in``). Once recognised, Dimorphos's trajectory is the better bound."""
        if not self.cfg.tracking.didymos_stands_in or det.didymos is None or didymos_los is None \
                or self._recognition_trusted() \
                or prediction is None or prediction.dimorphos_col_row is None \
                or prediction.dimorphos_uncertainty_px is None or prediction.orbit_radius_max_px is None:
            return None
        reach, spread = prediction.orbit_radius_max_px, prediction.dimorphos_uncertainty_px
        col, row = det.didymos.centroid_col_row
        if not reach < spread or math.hypot(col - prediction.dimorphos_col_row[0],
                                            row - prediction.dimorphos_col_row[1]) > reach + spread:
            return None
        return didymos_los

    def _inertial_los(self, offset_px: tuple[float, float], binned_size_px: int, obt: float) -> np.ndarray:
        """The inertial line of sight of an image offset from the centre, with the attitude at exposure ``obt``."""
        los_b = los_body(offset_px[0], offset_px[1], self.camera.fov_deg, binned_size_px)
        q = self._attitude_at(obt)
        # Didymos's and Dimorphos's lines of sight of a frame turn with one attitude: its rotation is built once
        if self._exposure_rotation is None or self._exposure_rotation[0] is not q:
            self._exposure_rotation = (q, matrix_of_quaternion(q))
        return self._exposure_rotation[1] @ los_b

    def _los_knowledge(self, recognised: NominalTrajectory | None, obt: float) -> LosKnowledge | None:
        """The continuous estimate's line of sight at ``obt``, when the recognised trajectory is that estimate's, with
        the lock gate's count of its one-sigma (the attitude's knowledge included) around it: the imaging chain looks
        for Dimorphos where a line of sight would be accepted (the centroid's noise and the body's radius it adds)."""
        if recognised is None or self.cfg.autonomy_estimate != "continuous":
            return None
        assert self.recognizer is not None  # a recognised trajectory comes from it
        los, sigma = predicted_los(recognised, self.recognizer.continuous_estimate(), obt)
        return LosKnowledge(los_inertial=(float(los[0]), float(los[1]), float(los[2])),
                            bound_rad=self.cfg.fdir.false_lock_residual_sigma * math.hypot(sigma,
                                                                                           self._attitude_sigma_rad))

    def _prediction(self, obt: float) -> Prediction | None:
        """What the reference C/A estimate (``obsw.lock_gate.ReferenceEstimates``) predicts of Dimorphos's line of
        sight at ``obt``, once the recognition is trusted."""
        rec = self.recognizer
        newest = None if rec is None else rec.last_measurement_obt_s
        if rec is None or newest is None or not self._recognition_trusted():
            return None
        self.lock_gate.references.add(Estimate(newest, rec.continuous_estimate()))
        reference = self.lock_gate.reference(obt)
        assert reference is not None  # one was just added
        targets = self.cfg.targets
        return reference.prediction(obt, rec.nominal.speed_m_s,
                                    math.hypot(self.cfg.recognition.angle_noise_rad, self._attitude_sigma_rad),
                                    targets.max_axis_ratio * targets.dimorphos_diameter_m / 2)

    def _stand_in_trajectory(self) -> NominalTrajectory | None:
        """Before Dimorphos's own lines of sight are enough to recognise its trajectory, the one recognised on
        Didymos's standing in for them (on every line of sight of Didymos once Didymos's contradicted Dimorphos's:
        ``_contradicted``, or while Dimorphos goes unseen without enough stand-ins: ``_unseen_unrecognised``), its
        uncertainties widened by the orbit's radius (Dimorphos is that far from Didymos at most: along the track a
        C/A time, across it a C/A distance); None without enough of either."""
        n = self.cfg.min_recognition_measurements
        stand_ins = self.didymos_recognizer if self._contradicted() else self.stand_in_recognizer
        if self.recognizer is None or self._recognition_trusted():
            return None
        if (stand_ins is None or stand_ins.measurement_count < n) and self._unseen_unrecognised():
            stand_ins = self.didymos_recognizer
        if stand_ins is None or stand_ins.measurement_count < n:
            return None
        key = (stand_ins is self.didymos_recognizer, stand_ins.measurement_count)
        if self._stand_in_cache is None or self._stand_in_cache[0] != key:
            traj = stand_ins.continuous_trajectory()
            r_km = self.cfg.targets.orbit_radius_m / 1e3
            self._stand_in_cache = (key, traj.model_copy(update={
                "ca_time_sigma_s": math.hypot(traj.ca_time_sigma_s, r_km / traj.speed_km_s),
                "ca_distance_sigma_km": math.hypot(traj.ca_distance_sigma_km, r_km)}))
        return self._stand_in_cache[1]

    def _unseen_unrecognised(self) -> bool:
        """Whether, in NOMINAL_TRACKING or ACQUISITION, Dimorphos has gone unseen for ``tracking.didymos_when_unseen_s``
        (since it was last seen, or since ACQUISITION began) before its trajectory is trusted, while Didymos's
        recognition (on every line of sight of Didymos) has enough of them and fits its recent ones within its noise
        (``tracking.cross_check_fit_sigma``): Didymos's trajectory then bounds Dimorphos's place to the orbit's
        radius, where ground's nominal, 3 sigma off, carries the pointing away."""
        limit, didymos, m = self.cfg.tracking.didymos_when_unseen_s, self.didymos_recognizer, self.modes
        seen = self._last_seen_obt
        if seen is None and m.mode == Mode.ACQUISITION:
            seen = m.since_obt_s  # never seen: counted from ACQUISITION's start
        return limit is not None and didymos is not None and seen is not None \
            and self._req is not None and m.mode in (Mode.NOMINAL_TRACKING, Mode.ACQUISITION) \
            and self._tick_s() - seen >= limit \
            and didymos.measurement_count >= self.cfg.min_recognition_measurements and self._didymos_fits()

    def _recognition_trusted(self) -> bool:
        """Whether Dimorphos's own lines of sight are enough for its recognised trajectory to be trusted: enough
        of them, and not contradicted by Didymos's (``_contradicted``)."""
        rec = self.recognizer
        return rec is not None and rec.measurement_count >= self.cfg.min_recognition_measurements \
            and not self._contradicted()

    def _contradicted(self) -> bool:
        """Whether Dimorphos's recognised trajectory is farther from Didymos's (recognised on every line of sight of
        Didymos, ``tracking.didymos_cross_check``) than their centroids can be apart: the orbit's radius plus both
        bodies' largest apparent radii, along the track in C/A time and across it in C/A distance, beyond
        ``tracking.cross_check_sigma`` of their uncertainties (``recognition.estimates_agree``), while Didymos's fits
        its own recent lines of sight within its noise (``tracking.cross_check_fit_sigma``: other blobs taken for
        Didymos scatter them, and its trajectory then says nothing of Dimorphos's)."""
        rec, didymos, n = self.recognizer, self.didymos_recognizer, self.cfg.min_recognition_measurements
        if not self.cfg.tracking.didymos_cross_check or rec is None or didymos is None \
                or rec.measurement_count < n or didymos.measurement_count < n:
            return False
        key = (rec.measurement_count, didymos.measurement_count)
        if self._cross_check is None or self._cross_check[0] != key:
            tc = self.cfg.tracking
            agree = estimates_agree(rec.continuous_estimate(), didymos.continuous_estimate(),
                                    self.cfg.targets.centroids_apart_max_m / 1e3,
                                    rec.nominal.speed_km_s, tc.cross_check_sigma)
            self._cross_check = (key, not agree and self._didymos_fits())
        return self._cross_check[1]

    def _didymos_fits(self) -> bool:
        """Whether Didymos's recognition fits its own last ``tracking.cross_check_recent`` lines of sight within
        ``tracking.cross_check_fit_sigma`` of the angle noise (other blobs taken for Didymos scatter them), judged once
        per measurement count."""
        didymos = self.didymos_recognizer
        assert didymos is not None
        count = didymos.measurement_count
        if self._didymos_fit is None or self._didymos_fit[0] != count:
            tc = self.cfg.tracking
            self._didymos_fit = (count, didymos.recent_scatter_rad(tc.cross_check_recent)
                                 <= tc.cross_check_fit_sigma * self.cfg.recognition.angle_noise_rad)
        return self._didymos_fit[1]

    def _recognised_trajectory(self) -> NominalTrajectory | None:
        """The trajectory recognised on board, once it is trusted (None before)."""
        return self._autonomous_trajectory() if self._recognition_trusted() else None

    def _frame_anomaly(self, kind: pus.FrameAnomaly, frame_id: int, statistic: float, now: float) -> None:
        """Count a discarded frame; report the first of a run of them."""
        if self.frame_watch.anomaly(kind):
            self._event(pus.FrameAnomalyEvent(anomaly=kind, frame_id=frame_id, statistic=statistic), now,
                        f"frame {frame_id} {kind.name.lower()} ({statistic:.3g}): discarded")

    def _tick_s(self) -> float:
        """OBT of this minor frame's tick."""
        assert self._req is not None
        return self._req.obt_s

    def _frame_request(self, obt: float) -> FrameRequest | None:
        if not self.imaging or self._next_frame_obt is None or obt < self._next_frame_obt:
            return None
        if self._settle_since_obt is not None:
            if obt < self._settle_since_obt + self.cfg.modes.acquisition_settle_timeout_s and not self._settled():
                return None
            self._settle_since_obt = None
            self._next_frame_obt = obt  # the cadence counts from the first frame, not from the held ones
        self._next_frame_obt = max(self._next_frame_obt + self.frame_period_s, obt)
        return FrameRequest(exposure_s=self.exposure_s)

    def _settled(self) -> bool:
        """The estimated boresight within ``modes.acquisition_settle_deg`` of the reference computed in
        ACQUISITION after its entry (``_settle_since_obt``, cleared by any other mode change)."""
        ref = self.last_reference
        if ref is None or self._reference_obt is None or self._settle_since_obt is None \
                or self._reference_obt <= self._settle_since_obt:
            return False
        aim = matrix_of_quaternion(ref.q_des) @ np.asarray(self.camera.boresight_body, dtype=float)
        return boresight_error_rad(self._q, self.camera.boresight_body, aim) \
            <= math.radians(self.cfg.modes.acquisition_settle_deg)

    # -- modes ---------------------------------------------------------------------------------------------
    def _mode_event(self, ev: ModeEvent | None, obt: float) -> None:
        if ev is None:
            return
        cause = ev.cause.value + (f": {ev.detail}" if ev.detail else "")
        self._event(pus.ModeChangedEvent(from_mode=ev.from_mode, to_mode=ev.to_mode, cause=cause[:255]), obt,
                    f"mode {ev.from_mode.name} -> {ev.to_mode.name} ({cause})")
        if ev.cause == Cause.TARGET_ACQUIRED and self.detections is not None and self.detections.dimorphos is not None:
            b = self.detections.dimorphos
            self._event(pus.TargetAcquiredEvent(centroid_x_px=b.centroid_col_row[0], centroid_y_px=b.centroid_col_row[1],
                                                area_px=b.area_px), obt, "target acquired")
        if ev.cause == Cause.TARGET_LOST and self._last_seen_obt is not None:
            self._event(pus.TargetLostEvent(unseen_s=obt - self._last_seen_obt), obt, "target lost")
        if ev.to_mode in POINTING_MODES and not self.imaging:
            self.imaging, self._next_frame_obt = True, self._tick_s()
        self._settle_since_obt = obt if ev.to_mode == Mode.ACQUISITION and ev.from_mode in (Mode.STANDBY, Mode.SAFE) \
            else None
        if ev.to_mode == Mode.AUTONOMOUS_TRACKING and self.recognizer is not None and self.trajectory is not None:
            t_ca, d_ca = self.best_estimate()
            self.trajectory = self.trajectory.with_ca(t_ca, d_ca)
            moved = self.schedule.reanchor_ca(t_ca)
            self._log.append(f"OBT {obt:.2f} s: autonomous trajectory C/A at OBT {t_ca:.2f} s, {d_ca:.2f} km; "
                             f"{len(moved)} C/A-relative command(s) re-anchored")
        if ev.to_mode in (Mode.STANDBY, Mode.SAFE):
            self.imaging = False
        if ev.to_mode == Mode.SAFE:  # hold the attitude of entry; no scheduled command runs until ground says so
            self._safe_q = self._q.copy()
            self.schedule.enabled = False
            self._log.append(f"OBT {obt:.2f} s: SAFE: attitude held, time-based schedule disabled")

    def best_estimate(self) -> tuple[float, float]:
        """(C/A time OBT s, C/A distance km) of the best trajectory recognised on board."""
        assert self.recognizer is not None
        if self.cfg.autonomy_estimate == "continuous":
            t, d, _ = self.recognizer.continuous()
            return t, d
        t, d, _ = self.recognizer.best_grid()
        return t, d

    def _mode_by_events(self, obt: float, detected: bool) -> None:
        m = self.modes
        if self.trajectory is not None and m.mode == Mode.NOMINAL_TRACKING and self._recognition_trusted():
            # C/A-30 s is judged on the on-board estimate, which absorbs both ephemeris and clock errors
            self._mode_event(m.handle(CaEstimate(self.best_estimate()[0]), obt), obt)
        if detected:
            self._mode_event(m.handle(TargetDetected(), obt), obt)
        self._mode_event(m.handle(Tick(), obt), obt)

    # -- control -------------------------------------------------------------------------------------------
    def pointing_trajectory(self) -> NominalTrajectory | None:
        """The trajectory the camera follows: the recognised one, refreshed with every measurement, in
        AUTONOMOUS_TRACKING, and in NOMINAL_TRACKING or ACQUISITION while Dimorphos, once recognised, goes unseen
        (``_unseen_since_recognised``); before Dimorphos's is trusted, Didymos's standing in once there is one
        (``_stand_in_trajectory``; in NOMINAL_TRACKING with ``tracking.stand_in_pointed_on``); the ground's nominal
        otherwise."""
        rec = self.recognizer
        if rec is None:
            return self.trajectory
        if self.modes.mode != Mode.AUTONOMOUS_TRACKING:
            if self._unseen_since_recognised():
                return self._autonomous_trajectory()
            stand_in = self._stand_in_trajectory() if self.cfg.tracking.stand_in_pointed_on else None
            return stand_in or self.trajectory
        if not self._recognition_trusted():
            return self._stand_in_trajectory() or self.trajectory
        return self._autonomous_trajectory()

    def _unseen_since_recognised(self) -> bool:
        """Whether, in NOMINAL_TRACKING or ACQUISITION, Dimorphos has gone unseen for
        ``tracking.recognised_when_unseen_s`` since it was last seen, its trajectory recognised: ground's nominal
        alone would carry the pointing away (its C/A seconds off) before the target is found again."""
        limit = self.cfg.tracking.recognised_when_unseen_s
        return limit is not None and self._last_seen_obt is not None and self._req is not None \
            and self.modes.mode in (Mode.NOMINAL_TRACKING, Mode.ACQUISITION) and self._recognition_trusted() \
            and self._tick_s() - self._last_seen_obt >= limit

    def _autonomous_trajectory(self) -> NominalTrajectory:
        """The recognised trajectory pointed on, refreshed with every measurement (trusted: ``_recognition_trusted``)."""
        rec = self.recognizer
        assert rec is not None
        if self.autonomous_trajectory is None or self._autonomous_count != rec.measurement_count:
            self._autonomous_count = rec.measurement_count
            self.autonomous_trajectory = rec.continuous_trajectory() if self.cfg.autonomy_estimate == "continuous" \
                else rec.best_trajectory()
        return self.autonomous_trajectory

    def _control(self, obt: float, dt: float, q: np.ndarray, omega: np.ndarray, wheel_h: np.ndarray,
                 seen: Measurement | None) -> np.ndarray:
        traj = self.pointing_trajectory()
        tc = self.cfg.tracking
        if self.modes.mode in POINTING_MODES and traj is not None:
            meas = seen if self.modes.mode in TRACKING_MODES else None
            autonomous = self.modes.mode == Mode.AUTONOMOUS_TRACKING and traj is self.autonomous_trajectory
            # a late measurement is taken at its exposure, unless the comparison without propagation is asked for
            taken = None if meas is None else min(meas.exposure_obt_s, obt) if tc.propagate_late_measurements else obt
            ref = self.tracking.update(obt, dt, traj, None if meas is None else meas.los_inertial,
                                       measured_obt_s=taken,
                                       extrapolate=tc.autonomous_extrapolation or not autonomous,
                                       gate_rad=math.radians(tc.autonomous_gate_deg) if autonomous else None)
        elif self.modes.mode == Mode.SAFE and self._safe_q is not None:  # the attitude of SAFE's entry, at rest
            self.tracking.reset()
            ref = Reference(q_des=self._safe_q, omega_des_body=np.zeros(3), alpha_des_body=np.zeros(3))
        else:  # hold the current attitude, rate to zero
            if self.last_reference is None or self.modes.mode not in (Mode.STANDBY, Mode.SAFE):
                self.tracking.reset()
            ref = Reference(q_des=q if self.last_reference is None else self.last_reference.q_des,
                            omega_des_body=np.zeros(3), alpha_des_body=np.zeros(3))
        self.last_reference, self._reference_obt = ref, obt
        if seen is not None:  # the boresight at the exposure against the LOS measured then
            q_exposure = self._attitude_at(seen.exposure_obt_s)
            self.pointing_error_est_rad = boresight_error_rad(q_exposure, self.camera.boresight_body,
                                                              seen.los_inertial)
        body_torque = pd_torque_nm(q, omega, ref, self.inertia, self.cfg.control, self.axes @ wheel_h)
        tau = wheel_torques_nm(body_torque, self.axes, wheel_h, self.max_torque_nm, self.max_momentum_nms,
                               self._in_use())
        if not all(math.isfinite(t) for t in tau.tolist()):
            raise InternalFault(f"non-finite wheel torque {tau.tolist()} at OBT {obt}")
        return tau

    def _time_report(self, obt: float) -> None:
        """A service 9 time report when due, first in the period's downlink so its delay on the link is known."""
        if self._time_report_period is not None and self._time_report_next is not None and \
                obt >= self._time_report_next and self._time_reports_left != 0:
            self._send(pus.TimeReport(rate_exponent=self._time_rate_exponent, obt_s=obt), obt)
            self._time_report_next += self._time_report_period
            if self._time_reports_left > 0:
                self._time_reports_left -= 1

    # -- periodic telemetry ----------------------------------------------------------------------------------
    def _periodic_tm(self, obt: float) -> int:
        """Housekeeping and the estimate report when due; the number of packets sent."""
        q, omega, wheel_speed, wheel_h = self._q, self._omega, self._wheel_speed, self._wheel_h
        ex = self.executive
        sent = 0
        if self._hk_next is None or obt >= self._hk_next:
            self._hk_next = (obt if self._hk_next is None else self._hk_next) + self.cfg.housekeeping_period_s
            best_t = best_d = mse = None
            if self.recognizer is not None:
                best_t, best_d, mse = self.recognizer.best_grid()
            self._send(pus.Housekeeping(
                mode=self.modes.mode, q=tuple(float(c) for c in q),
                rate_rad_s=tuple(float(c) for c in omega), wheel_speed_rad_s=tuple(float(c) for c in wheel_speed),
                wheel_momentum_nms=tuple(float(c) for c in wheel_h), pointing_error_rad=self.pointing_error_est_rad,
                best_ca_obt_s=best_t, best_ca_distance_km=best_d, best_mse_rad2=mse,
                task_time_last_s=tuple(ex.last_execution_s[t] for t in _TASKS),
                task_time_max_s=tuple(ex.max_execution_s[t] for t in _TASKS),
                exposure_to_centroid_s=self._exposure_to_centroid_s, centroid_to_torque_s=self._centroid_to_torque_s,
                task_overruns=ex.task_overruns, frame_overruns=ex.frame_overruns, skipped_releases=ex.skipped,
                gyro_bias_rad_s=tuple(float(c) for c in self._bias), attitude_sigma_rad=self._attitude_sigma_rad,
                wheels_in_use=self.wheels_in_use, wheels_failed=self.wheel_health.failed_mask,
                frames_discarded=min(self.frame_watch.discarded, 0xFFFF),
                measurements_rejected=min(self.lock_gate.rejected, 0xFFFF), **self.security.housekeeping()), obt)
            sent += 1
        if self.recognizer is not None and self.recognizer.measurement_count > 0 and obt >= self._estimate_next:
            self._estimate_next = obt + self.cfg.housekeeping_period_s
            gt, gd, mse = self.recognizer.best_grid()
            e = self.recognizer.continuous_estimate()
            self._send(pus.EstimateReport(
                n_measurements=self.recognizer.measurement_count, grid_ca_obt_s=gt, grid_ca_distance_km=gd,
                grid_mse_rad2=mse, continuous_ca_obt_s=e.ca_time_obt_s, continuous_ca_distance_km=e.ca_distance_km,
                continuous_sigma_time_s=float(np.sqrt(e.cov[0, 0])),
                continuous_sigma_distance_km=float(np.sqrt(e.cov[1, 1])), los_offset_in_plane_rad=e.in_plane_offset_rad,
                los_offset_out_of_plane_rad=e.out_of_plane_offset_rad), obt)
            sent += 1
        return sent


_TASKS = tuple(Task)  # in the dictionary's order; iterating the enumeration itself is slow


def _col_row(blob: object) -> tuple[float, float] | None:
    return None if blob is None else blob.centroid_col_row  # type: ignore[attr-defined]
