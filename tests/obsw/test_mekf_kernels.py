"""The MEKF's compiled steps: the covariance's against filterpy's generic Kalman filter fed the textbook matrices,
the quaternion's against SciPy's rotations."""

from __future__ import annotations

import numpy as np
from filterpy.kalman import KalmanFilter
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from obsw import control_kernels, mekf_kernels


def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def _covariance(seed: int) -> np.ndarray:
    """A random symmetric positive-definite 6x6 covariance of attitude (rad) and bias (rad/s) errors."""
    rng = np.random.default_rng(seed)
    a = rng.standard_normal((6, 6)) * np.array([1e-3] * 3 + [1e-5] * 3)[:, None]
    return a @ a.T + np.diag([1e-8] * 3 + [1e-12] * 3)


def _filter(p: np.ndarray, r: np.ndarray) -> KalmanFilter:
    kf = KalmanFilter(dim_x=6, dim_z=3)
    kf.H = np.hstack([np.eye(3), np.zeros((3, 3))])
    kf.R, kf.P = r, p.copy()
    return kf


rates = st.lists(st.floats(-0.2, 0.2), min_size=3, max_size=3).map(np.array)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31), w=rates, dt=st.floats(0.01, 1.0))
def test_prediction_is_phi_p_phi_t_plus_q(seed: int, w: np.ndarray, dt: float) -> None:
    """The prediction equals filterpy's F P F^T + Q with the textbook second-order Phi and the random-walk Q_d."""
    p, sv, su = _covariance(seed), 3e-5, 2e-6
    phi = np.eye(6)
    phi[:3, :3] = np.eye(3) - _skew(w) * dt + 0.5 * (_skew(w) @ _skew(w)) * dt**2
    phi[:3, 3:] = -np.eye(3) * dt + 0.5 * _skew(w) * dt**2
    q_d = np.zeros((6, 6))
    q_d[:3, :3] = np.eye(3) * (sv**2 * dt + su**2 * dt**3 / 3.0)
    q_d[:3, 3:] = q_d[3:, :3] = -np.eye(3) * (su**2 * dt**2 / 2.0)
    q_d[3:, 3:] = np.eye(3) * (su**2 * dt)
    kf = _filter(p, np.eye(3))
    kf.predict(F=phi, Q=q_d)
    got = mekf_kernels.predict(p, w, dt, sv, su)
    np.testing.assert_allclose(got, kf.P, rtol=1e-12, atol=1e-13 * np.max(np.abs(kf.P)))  # to rounding, at P's scale


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31), z=st.lists(st.floats(-1e-3, 1e-3), min_size=3, max_size=3).map(np.array))
def test_update_is_the_joseph_form_kalman_update(seed: int, z: np.ndarray) -> None:
    """The state correction and the covariance equal filterpy's update (Joseph form) from a zero state."""
    p = _covariance(seed)
    r = np.diag(np.random.default_rng(seed + 1).uniform(1e-10, 1e-8, 3))
    kf = _filter(p, r)
    kf.x = np.zeros((6, 1))
    kf.update(z.reshape(3, 1))
    dx, got = mekf_kernels.update(p, r, z)
    np.testing.assert_allclose(dx, kf.x.ravel(), rtol=1e-9, atol=1e-18)
    np.testing.assert_allclose(got, kf.P, rtol=1e-9, atol=1e-13 * np.max(np.abs(kf.P)))
    np.testing.assert_allclose(got, got.T, rtol=0, atol=1e-12 * np.max(np.abs(got)))  # symmetric to rounding


unit_quaternions = st.lists(st.floats(-1, 1), min_size=4, max_size=4).map(np.array).filter(
    lambda q: np.linalg.norm(q) > 0.1).map(lambda q: q / np.linalg.norm(q))
rotation_vectors = st.lists(st.floats(-3.0, 3.0), min_size=3, max_size=3).map(np.array)


@settings(max_examples=200, deadline=None)
@given(p=unit_quaternions, q=unit_quaternions, v=rotation_vectors)
def test_quaternion_steps_are_scipys_rotations(p: np.ndarray, q: np.ndarray, v: np.ndarray) -> None:
    """The compiled quaternion steps equal SciPy's Rotation: the product composes (q first), the rotation vector's
    quaternion is from_rotvec's, and the rotation between two attitudes is the shorter one, in the first's axes."""
    rp, rq = Rotation.from_quat(p), Rotation.from_quat(q)
    assert Rotation.from_quat(mekf_kernels.product(p, q)).approx_equal(rp * rq, atol=1e-12)
    assert Rotation.from_quat(mekf_kernels.of_rotvec(v)).approx_equal(Rotation.from_rotvec(v), atol=1e-12)
    between = control_kernels.rotvec(control_kernels.error_quaternion(q, p))  # the innovation's rotation
    assert np.linalg.norm(between) <= np.pi + 1e-12
    assert Rotation.from_rotvec(between).approx_equal(rp.inv() * rq, atol=1e-9)


@settings(max_examples=100, deadline=None)
@given(q=unit_quaternions, w=rotation_vectors, dt=st.floats(0.01, 1.0), seed=st.integers(0, 2**16))
def test_propagation_turns_the_attitude_by_the_rate(q: np.ndarray, w: np.ndarray, dt: float, seed: int) -> None:
    """``propagate`` turns the attitude by ``w dt`` about the body axes, keeps it a unit quaternion, and carries the
    covariance as ``predict`` does."""
    p = _covariance(seed)
    q_new, p_new = mekf_kernels.propagate(q, p, w, dt, 1e-5, 1e-6)
    assert abs(np.linalg.norm(q_new) - 1.0) < 1e-12
    assert Rotation.from_quat(q_new).approx_equal(Rotation.from_quat(q) * Rotation.from_rotvec(w * dt), atol=1e-12)
    assert np.array_equal(p_new, mekf_kernels.predict(p, w, dt, 1e-5, 1e-6))
