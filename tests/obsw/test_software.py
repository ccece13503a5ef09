"""The flight software core: PUS verification and rejection reports, schedule release, mode events, frame
geometry at exposure time, and a short image-in-the-loop flyby through C/A against the simulation truth."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import minimize_scalar
from scipy.spatial.transform import Rotation

from contracts import pus, sdls
from contracts.messages import CentroidMeasurement, FrameMeta, SensorData, StepRequest
from contracts.task import Task
from scenario.model import scenario_from_dict
from obsw.config import ObswConfig, TrackingConfig
from obsw.errors import RejectReason
from obsw.executive import EventKind
from obsw.imaging import predict_frame
from obsw.software import FlightSoftware
from obsw.tracking import TrackingLoop
from obsw.trajectory import NominalTrajectory
from timeline.parse import timeline_from_data
from universe.geometry import FlybyGeometry

APID = ObswConfig().apid
OBT0 = 1000.0
DT = ObswConfig().control_period_s
Q0 = (0.0, 0.0, 0.0, 1.0)


KEYS = sdls.KeyRing.generate()
GROUND = sdls.Sender(KEYS)  # its anti-replay numbers only grow, so each new flight software accepts them


def _fsw() -> FlightSoftware:
    return FlightSoftware(ObswConfig(), KEYS)


def _request(step: int, obt_s: float, uplink: tuple[bytes, ...] = (), q: tuple | None = Q0,
             gyro: tuple[float, float, float] = (0.0, 0.0, 0.0), wheels: tuple[float, ...] = (0.0, 0.0, 0.0),
             frame: FrameMeta | None = None) -> StepRequest:
    """A control period's inputs; the uplinked TC packets are secured as ground radiates them."""
    return StepRequest(step=step, obt_s=obt_s, uplink=tuple(GROUND.secure(p) for p in uplink), frame=frame,
                       sensors=SensorData(star_tracker_q=q, gyro_rad_s=gyro, wheel_speed_rad_s=wheels))


def _tm(reply_downlink: tuple[bytes, ...]) -> list[tuple[pus.TmHeader, pus.TmReport]]:
    return [pus.decode_tm(p) for p in reply_downlink]


def _of(tm: list[tuple[pus.TmHeader, pus.TmReport]], kind: type) -> list:
    return [r for _, r in tm if isinstance(r, kind)]


def test_accepted_command_is_verified_at_acceptance_start_and_completion() -> None:
    """A valid TC asking for every report gets successful acceptance and start reports, its execution (a ping
    reply), then a successful completion."""
    fsw = _fsw()
    tc = pus.encode_tc(pus.Ping(), APID, 42)
    reply = fsw.step(_request(0, OBT0, (tc,)), None)
    kinds = [(type(r).__name__, getattr(r, "stage", None)) for _, r in _tm(reply.downlink)
             if isinstance(r, pus.Verification | pus.PingReply)]
    assert kinds == [("Verification", pus.Stage.ACCEPTANCE), ("Verification", pus.Stage.START), ("PingReply", None),
                     ("Verification", pus.Stage.COMPLETION)]
    for v in _of(_tm(reply.downlink), pus.Verification):
        assert v.success and v.request_id == pus.RequestId(apid=APID, seq_count=42)


def test_corrupted_command_gets_an_acceptance_failure_and_the_next_is_still_served() -> None:
    """A TC with a broken CRC is answered by a BAD_CRC acceptance failure naming it; the TC after it executes."""
    fsw = _fsw()
    bad = bytearray(pus.encode_tc(pus.Ping(), APID, 7))
    bad[-1] ^= 0xFF
    reply = fsw.step(_request(0, OBT0, (bytes(bad), pus.encode_tc(pus.Ping(), APID, 8))), None)
    tm = _tm(reply.downlink)
    failures = [v for v in _of(tm, pus.Verification) if not v.success]
    assert len(failures) == 1
    assert failures[0].stage == pus.Stage.ACCEPTANCE
    assert failures[0].failure_code == pus.FailureCode.BAD_CRC
    assert failures[0].request_id == pus.RequestId(apid=APID, seq_count=7)
    assert len(_of(tm, pus.PingReply)) == 1
    assert {v.request_id.seq_count for v in _of(tm, pus.Verification) if v.success} == {8}


def test_every_telecommand_of_the_dictionary_has_an_on_board_handler() -> None:
    """No TC of the dictionary is accepted only to be refused for want of a handler."""
    fsw = _fsw()
    assert [p.__name__ for p in pus.DICTIONARY.packets if p.KIND == "TC" and p not in fsw._handlers] == []


def test_a_telecommand_without_a_handler_is_refused_at_completion_as_unknown() -> None:
    """A TC the build has no handler for is accepted, then refused at completion with UNKNOWN_COMMAND and a
    rejection event (a build that drops a handler never executes the TC silently)."""
    fsw = _fsw()
    del fsw._handlers[pus.Ping]
    reply = fsw.step(_request(0, OBT0, (pus.encode_tc(pus.Ping(), APID, 5),)), None)
    tm = _tm(reply.downlink)
    stages = [(v.stage, v.failure_code) for v in _of(tm, pus.Verification)]
    code = 0x0100 + int(RejectReason.UNKNOWN_COMMAND)
    assert stages == [(pus.Stage.ACCEPTANCE, None), (pus.Stage.START, None), (pus.Stage.COMPLETION, code)]
    assert [e.failure_code for e in _of(tm, pus.CommandRejectedEvent)] == [code]
    assert _of(tm, pus.PingReply) == []


def test_illegal_mode_command_is_refused_with_a_completion_failure_and_an_event() -> None:
    """AUTONOMOUS_TRACKING commanded from STANDBY: accepted, then refused (failure + rejection event), mode kept."""
    fsw = _fsw()
    tc = pus.encode_tc(pus.SetMode(mode=pus.Mode.AUTONOMOUS_TRACKING), APID, 3)
    reply = fsw.step(_request(0, OBT0, (tc,)), None)
    tm = _tm(reply.downlink)
    ver = _of(tm, pus.Verification)
    assert [(v.stage, v.success) for v in ver] == [(pus.Stage.ACCEPTANCE, True), (pus.Stage.START, True),
                                                   (pus.Stage.COMPLETION, False)]
    code = 0x0100 + 10  # RejectReason.ILLEGAL_TRANSITION in the OBSW's execution-failure range
    assert ver[2].failure_code == code and "AUTONOMOUS_TRACKING" in ver[2].reason
    events = _of(tm, pus.CommandRejectedEvent)
    assert len(events) == 1 and events[0].failure_code == code and events[0].request_id == ver[2].request_id
    assert not _of(tm, pus.ModeChangedEvent)
    assert fsw.mode_name == "STANDBY"


def test_scheduled_command_is_released_at_its_tag_with_a_mode_event() -> None:
    """A SetMode(ACQUISITION) scheduled at OBT0+1.55 s executes at the first period at or after its tag (not
    before), reports its completion and the mode change stamped with the OBT the schedule task ran at in that
    period, and starts imaging in the next period (the first reference of ACQUISITION, here the attitude held, shows
    no slew to wait for)."""
    fsw = _fsw()
    tag = OBT0 + 1.55
    inner = pus.encode_tc(pus.SetMode(mode=pus.Mode.ACQUISITION), APID, 11)
    insert = pus.InsertActivities(activities=(pus.ScheduledActivity(release_obt_s=tag, tc_packet=inner),))
    fsw.step(_request(0, OBT0, (pus.encode_tc(insert, APID, 10),)), None)
    released_at = first_frame = None
    for k in range(1, 30):
        obt = OBT0 + k * DT
        reply = fsw.step(_request(k, obt), None)
        if reply.frame_request is not None and first_frame is None:
            first_frame = obt
        tm = _tm(reply.downlink)
        changes = [(h, r) for h, r in tm if isinstance(r, pus.ModeChangedEvent)]
        if obt < tag - 1e-9:
            assert not changes and fsw.mode_name == "STANDBY"
            continue
        if released_at is None:
            released_at = obt
            assert len(changes) == 1
            header, ev = changes[0]
            assert (ev.from_mode, ev.to_mode) == (pus.Mode.STANDBY, pus.Mode.ACQUISITION)
            assert ev.cause.startswith("COMMANDED")
            released = next(r for r in fsw.last_frame.runs if r.task == Task.SCHEDULE)
            assert abs(header.obt_s - released.start_s) < 2**-16 and obt <= released.start_s < obt + DT
            done = _of(tm, pus.Verification)
            assert [(v.stage, v.success, v.request_id.seq_count) for v in done] == [
                (stage, True, 11) for stage in (pus.Stage.ACCEPTANCE, pus.Stage.START, pus.Stage.COMPLETION)]
            assert reply.frame_request is None
    assert released_at is not None and tag <= released_at < tag + DT
    assert first_frame == pytest.approx(released_at + DT)
    assert fsw.mode_name == "ACQUISITION"


def test_wheel_saturation_is_reported_and_sends_the_spacecraft_to_safe() -> None:
    """A wheel at its momentum limit raises one saturation event naming it and a mode change to SAFE."""
    fsw = _fsw()
    w = ObswConfig().wheels
    speed = 1.01 * w.max_momentum_nms / w.inertia_kgm2
    reply = fsw.step(_request(0, OBT0, wheels=(0.0, -speed, 0.0)), None)
    tm = _tm(reply.downlink)
    sat = _of(tm, pus.WheelSaturationEvent)
    assert len(sat) == 1 and sat[0].wheel == 1 and sat[0].momentum_nms < -w.max_momentum_nms
    changes = _of(tm, pus.ModeChangedEvent)
    assert [(c.from_mode, c.to_mode) for c in changes] == [(pus.Mode.STANDBY, pus.Mode.SAFE)]
    again = fsw.step(_request(1, OBT0 + DT, wheels=(0.0, -speed, 0.0)), None)
    assert not _of(_tm(again.downlink), pus.WheelSaturationEvent)  # reported once, on entering saturation


def test_gyro_propagation_over_an_outage_advances_one_control_period_despite_a_clock_jump() -> None:
    """Star tracker out and OBT jumping 100 s: the attitude is propagated by the gyro's constant rate over one control
    period."""
    fsw = _fsw()
    q0 = Rotation.from_rotvec([0.1, -0.2, 0.3])
    omega = np.array([0.01, 0.02, -0.03])
    fsw.step(_request(0, OBT0, q=tuple(q0.as_quat()), gyro=tuple(omega)), None)
    fsw.step(_request(1, OBT0 + 100.0, q=None, gyro=tuple(omega)), None)
    expected = q0 * Rotation.from_rotvec(omega * DT)
    got = Rotation.from_quat(fsw.attitude.q)
    assert (got.inv() * expected).magnitude() < 1e-6
    assert (got.inv() * q0 * Rotation.from_rotvec(omega * 100.0)).magnitude() > 0.1


def _two_bodies_frame(did_col_row: tuple[int, int], dim_col_row: tuple[int, int]) -> np.ndarray:
    """A 1024x1024 12-bit frame: a flat background and two uniform squares, 20 and 4 binned pixels on a side,
    starting at the given binned (col, row); their binned centroids are start + (side - 1) / 2."""
    frame = np.full((1024, 1024), 200, dtype=np.uint16)
    for (c, r), side in ((did_col_row, 20), (dim_col_row, 4)):
        frame[2 * r : 2 * (r + side), 2 * c : 2 * (c + side)] = 3000
    return frame


def test_frame_line_of_sight_uses_the_attitude_at_exposure() -> None:
    """A frame processed periods after its exposure (readout, FPGA stages, software) is turned into inertial with
    the attitude of its exposure: the reported LOS is R(q_exposure) times the pinhole ray of Dimorphos's centroid."""
    fsw = _fsw()
    q_exp = Rotation.from_rotvec([0.2, 0.1, -0.4])
    q_now = q_exp * Rotation.from_rotvec([0.0, 0.02, 0.0])  # 1.1 deg later
    fsw.step(_request(0, OBT0, q=tuple(q_exp.as_quat())), None)
    frame = _two_bodies_frame((300, 240), (330, 220))
    meta = FrameMeta(frame_id=0, obt_s=OBT0, width=1024, height=1024, bit_depth=12, exposure_s=0.01)
    nav = _of(_tm(fsw.step(_request(1, OBT0 + DT, q=tuple(q_now.as_quat()), frame=meta), frame).downlink),
              pus.NavigationReport)
    for k in range(2, 6):
        nav += _of(_tm(fsw.step(_request(k, OBT0 + k * DT, q=tuple(q_now.as_quat())), None).downlink),
                   pus.NavigationReport)
    assert len(nav) == 1 and nav[0].dimorphos_col_row == pytest.approx((331.5, 221.5))
    f_px = 256.0 / np.tan(np.radians(ObswConfig().camera.fov_deg / 2))
    ray = np.array([331.5 - 255.5, 221.5 - 255.5, f_px])
    expected = q_exp.apply(ray / np.linalg.norm(ray))
    assert np.asarray(nav[0].los_inertial) == pytest.approx(expected, abs=1e-6)


def test_a_centroid_measurement_takes_the_place_of_the_frame() -> None:
    """A frame that carries a measurement and no pixels is reported binned, and its LOS is the pinhole ray of the
    measured full-resolution centroid turned with the attitude of its exposure."""
    fsw = _fsw()
    q_exp = Rotation.from_rotvec([0.2, 0.1, -0.4])
    fsw.step(_request(0, OBT0, q=tuple(q_exp.as_quat())), None)
    m = CentroidMeasurement(dimorphos_col_row=(663.5, 443.5), dimorphos_area_px=40.0, didymos_col_row=(600.5, 480.5),
                            didymos_area_px=400.0)
    meta = FrameMeta(frame_id=0, obt_s=OBT0, width=1024, height=1024, bit_depth=12, exposure_s=0.01, measurement=m)
    q_later = tuple((q_exp * Rotation.from_rotvec([0, 0.02, 0])).as_quat())
    nav = _of(_tm(fsw.step(_request(1, OBT0 + DT, q=q_later, frame=meta), None).downlink), pus.NavigationReport)
    for k in range(2, 6):  # the measurement takes the frame's modelled readout and processing time, as a frame would
        nav += _of(_tm(fsw.step(_request(k, OBT0 + k * DT, q=q_later), None).downlink), pus.NavigationReport)
    assert len(nav) == 1 and nav[0].dimorphos_col_row == pytest.approx((331.5, 221.5))
    assert nav[0].didymos_col_row == pytest.approx((300.0, 240.0)) and nav[0].dimorphos_area_px == 10
    f_px = 512.0 / np.tan(np.radians(ObswConfig().camera.fov_deg / 2))
    ray = np.array([663.5 - 511.5, 443.5 - 511.5, f_px])
    assert np.asarray(nav[0].los_inertial) == pytest.approx(q_exp.apply(ray / np.linalg.norm(ray)), abs=1e-6)


# --- a short flyby in the loop ------------------------------------------------------------------------------------

SHORT_FLYBY = {
    "name": "short-closed-loop",
    "seed": 3,
    "universe": {
        "start_s": 110.0,  # C/A-58 s ... C/A+12 s; the timeline is accepted from ~6 s after the start
        "end_s": 180.0,
        # ground's nominal off by -4 s and +2 km: the camera must find the true C/A on board
        "uncertainty": {"ca_time_offset_sigma": -0.4, "ca_distance_offset_sigma": 0.4},
        "save_frames_every": 0,
        "link": {"one_way_light_time_s": 1.0},
    },
}
SHORT_TIMELINE = {
    "description": "acquisition at C/A-44 s, frames every 0.5 s",
    "commands": [
        {"time": "CA-44s", "command": "set_mode", "args": {"mode": "ACQUISITION"}},
        {"time": "+0s", "command": "start_imaging", "args": {"period_s": 0.5}},
    ],
}


@pytest.fixture(scope="module")
def short_flyby() -> object:
    """The short flyby in process with the default timing and schedule (one run for the tests that read it)."""
    from flyby.inprocess import run_in_process

    return run_in_process(scenario_from_dict(SHORT_FLYBY), timeline_from_data(SHORT_TIMELINE))


def test_short_flyby_in_the_loop_holds_dimorphos_through_ca(short_flyby) -> None:  # noqa: ANN001
    """Acquisition, tracking and autonomous tracking from the on-board C/A-30 s through C/A (7.4 deg/s): Dimorphos
    in every frame after acquisition, within 0.2 deg once autonomous, and the recognised C/A within 0.1 s and
    0.3 km of the spacecraft-Dimorphos truth found by minimising the true distance."""
    scenario = scenario_from_dict(SHORT_FLYBY)
    run = short_flyby
    packets = [(p.header, p.report) for p in run.received if p.report is not None]
    changes = [(h.obt_s, r) for h, r in packets if isinstance(r, pus.ModeChangedEvent)]
    assert [(r.to_mode, r.cause.split(":")[0]) for _, r in changes] == [
        (pus.Mode.ACQUISITION, "COMMANDED"), (pus.Mode.NOMINAL_TRACKING, "TARGET_ACQUIRED"),
        (pus.Mode.AUTONOMOUS_TRACKING, "AUTONOMY_TIME")]
    tracked_from = changes[1][0]
    u = scenario.universe
    g = FlybyGeometry(u.flyby, u.bodies)
    ca = minimize_scalar(lambda t: float(np.linalg.norm(g.spacecraft_position_m(t) - g.dimorphos_position_m(t))),
                         bounds=(u.flyby.ca_time_s - 20, u.flyby.ca_time_s + 20), method="bounded",
                         options={"xatol": 1e-6})
    truth = run.truth
    ca_obt = float(np.interp(ca.x, [x.t_s for x in truth], [x.obt_s for x in truth]))
    frames = [x for x in truth if x.frame_id is not None and x.obt_s >= tracked_from]
    assert len(frames) > 80
    assert all(x.target_in_fov for x in frames)
    assert changes[2][0] == pytest.approx(ca_obt - 30.0, abs=0.2)  # C/A-30 s judged on the on-board estimate
    autonomous = [x for x in truth if x.obt_s >= changes[2][0]]
    assert max(x.pointing_error_rad for x in autonomous) < np.radians(0.2)
    assert max(np.linalg.norm(x.omega_rad_s) for x in truth) > np.radians(7.0)
    estimates = [r for h, r in packets if isinstance(r, pus.EstimateReport) and h.obt_s <= ca_obt]
    last = estimates[-1]
    assert abs(last.continuous_ca_obt_s - ca_obt) < 0.1
    assert abs(last.continuous_ca_distance_km - ca.fun / 1e3) < 0.3


def test_the_default_schedule_holds_the_heaviest_frames_of_a_flyby_without_overrun(short_flyby) -> None:  # noqa: ANN001
    """Through C/A, where the frames hold the most foreground and Dimorphos's limb is fitted, the imaging and
    recognition tasks finish within their slots at the nominal processor speed: no overrun is counted or reported
    (the heaviest frame of this flyby takes 75.6 ms, beyond the 58 ms the imaging slot once had)."""
    packets = [r for r in (p.report for p in short_flyby.received) if r is not None]
    hk = [r for r in packets if isinstance(r, pus.Housekeeping)]
    assert len(hk) > 50 and all((r.task_overruns, r.frame_overruns, r.skipped_releases) == (0, 0, 0) for r in hk)
    assert not [r for r in packets if isinstance(r, pus.TaskOverrunEvent | pus.FrameOverrunEvent)]
    assert not [line for line in short_flyby.log if "overran" in line]


# --- the tracking feedback in autonomous tracking -----------------------------------------------------------------

LINE = NominalTrajectory(ca_time_obt_s=0.0, ca_distance_km=55.0, speed_km_s=7.0, approach_direction=(1.0, 0.0, 0.0),
                         ca_direction=(0.0, 1.0, 0.0))


def _offset_los(t: float, offset_rad: float) -> np.ndarray:
    """The trajectory's LOS at t turned by offset_rad about the plane normal."""
    return Rotation.from_rotvec(offset_rad * LINE.plane_normal).apply(LINE.los_inertial(t))


def _settled_correction(measurements: list[tuple[float, float]], extrapolate: bool, gate_rad: float | None = None,
                        end_s: float = -40.0) -> TrackingLoop:
    """Run the loop from C/A-100 s at 10 Hz with offset measurements (t, offset rad) until end_s."""
    loop = TrackingLoop(TrackingConfig())
    pending = dict(measurements)
    for k in range(int(round((end_s + 100.0) / DT)) + 1):
        t = round(-100.0 + k * DT, 6)
        off = pending.get(t)
        loop.update(t, DT, LINE, None if off is None else _offset_los(t, off), extrapolate=extrapolate,
                    gate_rad=gate_rad)
    return loop


def test_held_offset_settles_on_the_last_measurement_and_extrapolated_on_its_slope() -> None:
    """After two measurements 1 s apart then none, the correction settles on the last offset when held, and on
    the last offset plus slope x extrapolation limit when extrapolated (the loop's type-2 steady state)."""
    meas = [(-95.0, 1e-3), (-94.0, 2e-3)]
    held = _settled_correction(meas, extrapolate=False).correction_rotvec @ LINE.plane_normal
    extended = _settled_correction(meas, extrapolate=True).correction_rotvec @ LINE.plane_normal
    assert held == pytest.approx(2e-3, abs=2e-6)
    assert extended == pytest.approx(2e-3 + 1e-3 * TrackingConfig().extrapolation_limit_s, abs=2e-6)


def test_gate_ignores_an_outlier_and_takes_a_lasting_shift() -> None:
    """An offset 2 mrad off the prediction is ignored under a 1 mrad gate (the loop runs exactly as without it);
    a shift lasting longer than gate_release_count measurements is taken after them."""
    base = [(-95.0 + 0.5 * i, 1e-3) for i in range(10)]
    clean = _settled_correction(base, extrapolate=False, gate_rad=1e-3)
    outlier = _settled_correction([*base[:5], (-92.5, 3e-3), *base[6:]], extrapolate=False, gate_rad=1e-3)
    assert outlier.rejected_count == 1 and clean.rejected_count == 0
    assert np.array_equal(outlier.correction_rotvec, clean.correction_rotvec)
    release = TrackingConfig().gate_release_count
    shifted = _settled_correction([*base, *((-90.0 + 0.5 * i, 4e-3) for i in range(release + 4))],
                                  extrapolate=False, gate_rad=1e-3)
    assert shifted.rejected_count == release
    assert shifted.correction_rotvec @ LINE.plane_normal == pytest.approx(4e-3, abs=2e-5)


@pytest.mark.parametrize("jump_s", [-3.0, -0.2, 0.2, 100.0])
def test_clock_jump_is_reported_once_with_its_size(jump_s: float) -> None:
    """An OBT step of the control period plus J between two periods gives one clock-jump event of J; steady
    periods (with microsecond drift) give none."""
    fsw = _fsw()
    events = []
    obt = OBT0
    for k in range(6):
        if k == 3:
            obt += jump_s
        reply = fsw.step(_request(k, obt), None)
        events += _of(_tm(reply.downlink), pus.ClockJumpEvent)
        obt += DT * (1 + 20e-6)
    assert len(events) == 1
    assert events[0].step_s == pytest.approx(jump_s, abs=1e-5)


# --- the executive's timing in the flight software ------------------------------------------------------------

# C/A 60 s on: Didymos 19 and Dimorphos 4 binned px across, the sizes of _two_bodies_frame's squares
TRAJECTORY = pus.UploadNominalTrajectory(
    ca_obt_s=OBT0 + 60.0, ca_distance_km=55.0, speed_km_s=7.0, approach_direction=(1.0, 0.0, 0.0),
    ca_direction=(0.0, 1.0, 0.0), sigma_ca_time_s=10.0, sigma_ca_distance_km=5.0)
# a frame's modelled latency with the default timing: half the 10 ms exposure, 1024 x 1024 x 12 bit over 80 Mbit/s,
# 512 x 512 binned pixels through binarisation (20 ns) and labelling (40 ns)
FRAME_LATENCY_S = 0.005 + 1024 * 1024 * 12 / 80e6 + 512 * 512 * 60e-9


def _imaging_fsw(cfg: ObswConfig | None = None) -> tuple[FlightSoftware, object]:
    """A flight software with the nominal trajectory, in ACQUISITION, imaging every 0.2 s: its first reply. The
    callers hold the attitude themselves, so ACQUISITION waits for no slew (``acquisition_settle_deg`` 180)."""
    cfg = cfg or ObswConfig()
    cfg = cfg.model_copy(update={"modes": cfg.modes.model_copy(update={"acquisition_settle_deg": 180.0})})
    fsw = FlightSoftware(cfg, KEYS)
    tcs = (pus.encode_tc(TRAJECTORY, APID, 1), pus.encode_tc(pus.SetMode(mode=pus.Mode.ACQUISITION), APID, 2),
           pus.encode_tc(pus.StartImaging(period_s=0.2), APID, 3))
    return fsw, fsw.step(_request(0, OBT0, tcs), None)


def _fly(fsw: FlightSoftware, reply, slowdowns: list[float], delays: list[float]) -> list[tuple]:
    """Step on with a two-body frame exposed at each tick after a frame request, Dimorphos where the trajectory
    puts it; (reply, frame report, frame meta, request) of each step."""
    assert fsw.trajectory is not None
    # the camera held on the trajectory's line of sight at the middle of the run, +X body in the inertial XY plane
    z = fsw.trajectory.los_inertial(OBT0 + 0.5 * len(slowdowns) * DT)
    x = np.cross([0.0, 0.0, 1.0], z)
    x /= np.linalg.norm(x)
    q = tuple(float(v) for v in Rotation.from_matrix(np.column_stack([x, np.cross(z, x), z])).as_quat())
    place = predict_frame(np.asarray(q), fsw.cfg.targets, fsw.camera, fsw.cfg.imaging, fsw.trajectory,
                          OBT0 + DT).dimorphos_col_row
    assert place is not None
    c, r = round(place[0] - 1.5), round(place[1] - 1.5)
    pixels = _two_bodies_frame((c - 30, r + 10), (c, r))
    out, frame_id = [], 0
    speeds = np.zeros(3)  # the wheels follow their torques (the body, held by the fixture, does not turn)
    for k in range(1, len(slowdowns)):
        obt = OBT0 + k * DT
        speeds = speeds + np.asarray(reply.wheel_torque_nm) * DT / fsw.wheel_inertia_kgm2
        meta = None
        if reply.frame_request is not None:
            meta = FrameMeta(frame_id=frame_id, obt_s=obt, width=1024, height=1024, bit_depth=12, exposure_s=0.01)
            frame_id += 1
        req = _request(k, obt, q=q, frame=meta, wheels=tuple(float(w) for w in speeds)).model_copy(update={
            "cpu_slowdown": slowdowns[k], "imaging_delay_s": delays[k] if meta is not None else 0.0})
        reply = fsw.step(req, pixels if meta is not None else None)
        out.append((reply, fsw.last_frame, meta, req))
    return out


@settings(max_examples=12, deadline=None)
@given(slowdowns=st.lists(st.floats(1.0, 4.0), min_size=30, max_size=30),
       delays=st.lists(st.floats(0.0, 0.6), min_size=30, max_size=30))
def test_a_measurement_is_used_only_after_its_latency_and_carries_its_exposure_time(slowdowns, delays) -> None:
    """Whatever the processor's speed and the interface's delay, a line of sight reaches a task no earlier than its
    exposure plus readout, FPGA stages and the delay; the recognition and the tracking loop get the exposure time."""
    fsw, reply = _imaging_fsw()
    steps = _fly(fsw, reply, slowdowns, delays)
    metas = {m.frame_id: (m, req.imaging_delay_s) for _, _, m, req in steps if m is not None}
    recognised, tracked = [], []
    for _, report, _, _ in steps:
        for run in report.runs:
            for ev in run.events:
                if ev.kind != EventKind.MEASUREMENT:
                    continue
                meta, delay = metas[ev.payload.frame_id]
                assert ev.payload.exposure_obt_s == meta.obt_s
                assert run.start_s >= ev.time_s >= meta.obt_s + FRAME_LATENCY_S + delay - 1e-9
                if run.task == Task.RECOGNITION:
                    recognised.append(meta.obt_s)
                if run.task == Task.CONTROL:
                    tracked.append(meta.obt_s)
    assert recognised and fsw.recognizer.measurement_times_obt_s == tuple(recognised)
    assert fsw.mode_name == "NOMINAL_TRACKING" and fsw.tracking.last_measurement_obt_s == tracked[-1]


@settings(max_examples=20, deadline=None)
@given(tag_after_s=st.floats(1.02, 2.5), time_task_s=st.floats(0.0, 0.01),  # the margin is 1 s
       slowdowns=st.lists(st.floats(1.0, 30.0), min_size=40, max_size=40))
def test_a_time_tagged_command_is_released_in_the_first_minor_frame_at_or_after_its_tag(
        tag_after_s, time_task_s, slowdowns) -> None:
    """With the schedule task starting anywhere in its minor frame (a slow TIME task before it, a slowed processor),
    a scheduled command executes in the first minor frame whose schedule release starts at or after its tag and
    before its deadline (else the release is skipped), never earlier."""
    fsw = FlightSoftware(ObswConfig(timing={"time_s": time_task_s}), KEYS)
    tag = OBT0 + tag_after_s
    inner = pus.encode_tc(pus.Ping(), APID, 11)
    insert = pus.InsertActivities(activities=(pus.ScheduledActivity(release_obt_s=tag, tc_packet=inner),))
    fsw.step(_request(0, OBT0, (pus.encode_tc(insert, APID, 10),)), None)
    tag = pus.decode_tc(pus.encode_tc(insert, APID, 10))[1].activities[0].release_obt_s  # as carried: on the CUC grid
    released, expected = [], None
    for k in range(1, len(slowdowns)):
        reply = fsw.step(_request(k, OBT0 + k * DT).model_copy(update={"cpu_slowdown": slowdowns[k]}), None)
        sched = next(r for r in fsw.last_frame.runs if r.task == Task.SCHEDULE)
        if expected is None and sched.start_s >= tag and sched.start_s < sched.deadline_s:
            expected = k
        if _of(_tm(reply.downlink), pus.PingReply):
            released.append((k, sched.start_s))
    if expected is None:  # every release after the tag was skipped under the overload: nothing may run early
        assert released == []
    else:
        assert [k for k, _ in released] == [expected]
        assert released[0][1] >= tag


@settings(max_examples=8, deadline=None)
@given(st.lists(st.floats(1.0, 150.0), min_size=31, max_size=31))
def test_overloads_are_counted_in_housekeeping_raised_once_per_run_and_never_stop_the_torques(slowdowns) -> None:
    """Under random slow-downs the control runs and the reply carries torques every period; housekeeping counts
    every task overrun, minor frame overrun and skipped release before it, and an overrun event opens each run of
    overruns of a task or of minor frames."""
    fsw, reply = _imaging_fsw()
    steps = _fly(fsw, reply, slowdowns, [0.0] * len(slowdowns))
    task_overruns = frame_overruns = skipped = 0
    was = {t: False for t in Task}
    frame_was = False
    task_events = frame_events = 0
    for reply, report, _, _ in steps:
        assert len(reply.wheel_torque_nm) == 3 and np.all(np.isfinite(reply.wheel_torque_nm))
        assert [r.ran for r in report.runs if r.task == Task.CONTROL] == [True]
        tm = _tm(reply.downlink)
        for run in report.runs:
            if run.task == Task.TELEMETRY:
                for hk in _of(tm, pus.Housekeeping):
                    assert (hk.task_overruns, hk.frame_overruns, hk.skipped_releases) == (
                        task_overruns, frame_overruns, skipped)
            task_overruns += run.ran and run.finish_s > run.deadline_s
            skipped += run.skipped
            if run.ran:
                task_events += run.finish_s > run.deadline_s and not was[run.task]
                was[run.task] = run.finish_s > run.deadline_s
        late = report.busy_until_s > report.tick_s + DT
        frame_overruns += late
        frame_events += late and not frame_was
        frame_was = late
    events = [r for reply, *_ in steps for _, r in _tm(reply.downlink)]
    assert sum(isinstance(e, pus.TaskOverrunEvent) for e in events) == task_events
    assert sum(isinstance(e, pus.FrameOverrunEvent) for e in events) == frame_events
    assert fsw.executive.task_overruns == task_overruns and fsw.executive.frame_overruns == frame_overruns


def test_a_schedule_reset_deletes_every_activity_and_disables_the_release() -> None:
    """TC[11,3] (ECSS-E-ST-70-41C): the pending activities are never released; one inserted afterwards waits for
    TC[11,1] and is then released at its tag."""
    fsw = FlightSoftware(ObswConfig(), KEYS)

    def insert(seq: int, inner_seq: int, tag_s: float) -> bytes:
        ping = pus.encode_tc(pus.Ping(), APID, inner_seq)
        return pus.encode_tc(pus.InsertActivities(activities=(
            pus.ScheduledActivity(release_obt_s=OBT0 + tag_s, tc_packet=ping),)), APID, seq)

    uplink = {0: (insert(0, 0x2200, 3.0), insert(1, 0x2201, 4.0)), 1: (pus.encode_tc(pus.ResetSchedule(), APID, 2),),
              2: (insert(3, 0x2202, 6.0),), 80: (pus.encode_tc(pus.EnableSchedule(), APID, 4),)}
    pings = []
    for k in range(0, 100):
        reply = fsw.step(_request(k, OBT0 + k * DT, uplink.get(k, ())), None)
        pings += [k] * len(_of(_tm(reply.downlink), pus.PingReply))
        if k == 1:
            assert len(fsw.schedule) == 0 and not fsw.schedule.enabled
    assert pings == [80]  # 0x2202's tag (step 60) passed while disabled: released at once when enabled


# C/A ten minutes on: the line of sight turns by about 0.02 deg a second, slowly enough to hold an offset against it
FAR_TRAJECTORY = TRAJECTORY.model_copy(update={"ca_obt_s": OBT0 + 600.0})


def _frames_while_off(offsets_deg: list[float], cfg: ObswConfig | None = None) -> list[int]:
    """Periods (from 1) with a frame request after entering ACQUISITION from STANDBY, imaging commanded at once, the
    star tracker reading the boresight (body Z) ``offsets_deg[k]`` off the trajectory's line of sight, where
    ACQUISITION points it; before the entry, ten periods on the line of sight settle the attitude estimate."""
    u = FAR_TRAJECTORY
    traj = NominalTrajectory(ca_time_obt_s=u.ca_obt_s, ca_distance_km=u.ca_distance_km, speed_km_s=u.speed_km_s,
                             approach_direction=u.approach_direction, ca_direction=u.ca_direction)

    def aim(t: float, off_deg: float) -> tuple[float, ...]:
        z = traj.los_inertial(t)
        x = np.cross([0.0, 0.0, 1.0], z)
        x /= np.linalg.norm(x)
        q = Rotation.from_matrix(np.column_stack([x, np.cross(z, x), z])) * Rotation.from_rotvec(
            [np.radians(off_deg), 0.0, 0.0])
        return tuple(float(v) for v in q.as_quat())

    fsw = FlightSoftware(cfg or ObswConfig(), KEYS)
    fsw.step(_request(0, OBT0, (pus.encode_tc(u, APID, 1),), q=aim(OBT0, offsets_deg[0])), None)
    for k in range(1, 11):
        fsw.step(_request(k, OBT0 + k * DT, q=aim(OBT0 + k * DT, offsets_deg[0])), None)
    t0 = OBT0 + 11 * DT
    tcs = (pus.encode_tc(pus.SetMode(mode=pus.Mode.ACQUISITION), APID, 2),
           pus.encode_tc(pus.StartImaging(period_s=0.2), APID, 3))
    reply = fsw.step(_request(11, t0, tcs, q=aim(t0, offsets_deg[0])), None)
    assert fsw.mode_name == "ACQUISITION"
    assert reply.frame_request is None  # the entry's period: no reference of ACQUISITION yet
    out = []
    speeds = np.zeros(3)  # the wheels follow their torques, so wheel health finds none failed
    for k, off in enumerate(offsets_deg, start=1):
        speeds = speeds + np.asarray(reply.wheel_torque_nm) * DT / fsw.wheel_inertia_kgm2
        rate = np.radians(off - offsets_deg[k - 2]) / DT if k > 1 else 0.0  # the slew about body X, gyro-measured
        reply = fsw.step(_request(11 + k, t0 + k * DT, q=aim(t0 + k * DT, off), gyro=(float(rate), 0.0, 0.0),
                                  wheels=tuple(float(w) for w in speeds)), None)
        assert fsw.mode_name == "ACQUISITION"
        if reply.frame_request is not None:
            out.append(k)
    return out


def test_acquisition_from_standby_exposes_its_first_frame_once_the_slew_onto_the_target_is_done() -> None:
    """Entering ACQUISITION from STANDBY, no frame is exposed while the boresight is more than
    modes.acquisition_settle_deg off the reference; the first one in the period the attitude comes within."""
    settle = ObswConfig().modes.acquisition_settle_deg
    slew = list(np.linspace(3.0 * settle, 0.5 * settle, 12))  # 0.68 deg/s, gyro-measured; no sample at the limit
    frames = _frames_while_off([3.0 * settle] * 15 + slew + [0.5 * settle] * 10)
    inside = 15 + next(i for i, v in enumerate(slew) if v <= settle) + 1  # the first period within
    # the attitude estimate follows within a few periods
    assert frames and inside <= frames[0] <= inside + 3
    assert _frames_while_off([0.5 * settle] * 5)[0] == 1


def test_acquisition_that_never_settles_images_from_the_timeout() -> None:
    """A slew that never settles (held 3 x acquisition_settle_deg off) delays the first frame by
    modes.acquisition_settle_timeout_s of on-board time, not for ever (5 s here: held off longer, the wheels
    saturate against the attitude the test holds)."""
    base = ObswConfig()
    cfg = base.model_copy(update={"modes": base.modes.model_copy(update={"acquisition_settle_timeout_s": 5.0})})
    n = round(cfg.modes.acquisition_settle_timeout_s / DT)
    frames = _frames_while_off([3.0 * cfg.modes.acquisition_settle_deg] * (n + 10), cfg)
    assert frames and n <= frames[0] <= n + 1  # the entry is stamped within its period
