"""Tracking loop against the closed-form responses of a type-2 second-order loop and geometric identities."""

from __future__ import annotations

import copy
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from obsw.config import ObswConfig, TrackingConfig
from obsw.tracking import TrackingLoop, offset_rotvec, predicted_attitude, quaternion_of_matrix
from obsw.trajectory import NominalTrajectory

TRAJ = NominalTrajectory(
    ca_time_obt_s=0.0,
    ca_distance_km=55.0,
    speed_km_s=7.0,
    approach_direction=(1.0, 0.0, 0.0),
    ca_direction=(0.0, 1.0, 0.0),
)
CFG = TrackingConfig(natural_frequency_rad_s=0.3, damping=0.8)  # pinned: the closed forms below need zeta < 1
WN, ZETA = CFG.natural_frequency_rad_s, CFG.damping
WD = WN * np.sqrt(1 - ZETA**2)
BORESIGHT = np.array(ObswConfig().camera.boresight_body)


def _signed_angle(a: np.ndarray, b: np.ndarray, axis: np.ndarray) -> float:
    """Angle from a to b about axis (both orthogonal to it), rad."""
    return float(np.arctan2(np.cross(a, b) @ axis, a @ b))


def _step_error(t: float, x0: float) -> float:
    """Closed form of e'' + 2 zeta wn e' + wn^2 e = 0 with e(0) = x0, e'(0) = -2 zeta wn x0 (PI loop step)."""
    return x0 * np.exp(-ZETA * WN * t) * (np.cos(WD * t) - ZETA * WN / WD * np.sin(WD * t))


def _run(offset_rad, t0: float, duration_s: float, dt_s: float, frame_every: int, traj=TRAJ, truth=TRAJ):
    """Fly the loop with a measured LOS = truth LOS turned by offset_rad(t) about the plane normal."""
    loop = TrackingLoop(CFG)
    n = truth.plane_normal
    out = []
    for k in range(int(round(duration_s / dt_s)) + 1):
        t = t0 + k * dt_s
        meas = None
        if k % frame_every == 0:
            meas = Rotation.from_rotvec(offset_rad(t) * n).apply(truth.los_inertial(t))
        ref = loop.update(t, dt_s, traj, meas)
        out.append((t, ref))
    return out


@pytest.mark.parametrize("frame_every", [1, 10, 25])
def test_step_offset_follows_the_analytic_second_order_response(frame_every: int) -> None:
    """A constant offset is removed exactly as 1 - e^{-zeta wn t}(cos wd t - zeta wn/wd sin wd t), any frame rate."""
    x0 = 0.01
    for t, ref in _run(lambda t: x0, -200.0, 40.0, 0.1, frame_every):
        achieved = _signed_angle(TRAJ.los_inertial(t), ref.los_commanded_inertial, TRAJ.plane_normal)
        assert achieved == pytest.approx(x0 - _step_error(t + 200.0, x0), abs=1e-12)


def test_step_overshoot_is_that_of_a_type_2_loop() -> None:
    """The correction overshoots by the closed-form peak of the PI-loop step response (18 % at zeta 0.8)."""
    x0 = 0.02
    run = _run(lambda t: x0, -240.0, 40.0, 0.05, 20)
    achieved = np.array(
        [_signed_angle(TRAJ.los_inertial(t), r.los_commanded_inertial, TRAJ.plane_normal) for t, r in run]
    )
    # e(t) = x0 e^{-s t}(cos wd t - s/wd sin wd t) has its first minimum where e' = 0: tan(wd t) = -2 s wd/(wd^2 - s^2)
    s = ZETA * WN
    t_peak = (np.pi + np.arctan2(-2 * s * WD, WD**2 - s**2)) / WD
    # sampling every 0.05 s misses the peak by at most (wn dt)^2 / 2 of it
    assert achieved.max() / x0 - 1 == pytest.approx(-_step_error(t_peak, x0) / x0, rel=2e-3)
    assert abs(achieved[-1] - x0) < 2e-3 * x0


@pytest.mark.parametrize("frame_every", [1, 10])
def test_ramp_offset_leaves_no_steady_state_error(frame_every: int) -> None:
    """A constant rate error r is tracked with error r/wd e^{-zeta wn t} sin(wd t) -> 0 (type-2 loop)."""
    rate = 1e-3
    t0 = -200.0
    run = _run(lambda t: rate * (t - t0), t0, 80.0, 0.1, frame_every)
    errors = []
    for t, ref in run:
        achieved = _signed_angle(TRAJ.los_inertial(t), ref.los_commanded_inertial, TRAJ.plane_normal)
        errors.append(rate * (t - t0) - achieved)
    errors = np.array(errors)
    times = np.array([t for t, _ in run]) - t0
    analytic = rate / WD * np.exp(-ZETA * WN * times) * np.sin(WD * times)
    # the slope is known only from the second frame on: the first frame interval holds the input flat
    frame_s = 0.1 * frame_every
    assert np.max(np.abs(errors - analytic)) < rate * frame_s**2 * WN
    assert abs(errors[-1]) < 1e-9


def test_constant_acceleration_offset_leaves_a_over_wn_squared() -> None:
    """A parabolic offset a t^2/2 leaves the closed-form steady-state error a / wn^2 (type-2 loop)."""
    accel = 2e-5
    t0 = -240.0
    run = _run(lambda t: 0.5 * accel * (t - t0) ** 2, t0, 60.0, 0.1, 1)
    t, ref = run[-1]
    achieved = _signed_angle(TRAJ.los_inertial(t), ref.los_commanded_inertial, TRAJ.plane_normal)
    assert 0.5 * accel * (t - t0) ** 2 - achieved == pytest.approx(accel / WN**2, rel=1e-2)


def test_without_measurements_the_reference_is_the_trajectory() -> None:
    """No image: boresight on the predicted LOS, normal axis on the normal, omega = theta' p, alpha = theta'' p."""
    loop = TrackingLoop(CFG)
    p = np.array(CFG.plane_normal_axis_body)
    for t in np.arange(-30.0, 30.0, 0.5):
        ref = loop.update(float(t), 0.5, TRAJ, None)
        r = Rotation.from_quat(ref.q_des)
        assert np.allclose(r.apply(BORESIGHT), TRAJ.los_inertial(t), atol=1e-12)
        assert np.allclose(r.apply(p), TRAJ.plane_normal, atol=1e-12)
        assert np.allclose(ref.omega_des_body, TRAJ.los_rate_rad_s(t) * p, atol=1e-15)
        assert np.allclose(ref.alpha_des_body, TRAJ.los_accel_rad_s2(t) * p, atol=1e-15)


@settings(max_examples=30, deadline=None)
@given(
    st.floats(-300.0, 300.0),
    st.tuples(st.floats(-0.02, 0.02), st.floats(-0.02, 0.02), st.floats(-0.02, 0.02)),
)
def test_reference_points_the_boresight_exactly_along_the_commanded_los(obt_s: float, off: tuple) -> None:
    """The boresight of q_des is the commanded LOS, and the correction is the measured offset after a long time."""
    loop = TrackingLoop(CFG)
    meas = Rotation.from_rotvec(off).apply(TRAJ.los_inertial(obt_s - 200.0))
    loop.update(obt_s - 200.0, 0.0, TRAJ, meas)
    ref = loop.update(obt_s, 200.0, TRAJ, None)
    r = Rotation.from_quat(ref.q_des)
    assert np.allclose(r.apply(BORESIGHT), ref.los_commanded_inertial, atol=1e-12)
    held = offset_rotvec(TRAJ.los_inertial(obt_s - 200.0), meas)
    assert np.allclose(loop.correction_rotvec, held, atol=1e-12)


def test_offset_rotvec_turns_one_vector_onto_the_other() -> None:
    """offset_rotvec gives the smallest rotation: it maps a onto b and is orthogonal to both."""
    rng = np.random.default_rng(1)
    for _ in range(20):
        a, b = rng.normal(size=(2, 3))
        a, b = a / np.linalg.norm(a), b / np.linalg.norm(b)
        rv = offset_rotvec(a, b)
        assert np.allclose(Rotation.from_rotvec(rv).apply(a), b, atol=1e-12)
        assert abs(rv @ a) < 1e-12 and abs(rv @ b) < 1e-12
    with pytest.raises(ValueError, match="opposite"):
        offset_rotvec([1.0, 0.0, 0.0], [-1.0, 0.0, 0.0])


def test_rate_and_acceleration_are_the_derivatives_of_the_reference() -> None:
    """omega_des and alpha_des match finite differences of q_des and omega_des through C/A with a correction active."""
    loop = TrackingLoop(CFG)
    h, dt = 1e-3, 0.25
    t0 = -5.0
    meas = Rotation.from_rotvec([0.004, -0.006, 0.002]).apply(TRAJ.los_inertial(t0))
    loop.update(t0, dt, TRAJ, meas)
    for k in range(1, 40):
        t = t0 + k * dt
        loop.update(t - h, dt - h, TRAJ, None)
        probe = copy.deepcopy(loop)
        refs = [loop.update(t - h, 0.0, TRAJ, None), probe.update(t, h, TRAJ, None), probe.update(t + h, h, TRAJ, None)]
        loop.update(t, h, TRAJ, None)
        r_prev, r_next = Rotation.from_quat(refs[0].q_des), Rotation.from_quat(refs[2].q_des)
        omega_fd = (r_prev.inv() * r_next).as_rotvec() / (2 * h)
        assert np.allclose(refs[1].omega_des_body, omega_fd, atol=2e-7)
        alpha_fd = (refs[2].omega_des_body - refs[0].omega_des_body) / (2 * h)
        # J' c' is neglected in alpha: second order in the ~0.01 rad correction and its ~0.005 rad/s rate
        assert np.allclose(refs[1].alpha_des_body, alpha_fd, atol=2e-5)


def test_switching_trajectory_keeps_the_reference_continuous() -> None:
    """Replacing the trajectory model (nominal -> recognised) changes neither q_des nor omega_des at the switch."""
    nominal = TRAJ.with_ca(8.0, 50.0)
    truth = TRAJ
    loop = TrackingLoop(CFG)
    dt = 0.1
    t = -120.0
    prev = None
    for k in range(1200):
        t = -120.0 + k * dt
        model = nominal if t < -30.0 else truth
        meas = truth.los_inertial(t) if k % 10 == 0 else None
        ref = loop.update(t, dt, model, meas)
        if prev is not None:
            step = (Rotation.from_quat(prev.q_des).inv() * Rotation.from_quat(ref.q_des)).as_rotvec()
            assert np.linalg.norm(step) < 0.2 * dt + 1e-3 * dt
            assert np.linalg.norm(ref.omega_des_body - prev.omega_des_body) < 0.05 * dt + 0.003
        prev = ref
    # after the switch the loop removes the remaining offset: the commanded LOS ends on the truth
    assert np.degrees(np.arccos(np.clip(ref.los_commanded_inertial @ truth.los_inertial(t), -1, 1))) < 0.01


def test_frame_time_stamp_removes_the_latency_offset_near_ca() -> None:
    """A perfect frame exposed 0.1 s before it is used gives no correction when stamped with its exposure time."""
    loop, late = TrackingLoop(CFG), TrackingLoop(CFG)
    dt = 0.1
    for k in range(51):
        t = -2.5 + k * dt
        frame = TRAJ.los_inertial(t - dt) if k % 5 == 0 else None
        loop.update(t, dt, TRAJ, frame, measured_obt_s=t - dt)
        late.update(t, dt, TRAJ, frame)
    assert np.linalg.norm(loop.correction_rotvec) < 1e-12
    # unstamped, the frame looks a LOS-rate x latency (~1 deg at C/A) behind: the loop chases that
    assert np.linalg.norm(late.correction_rotvec) > 0.5 * TRAJ.los_rate_rad_s(0.0) * dt


def test_reset_forgets_the_correction() -> None:
    """After reset the loop restarts on the bare trajectory, as a new loop does."""
    loop = TrackingLoop(CFG)
    loop.update(-100.0, 0.1, TRAJ, Rotation.from_rotvec([0.0, 0.0, 0.01]).apply(TRAJ.los_inertial(-100.0)))
    loop.update(-90.0, 10.0, TRAJ, None)
    assert np.linalg.norm(loop.correction_rotvec) > 1e-3
    loop.reset()
    ref = loop.update(-80.0, 10.0, TRAJ, None)
    assert np.allclose(ref.q_des, TrackingLoop(CFG).update(-80.0, 0.1, TRAJ, None).q_des, atol=1e-15)
    assert np.linalg.norm(loop.correction_rotvec) == 0.0


def test_predicted_attitude_honours_other_boresights() -> None:
    """With a boresight along body -X and the normal axis along body +Z the triad still maps them exactly."""
    cfg = TrackingConfig(plane_normal_axis_body=(0.0, 0.0, 3.0))
    r = predicted_attitude(TRAJ, 12.0, cfg, boresight_body=(-2.0, 0.0, 0.0))
    assert np.allclose(r.apply([-1.0, 0.0, 0.0]), TRAJ.los_inertial(12.0), atol=1e-12)
    assert np.allclose(r.apply([0.0, 0.0, 1.0]), TRAJ.plane_normal, atol=1e-12)


def test_bad_inputs_are_rejected_with_the_field_named() -> None:
    """A non-unit measured LOS or a negative dt raises ValueError naming it."""
    loop = TrackingLoop(CFG)
    loop.update(0.0, 0.1, TRAJ, None)
    with pytest.raises(ValueError, match="los_measured_inertial"):
        loop.update(0.1, 0.1, TRAJ, [0.0, 0.0, 2.0])
    with pytest.raises(ValueError, match="dt_s"):
        loop.update(0.2, -0.1, TRAJ, None)
    with pytest.raises(ValueError, match="measured_obt_s"):
        loop.update(0.3, 0.1, TRAJ, TRAJ.los_inertial(0.3), measured_obt_s=0.4)


def test_quaternion_of_a_matrix_is_scipys_to_the_last_bit() -> None:
    """quaternion_of_matrix equals SciPy's from_matrix bit for bit: random rotations, products of two (as the loop
    makes them), rotations near pi about each axis and near the identity (every branch of Markley's method), and
    matrices SciPy orthogonalises first."""
    rng = np.random.default_rng(7)
    a, b = Rotation.random(2000, random_state=1).as_matrix(), Rotation.random(2000, random_state=2).as_matrix()
    mats = [*a, *(x @ y for x, y in zip(a, b))]
    mats += [Rotation.from_rotvec(axis * angle).as_matrix() for axis in np.eye(3)
             for angle in np.linspace(np.pi - 1e-3, np.pi, 50)]
    mats += [Rotation.from_rotvec(rng.standard_normal(3) * 1e-7).as_matrix() for _ in range(50)]
    mats += [m + rng.standard_normal((3, 3)) * 1e-10 for m in a[:50]]
    for m in mats:
        assert quaternion_of_matrix(m).tolist() == Rotation.from_matrix(m).as_quat().tolist()
