"""Trajectory recognition against brute-force recomputation, an independent least-squares solver and the noise."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from obsw import recognition_kernels
from obsw.config import RecognitionConfig
from obsw.recognition import (ContinuousEstimate, TrajectoryRecognizer, estimates_agree, measured_theta_rad,
                              out_of_plane_rad, predicted_los, predicted_theta)
from obsw.trajectory import NominalTrajectory
from tests.obsw.recognition_reference import reference_solve

NOMINAL = NominalTrajectory(
    ca_time_obt_s=1000.0,
    ca_distance_km=55.0,
    speed_km_s=7.0,
    approach_direction=(1.0, 0.2, 0.0),
    ca_direction=(0.0, 1.0, 0.3),
    ca_time_sigma_s=10.0,
    ca_distance_sigma_km=5.0,
)
# centroid (1 px of 512 over 2.9 deg, 9.9e-5 rad) and star tracker (6 arcsec, 2.9e-5 rad) in quadrature
CENTROID_SIGMA, ATTITUDE_SIGMA = 9.9e-5, 2.9e-5
SIGMA = float(np.hypot(CENTROID_SIGMA, ATTITUDE_SIGMA))
CFG = RecognitionConfig(angle_noise_rad=SIGMA)
TIMES = np.arange(1000.0 - 240.0, 1000.0 - 30.0, 1.0)  # acquisition to autonomous tracking, one frame a second


def _measured_los(truth: NominalTrajectory, t: float, rng: np.random.Generator) -> np.ndarray:
    """LOS as the OBSW forms it: R(q_est) (los_body + centroid noise), with q_est = q_true perturbed."""
    q_true = Rotation.from_rotvec(rng.normal(0.0, 0.3, 3))  # any attitude: the result must not depend on it
    los_body = q_true.inv().apply(truth.los_inertial(t))
    los_body = los_body + np.array([*rng.normal(0.0, CENTROID_SIGMA, 2), 0.0]) * los_body[2]
    los_body /= np.linalg.norm(los_body)
    q_est = q_true * Rotation.from_rotvec(rng.normal(0.0, ATTITUDE_SIGMA, 3))
    return q_est.apply(los_body)


def _fed(truth: NominalTrajectory, seed: int, cfg: RecognitionConfig = CFG) -> TrajectoryRecognizer:
    rng = np.random.default_rng(seed)
    rec = TrajectoryRecognizer(NOMINAL, cfg)
    for t in TIMES:
        rec.add_measurement(float(t), _measured_los(truth, float(t), rng))
    return rec


def _cell(rec: TrajectoryRecognizer, t: float, d_km: float) -> tuple[int, int]:
    times, dists = rec.candidate_axes()
    return int(np.argmin(np.abs(times - t))), int(np.argmin(np.abs(dists - d_km)))


def test_without_measurements_the_nominal_is_returned() -> None:
    """No measurement: the grid gives the nominal (mse nan) and the continuous estimate the nominal and its prior."""
    rec = TrajectoryRecognizer(NOMINAL, CFG)
    t, d, mse = rec.best_grid()
    assert (t, d) == (1000.0, 55.0) and np.isnan(mse)
    t, d, cov = rec.continuous()
    assert (t, d) == (1000.0, 55.0)
    assert np.allclose(cov, np.diag([100.0, 25.0]))
    assert rec.best_trajectory() == NOMINAL


def test_grid_is_centred_on_the_nominal_and_spans_k_sigma() -> None:
    """13 x 13 candidates from -3 to +3 sigma, the nominal in the middle."""
    times, dists = TrajectoryRecognizer(NOMINAL, CFG).candidate_axes()
    assert np.allclose(times, np.linspace(970.0, 1030.0, 13))
    assert np.allclose(dists, np.linspace(40.0, 70.0, 13))
    assert times[6] == 1000.0 and dists[6] == 55.0


def _noise_free_mse(truth: NominalTrajectory, t: float, d_km: float) -> tuple[float, np.ndarray]:
    """Mean capped square distance between the truth's and a candidate's theta histories, and the differences."""
    delta = truth.theta_rad(TIMES) - NOMINAL.with_ca(t, d_km).theta_rad(TIMES)
    return float(np.mean(np.minimum(delta**2, CFG.residual_cap_rad**2))), delta


@settings(max_examples=15, deadline=None, derandomize=True)
@given(st.floats(-2.9, 2.9), st.floats(-2.9, 2.9), st.integers(0, 2**32 - 1))
def test_grid_picks_the_candidate_nearest_the_truth(u: float, w: float, seed: int) -> None:
    """The best candidate is the nearest one or its neighbour, unless a farther one fits the truth's LOS better.

    Before C/A-30 s, theta ~ d / (v |t - t_ca|) leaves a long valley in (t_ca, d): near the grid's edge a candidate
    two cells along it can explain the truth's angles better than the nearest; the MSE rightly picks that one.
    """
    truth = NOMINAL.with_ca(1000.0 + 10.0 * u, 55.0 + 5.0 * w)
    rec = _fed(truth, seed)
    t, d, _ = rec.best_grid()
    got, nearest = _cell(rec, t, d), _cell(rec, truth.ca_time_obt_s, truth.ca_distance_km)
    if abs(got[0] - nearest[0]) <= 1 and abs(got[1] - nearest[1]) <= 1:
        return
    times, dists = rec.candidate_axes()
    mse_got, delta_got = _noise_free_mse(truth, t, d)
    mse_nearest, delta_nearest = _noise_free_mse(truth, times[nearest[0]], dists[nearest[1]])
    # the noise can favour one of two candidates by 2 mean((delta_1 - delta_2) n): allow four sigmas of that
    margin = 8 * SIGMA * float(np.sqrt(np.mean((delta_got - delta_nearest) ** 2) / TIMES.size))
    assert mse_got <= mse_nearest + margin


def test_grid_picks_the_nearest_candidate_inside_the_grid() -> None:
    """For truths well inside the grid (within 2 sigma) the best candidate is the nearest one or its neighbour."""
    rng = np.random.default_rng(7)
    for seed in range(8):
        u, w = rng.uniform(-2.0, 2.0, 2)
        truth = NOMINAL.with_ca(1000.0 + 10.0 * u, 55.0 + 5.0 * w)
        rec = _fed(truth, seed)
        got, nearest = _cell(rec, *rec.best_grid()[:2]), _cell(rec, truth.ca_time_obt_s, truth.ca_distance_km)
        assert abs(got[0] - nearest[0]) <= 1 and abs(got[1] - nearest[1]) <= 1


def test_mse_grid_equals_a_brute_force_recomputation() -> None:
    """The running sums equal the capped mean square residual recomputed from each candidate's own theta(t)."""
    truth = NOMINAL.with_ca(1013.0, 50.9)
    rng = np.random.default_rng(3)
    rec = TrajectoryRecognizer(NOMINAL, CFG)
    measured = []
    for t in TIMES:
        los = _measured_los(truth, float(t), rng)
        rec.add_measurement(float(t), los)
        in_plane = los - (los @ NOMINAL.plane_normal) * NOMINAL.plane_normal  # the angle is taken in the flyby plane
        measured.append(np.arccos(np.clip(NOMINAL.e_v @ in_plane / np.linalg.norm(in_plane), -1.0, 1.0)))
    times, dists = rec.candidate_axes()
    expected = np.empty((times.size, dists.size))
    for i, tc in enumerate(times):
        for j, dc in enumerate(dists):
            r = np.asarray(measured) - NOMINAL.with_ca(tc, dc).theta_rad(TIMES)
            expected[i, j] = np.mean(np.minimum(r**2, CFG.residual_cap_rad**2))
    assert np.allclose(rec.mse_grid(), expected, rtol=1e-6, atol=1e-12)
    t, d, mse = rec.best_grid()
    i, j = np.unravel_index(np.argmin(expected), expected.shape)
    assert (t, d) == (times[i], dists[j]) and mse == pytest.approx(expected[i, j], rel=1e-6)


@pytest.mark.parametrize("seed", range(4))
def test_continuous_estimate_is_within_its_noise_bound(seed: int) -> None:
    """The continuous C/A time, distance and LOS offset are within 4 sigma of the truth, sigma from the Cramer-Rao
    bound."""
    truth = NOMINAL.with_ca(1013.0, 50.9)
    est = _fed(truth, seed).continuous_estimate()
    # Cramer-Rao bound computed here from finite differences of theta and the priors (the offset's: a constant), at
    # the estimate (with three parameters the information changes by 0.2 % between it and the truth)
    h_t, h_d, t0, d0 = 1e-3, 1e-3, est.ca_time_obt_s, est.ca_distance_km
    jac = np.column_stack(
        [
            (truth.with_ca(t0 + h_t, d0).theta_rad(TIMES) - truth.with_ca(t0 - h_t, d0).theta_rad(TIMES)) / (2 * h_t),
            (truth.with_ca(t0, d0 + h_d).theta_rad(TIMES) - truth.with_ca(t0, d0 - h_d).theta_rad(TIMES)) / (2 * h_d),
            np.ones(TIMES.size),
        ]
    )
    crb = np.linalg.inv(jac.T @ jac / SIGMA**2 + np.diag([1 / 100.0, 1 / 25.0, 1 / CFG.los_offset_sigma_rad**2]))
    assert np.allclose(est.cov, crb, rtol=1e-3)
    assert abs(est.ca_time_obt_s - 1013.0) < 4 * np.sqrt(crb[0, 0])
    assert abs(est.ca_distance_km - 50.9) < 4 * np.sqrt(crb[1, 1])
    assert abs(est.in_plane_offset_rad) < 4 * np.sqrt(crb[2, 2])
    assert abs(est.out_of_plane_offset_rad) < 4 * est.out_of_plane_sigma_rad
    assert np.sqrt(crb[0, 0]) < 0.1 and np.sqrt(crb[1, 1]) < 0.1  # tens of ms and tens of metres
    t, d, cov = _fed(truth, seed).continuous()
    assert (t, d) == (est.ca_time_obt_s, est.ca_distance_km) and np.array_equal(cov, est.cov[:2, :2])


def test_continuous_estimate_matches_scipy_least_squares() -> None:
    """The Gauss-Newton MAP estimate is the minimum scipy.optimize.least_squares finds on the same cost."""
    truth = NOMINAL.with_ca(992.0, 61.0)
    rng = np.random.default_rng(11)
    rec = TrajectoryRecognizer(NOMINAL, CFG)
    theta = []
    for t in TIMES:
        los = _measured_los(truth, float(t), rng)
        rec.add_measurement(float(t), los)
        theta.append(measured_theta_rad(NOMINAL, los))
    theta_arr = np.asarray(theta)
    s_e = CFG.los_offset_sigma_rad

    def residuals(p: np.ndarray) -> np.ndarray:
        model = NOMINAL.with_ca(p[0], p[1]).theta_rad(TIMES) + p[2]
        return np.concatenate([(theta_arr - model) / SIGMA, [(p[0] - 1000.0) / 10.0, (p[1] - 55.0) / 5.0, p[2] / s_e]])

    ref = least_squares(residuals, x0=[1000.0, 55.0, 0.0], x_scale=[10.0, 5.0, s_e], xtol=1e-15, ftol=1e-15,
                        gtol=1e-15)
    est = rec.continuous_estimate()
    assert est.ca_time_obt_s == pytest.approx(ref.x[0], abs=1e-6)
    assert est.ca_distance_km == pytest.approx(ref.x[1], abs=1e-6)
    assert est.in_plane_offset_rad == pytest.approx(ref.x[2], abs=1e-9)


def _tracking_attitude(t: float) -> Rotation:
    """Body -> inertial as the tracking loop holds it: the boresight (+Z) on the ground nominal's line of sight, body
    +Y on the flyby plane's normal."""
    z = NOMINAL.los_inertial(t)
    y = NOMINAL.plane_normal
    return Rotation.from_matrix(np.column_stack([np.cross(y, z), y, z]))


def _misaligned_los(truth: NominalTrajectory, t: float, camera_to_body: Rotation,
                    rng: np.random.Generator) -> np.ndarray:
    """The LOS the OBSW forms with a camera turned by ``camera_to_body`` from its nominal axes (it takes camera axes
    for body axes), on the tracking attitude, with centroid and attitude noise."""
    q_true = _tracking_attitude(t)
    los_camera = (q_true * camera_to_body).inv().apply(truth.los_inertial(t))
    los_camera = los_camera + np.array([*rng.normal(0.0, CENTROID_SIGMA, 2), 0.0]) * los_camera[2]
    q_est = q_true * Rotation.from_rotvec(rng.normal(0.0, ATTITUDE_SIGMA, 3))
    return q_est.apply(los_camera / np.linalg.norm(los_camera))


@pytest.mark.parametrize("seed", range(3))
def test_a_misaligned_camera_is_estimated_and_leaves_the_ca_time_unbiased(seed: int) -> None:
    """A camera misaligned by 0.04 deg (twice the prior's sigma) about an axis across the boresight: the estimate's
    LOS offsets are the misalignment's in-plane and out-of-plane parts within 4 sigma, and the C/A time is within 4
    sigma of the truth; holding the offset at zero (the paper's estimate), an in-plane part of at least half the
    misalignment puts the C/A time beyond 4 sigma (20 to 44 sigma)."""
    truth = NOMINAL.with_ca(1006.0, 53.0)
    rng = np.random.default_rng(seed)
    azimuth = np.radians(rng.uniform(30.0, 150.0) + 180.0 * rng.integers(2))  # a rotation about body X is out of plane
    axis = np.array([np.cos(azimuth), np.sin(azimuth), 0.0])
    camera_to_body = Rotation.from_rotvec(np.radians(0.04) * axis)
    # the camera's +Z in body axes: off +Z towards +X turns the measured angle within the plane, towards +Y out of it
    z_body = camera_to_body.apply([0.0, 0.0, 1.0])
    recs = {sigma: TrajectoryRecognizer(NOMINAL, RecognitionConfig(angle_noise_rad=SIGMA,
                                                                   los_offset_sigma_rad=sigma)) for sigma in (3.5e-4, 0.0)}
    for t in TIMES:
        los = _misaligned_los(truth, float(t), camera_to_body, rng)
        for rec in recs.values():
            rec.add_measurement(float(t), los)
    est = recs[3.5e-4].continuous_estimate()
    # theta grows from the approach direction towards -e_ca: body +X (= y x z) points the way theta grows
    in_plane, out_of_plane = -float(np.arcsin(z_body[0])), -float(np.arcsin(z_body[1]))
    assert abs(est.in_plane_offset_rad - in_plane) < 4 * np.sqrt(est.cov[2, 2])
    assert abs(est.out_of_plane_offset_rad - out_of_plane) < 4 * est.out_of_plane_sigma_rad
    assert abs(est.ca_time_obt_s - 1006.0) < 4 * np.sqrt(est.cov[0, 0])
    t_held, _, cov_held = recs[0.0].continuous()
    assert abs(t_held - 1006.0) > 4 * np.sqrt(cov_held[0, 0])


def _fed_with_outliers(truth: NominalTrajectory, cfg: RecognitionConfig) -> TrajectoryRecognizer:
    """Five frames where another blob a FOV half-width (1.4 deg) away in the flyby plane was taken for Dimorphos."""
    rng = np.random.default_rng(5)
    rec = TrajectoryRecognizer(NOMINAL, cfg)
    wrong = set(range(20, 200, 40))
    for k, t in enumerate(TIMES):
        los = _measured_los(truth, float(t), rng)
        if k in wrong:
            los = Rotation.from_rotvec(np.radians(1.4) * NOMINAL.plane_normal).apply(los)
        rec.add_measurement(float(t), los)
    return rec


def test_outliers_do_not_flip_the_choice() -> None:
    """A few false detections change neither the grid choice nor the continuous fix (they would, uncapped)."""
    truth = NOMINAL.with_ca(1007.0, 57.2)
    clean = _fed(truth, 5)
    dirty = _fed_with_outliers(truth, CFG)
    assert dirty.best_grid()[:2] == clean.best_grid()[:2]
    t, d, cov = dirty.continuous()
    assert abs(t - 1007.0) < 4 * np.sqrt(cov[0, 0]) and abs(d - 57.2) < 4 * np.sqrt(cov[1, 1])
    # the same data without the cap and the gate: the outliers do move both estimates
    uncapped = RecognitionConfig(angle_noise_rad=SIGMA, residual_cap_rad=10.0, outlier_gate_sigma=1e6)
    naive = _fed_with_outliers(truth, uncapped)
    assert naive.best_grid()[:2] != clean.best_grid()[:2]
    t, d, cov = naive.continuous()
    assert abs(t - 1007.0) > 10 * np.sqrt(cov[0, 0])


def test_measurements_nothing_explains_leave_the_nominal_and_its_prior() -> None:
    """LOS far from every candidate (all residuals capped) carry no information: nominal and prior covariance."""
    rec = TrajectoryRecognizer(NOMINAL, CFG)
    for t in TIMES[::10]:
        rec.add_measurement(float(t), NOMINAL.e_ca)  # looking back at where the asteroid is not
    t, d, mse = rec.best_grid()
    assert (t, d) == (1000.0, 55.0) and mse == pytest.approx(CFG.residual_cap_rad**2)
    t, d, cov = rec.continuous()
    assert (t, d) == (1000.0, 55.0)
    assert np.allclose(cov, np.diag([100.0, 25.0]))


def test_clock_offset_is_absorbed_in_the_ca_time() -> None:
    """Measurements stamped by a clock running 25 s ahead give a C/A time 25 s later in OBT, the same distance."""
    truth = NOMINAL.with_ca(1004.0, 53.0)
    rng = np.random.default_rng(8)
    rec = TrajectoryRecognizer(NOMINAL, CFG)
    for t in TIMES[::2]:
        rec.add_measurement(float(t) + 25.0, _measured_los(truth, float(t), rng))
    t, d, cov = rec.continuous()
    assert abs(t - 1029.0) < 4 * np.sqrt(cov[0, 0]) and abs(d - 53.0) < 4 * np.sqrt(cov[1, 1])


def test_a_step_of_on_board_time_moves_the_measurements_and_the_estimate_with_it() -> None:
    """After shift_time(s) the recognition is the one fed the same lines of sight s later against the nominal moved by
    s: the measurements' times, the grid's choice and the continuous estimate move by s, the distance stays."""
    truth, step_s = NOMINAL.with_ca(1003.0, 57.0), 12.5
    rng = np.random.default_rng(21)
    shifted = TrajectoryRecognizer(NOMINAL, CFG)
    later = TrajectoryRecognizer(NOMINAL.with_ca(1000.0 + step_s, 55.0), CFG)
    for t in TIMES:  # 210 measurements: past the first sizes of the recognizer's buffer
        los = _measured_los(truth, float(t), rng)
        shifted.add_measurement(float(t), los)
        later.add_measurement(float(t) + step_s, los)
    shifted.continuous_estimate()  # solved before the step: the cached estimate must move too
    shifted.shift_time(step_s)
    assert shifted.measurement_times_obt_s == pytest.approx(tuple(TIMES + step_s), abs=1e-9)
    assert shifted.last_measurement_obt_s == pytest.approx(float(TIMES[-1]) + step_s, abs=1e-9)
    assert shifted.best_grid() == pytest.approx(later.best_grid(), abs=1e-9)
    a, b = shifted.continuous_estimate(), later.continuous_estimate()
    assert a.ca_time_obt_s == pytest.approx(b.ca_time_obt_s, abs=1e-6)
    assert a.ca_distance_km == pytest.approx(b.ca_distance_km, abs=1e-6)
    assert np.allclose(a.cov, b.cov, rtol=1e-6, atol=1e-12)


def test_the_estimate_is_one_read_only_value_until_the_next_measurement() -> None:
    """Every caller gets the same estimate until a measurement is added, and none can write its covariance (the next
    caller would get the change); a new measurement gives a new estimate."""
    rec = _fed(NOMINAL.with_ca(1002.0, 56.0), 5)
    first = rec.continuous_estimate()
    assert rec.continuous_estimate() is first
    with pytest.raises(ValueError, match="read-only"):
        first.cov[0, 0] = 0.0
    rec.add_measurement(float(TIMES[-1]) + 1.0, NOMINAL.with_ca(1002.0, 56.0).los_inertial(float(TIMES[-1]) + 1.0))
    assert rec.continuous_estimate() is not first and rec.measurement_count == TIMES.size + 1


def test_zero_sigma_fixes_that_parameter() -> None:
    """A zero one-sigma uncertainty pins that parameter to the nominal, with zero variance."""
    nominal = NOMINAL.model_copy(update={"ca_distance_sigma_km": 0.0})
    truth = nominal.with_ca(1006.0, 55.0)
    rng = np.random.default_rng(2)
    rec = TrajectoryRecognizer(nominal, CFG)
    for t in TIMES[::3]:
        rec.add_measurement(float(t), _measured_los(truth, float(t), rng))
    t, d, cov = rec.continuous()
    assert d == 55.0 and cov[1, 1] == 0.0 and cov[0, 1] == 0.0
    assert abs(t - 1006.0) < 4 * np.sqrt(cov[0, 0])
    assert rec.best_grid()[1] == 55.0


def test_bad_inputs_are_rejected_with_the_field_named() -> None:
    """A grid reaching a non-positive distance, or a non-unit LOS, raises ValueError naming it."""
    with pytest.raises(ValueError, match="ca_distance_sigma_km"):
        TrajectoryRecognizer(NOMINAL.model_copy(update={"ca_distance_sigma_km": 20.0}), CFG)
    rec = TrajectoryRecognizer(NOMINAL, CFG)
    with pytest.raises(ValueError, match="los_inertial"):
        rec.add_measurement(900.0, [0.0, 0.0, 2.0])
    assert rec.measurement_count == 0


def test_the_predicted_angle_and_its_sigma_follow_the_estimate_and_its_covariance() -> None:
    """The predicted in-plane angle is the continuous trajectory's plus the LOS offset; its sigma is the covariance
    (of C/A time and distance, or of those and the offset) carried through the angle's derivatives, here taken by
    central differences of NominalTrajectory.theta_rad."""
    truth = NOMINAL.with_ca(1004.0, 52.0)
    rec = _fed(truth, seed=5)
    est = rec.continuous_estimate()
    t_ca, d_km, e = est.ca_time_obt_s, est.ca_distance_km, est.in_plane_offset_rad
    for t in (800.0, 950.0, 995.0, 1010.0):
        h = 1e-4  # s and km

        def theta_at(dt: float, dd: float) -> float:
            return float(NOMINAL.with_ca(t_ca + dt, d_km + dd).theta_rad(t))  # noqa: B023

        jac = np.array([(theta_at(h, 0.0) - theta_at(-h, 0.0)) / (2 * h),
                        (theta_at(0.0, h) - theta_at(0.0, -h)) / (2 * h), 1.0])
        theta, sigma = predicted_theta(t_ca, d_km, est.cov[:2, :2], NOMINAL.speed_m_s, t)
        assert theta == pytest.approx(theta_at(0.0, 0.0), abs=1e-12)
        assert sigma == pytest.approx(float(np.sqrt(jac[:2] @ est.cov[:2, :2] @ jac[:2])), rel=1e-5)
        theta, sigma = predicted_theta(t_ca, d_km, est.cov, NOMINAL.speed_m_s, t, e)
        assert theta == pytest.approx(theta_at(0.0, 0.0) + e, abs=1e-12)
        assert sigma == pytest.approx(float(np.sqrt(jac @ est.cov @ jac)), rel=1e-5)


@settings(max_examples=60, deadline=None)
@given(t=st.floats(700.0, 1300.0), dt=st.floats(-30.0, 30.0), dd_km=st.floats(-15.0, 15.0),
       e_in=st.floats(-2e-3, 2e-3), e_out=st.floats(-2e-3, 2e-3), sig_out=st.floats(0.0, 1e-3),
       axis=st.tuples(st.floats(-1, 1), st.floats(-1, 1), st.floats(-1, 1)).filter(lambda v: np.linalg.norm(v) > 0.1),
       turn_deg=st.floats(0.0, 180.0))
def test_the_predicted_line_of_sight_is_measured_at_the_predicted_angles(t, dt, dd_km, e_in, e_out, sig_out, axis,
                                                                         turn_deg) -> None:
    """predicted_los is the unit line of sight whose measured in-plane angle is the estimate's angle plus its in-plane
    offset and whose angle out of the plane is its out-of-plane offset (the measurement functions inverted); with no
    offset it is the moved trajectory's own line of sight; its sigma is the in-plane one and the out-of-plane one
    combined, on any flyby geometry."""
    turn = Rotation.from_rotvec(np.radians(turn_deg) * np.asarray(axis) / np.linalg.norm(axis))
    traj = NOMINAL.model_copy(update={
        "approach_direction": tuple(turn.apply(NOMINAL.approach_direction)),
        "ca_direction": tuple(turn.apply(NOMINAL.ca_direction))})
    cov = np.diag([4.0, 1.0, 1e-8])
    est = ContinuousEstimate(ca_time_obt_s=traj.ca_time_obt_s + dt, ca_distance_km=traj.ca_distance_km + dd_km,
                             in_plane_offset_rad=e_in, cov=cov, out_of_plane_offset_rad=e_out,
                             out_of_plane_sigma_rad=sig_out)
    los, sigma = predicted_los(traj, est, t)
    assert np.linalg.norm(los) == pytest.approx(1.0, abs=1e-12)
    moved = traj.with_ca(est.ca_time_obt_s, est.ca_distance_km)
    assert measured_theta_rad(traj, los) == pytest.approx(float(moved.theta_rad(t)) + e_in, abs=1e-9)
    assert out_of_plane_rad(traj, los) == pytest.approx(e_out, abs=1e-9)
    _, sigma_in = predicted_theta(est.ca_time_obt_s, est.ca_distance_km, cov, traj.speed_m_s, t, e_in)
    assert sigma == pytest.approx(float(np.hypot(sigma_in, sig_out)), rel=1e-12)
    bare, _ = predicted_los(traj, ContinuousEstimate(est.ca_time_obt_s, est.ca_distance_km, 0.0, cov, 0.0, 0.0), t)
    assert bare == pytest.approx(moved.los_inertial(t), abs=1e-12)


@settings(max_examples=60, deadline=None)
@given(dt=st.floats(-30.0, 30.0), dd_km=st.floats(-15.0, 15.0), offset=st.floats(-1e-3, 1e-3),
       seed=st.integers(0, 2**16), outliers=st.integers(0, 20),
       span=st.sampled_from([(-240.0, -30.0), (-240.0, 60.0), (-100.0, -80.0)]),
       sigmas=st.sampled_from([(10.0, 5.0, 3.5e-4), (10.0, 5.0, 0.0), (10.0, 0.0, 3.5e-4), (0.0, 5.0, 3.5e-4),
                               (3.0, 20.0, 1e-3), (0.0, 0.0, 3.5e-4)]))
def test_compiled_estimate_equals_the_numpy_reference(dt: float, dd_km: float, offset: float, seed: int,
                                                      outliers: int, span: tuple[float, float],
                                                      sigmas: tuple[float, float, float]) -> None:
    """The compiled MAP estimate and covariance equal a plain numpy Gauss-Newton's on the same measurements (noise,
    a constant offset, outliers beyond the gate, parameters held by a zero prior sigma), to rounding."""
    nominal = NOMINAL.model_copy(update={"ca_time_sigma_s": sigmas[0], "ca_distance_sigma_km": sigmas[1]})
    truth = nominal.with_ca(1000.0 + dt, 55.0 + dd_km)
    rng = np.random.default_rng(seed)
    times = np.arange(1000.0 + span[0], 1000.0 + span[1], 1.0)
    theta = truth.theta_rad(times) + offset + rng.normal(0.0, SIGMA, times.size)
    theta[rng.choice(times.size, size=min(outliers, times.size), replace=False)] += rng.uniform(0.01, 0.2, 1)[0]
    start = (1000.0 + dt + rng.normal(0, 2.0), (55.0 + dd_km + rng.normal(0, 1.0)) * 1e3, 0.0)
    origin = (nominal.ca_time_obt_s, nominal.ca_distance_m, 0.0)
    sigma = (sigmas[0], sigmas[1] * 1e3, sigmas[2])
    p, cov, _ = recognition_kernels.solve(times, theta, np.array(origin), np.array(sigma), np.array(start),
                                          nominal.speed_m_s, CFG.angle_noise_rad, CFG.residual_cap_rad,
                                          CFG.outlier_gate_sigma * CFG.angle_noise_rad, CFG.max_iterations)
    p_ref, cov_ref = reference_solve(times, theta, origin, sigma, start, nominal.speed_m_s, CFG)
    assert p[0] == pytest.approx(p_ref[0], abs=1e-6) and p[1] == pytest.approx(p_ref[1], abs=1e-3)
    assert p[2] == pytest.approx(p_ref[2], abs=1e-8)  # 1e-4 of the angle noise: both stop at the same cost change
    assert np.allclose(cov, cov_ref, rtol=1e-6, atol=1e-12)


# --- the cross-check of Dimorphos's recognition against Didymos's ---------------------------------------------------
# the two bodies' centroids are at most the orbit's radius plus both bodies' largest apparent radii apart (obsw's
# default knowledge: 1190 m + 1.5 x (780 + 164) / 2 m)
APART_KM = (1190.0 + 1.5 * (780.0 + 164.0) / 2) / 1e3


def _fed_apart(truth: NominalTrajectory, offset_m: np.ndarray, seed: int) -> TrajectoryRecognizer:
    """A recognition fed the lines of sight of a body ``offset_m`` (inertial) from ``truth``'s point, noisy as
    ``_measured_los``: the spacecraft's position relative to that body is ``truth``'s plus the offset."""
    rng = np.random.default_rng(seed)
    rec = TrajectoryRecognizer(NOMINAL, CFG)
    for t in TIMES:
        r = truth.position_m(float(t)) + offset_m
        los = -r / np.linalg.norm(r)
        q_true = Rotation.from_rotvec(rng.normal(0.0, 0.3, 3))
        los_body = q_true.inv().apply(los)
        los_body = los_body + np.array([*rng.normal(0.0, CENTROID_SIGMA, 2), 0.0]) * los_body[2]
        los_body /= np.linalg.norm(los_body)
        q_est = q_true * Rotation.from_rotvec(rng.normal(0.0, ATTITUDE_SIGMA, 3))
        rec.add_measurement(float(t), q_est.apply(los_body))
    return rec


@pytest.mark.parametrize("k", range(12))
def test_two_bodies_no_farther_apart_than_the_allowance_are_recognised_as_agreeing(k: int) -> None:
    """Two recognitions fed the lines of sight of two bodies the whole allowance apart, in any direction (along the
    track, across it, out of the plane), agree (``estimates_agree`` at 3 sigma)."""
    rng = np.random.default_rng(100 + k)
    direction = rng.normal(size=3) if k >= 3 else np.eye(3)[k]  # the three axes, then random directions
    offset = APART_KM * 1e3 * direction / np.linalg.norm(direction)
    truth = NOMINAL.with_ca(1008.0, 58.0)
    a, b = _fed_apart(truth, np.zeros(3), 2 * k), _fed_apart(truth, offset, 2 * k + 1)
    assert estimates_agree(a.continuous_estimate(), b.continuous_estimate(), APART_KM, truth.speed_km_s, 3.0)


@pytest.mark.parametrize("dt_s", [-6.0, -2.0, 2.0, 6.0])
def test_a_recognition_seconds_off_does_not_agree_with_the_other_body(dt_s: float) -> None:
    """A recognition fed lines of sight of a trajectory seconds off in C/A time (what lines of sight of an unresolved
    pair did) does not agree with the other body's, fed the true one."""
    truth = NOMINAL.with_ca(1008.0, 58.0)
    a, b = _fed_apart(truth.with_ca(1008.0 + dt_s, 58.0), np.zeros(3), 7), _fed_apart(truth, np.zeros(3), 8)
    assert not estimates_agree(a.continuous_estimate(), b.continuous_estimate(), APART_KM, truth.speed_km_s, 3.0)


def test_the_agreement_is_symmetric_and_bounded_by_each_component() -> None:
    """The agreement is symmetric, and fails as soon as either the C/A times or the C/A distances differ by more
    than their allowance (closed form on hand-made estimates)."""
    cov = np.diag([0.1**2, 0.2**2, 1e-8])
    e = ContinuousEstimate(1000.0, 55.0, 0.0, cov, 0.0, 1e-4)
    allowed_t = 1.0 / 7.0 + 3.0 * np.sqrt(2) * 0.1
    allowed_d = 1.0 + 3.0 * np.sqrt(2) * 0.2
    for dt, dd, ok in [(0.99 * allowed_t, 0.0, True), (1.01 * allowed_t, 0.0, False), (0.0, 0.99 * allowed_d, True),
                       (0.0, -1.01 * allowed_d, False), (-0.99 * allowed_t, 0.99 * allowed_d, True)]:
        f = ContinuousEstimate(1000.0 + dt, 55.0 + dd, 0.0, cov, 0.0, 1e-4)
        assert estimates_agree(e, f, 1.0, 7.0, 3.0) is ok and estimates_agree(f, e, 1.0, 7.0, 3.0) is ok


def test_the_recent_scatter_is_the_noise_and_grows_with_other_blobs() -> None:
    """The median absolute residual of the last lines of sight is under one sigma of their noise, and exceeds the
    cross-check's 3 sigma once most of them are another blob's, 10 sigma off in angle."""
    truth = NOMINAL.with_ca(1008.0, 58.0)
    rec = _fed(truth, 11)
    assert 0.0 < rec.recent_scatter_rad(40) < SIGMA
    rng = np.random.default_rng(12)
    normal = np.cross(truth.approach_direction, truth.ca_direction)
    for t in np.arange(1000.0 - 29.0, 1000.0 - 5.0, 1.0):  # 24 more, each turned 10 sigma out of its place in plane
        los = Rotation.from_rotvec(normal / np.linalg.norm(normal) * 10 * SIGMA).apply(_measured_los(truth, t, rng))
        rec.add_measurement(float(t), los)
    assert rec.recent_scatter_rad(20) > 3.0 * SIGMA



def test_the_best_candidate_asked_between_measurements_and_steps_is_the_one_computed_afresh() -> None:
    """best_grid() after any measurement or step of on-board time equals that of a recognizer given the same
    measurements and steps and never asked before: nothing kept from an earlier question outlives a change."""
    truth = NOMINAL.with_ca(1004.0, 58.0)
    rng = np.random.default_rng(5)
    ops: list[tuple[str, float, np.ndarray | None]] = []
    for k, t in enumerate(TIMES[:50]):
        ops.append(("add", float(t), _measured_los(truth, float(t), rng)))
        if k % 7 == 3:
            ops.append(("shift", 2.5, None))
    asked = TrajectoryRecognizer(NOMINAL, CFG)
    for n, (op, value, los) in enumerate(ops):
        before = asked.best_grid()
        if op == "add":
            asked.add_measurement(value, los)
        else:
            asked.shift_time(value)
            assert asked.best_grid()[0] == pytest.approx(before[0] + value, abs=1e-9)  # the candidates moved
        fresh = TrajectoryRecognizer(NOMINAL, CFG)
        for op2, value2, los2 in ops[: n + 1]:
            if op2 == "add":
                fresh.add_measurement(value2, los2)
            else:
                fresh.shift_time(value2)
        assert asked.best_grid() == fresh.best_grid()
