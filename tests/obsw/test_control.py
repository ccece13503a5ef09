"""PD attitude control and wheel torque split against closed forms, a rigid-body RK4 written here, and properties."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from scipy.linalg import null_space
from scipy.spatial.transform import Rotation

from obsw.config import ControlConfig, RecognitionConfig, TrackingConfig
from obsw.control import attitude_error_rad, pd_torque_nm, wheel_torques_nm
from obsw.recognition import TrajectoryRecognizer
from obsw.tracking import TrackingLoop
from obsw.trajectory import NominalTrajectory

INERTIA = np.diag([0.152, 0.117, 0.058])
MAX_TORQUE_NM, MAX_MOMENTUM_NMS = 0.007, 0.1
ORTHOGONAL = np.eye(3)
_EL, _AZ = np.radians(54.7356), np.radians([45.0, 135.0, 225.0, 315.0])
PYRAMID = np.vstack([np.cos(_EL) * np.cos(_AZ), np.cos(_EL) * np.sin(_AZ), np.full(4, np.sin(_EL))])


@dataclass(frozen=True)
class Ref:
    """A reference as the tracking loop gives it."""

    q_des: np.ndarray
    omega_des_body: np.ndarray
    alpha_des_body: np.ndarray


def _qmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product, scalar-last."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return np.array(
        [
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz,
        ]
    )


def _derivative(x: np.ndarray, wheel_torque: np.ndarray, axes: np.ndarray, body_torque: np.ndarray) -> np.ndarray:
    """Rigid body with wheels: q' = q (x) [w, 0] / 2, I w' = T - A tau - w x (I w + A h), h' = tau."""
    q, w, h = x[:4], x[4:7], x[7:]
    q_dot = 0.5 * _qmul(q, np.array([*w, 0.0]))
    w_dot = np.linalg.solve(INERTIA, body_torque - axes @ wheel_torque - np.cross(w, INERTIA @ w + axes @ h))
    return np.concatenate([q_dot, w_dot, wheel_torque])


def _rk4(x: np.ndarray, t: float, h: float, f: Callable[[float, np.ndarray], np.ndarray]) -> np.ndarray:
    """One classical Runge-Kutta step of x' = f(t, x), renormalising the quaternion."""
    k1 = f(t, x)
    k2 = f(t + h / 2, x + h / 2 * k1)
    k3 = f(t + h / 2, x + h / 2 * k2)
    k4 = f(t + h, x + h * k3)
    out = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    out[:4] /= np.linalg.norm(out[:4])
    return out


def _no_wheels(x: np.ndarray, body_torque: np.ndarray) -> np.ndarray:
    return _derivative(x, np.zeros(0), np.zeros((3, 0)), body_torque)


@pytest.mark.parametrize(
    "cfg", [ControlConfig(kp_nm_per_rad=0.02, kd_nms_per_rad=0.03, feedforward=False), ControlConfig()]
)
@pytest.mark.parametrize("axis", [0, 1, 2])
def test_single_axis_pd_is_a_damped_oscillator(cfg: ControlConfig, axis: int) -> None:
    """About a principal axis the loop is I e'' + kd e' + kp e = 0: wn = sqrt(kp/I), zeta = kd / (2 sqrt(kp I))."""
    inertia = INERTIA[axis, axis]
    wn = np.sqrt(cfg.kp_nm_per_rad / inertia)
    zeta = cfg.kd_nms_per_rad / (2 * np.sqrt(cfg.kp_nm_per_rad * inertia))
    phi0 = 0.05
    unit = np.eye(3)[axis]
    ref = Ref(np.array([0.0, 0.0, 0.0, 1.0]), np.zeros(3), np.zeros(3))
    x = np.concatenate([Rotation.from_rotvec(phi0 * unit).as_quat(), np.zeros(3)])

    def f(_: float, s: np.ndarray) -> np.ndarray:
        return _no_wheels(s, pd_torque_nm(s[:4], s[4:7], ref, INERTIA, cfg))

    h = 0.01
    for k in range(1, 801):
        x = _rk4(x, 0.0, h, f)
        t = k * h
        if zeta < 1:
            wd = wn * np.sqrt(1 - zeta**2)
            expected = phi0 * np.exp(-zeta * wn * t) * (np.cos(wd * t) + zeta * wn / wd * np.sin(wd * t))
        else:
            r1, r2 = -wn * (zeta - np.sqrt(zeta**2 - 1)), -wn * (zeta + np.sqrt(zeta**2 - 1))
            expected = phi0 * (r2 * np.exp(r1 * t) - r1 * np.exp(r2 * t)) / (r2 - r1)
        assert attitude_error_rad(x[:4], ref.q_des) @ unit == pytest.approx(expected, abs=1e-9)


def test_feedforward_makes_a_rotating_reference_an_exact_trajectory() -> None:
    """Starting on a reference accelerating about a non-principal axis, feedforward keeps the error at zero."""
    axis = np.array([1.0, 2.0, -1.5]) / np.linalg.norm([1.0, 2.0, -1.5])
    b = 0.01  # phi = b t^2: omega = 2 b t, alpha = 2 b about the fixed axis

    def ref_at(t: float) -> Ref:
        return Ref(Rotation.from_rotvec(b * t * t * axis).as_quat(), 2 * b * t * axis, 2 * b * axis)

    for feedforward, bound in ((True, 1e-9), (False, None)):
        cfg = ControlConfig(feedforward=feedforward)
        x = np.concatenate([[0.0, 0.0, 0.0, 1.0], np.zeros(3)])
        h, t = 0.01, 0.0
        worst = 0.0
        for _ in range(500):
            # the torque follows the reference at each RK4 stage time: continuous control, as the closed form assumes
            x = _rk4(x, t, h, lambda tt, s: _no_wheels(s, pd_torque_nm(s[:4], s[4:7], ref_at(tt), INERTIA, cfg)))
            t += h
            worst = max(worst, float(np.linalg.norm(attitude_error_rad(x[:4], ref_at(t).q_des))))
        if bound is not None:
            assert worst < bound
        else:
            # without feedforward the error approaches I alpha / kp: proves the test can see a missing term
            assert worst > 0.3 * float(np.linalg.norm(INERTIA @ (2 * b * axis))) / cfg.kp_nm_per_rad


def test_gyroscopic_feedforward_includes_wheel_momentum() -> None:
    """With wheel momentum A h, the feedforward adds omega x (I omega + A h) (the whole gyroscopic torque)."""
    cfg = ControlConfig()
    ref = Ref(np.array([0.0, 0.0, 0.0, 1.0]), np.array([0.1, 0.2, -0.1]), np.zeros(3))
    q = ref.q_des
    omega = ref.omega_des_body
    h_body = np.array([0.01, -0.03, 0.02])
    without = pd_torque_nm(q, omega, ref, INERTIA, cfg)
    with_wheels = pd_torque_nm(q, omega, ref, INERTIA, cfg, h_body)
    assert np.allclose(without, np.cross(omega, INERTIA @ omega) - INERTIA @ np.cross(omega, omega), atol=1e-15)
    assert np.allclose(with_wheels - without, np.cross(omega, h_body), atol=1e-15)


@settings(max_examples=50, deadline=None)
@given(st.integers(0, 2**32 - 1), st.booleans())
def test_attitude_error_matches_scipy_and_ignores_quaternion_sign(seed: int, flip: bool) -> None:
    """The error is scipy's rotvec of q_des^-1 q (|e| <= pi), the same for q and -q."""
    rng = np.random.default_rng(seed)
    body, desired = Rotation.random(2, random_state=rng)
    q = body.as_quat() * (-1.0 if flip else 1.0)
    assert np.allclose(attitude_error_rad(q, desired.as_quat()), (desired.inv() * body).as_rotvec(), atol=1e-12)


# --- wheel torque split ------------------------------------------------------------------------------------------

_torque = st.tuples(*[st.floats(-0.02, 0.02)] * 3).map(np.array)
_layouts = st.sampled_from([ORTHOGONAL, PYRAMID])


@settings(max_examples=100, deadline=None)
@given(_torque, _layouts, st.data())
def test_split_realises_the_torque_within_limits(torque: np.ndarray, axes: np.ndarray, data: st.DataObject) -> None:
    """Within limits the wheels give exactly the body torque (-A tau = T) with the minimum-norm split."""
    n = axes.shape[1]
    momentum = np.array(data.draw(st.lists(st.floats(-0.09, 0.09), min_size=n, max_size=n)))
    tau = wheel_torques_nm(torque, axes, momentum, MAX_TORQUE_NM, MAX_MOMENTUM_NMS)
    unlimited = -np.linalg.lstsq(axes, torque, rcond=None)[0]
    assume(np.max(np.abs(unlimited)) <= MAX_TORQUE_NM)
    assert np.allclose(-axes @ tau, torque, atol=1e-15)
    null = null_space(axes)
    if null.size:
        assert np.allclose(null.T @ tau, 0.0, atol=1e-15)  # minimum norm: nothing in the null space


@settings(max_examples=100, deadline=None)
@given(_torque, _layouts)
def test_split_scales_down_keeping_the_direction(torque: np.ndarray, axes: np.ndarray) -> None:
    """Beyond a wheel's torque limit all torques shrink by one factor: the body torque keeps its direction."""
    assume(np.linalg.norm(torque) > 1e-6)
    tau = wheel_torques_nm(torque, axes, np.zeros(axes.shape[1]), MAX_TORQUE_NM, MAX_MOMENTUM_NMS)
    assert np.max(np.abs(tau)) <= MAX_TORQUE_NM * (1 + 1e-12)
    got = -axes @ tau
    scale = float(got @ torque) / float(torque @ torque)
    assert 0 < scale <= 1 + 1e-12
    assert np.allclose(got, scale * torque, atol=1e-15)
    unlimited = np.max(np.abs(np.linalg.pinv(axes) @ torque))
    assert scale == pytest.approx(min(1.0, MAX_TORQUE_NM / unlimited), rel=1e-12)


@settings(max_examples=100, deadline=None)
@given(_torque, st.integers(0, 3), st.sampled_from([-1.0, 1.0]))
def test_saturated_wheel_is_never_pushed_further(torque: np.ndarray, wheel: int, sign: float) -> None:
    """A wheel at its momentum limit gets no torque that speeds it up; the other three still give the torque."""
    momentum = np.zeros(4)
    momentum[wheel] = sign * MAX_MOMENTUM_NMS
    tau = wheel_torques_nm(torque, PYRAMID, momentum, MAX_TORQUE_NM, MAX_MOMENTUM_NMS)
    assert tau[wheel] * momentum[wheel] <= 0
    assert np.max(np.abs(tau)) <= MAX_TORQUE_NM * (1 + 1e-12)
    got = -PYRAMID @ tau
    if np.linalg.norm(torque) > 1e-9:
        scale = float(got @ torque) / float(torque @ torque)
        assert 0 < scale <= 1 + 1e-12
        assert np.allclose(got, scale * torque, atol=1e-15)


def test_saturated_orthogonal_wheel_can_only_unload() -> None:
    """With three orthogonal wheels a saturated one drops out: the body torque loses that axis, keeps the others."""
    momentum = np.array([0.0, MAX_MOMENTUM_NMS, 0.0])
    tau = wheel_torques_nm(np.array([0.001, -0.002, 0.0005]), ORTHOGONAL, momentum, MAX_TORQUE_NM, MAX_MOMENTUM_NMS)
    assert np.allclose(tau, [-0.001, 0.0, -0.0005])
    # the opposite torque slows the saturated wheel and is allowed
    tau = wheel_torques_nm(np.array([0.0, 0.002, 0.0]), ORTHOGONAL, momentum, MAX_TORQUE_NM, MAX_MOMENTUM_NMS)
    assert np.allclose(tau, [0.0, -0.002, 0.0])


def test_bad_shapes_are_rejected_with_the_field_named() -> None:
    """Wrong shapes or limits raise ValueError naming the argument."""
    with pytest.raises(ValueError, match="wheel_axes"):
        wheel_torques_nm(np.zeros(3), np.zeros((2, 3)), np.zeros(3), 0.007, 0.1)
    with pytest.raises(ValueError, match="wheel_momentum_nms"):
        wheel_torques_nm(np.zeros(3), np.eye(3), np.zeros(4), 0.007, 0.1)
    with pytest.raises(ValueError, match="max_torque_nm"):
        wheel_torques_nm(np.zeros(3), np.eye(3), np.zeros(3), 0.0, 0.1)
    ref = Ref(np.array([0.0, 0.0, 0.0, 1.0]), np.zeros(3), np.zeros(3))
    with pytest.raises(ValueError, match="omega_rad_s"):
        pd_torque_nm(ref.q_des, np.zeros(2), ref, INERTIA, ControlConfig())
    with pytest.raises(ValueError, match="inertia_kgm2"):
        pd_torque_nm(ref.q_des, np.zeros(3), ref, np.eye(2), ControlConfig())


# --- closed loop through the worst-case flyby --------------------------------------------------------------------


def _fly_worst_case(axes: np.ndarray, inertia_knowledge: np.ndarray) -> tuple[float, float, float, float]:
    """Fly C/A at 40 km, 7 km/s with tracking + PD + wheel split at 10 Hz; return the worst pointing error (deg),
    the peak body rate (deg/s), the peak wheel torque (N m) and the peak wheel momentum (N m s)."""
    traj = NominalTrajectory(
        ca_time_obt_s=0.0,
        ca_distance_km=40.0,
        speed_km_s=7.0,
        approach_direction=(1.0, 0.0, 0.0),
        ca_direction=(0.0, 1.0, 0.0),
    )
    cfg = ControlConfig()
    loop = TrackingLoop(TrackingConfig())
    dt, t0 = 0.1, -60.0
    ref = loop.update(t0, dt, traj, None)
    x = np.concatenate([ref.q_des, ref.omega_des_body, -np.linalg.pinv(axes) @ (INERTIA @ ref.omega_des_body)])
    worst = peak_rate = peak_tau = peak_h = 0.0
    for k in range(1201):
        t = t0 + k * dt
        ref = loop.update(t, dt, traj, traj.los_inertial(t) if k % 10 == 0 else None)
        q, w, h = x[:4], x[4:7], x[7:]
        boresight = Rotation.from_quat(q).apply([0.0, 0.0, 1.0])
        worst = max(worst, float(np.degrees(np.arccos(np.clip(boresight @ traj.los_inertial(t), -1.0, 1.0)))))
        peak_rate = max(peak_rate, float(np.degrees(np.linalg.norm(w))))
        peak_h = max(peak_h, float(np.max(np.abs(h))))
        body_torque = pd_torque_nm(q, w, ref, inertia_knowledge, cfg, axes @ h)
        tau = wheel_torques_nm(body_torque, axes, h, MAX_TORQUE_NM, MAX_MOMENTUM_NMS)
        peak_tau = max(peak_tau, float(np.max(np.abs(tau))))
        x = _rk4(x, t, dt, lambda _, s, tau=tau: _derivative(s, tau, axes, np.zeros(3)))
    return worst, peak_rate, peak_tau, peak_h


@pytest.mark.parametrize(
    ("axes", "inertia_error"), [(ORTHOGONAL, 1.0), (PYRAMID, 1.0), (ORTHOGONAL, 1.2)], ids=["orth", "pyramid", "I+20%"]
)
def test_worst_case_flyby_keeps_the_target_well_inside_the_fov(axes: np.ndarray, inertia_error: float) -> None:
    """At C/A 40 km the default gains keep the pointing error < 0.5 deg at > 7 deg/s, inside the wheel limits."""
    worst, peak_rate, peak_tau, peak_h = _fly_worst_case(axes, INERTIA * inertia_error)
    assert worst < 0.5
    assert peak_rate > 7.0
    assert peak_tau <= MAX_TORQUE_NM * (1 + 1e-12)
    assert peak_h < MAX_MOMENTUM_NMS


def test_recognition_carries_a_three_sigma_miss_through_ca() -> None:
    """Ground's nominal 30 s early and 15 km far (3 sigma): following the live recognised trajectory, tracking and
    control keep the target in the FOV from acquisition and within 0.1 deg from C/A-30 s through C/A."""
    truth = NominalTrajectory(
        ca_time_obt_s=0.0,
        ca_distance_km=40.0,
        speed_km_s=7.0,
        approach_direction=(1.0, 0.0, 0.0),
        ca_direction=(0.0, 1.0, 0.0),
    )
    nominal = truth.with_ca(-30.0, 55.0)
    rng = np.random.default_rng(42)
    recognizer = TrajectoryRecognizer(nominal, RecognitionConfig())
    loop, cfg = TrackingLoop(TrackingConfig()), ControlConfig()
    dt, t0, axes = 0.1, -200.0, ORTHOGONAL
    model = nominal
    ref = loop.update(t0, dt, model, None)
    x = np.concatenate([ref.q_des, ref.omega_des_body, -(INERTIA @ ref.omega_des_body)])
    errors = []
    for k in range(2301):
        t = t0 + k * dt
        q, w, h = x[:4], x[4:7], x[7:]
        attitude = Rotation.from_quat(q)
        error_deg = float(np.degrees(np.arccos(np.clip(attitude.apply([0, 0, 1]) @ truth.los_inertial(t), -1, 1))))
        errors.append(error_deg)
        los = None
        if k % 10 == 0 and error_deg < 1.45:  # a frame a second, the target seen only inside the FOV
            los_body = attitude.inv().apply(truth.los_inertial(t)) + np.array([*rng.normal(0.0, 1e-4, 2), 0.0])
            los_body /= np.linalg.norm(los_body)
            los = (attitude * Rotation.from_rotvec(rng.normal(0.0, 3e-5, 3))).apply(los_body)
            recognizer.add_measurement(t, los)
            if recognizer.measurement_count >= 10:
                model = recognizer.continuous_trajectory()
        ref = loop.update(t, dt, model, los)
        body_torque = pd_torque_nm(q, w, ref, INERTIA, cfg, axes @ h)
        tau = wheel_torques_nm(body_torque, axes, h, MAX_TORQUE_NM, MAX_MOMENTUM_NMS)
        x = _rk4(x, t, dt, lambda _, s, tau=tau: _derivative(s, tau, axes, np.zeros(3)))
    errors_arr = np.asarray(errors)  # the largest, 1.0 deg, is the nominal's own offset at the start
    assert errors_arr.max() < 1.45
    assert errors_arr[int(170 / dt) :].max() < 0.1  # from C/A-30 s to C/A+30 s


def test_wheel_split_remembered_per_wheel_set_is_numpy_pinv_bit_for_bit() -> None:
    """Wheel torques with the split remembered from earlier periods equal, to the last bit, the minimum-norm split
    computed afresh with numpy's pinv, for every set of wheels a saturated wheel leaves usable."""
    rng = np.random.default_rng(7)
    for _ in range(200):
        axes = PYRAMID if rng.random() < 0.5 else rng.normal(size=(3, 4))
        torque = rng.normal(scale=1e-3, size=3)
        momentum = rng.choice([0.0, MAX_MOMENTUM_NMS, -MAX_MOMENTUM_NMS], size=axes.shape[1])
        got = wheel_torques_nm(torque, axes, momentum, 1.0, MAX_MOMENTUM_NMS)
        usable = np.ones(axes.shape[1], dtype=bool)
        for _ in range(axes.shape[1]):  # the allocation's rule, with a fresh pseudo-inverse each time
            tau = np.zeros(axes.shape[1])
            tau[usable] = -np.linalg.pinv(axes[:, usable]) @ torque
            pushing = usable & (np.abs(momentum) >= MAX_MOMENTUM_NMS) & (tau * momentum > 0)
            if not pushing.any():
                break
            usable &= ~pushing
        assert got.tobytes() == tau.tobytes()
