"""On-board FDIR in the flight software: wheel failures answered by reconfiguration or SAFE, SAFE as a real mode, an
OBT jump that moves nothing physical, discarded frames, late C/A-relative releases, lost uplink, and services 12
and 19 commanded from the ground."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from contracts import pus
from flyby.inprocess import run_in_process
from obsw.config import ObswConfig
from obsw.software import FlightSoftware
from scenario.model import scenario_from_dict
from tests.obsw.test_software import (
    APID,
    DT,
    KEYS,
    OBT0,
    SHORT_FLYBY,
    SHORT_TIMELINE,
    TRAJECTORY,
    _fly,
    _imaging_fsw,
    _of,
    _request,
    _tm,
    _two_bodies_frame,
)
from contracts.messages import FrameMeta
from timeline.parse import timeline_from_data

FAILED_AT_S = 128.0  # C/A-40 s of the short flyby: tracking, slewing about body Y

CA_AFTER_OBT0_S = TRAJECTORY.ca_obt_s - OBT0  # the C/A-relative tags below are placed against it


def _short_flyby_with(fault: dict, layout: str) -> tuple[object, list]:
    """The short closed-loop flyby at centroid fidelity with one fault and a wheel layout: the run and its packets."""
    data = {**SHORT_FLYBY, "universe": {**SHORT_FLYBY["universe"], "fidelity": "centroid", "faults": [fault],
                                        "spacecraft": {"wheels": {"layout": layout}}}}
    run = run_in_process(scenario_from_dict(data), timeline_from_data(SHORT_TIMELINE))
    return run, [(p.header, p.report) for p in run.received if p.report is not None]


def _obt_at(run: object, t_s: float) -> float:
    truth = run.truth  # type: ignore[attr-defined]
    return float(np.interp(t_s, [x.t_s for x in truth], [x.obt_s for x in truth]))


def test_main_slew_wheel_failed_on_three_wheels_goes_to_safe_within_ten_seconds() -> None:
    """Wheel 1 (body Y, the slew axis) dies: found failed, the event action switches to wheels 0 and 2, which cannot
    torque Y, so a FaultEvent and SAFE follow within 10 s of the failure; in SAFE the wheels stay within their limit
    and the axes they control are held at rest."""
    run, packets = _short_flyby_with({"kind": "wheel_failed", "wheel": 1, "start_s": FAILED_AT_S, "end_s": 180.0},
                                     "orthogonal")
    t0 = _obt_at(run, FAILED_AT_S)
    failed = [h.obt_s for h, r in packets if isinstance(r, pus.WheelFailedEvent) and r.wheel == 1]
    sets = [r for _, r in packets if isinstance(r, pus.WheelSetEvent)]
    faults = [r for _, r in packets if isinstance(r, pus.FaultEvent)]
    safe = [h.obt_s for h, r in packets if isinstance(r, pus.ModeChangedEvent) and r.to_mode == pus.Mode.SAFE]
    assert failed and t0 < failed[0] < t0 + 10.0
    assert [(s.wheels_in_use, s.controllable_axes) for s in sets] == [(0b101, 0b101)]
    assert [f.fault_code for f in faults] == [pus.FaultCode.WHEELS_CANNOT_CONTROL]
    assert len(safe) == 1 and safe[0] < t0 + 10.0
    after = [x for x in run.truth if x.obt_s > safe[0] + 10.0]
    assert max(max(abs(h) for h in x.wheel_momentum_nms) for x in after) < 0.1
    assert max(abs(x.omega_rad_s[0]) + abs(x.omega_rad_s[2]) for x in after[-50:]) < np.radians(0.05)
    hk = [r for _, r in packets if isinstance(r, pus.Housekeeping)]
    assert hk[-1].mode == pus.Mode.SAFE and hk[-1].wheels_failed == 0b010 and hk[-1].wheels_in_use == 0b101


def test_a_pyramid_losing_a_wheel_reconfigures_to_three_and_keeps_tracking() -> None:
    """Wheel 1 of four stuck: found, the control goes on with wheels 0, 2 and 3 (all axes controllable), no SAFE,
    Dimorphos in every frame to the end of the run past C/A."""
    run, packets = _short_flyby_with({"kind": "wheel_stuck", "wheel": 1, "start_s": FAILED_AT_S, "end_s": 180.0},
                                     "pyramid")
    sets = [r for _, r in packets if isinstance(r, pus.WheelSetEvent)]
    assert [(s.wheels_in_use, s.wheels_failed, s.controllable_axes) for s in sets] == [(0b1101, 0b0010, 0b111)]
    assert not [r for _, r in packets if isinstance(r, pus.ModeChangedEvent) and r.to_mode == pus.Mode.SAFE]
    frames = [x for x in run.truth if x.frame_id is not None and x.t_s > FAILED_AT_S]
    assert len(frames) > 80 and all(x.target_in_fov for x in frames)


class Wheels:
    """Wheel speeds that follow the commanded torques (the body, held by the fixture, does not turn)."""

    def __init__(self) -> None:
        self.speeds = np.zeros(3)

    def request(self, fsw: FlightSoftware, reply: object, step: int, obt_s: float, **kw: object) -> object:
        """The next period's request, with the speeds the last torques gave."""
        self.speeds = self.speeds + np.asarray(reply.wheel_torque_nm) * DT / fsw.wheel_inertia_kgm2  # type: ignore
        return _request(step, obt_s, wheels=tuple(float(w) for w in self.speeds), **kw)  # type: ignore[arg-type]


def _safe_fsw() -> tuple[FlightSoftware, np.ndarray, Wheels, object]:
    """A flight software commanded to SAFE at an attitude turned from the reference: (it, the attitude of entry, its
    wheels, its last reply)."""
    fsw, reply = _imaging_fsw()
    wheels = Wheels()
    q_entry = Rotation.from_rotvec([0.0, 0.02, 0.0]).as_quat()
    for k in range(1, 20):  # the estimator takes the attitude
        reply = fsw.step(wheels.request(fsw, reply, k, OBT0 + k * DT, q=tuple(q_entry)), None)
    reply = fsw.step(wheels.request(fsw, reply, 20, OBT0 + 20 * DT, q=tuple(q_entry),
                                    uplink=(pus.encode_tc(pus.SetMode(mode=pus.Mode.SAFE), APID, 4),)), None)
    assert fsw.mode_name == "SAFE"
    return fsw, q_entry, wheels, reply


def test_safe_holds_the_attitude_of_its_entry_at_rest() -> None:
    """In SAFE the reference is the attitude at entry with zero rate: turned away from it, the body torque points
    back; at it and at rest, no torque; imaging stops and the schedule releases nothing."""
    fsw, q_entry, wheels, reply = _safe_fsw()
    assert not fsw.imaging and not fsw.schedule.enabled
    reply = fsw.step(wheels.request(fsw, reply, 21, OBT0 + 21 * DT, q=tuple(q_entry)), None)
    held = Rotation.from_quat(fsw.last_reference.q_des) * Rotation.from_quat(q_entry).inv()
    assert held.magnitude() < 1e-4 and not np.any(fsw.last_reference.omega_des_body)
    turned = Rotation.from_rotvec([0.0, 0.03, 0.0]).as_quat()
    for k in range(22, 30):  # a few periods for the estimator to take the new attitude
        reply = fsw.step(wheels.request(fsw, reply, k, OBT0 + k * DT, q=tuple(turned)), None)
    body = -fsw.axes @ np.asarray(reply.wheel_torque_nm)
    assert body[1] < 0 and abs(body[1]) > 10 * max(abs(body[0]), abs(body[2]))


def test_safe_is_left_by_command_and_the_schedule_enabled_again() -> None:
    """SAFE -> STANDBY by command, the schedule enabled by TC[11,1], then ACQUISITION: a scheduled command is
    released again."""
    fsw, q, wheels, reply = _safe_fsw()
    inner = pus.encode_tc(pus.Ping(), APID, 0x2100)
    insert = pus.InsertActivities(activities=(pus.ScheduledActivity(release_obt_s=OBT0 + 5.0, tc_packet=inner),))
    tcs = (pus.encode_tc(pus.SetMode(mode=pus.Mode.STANDBY), APID, 5), pus.encode_tc(pus.EnableSchedule(), APID, 6),
           pus.encode_tc(pus.SetMode(mode=pus.Mode.ACQUISITION), APID, 7), pus.encode_tc(insert, APID, 8))
    reply = fsw.step(wheels.request(fsw, reply, 21, OBT0 + 21 * DT, q=tuple(q), uplink=tcs), None)
    assert fsw.mode_name == "ACQUISITION" and fsw.schedule.enabled
    pings = []
    for k in range(22, 60):
        reply = fsw.step(wheels.request(fsw, reply, k, OBT0 + k * DT, q=tuple(q)), None)
        pings += [k] * len(_of(_tm(reply.downlink), pus.PingReply))
    assert pings == [50]


def test_an_obt_jump_moves_nothing_physical() -> None:
    """Two flight softwares in ACQUISITION on the same trajectory and schedule; one's clock jumps +5 s midway: from
    then on it commands the same torques at the same physical times, and releases its C/A-relative command at the
    same period, with a ClockJumpEvent and a TimeShiftedEvent naming the entry moved."""
    tcs = (pus.encode_tc(TRAJECTORY, APID, 0), pus.encode_tc(pus.SetMode(mode=pus.Mode.ACQUISITION), APID, 1),
           pus.encode_tc(pus.InsertCaRelativeActivities(activities=(pus.CaRelativeActivity(
               ca_offset_s=3.0 - CA_AFTER_OBT0_S, release_obt_s=OBT0 + 3.0, tc_packet=pus.encode_tc(pus.Ping(), APID, 0x2001)),)),
               APID, 2))
    a, b = FlightSoftware(ObswConfig(), KEYS), FlightSoftware(ObswConfig(), KEYS)
    q = tuple(Rotation.from_rotvec([0.01, -0.02, 0.03]).as_quat())
    first = _request(0, OBT0, tcs, q=q)
    ra, rb = a.step(first, None), b.step(first, None)
    wa, wb = Wheels(), Wheels()
    jump = 5.0
    pings: dict[str, list[int]] = {"a": [], "b": []}
    events = []
    for k in range(1, 50):
        shift = jump if k >= 10 else 0.0
        ra = a.step(wa.request(a, ra, k, OBT0 + k * DT, q=q), None)
        rb = b.step(wb.request(b, rb, k, OBT0 + k * DT + shift, q=q), None)
        assert np.allclose(ra.wheel_torque_nm, rb.wheel_torque_nm, rtol=1e-6, atol=1e-12), k
        pings["a"] += [k] * len(_of(_tm(ra.downlink), pus.PingReply))
        pings["b"] += [k] * len(_of(_tm(rb.downlink), pus.PingReply))
        events += [r for _, r in _tm(rb.downlink) if isinstance(r, pus.ClockJumpEvent | pus.TimeShiftedEvent)]
    assert pings["a"] == pings["b"] == [30]
    assert [type(e).__name__ for e in events] == ["ClockJumpEvent", "TimeShiftedEvent"]
    assert events[1].step_s == pytest.approx(jump) and events[1].schedule_entries == 1
    assert b.trajectory.ca_time_obt_s == pytest.approx(a.trajectory.ca_time_obt_s + jump)


def test_saturated_blank_and_missing_frames_are_discarded_and_reported_once_per_run() -> None:
    """After the target is seen: two saturated frames give one SATURATED event, a blank one a BLANK event, a frame
    requested and never delivered a MISSING one; none gives a line of sight; housekeeping counts all four."""
    fsw, reply = _imaging_fsw()
    good = _two_bodies_frame((300, 240), (330, 220))
    full = np.full((1024, 1024), 4095, dtype=np.uint16)
    blank = np.full((1024, 1024), 200, dtype=np.uint16)
    plan = [good, good, full, full, blank, good, None, good, good]
    events, measured_frames, frame_id = [], [], 0
    speeds = np.zeros(3)
    k = 0
    for pixels in plan:
        while True:  # step until the next frame request, then expose (or lose) the frame at the next tick
            k += 1
            speeds = speeds + np.asarray(reply.wheel_torque_nm) * DT / fsw.wheel_inertia_kgm2
            requested = reply.frame_request is not None
            meta = None
            if requested and pixels is not None:
                meta = FrameMeta(frame_id=frame_id, obt_s=OBT0 + k * DT, width=1024, height=1024, bit_depth=12,
                                 exposure_s=0.01)
            reply = fsw.step(_request(k, OBT0 + k * DT, frame=meta, wheels=tuple(speeds)),
                             pixels if meta is not None else None)
            events += _of(_tm(reply.downlink), pus.FrameAnomalyEvent)
            measured_frames += [ev.payload.frame_id for run in fsw.last_frame.runs if run.task.name == "CONTROL"
                                for ev in run.events if ev.kind.name == "MEASUREMENT"]
            if requested:
                frame_id += meta is not None
                break
    assert [e.anomaly for e in events] == [pus.FrameAnomaly.SATURATED, pus.FrameAnomaly.BLANK,
                                           pus.FrameAnomaly.MISSING]
    assert events[0].statistic == 1.0
    assert not {2, 3, 4} & set(measured_frames) and {0, 1, 5}.issubset(measured_frames)
    assert fsw.frame_watch.discarded == 4


def test_a_ca_relative_command_past_on_arrival_is_released_at_once_with_an_event() -> None:
    """A C/A-relative activity whose tag is 20 s past when it arrives runs at the schedule's next release, in the
    same minor frame, with a LateReleaseEvent of about 20 s; an absolute one as late is refused."""
    fsw = FlightSoftware(ObswConfig(), KEYS)
    ping = pus.encode_tc(pus.Ping(), APID, 0x2002)
    late = pus.InsertCaRelativeActivities(activities=(pus.CaRelativeActivity(
        ca_offset_s=-20.0 - CA_AFTER_OBT0_S, release_obt_s=OBT0 - 20.0, tc_packet=ping),))
    tm = _tm(fsw.step(_request(0, OBT0, (pus.encode_tc(TRAJECTORY, APID, 0), pus.encode_tc(late, APID, 1))),
                      None).downlink)
    (ev,) = _of(tm, pus.LateReleaseEvent)
    assert ev.late_s == pytest.approx(20.0, abs=0.01) and ev.request_id.seq_count == 0x2002
    assert len(_of(tm, pus.PingReply)) == 1
    absolute = pus.InsertActivities(activities=(pus.ScheduledActivity(release_obt_s=OBT0 - 20.0, tc_packet=ping),))
    tm = _tm(fsw.step(_request(2, OBT0 + 2 * DT, (pus.encode_tc(absolute, APID, 2),)), None).downlink)
    assert [v.failure_code for v in _of(tm, pus.Verification) if not v.success] == [0x0104]


def test_a_gap_in_the_uplinked_sequence_counts_is_reported() -> None:
    """TCs 0 and 1 received, then 5: an UplinkGapEvent of 3 lost before 5."""
    fsw = FlightSoftware(ObswConfig(), KEYS)
    tcs = tuple(pus.encode_tc(pus.Ping(), APID, n) for n in (0, 1, 5))
    (gap,) = _of(_tm(fsw.step(_request(0, OBT0, tcs), None).downlink), pus.UplinkGapEvent)
    assert (gap.expected_seq, gap.received_seq, gap.lost) == (2, 5, 3)


def test_monitoring_and_event_actions_loaded_by_telecommand() -> None:
    """A limit check on the body rate added by TC[12,5] reports the rate leaving it (with the definition's severity);
    an event-action added by TC[19,1] and enabled by TC[19,4] stops imaging on that event; its own events trigger
    nothing further."""
    fsw, reply = _imaging_fsw()
    d = pus.MonitoringDefinition(pmon_id=7, parameter=pus.Parameter.BODY_RATE, check_type=pus.CheckType.LIMIT,
                                 repetition=2, low=0.0, high=0.01, severity=pus.Severity.HIGH)
    stop = pus.encode_tc(pus.StopImaging(), APID, 0x2003, source_id=1)
    tcs = (pus.encode_tc(pus.AddParameterMonitoringDefinitions(definitions=(d,)), APID, 4),
           pus.encode_tc(pus.AddEventActions(definitions=(pus.EventActionDefinition(
               event_id=pus.EventId.PARAMETER_CHECK, tc_packet=stop),)), APID, 5),
           pus.encode_tc(pus.EnableEventActions(event_ids=(pus.EventId.PARAMETER_CHECK,)), APID, 6))
    fsw.step(_request(1, OBT0 + DT, tcs), None)
    assert fsw.imaging
    checks = []
    for k in range(2, 6):
        tm = _tm(fsw.step(_request(k, OBT0 + k * DT, gyro=(0.0, 0.02, 0.0)), None).downlink)
        checks += _of(tm, pus.ParameterCheckEvent)
    assert [(c.pmon_id, c.severity, c.status) for c in checks] == [(7, pus.Severity.HIGH, pus.CheckStatus.ABOVE_HIGH)]
    assert not fsw.imaging
