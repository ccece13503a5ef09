"""Scenario faults act in their window and only there, and the run's log names each one's start and end.

Every run here starts at t = 100 s (C/A - 68 s: Didymos ~33 px, the plume filling a ~200 px disc) and steps at
0.1 s; the fault window [101.05, 102.05) s holds exactly the steps k = 11..20 (t = 101.1 .. 102.0 s). Where a fault
leaves the random draws alone, a paired run without it (same seed, same replies) is the truth it is compared with.
"""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from contracts.messages import FrameRequest, GroundReply, StepReply, StepRequest, TruthRecord
from scenario.model import Scenario
from universe.camera import focal_length_px
from universe.config import FaultConfig, SpacecraftConfig, UniverseConfig
from scenario import compose

START_S, DT_S, STEPS = 100.0, 0.1, 30
WINDOW_S = (101.05, 102.05)
IN_WINDOW = set(range(11, 21))  # request/step indices k with t_k = 100 + 0.1 k inside WINDOW_S


def fault(kind: str, **kw: object) -> FaultConfig:
    """A fault of ``kind`` over WINDOW_S."""
    return FaultConfig(kind=kind, start_s=WINDOW_S[0], end_s=WINDOW_S[1], **kw)


def scenario(faults: list[FaultConfig], seed: int = 11, **universe: object) -> Scenario:
    """The test scenario: 3 s from t = 100 s with ``faults``; ``universe`` overrides other fields."""
    fields: dict[str, object] = {"start_s": START_S, "end_s": START_S + STEPS * DT_S, "control_period_s": DT_S,
                                 "link": {"one_way_light_time_s": 0.3}}
    fields.update(universe)
    return Scenario(name="faults", seed=seed, universe=UniverseConfig(faults=faults, **fields))


class Run:
    """One run driven to its end: requests (k = 0..STEPS-1), their frame blobs, truth per step and the log."""

    def __init__(self, sc: Scenario, torque_nm: tuple[float, ...] = (0.0, 0.0, 0.0), frames_at: frozenset = frozenset(),
                 downlink: bool = False, uplink: bool = False) -> None:
        u = compose.universe(sc)
        self.universe = u
        req, blob = u.begin()
        self.requests: list[StepRequest] = [req]
        self.blobs: list[bytes] = [blob]
        self.truth: list[TruthRecord] = []
        self.log: list[str] = u.take_log()
        self.downlink_received: list[bytes] = []
        for k in range(STEPS):
            if u.ground_due():
                gs = u.ground_step()
                self.truth.extend(gs.truth)
                self.downlink_received.extend(gs.downlink)
                u.accept_ground(GroundReply(step=gs.step, uplink=(b"tc@%.2f" % u.t_s,) if uplink else ()))
            # the reply to request k asks for the frame of request k + 1
            r = StepReply(step=k, wheel_torque_nm=torque_nm,
                          frame_request=FrameRequest(exposure_s=0.01) if k + 1 in frames_at else None,
                          downlink=(b"tm%03d" % k,) if downlink else ())
            nxt = u.advance(r)
            self.log.extend(u.take_log())
            if nxt is None:
                break
            self.requests.append(nxt[0])
            self.blobs.append(nxt[1])
        while (gs := u.drain()) is not None:
            self.truth.extend(gs.truth)
            self.downlink_received.extend(gs.downlink)

    def frame(self, k: int) -> np.ndarray | None:
        """The pixels of the frame in request k, or None if none came."""
        meta = self.requests[k].frame
        if meta is None:
            return None
        return np.frombuffer(self.blobs[k], dtype="<u2").reshape(meta.height, meta.width)

    def truth_at(self, k: int) -> TruthRecord:
        """The truth record of step k."""
        return self.truth[k]


def dark_level_dn(sc: Scenario) -> float:
    """Mean DN of a pixel without light: bias plus dark current over the exposure."""
    c = sc.universe.camera
    return c.dark_offset_dn + c.dark_current_e_s * 0.01 / c.gain_e_per_dn


def log_times(log: list[str], word: str, kind: str) -> list[float]:
    """True times of the log's 'fault start'/'fault end' lines for ``kind``."""
    pat = re.compile(rf"fault {word}\s+t=([-\d.]+) s: {kind}\b")
    return [float(m.group(1)) for line in log if (m := pat.search(line))]


ALL_KINDS = [
    fault("frame_lost"), fault("frame_blank"), fault("frame_saturated"), fault("star_tracker_outage"),
    fault("gyro_bias_step", magnitude=0.2), fault("wheel_stuck", wheel=0), fault("wheel_failed", wheel=1),
    fault("plume_brightening", magnitude=3.0), fault("clock_jump", magnitude=2.5), fault("link_outage"),
    fault("cpu_overload", magnitude=4.0), fault("imaging_latency", magnitude=0.3),
]


def test_every_fault_kind_logs_its_start_and_end_once() -> None:
    """Each kind logs one start at the first step inside its window and one end at the first step after it."""
    run = Run(scenario(ALL_KINDS))
    for f in ALL_KINDS:
        assert log_times(run.log, "start", f.kind) == pytest.approx([101.1]), f.kind
        assert log_times(run.log, "end", f.kind) == pytest.approx([102.1]), f.kind
    starts = [line for line in run.log if line.startswith("fault start")]
    assert all("window 101.05..102.05 s" in line for line in starts) and len(starts) == len(ALL_KINDS)


def test_frame_lost_gives_no_frame_in_its_window_only() -> None:
    """Frames asked for inside the window do not come (and are logged lost); those outside do."""
    asked = frozenset({10, 11, 15, 20, 21})
    run = Run(scenario([fault("frame_lost")]), frames_at=asked)
    got = {k for k in range(len(run.requests)) if run.requests[k].frame is not None}
    assert got == asked - IN_WINDOW
    assert all(run.blobs[k] == b"" for k in asked & IN_WINDOW)
    assert [run.requests[k].frame.frame_id for k in sorted(got)] == [0, 1]
    assert sum("frame lost" in line for line in run.log) == len(asked & IN_WINDOW)


def test_frame_blank_is_dark_in_its_window_only() -> None:
    """A blank frame holds no scene light: mean at the dark level, no Didymos; frames either side show Didymos."""
    sc = scenario([fault("frame_blank")])
    run = Run(sc, frames_at=frozenset({10, 11, 20, 21}))
    dark = dark_level_dn(sc)
    cam = sc.universe.camera
    hot_bound_dn = cam.hot_pixel_count * cam.hot_pixel_signal_e / cam.gain_e_per_dn / cam.resolution_px**2
    for k in (10, 11, 20, 21):
        frame = run.frame(k)
        col, row = run.truth_at(k).didymos_px
        box = frame[int(row) - 5 : int(row) + 6, int(col) - 5 : int(col) + 6].astype(float)
        if k in IN_WINDOW:
            # read noise averages to ~0.002 DN over 1 M pixels; hot pixels add at most count * signal / gain / N
            assert -0.05 < frame.mean() - dark < hot_bound_dn + 0.05, k
            assert box.max() < dark + 4.4 * cam.read_noise_e / cam.gain_e_per_dn + 1, k  # quantiles clip at 4.3
        else:
            assert box.mean() > dark + 500.0, k


def test_frame_saturated_is_full_scale_in_its_window_only() -> None:
    """Frames in the window are 2^12 - 1 everywhere; frames either side have a dark median."""
    sc = scenario([fault("frame_saturated")])
    run = Run(sc, frames_at=frozenset({10, 11, 20, 21}))
    for k in (10, 11, 20, 21):
        frame = run.frame(k)
        if k in IN_WINDOW:
            assert frame.min() == frame.max() == 4095
        else:
            assert np.median(frame) < dark_level_dn(sc) + 5.0


def test_star_tracker_outage_gives_no_quaternion_in_its_window_only() -> None:
    """star_tracker_q is None exactly at the steps inside the window."""
    run = Run(scenario([fault("star_tracker_outage")]))
    assert {k for k, r in enumerate(run.requests) if r.sensors.star_tracker_q is None} == IN_WINDOW


def test_gyro_bias_step_shifts_every_axis_by_its_magnitude_in_its_window_only() -> None:
    """Against the same run without the fault, the gyro reads radians(magnitude) more on each axis, only inside."""
    magnitude_deg_s = 0.2
    faulty = Run(scenario([fault("gyro_bias_step", magnitude=magnitude_deg_s)]))
    clean = Run(scenario([]))
    for k, (a, b) in enumerate(zip(faulty.requests, clean.requests, strict=True)):
        shift = np.subtract(a.sensors.gyro_rad_s, b.sensors.gyro_rad_s)
        expected = math.radians(magnitude_deg_s) if k in IN_WINDOW else 0.0
        np.testing.assert_allclose(shift, expected, atol=1e-15, err_msg=f"step {k}")


def angular_momentum_inertial(sc: Scenario, r: TruthRecord) -> np.ndarray:
    """Total angular momentum from a truth record, by hand: I w + J (w + Omega) per orthogonal wheel, inertial."""
    i_body = np.asarray(sc.universe.spacecraft.inertia_kgm2)
    j = sc.universe.spacecraft.wheels.inertia_kgm2
    w = np.asarray(r.omega_rad_s)
    h_body = i_body @ w + j * w + np.asarray(r.wheel_momentum_nms)  # wheel_momentum is J Omega (relative)
    x, y, z, s = r.q
    rot = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - s * z), 2 * (x * z + s * y)],
                    [2 * (x * y + s * z), 1 - 2 * (x * x + z * z), 2 * (y * z - s * x)],
                    [2 * (x * z - s * y), 2 * (y * z + s * x), 1 - 2 * (x * x + y * y)]])
    return rot @ h_body


def test_wheel_failed_gets_no_motor_torque_in_its_window_only() -> None:
    """A failed wheel's speed stops following the command over the periods that start inside the window (friction
    only) and follows it again after; the other wheels follow it throughout."""
    sc = scenario([fault("wheel_failed", wheel=1)], sensors={"wheel_speed_noise_rad_s": 0.0})
    tau = 0.005
    run = Run(sc, torque_nm=(tau, tau, tau))
    speed = np.array([r.sensors.wheel_speed_rad_s for r in run.requests])
    d = np.diff(speed, axis=0)  # d[k] is step k -> k+1, driven over the period that starts at step k
    spin_up = tau * DT_S / sc.universe.spacecraft.wheels.inertia_kgm2  # rad/s per period, rotor alone
    for k in range(len(d)):
        if k in IN_WINDOW:
            assert abs(d[k, 1]) < 0.01 * spin_up, k  # Coulomb 1e-5 N m gives 0.2 % of the spin-up
        else:
            assert d[k, 1] == pytest.approx(spin_up, rel=0.01), k  # body reaction adds J / I_body ~ 0.1 %
        assert d[k, 0] == pytest.approx(spin_up, rel=0.01) and d[k, 2] == pytest.approx(spin_up, rel=0.01)


def test_wheel_stuck_locks_the_rotor_in_its_window_and_keeps_angular_momentum() -> None:
    """A stuck wheel reads zero relative speed after each period inside the window; total angular momentum never
    changes. Wheel faults govern the control periods that start inside their window, so step k + 1 shows them."""
    sc = scenario([fault("wheel_stuck", wheel=0)], sensors={"wheel_speed_noise_rad_s": 0.0},
                  spacecraft=SpacecraftConfig(initial_rate_deg_s=(0.5, -0.3, 0.2)))
    run = Run(sc, torque_nm=(0.004, 0.0, 0.0))
    speed0 = [r.sensors.wheel_speed_rad_s[0] for r in run.requests]
    for k, s in enumerate(speed0):
        if k - 1 in IN_WINDOW:
            assert s == pytest.approx(0.0, abs=1e-9), k
        elif k >= 1:
            assert abs(s) > 3.0, k  # spun up by the command over every period outside the window
    h0 = angular_momentum_inertial(sc, run.truth[0])
    for r in run.truth:
        # motor torque, friction and the seizure are internal: H is conserved to the integrator's accuracy
        np.testing.assert_allclose(angular_momentum_inertial(sc, r), h0, atol=1e-9 * float(np.linalg.norm(h0)) + 1e-12)


def test_plume_brightening_brightens_the_plume_in_its_window_only() -> None:
    """Against the run without the fault, frames differ only inside the window and only within the plume's disc."""
    brightening = fault("plume_brightening", magnitude=3.0)
    asked = frozenset({10, 15, 21})
    faulty = Run(scenario([brightening]), frames_at=asked)
    clean = Run(scenario([]), frames_at=asked)
    sc = scenario([])
    f_px = focal_length_px(sc.universe.camera)
    for k in sorted(asked):
        diff = faulty.frame(k).astype(float) - clean.frame(k).astype(float)
        if k not in IN_WINDOW:
            assert not diff.any(), k
            continue
        r = faulty.truth_at(k)
        col, row = r.dimorphos_px
        # the ejecta front is speed * time since impact from Dimorphos; one coarse plume-grid cell of margin
        front_px = sc.universe.plume.speed_m_s * (r.t_s - sc.universe.bodies.impact_time_s) / r.range_m * f_px
        rows, cols = np.mgrid[0:1024, 0:1024]
        inside = np.hypot(cols - col, rows - row) < front_px * (1 + 2 / 48) + 2
        assert not diff[~inside].any()
        assert diff[inside].mean() > 20.0  # brighter on average by tens of DN over a ~200 px disc
        assert (diff < -3 * sc.universe.camera.read_noise_e / sc.universe.camera.gain_e_per_dn).sum() < 10


def test_clock_jump_steps_obt_by_its_magnitude_at_its_start() -> None:
    """OBT advances by one control period per step, plus the magnitude at the first step inside the window."""
    run = Run(scenario([fault("clock_jump", magnitude=2.5)]))
    steps = np.diff([r.obt_s for r in run.requests])
    for k, d in enumerate(steps, start=1):
        assert d == pytest.approx(DT_S + (2.5 if k == 11 else 0.0), abs=1e-6), k


def test_link_outage_loses_what_is_radiated_during_it_both_ways() -> None:
    """Downlink packets sent and uplink packets radiated inside the window never arrive; the others all do."""
    run = Run(scenario([fault("link_outage")]), downlink=True, uplink=True)
    received = {int(p[2:]) for p in run.downlink_received if p.startswith(b"tm")}  # not the universe's own TM
    assert received == set(range(STEPS)) - IN_WINDOW  # reply k is radiated at t_k
    uplinked = [p for r in run.requests for p in r.uplink]
    sent_at = [float(p[3:]) for p in uplinked]
    # ground radiates one telecommand per ground step, at t = 100, 101 and 102 s: the one at 102 s is inside
    assert sent_at == pytest.approx([100.0, 101.0])
    assert run.universe.link.downlink.lost == len(IN_WINDOW) and run.universe.link.uplink.lost == 1


def test_cpu_overload_slows_the_processor_by_its_factor_in_its_window_only() -> None:
    """Each request reads the product of the slow-down factors whose window holds its step, 1 elsewhere."""
    second = FaultConfig(kind="cpu_overload", start_s=101.55, end_s=102.55, magnitude=2.5)
    run = Run(scenario([fault("cpu_overload", magnitude=4.0), second]))
    for k, req in enumerate(run.requests):
        t = START_S + k * DT_S
        expected = (4.0 if k in IN_WINDOW else 1.0) * (2.5 if 101.55 <= t < 102.55 else 1.0)
        assert req.cpu_slowdown == pytest.approx(expected), k


def test_imaging_latency_delays_the_frames_exposed_in_its_window_only() -> None:
    """A frame exposed inside the window reaches the processor the magnitude later; other frames, and periods
    without a frame, read no delay."""
    asked = frozenset({10, 11, 15, 20, 21})
    run = Run(scenario([fault("imaging_latency", magnitude=0.3)]), frames_at=asked)
    for k, req in enumerate(run.requests):
        assert req.imaging_delay_s == (0.3 if k in asked & IN_WINDOW else 0.0), k


@pytest.mark.parametrize(("kind", "magnitude", "problem"), [
    ("cpu_overload", None, "needs its magnitude"), ("cpu_overload", 0.5, "must be >= 1"),
    ("imaging_latency", None, "needs its magnitude"), ("imaging_latency", -0.1, "must be >= 0 s"),
])
def test_timing_faults_need_a_meaningful_magnitude(kind: str, magnitude: float | None, problem: str) -> None:
    """A slow-down factor below 1 or a negative delay, or none, is refused at load naming the fault's field."""
    with pytest.raises(ValueError, match=rf"faults\[0\]\.magnitude: .*{problem}"):
        UniverseConfig(faults=[FaultConfig(kind=kind, start_s=0.0, end_s=1.0, magnitude=magnitude)])


def test_a_window_between_two_steps_is_still_logged() -> None:
    """An instantaneous clock jump (start_s = end_s, between steps) steps OBT and logs its start and end at that step."""
    jump = FaultConfig(kind="clock_jump", start_s=101.05, end_s=101.05, magnitude=-1.5)
    run = Run(scenario([jump]))
    steps = np.diff([r.obt_s for r in run.requests])
    assert steps[10] == pytest.approx(DT_S - 1.5, abs=1e-6)  # request 11 is the first after the jump
    assert log_times(run.log, "start", "clock_jump") == pytest.approx([101.1])
    assert log_times(run.log, "end", "clock_jump") == pytest.approx([101.1])


def test_fault_book_logs_windows_by_the_calls_that_cross_their_edges() -> None:
    """FaultBook: a window before the first call is silent, one open at the first call starts there, others start and
    end at the first call at or after their edges."""
    from universe.simulator import FaultBook

    book = FaultBook([
        FaultConfig(kind="frame_lost", start_s=0.0, end_s=5.0),  # wholly before the run
        FaultConfig(kind="frame_blank", start_s=5.0, end_s=12.0),  # open when the run starts
        FaultConfig(kind="star_tracker_outage", start_s=10.5, end_s=10.7),  # between two calls
    ])
    lines = {t: list(book.transitions(t)) for t in (10.0, 10.3, 11.0, 11.5, 12.0)}
    assert [len(v) for v in lines.values()] == [1, 0, 2, 0, 1]
    assert "frame_blank" in lines[10.0][0] and lines[10.0][0].startswith("fault start t=10.00")
    assert [line.split(":")[0] for line in lines[11.0]] == ["fault start t=11.00 s", "fault end   t=11.00 s"]
    assert "star_tracker_outage" in lines[11.0][0] and lines[12.0][0].startswith("fault end   t=12.00 s: frame_blank")


def test_fault_active_at_the_end_is_logged_as_such() -> None:
    """A fault whose window outlasts the run gets a start line and a 'still active at the end' line."""
    from universe.simulator import FaultBook
    from universe.config import FaultConfig

    book = FaultBook([FaultConfig(kind="frame_lost", start_s=1.0, end_s=100.0)])
    assert list(book.transitions(0.0)) == []
    assert len(list(book.transitions(2.0))) == 1
    (line,) = book.still_active(10.0)
    assert "still active at the end of the run" in line and "frame_lost" in line
