"""The attitude estimator (multiplicative EKF) against closed forms: the covariance growth over an outage, the bias
variance of a line fitted to the star tracker solutions, a bias step followed, an outage declared and ended."""

from __future__ import annotations

import math

import numpy as np
import pytest

from scipy.spatial.transform import Rotation

from obsw.attitude import ARCSEC_RAD, DEG_SQRT_H_RAD_SQRT_S, AttitudeEstimator
from obsw.config import AttitudeConfig

DT = 0.1


def _noisy(q: np.ndarray, sigma_rad: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """A star tracker solution: the true attitude turned by a small random rotation about the body axes."""
    return (Rotation.from_quat(q) * Rotation.from_rotvec(sigma_rad * rng.standard_normal(3))).as_quat()


def test_attitude_variance_over_an_outage_grows_as_the_closed_form() -> None:
    """Without solutions and at rest, P_tt(t) = P_tt - 2 P_tb t + P_bb t^2 + s_v^2 t + s_u^2 t^3 / 3 on each axis."""
    cfg = AttitudeConfig(gyro_arw_deg_sqrt_h=0.15, gyro_bias_walk_deg_s_sqrt_s=1e-3)
    est = AttitudeEstimator(cfg)
    rng = np.random.default_rng(3)
    q = np.array([0.0, 0.0, 0.0, 1.0])
    st = np.asarray(cfg.star_tracker_noise_arcsec) * ARCSEC_RAD
    for _ in range(50):  # converge: the attitude-bias covariance is no longer zero
        est.step(np.zeros(3), _noisy(q, st, rng), DT)
    p0 = est.P.copy()
    sv, su = cfg.gyro_arw_deg_sqrt_h * DEG_SQRT_H_RAD_SQRT_S, math.radians(cfg.gyro_bias_walk_deg_s_sqrt_s)
    est.bias = np.zeros(3)  # at rest with a zero bias estimate, w = 0: the propagation is exact
    est._last_gyro = None
    n = 1200
    for _ in range(n):
        est.step(np.zeros(3), None, DT)
    t = n * DT
    for axis in range(3):
        ptt, ptb, pbb = p0[axis, axis], p0[axis, axis + 3], p0[axis + 3, axis + 3]
        expected = ptt - 2 * ptb * t + pbb * t**2 + sv**2 * t + su**2 * t**3 / 3
        assert est.P[axis, axis] == pytest.approx(expected, rel=1e-9)
    assert est.outage


def test_a_constant_bias_is_observed_as_the_slope_of_the_solutions() -> None:
    """With no process noise and a vague prior the filter is the least-squares line through the solutions: the bias
    variance after n solutions dt apart is 12 s^2 / (dt^2 n (n^2 - 1)), and the estimate is within 4 sigma of the
    true constant bias."""
    cfg = AttitudeConfig(gyro_arw_deg_sqrt_h=0.0, gyro_bias_walk_deg_s_sqrt_s=0.0, initial_attitude_sigma_deg=60.0,
                         initial_bias_sigma_deg_s=60.0)
    est = AttitudeEstimator(cfg)
    rng = np.random.default_rng(11)
    bias = np.radians([0.05, -0.03, 0.02])
    st = np.asarray(cfg.star_tracker_noise_arcsec) * ARCSEC_RAD
    q = np.array([0.0, 0.0, 0.0, 1.0])
    est.q = q.copy()  # the attitude known roughly; every solution below informs the filter
    n = 400
    for _ in range(n):
        est.step(bias, _noisy(q, st, rng), DT)  # at rest: the gyro reads its bias
    for axis in range(3):
        closed = 12 * st[axis] ** 2 / (DT**2 * n * (n**2 - 1))
        assert est.P[axis + 3, axis + 3] == pytest.approx(closed, rel=2e-3)
        assert abs(est.bias[axis] - bias[axis]) < 4 * math.sqrt(closed)


def test_a_bias_step_is_followed_within_twenty_seconds() -> None:
    """With the default tuning a 0.05 deg/s step on every axis is estimated to 10 % within 20 s of it, and the
    attitude error stays below 0.05 deg meanwhile (the pointing limit is 1.45 deg)."""
    cfg = AttitudeConfig()
    est = AttitudeEstimator(cfg)
    rng = np.random.default_rng(5)
    st = np.asarray(cfg.star_tracker_noise_arcsec) * ARCSEC_RAD
    arw = cfg.gyro_arw_deg_sqrt_h * DEG_SQRT_H_RAD_SQRT_S / math.sqrt(DT)
    q, w = np.array([0.0, 0.0, 0.0, 1.0]), np.radians([0.0, 0.5, 0.0])
    step = np.radians([0.05, 0.05, 0.05])
    worst = 0.0
    for k in range(600):
        bias = step if k * DT >= 30.0 else np.zeros(3)
        q = (Rotation.from_quat(q) * Rotation.from_rotvec(w * DT)).as_quat()
        e = est.step(w + bias + arw * rng.standard_normal(3), _noisy(q, st, rng), DT)
        worst = max(worst, (Rotation.from_quat(e.q).inv() * Rotation.from_quat(q)).magnitude())
    assert np.all(np.abs(est.bias - step) < 0.1 * step)
    assert math.degrees(worst) < 0.05


def test_an_outage_is_declared_after_its_delay_and_ends_with_a_reading() -> None:
    """No reading for outage_after_s declares an outage; a held (repeated) reading is no outage; a reading ends it."""
    cfg = AttitudeConfig(outage_after_s=0.5)
    est = AttitudeEstimator(cfg)
    q = np.array([0.0, 0.0, 0.0, 1.0])
    assert not est.step(np.zeros(3), q, DT).outage
    assert not any(est.step(np.zeros(3), q, DT).outage for _ in range(20))  # held by a slow tracker
    flags = [est.step(np.zeros(3), None, DT).outage for _ in range(6)]
    assert flags == [False, False, False, False, True, True]
    assert not est.step(np.zeros(3), q, DT).outage
