"""The tracking loop's compiled steps against SciPy: rotations, matrix exponentials and derivatives taken here."""

from __future__ import annotations

import numpy as np
from hypothesis import example, given, settings
from hypothesis import strategies as st
from scipy.linalg import expm
from scipy.spatial.transform import Rotation

from obsw import tracking_kernels as k
from obsw.config import TrackingConfig
from obsw.tracking import TrackingLoop, warm_up
from obsw.trajectory import NominalTrajectory

vectors = st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3).map(np.array)
angles = st.one_of(st.floats(0.0, 3.1), st.floats(0.0, 1e-6))
TRAJ = NominalTrajectory(ca_time_obt_s=210.0, ca_distance_km=55.0, speed_km_s=6.6,
                         approach_direction=(0.6, 0.8, 0.0), ca_direction=(0.0, 0.0, 1.0))
GEOMETRY = np.array([TRAJ.ca_time_obt_s, TRAJ.ca_distance_m, TRAJ.speed_m_s, *TRAJ.ca_direction,
                     *TRAJ.approach_direction])
TRIAD = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])  # boresight +z, plane normal +x, side +y


def _rotvec(direction: np.ndarray, angle: float) -> np.ndarray:
    norm = np.linalg.norm(direction)
    return np.zeros(3) if norm < 1e-3 else direction / norm * angle


@settings(max_examples=200, deadline=None)
@given(direction=vectors, angle=angles)
def test_rotation_matrix_is_scipys_rotation_of_the_rotation_vector(direction: np.ndarray, angle: float) -> None:
    """Rodrigues' matrix equals SciPy's matrix of the same rotation vector, small angles included."""
    v = _rotvec(direction, angle)
    np.testing.assert_allclose(k.rotation_matrix(v), Rotation.from_rotvec(v).as_matrix(), rtol=0, atol=1e-14)


@settings(max_examples=200, deadline=None)
@given(direction=vectors, angle=angles, rate=vectors)
def test_left_jacobian_maps_the_rotation_vector_rate_to_the_angular_velocity(direction: np.ndarray, angle: float,
                                                                              rate: np.ndarray) -> None:
    """J(phi) phi' is the angular velocity of R(phi(t)): the rotation vector of R(phi + h phi') R(phi - h phi')^T
    over 2 h (central difference, SciPy's rotations)."""
    phi, h = _rotvec(direction, angle), 1e-5
    numeric = (Rotation.from_rotvec(phi + h * rate) * Rotation.from_rotvec(phi - h * rate).inv()).as_rotvec() / (2 * h)
    np.testing.assert_allclose(k.left_jacobian(phi) @ rate, numeric, rtol=0, atol=1e-9)


@settings(max_examples=200, deadline=None)
@given(wn=st.floats(0.01, 3.0), zeta=st.one_of(st.floats(0.05, 3.0), st.just(1.0)), h=st.floats(0.0, 5.0))
def test_transition_is_the_matrix_exponential_of_the_loop(wn: float, zeta: float, h: float) -> None:
    """The closed-form transition equals SciPy's expm of [[-kp, -1], [ki, 0]] h, under-, critically and
    over-damped."""
    kp, ki = 2.0 * zeta * wn, wn * wn
    got = np.array(k.transition(kp, ki, h)).reshape(2, 2)
    np.testing.assert_allclose(got, expm(np.array([[-kp, -1.0], [ki, 0.0]]) * h), rtol=1e-10, atol=1e-13)


def _loop_matrix(kp: float, ki: float, sloping: bool) -> np.ndarray:
    """Per axis, x = [c, i, y, y']: c' = i + kp (y - c), i' = ki (y - c), y' = y' while sloping (else 0), y'' = 0."""
    return np.array([[-kp, 1.0, kp, 0.0], [-ki, 0.0, ki, 0.0], [0.0, 0.0, 0.0, 1.0 if sloping else 0.0],
                     [0.0, 0.0, 0.0, 0.0]])


@settings(max_examples=200, deadline=None)
@given(c=vectors, i=vectors, y_k=vectors, slope=vectors, t_k=st.floats(-2.0, 0.0), age_limit=st.floats(0.05, 3.0),
       t0=st.floats(0.0, 3.0), dt=st.floats(0.0, 1.0), wn=st.floats(0.1, 2.0), zeta=st.floats(0.3, 2.0))
# a knot where (t_k + limit) - t_k rounds below limit: the held piece went on sloping for the whole period
@example(c=np.zeros(3), i=np.zeros(3), y_k=np.zeros(3), slope=np.array([0.0, 0.0, 1.0]), t_k=-0.9594919670090587,
         age_limit=2.9999999999999996, t0=2.0, dt=1.0, wn=1.0, zeta=1.0)
def test_propagation_is_the_exact_solution_of_the_loop(c: np.ndarray, i: np.ndarray, y_k: np.ndarray,
                                                       slope: np.ndarray, t_k: float, age_limit: float, t0: float,
                                                       dt: float, wn: float, zeta: float) -> None:
    """Over a period, (c, i) move as SciPy's expm of the loop and its input (sloping until ``limit`` after the last
    measurement, then held), split at the knot."""
    kp, ki = 2.0 * zeta * wn, wn * wn
    knot = t_k + age_limit
    y0 = y_k + slope * (min(t0, knot) - t_k)  # the input at t0
    x = np.vstack([c, i, y0, np.where(t0 < knot, 1.0, 0.0) * slope])
    pieces = [(t0, min(max(knot, t0), t0 + dt), True), (min(max(knot, t0), t0 + dt), t0 + dt, False)]
    for a, b, sloping in pieces:
        x = expm(_loop_matrix(kp, ki, sloping) * (b - a)) @ x
    got_c, got_i = np.split(k.propagate(c, i, t0, dt, True, t_k, y_k, slope, age_limit, kp, ki), 2)
    np.testing.assert_allclose(got_c, x[0], rtol=1e-9, atol=1e-11)
    np.testing.assert_allclose(got_i, x[1], rtol=1e-9, atol=1e-11)


@settings(max_examples=50, deadline=None)
@given(c=vectors, i=vectors, dt=st.floats(0.0, 1.0))
def test_propagation_without_a_measurement_integrates_the_rate(c: np.ndarray, i: np.ndarray, dt: float) -> None:
    """Before any measurement the correction only moves at the integral's rate: c + i dt, i unchanged."""
    got_c, got_i = np.split(k.propagate(c, i, 0.0, dt, False, 0.0, np.zeros(3), np.zeros(3), 1.0, 0.5, 0.1), 2)
    np.testing.assert_allclose(got_c, c + i * dt, rtol=0, atol=1e-15)
    assert got_i.tolist() == i.tolist()


def _desired(c: np.ndarray, obt_s: float) -> Rotation:
    """R(c) [los, n, los x n] triad^T from SciPy and the trajectory's own methods."""
    los, n = TRAJ.los_inertial(obt_s), TRAJ.plane_normal
    return Rotation.from_rotvec(c) * Rotation.from_matrix(np.column_stack([los, n, np.cross(los, n)]) @ TRIAD.T)


@settings(max_examples=100, deadline=None)
@given(c=vectors.map(lambda v: v * 0.05), i=vectors.map(lambda v: v * 1e-3), y_k=vectors.map(lambda v: v * 0.05),
       slope=vectors.map(lambda v: v * 1e-3), obt=st.floats(0.0, 420.0), has_line=st.booleans())
def test_reference_is_the_corrected_trajectory_attitude_and_its_rate(c: np.ndarray, i: np.ndarray, y_k: np.ndarray,
                                                                     slope: np.ndarray, obt: float,
                                                                     has_line: bool) -> None:
    """q_des is SciPy's quaternion of R(c) R_pred, the commanded LOS R(c) los, and omega_des the body rate of that
    attitude with c moving at c' = i + kp (y - c) (central difference of SciPy's rotations)."""
    kp, ki, t, t_k, limit = 0.48, 0.09, 5.0, 4.8, 1.0
    out, valid = k.reference(c, i, kp, ki, t, has_line, t_k, y_k, slope, limit, GEOMETRY, obt, TRIAD)
    q, omega_b, los_cmd = out[:4], out[4:7], out[10:13]
    desired = _desired(c, obt)
    expected_q = desired.as_quat()
    assert valid
    np.testing.assert_allclose(q * np.sign(q @ expected_q), expected_q, rtol=0, atol=1e-12)
    np.testing.assert_allclose(los_cmd, Rotation.from_rotvec(c).apply(TRAJ.los_inertial(obt)), rtol=0, atol=1e-14)
    c_dot = i + kp * (y_k + slope * (t - t_k) - c) if has_line else i
    h = 1e-4
    turn = _desired(c + h * c_dot, obt + h) * _desired(c - h * c_dot, obt - h).inv()
    np.testing.assert_allclose(omega_b, desired.inv().apply(turn.as_rotvec() / (2 * h)), rtol=0, atol=1e-9)


@settings(max_examples=200, deadline=None)
@given(seed=st.integers(0, 2**31))
def test_quaternion_of_matrix_is_scipys_to_the_last_bit(seed: int) -> None:
    """Markley's quaternion of a rotation matrix is SciPy's bit for bit, and a matrix SciPy would orthogonalise
    first is flagged for SciPy."""
    m = Rotation.random(random_state=seed).as_matrix()
    q, valid = k.quaternion_of_matrix(m)
    assert valid and q.tolist() == Rotation.from_matrix(m).as_quat().tolist()
    assert not k.quaternion_of_matrix(m * (1.0 + 1e-9))[1]


@settings(max_examples=300, deadline=None)
@given(first=vectors, first_angle=st.one_of(st.floats(0.0, 1.5), st.floats(0.0, 1e-3)), second=vectors,
       second_angle=st.one_of(st.floats(0.0, 1.5), st.floats(0.0, 1e-3)))
def test_composed_rotation_vector_is_scipys(first: np.ndarray, first_angle: float, second: np.ndarray,
                                            second_angle: float) -> None:
    """The rotation vector of R(a) R(b) is SciPy's (from_rotvec(a) * from_rotvec(b)).as_rotvec(), small angles
    (SciPy's series) included, to a few units in the last place of the vector's largest component (angles near
    3 rad came 3 ulps apart, where 1e-15 absolute is about 2)."""
    a, b = _rotvec(first, first_angle), _rotvec(second, second_angle)
    expected = (Rotation.from_rotvec(a) * Rotation.from_rotvec(b)).as_rotvec()
    ulp = float(np.spacing(max(1.0, float(np.abs(expected).max()))))
    np.testing.assert_allclose(k.compose_rotvec(a, b), expected, rtol=0, atol=4.0 * ulp)


def _signatures() -> dict[str, int]:
    return {name: len(f.signatures) for name, f in vars(k).items() if hasattr(f, "signatures")}


def test_warm_up_compiles_every_kernel_a_period_calls() -> None:
    """After warm_up, periods of a loop (measurements, a gated one, a change of trajectory) compile nothing more."""
    warm_up()
    before = _signatures()
    assert all(before[name] >= 1 for name in ("propagate", "reference", "correction_rate", "compose_rotvec"))
    loop = TrackingLoop(TrackingConfig())
    for step in range(6):
        obt = 200.0 + 0.1 * step
        trajectory = TRAJ if step < 4 else TRAJ.with_ca(211.0, 54.0)
        loop.update(obt, 0.1, trajectory, TRAJ.los_inertial(obt - 0.05), measured_obt_s=obt - 0.05,
                    gate_rad=0.05 if step % 2 else None, extrapolate=step < 5)
    assert _signatures() == before
