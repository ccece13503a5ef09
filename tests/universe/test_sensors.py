"""Sensor models against their configured statistics, with fixed seeds."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from universe.config import GyroConfig, SensorsConfig, StarTrackerConfig
from universe.dynamics import AttitudeState
from universe.sensor_kernels import star_tracker_q
from universe.sensors import SensorError, Sensors

ARCSEC = math.pi / (180 * 3600)
QUIET_GYRO = GyroConfig(arw_deg_sqrt_h=0.0, bias_instability_deg_h=0.0)


def still_state(q=(0.0, 0.0, 0.0, 1.0), omega=(0.0, 0.0, 0.0), wheels=(0.0, 0.0, 0.0)) -> AttitudeState:
    """Return a state with the given attitude, rate and wheel speeds."""
    return AttitudeState(
        q=np.array(q, dtype=float),
        omega_rad_s=np.array(omega, dtype=float),
        wheel_speed_rad_s=np.array(wheels, dtype=float),
    )


def test_star_tracker_noise_and_bias_match_config() -> None:
    """Star tracker error about each body axis has the configured bias and sigma (10^4 draws, sigma within 10%)."""
    cfg = SensorsConfig(star_tracker=StarTrackerConfig(noise_arcsec=(6.0, 6.0, 40.0), bias_arcsec=(20.0, -10.0, 0.0)))
    sensors = Sensors(cfg, 3, np.random.default_rng(11))
    truth = Rotation.from_rotvec([0.3, -1.2, 2.0])
    state = still_state(q=truth.as_quat())
    measured = np.array([sensors.measure(k * 0.1, state, 0.1).star_tracker_q for k in range(10_000)])
    errors = (truth.inv() * Rotation.from_quat(measured)).as_rotvec() / ARCSEC
    np.testing.assert_allclose(errors.std(axis=0), [6.0, 6.0, 40.0], rtol=0.1)
    np.testing.assert_allclose(errors.mean(axis=0), [20.0, -10.0, 0.0], atol=4 * 40.0 / 100)


def test_star_tracker_holds_between_updates() -> None:
    """At 1 Hz sampled at 10 Hz the reading changes only on whole seconds and matches the truth of that instant."""
    cfg = SensorsConfig(star_tracker=StarTrackerConfig(noise_arcsec=(1.0, 1.0, 1.0), rate_hz=1.0))
    sensors = Sensors(cfg, 3, np.random.default_rng(0))
    rate = np.array([0.0, 0.0, 0.05])
    readings = []
    for k in range(50):
        t = k * 0.1
        q_true = Rotation.from_rotvec(rate * t).as_quat()
        readings.append(sensors.measure(t, still_state(q=q_true, omega=rate), 0.1).star_tracker_q)
    for k in range(1, 50):
        changed = not np.array_equal(readings[k], readings[k - 1])
        assert changed is (k % 10 == 0)
    # The reading held during second 2 is the truth at t = 2 s, to the 1 arcsec noise.
    held_err = (Rotation.from_rotvec(rate * 2.0).inv() * Rotation.from_quat(readings[25])).magnitude()
    assert held_err < 6 * ARCSEC


def test_star_tracker_outage_returns_none_then_fresh_reading() -> None:
    """During an outage the quaternion is None (gyro still reads); afterwards a fresh reading comes at once."""
    sensors = Sensors(SensorsConfig(star_tracker=StarTrackerConfig(rate_hz=1.0)), 3, np.random.default_rng(1))
    before = sensors.measure(0.0, still_state(), 0.1)
    out = sensors.measure(0.1, still_state(), 0.1, star_tracker_out=True)
    assert out.star_tracker_q is None and out.gyro_rad_s.shape == (3,)
    after = sensors.measure(0.2, still_state(), 0.1)
    assert after.star_tracker_q is not None and not np.array_equal(after.star_tracker_q, before.star_tracker_q)


def test_gyro_white_noise_sigma_is_arw_over_sqrt_dt() -> None:
    """With no bias drift, gyro error has sigma = ARW / sqrt(dt) (10^4 draws, within 10%) and zero mean."""
    arw = 0.15 * math.pi / 180 / 60
    cfg = SensorsConfig(gyro=GyroConfig(arw_deg_sqrt_h=0.15, bias_instability_deg_h=0.0))
    sensors = Sensors(cfg, 3, np.random.default_rng(5))
    omega = np.array([0.01, -0.02, 0.03])
    state = still_state(omega=omega)
    err = np.array([sensors.measure(k * 0.05, state, 0.05).gyro_rad_s - omega for k in range(10_000)])
    np.testing.assert_allclose(err.std(axis=0), arw / math.sqrt(0.05), rtol=0.1)
    np.testing.assert_allclose(err.mean(axis=0), 0.0, atol=4 * arw / math.sqrt(0.05) / 100)


def test_gyro_angle_random_walk_grows_as_sqrt_time() -> None:
    """The integrated gyro error over a window of T seconds has sigma ARW sqrt(T), for T = 1 s and 10 s."""
    arw = 0.15 * math.pi / 180 / 60
    cfg = SensorsConfig(gyro=GyroConfig(arw_deg_sqrt_h=0.15, bias_instability_deg_h=0.0))
    sensors = Sensors(cfg, 3, np.random.default_rng(9))
    dt = 0.1
    state = still_state()
    err = np.array([sensors.measure(k * dt, state, dt).gyro_rad_s for k in range(20_000)])
    for window_s in (1.0, 10.0):
        n = round(window_s / dt)
        angles = (err.reshape(-1, n, 3).sum(axis=1) * dt).ravel()
        assert angles.std() == pytest.approx(arw * math.sqrt(window_s), rel=0.1)


def test_gyro_bias_random_walk_from_bias_instability() -> None:
    """With no white noise the bias drifts as a random walk: over lag L its change has sigma B sqrt(L / T_walk)."""
    b = 1.0 * math.pi / 180 / 3600
    cfg = SensorsConfig(gyro=GyroConfig(arw_deg_sqrt_h=0.0, bias_instability_deg_h=1.0, bias_walk_time_s=3600.0))
    sensors = Sensors(cfg, 3, np.random.default_rng(13))
    dt = 0.1
    state = still_state()
    bias = np.array([sensors.measure(k * dt, state, dt).gyro_rad_s for k in range(20_001)])
    np.testing.assert_array_equal(bias[-1], sensors.gyro_bias_rad_s)
    lag = 100
    changes = (bias[lag::lag] - bias[:-lag:lag]).ravel()
    assert changes.std() == pytest.approx(b * math.sqrt(lag * dt / 3600.0), rel=0.1)


def test_gyro_initial_bias_and_bias_step_add_exactly() -> None:
    """A reading carries the initial bias, and a fault's bias step adds exactly on top of the same draws."""
    cfg = SensorsConfig(
        gyro=GyroConfig(arw_deg_sqrt_h=0.15, bias_instability_deg_h=1.0, initial_bias_deg_h=(36.0, 0.0, -72.0))
    )
    step = np.array([1e-3, -2e-3, 0.0])
    plain = Sensors(cfg, 3, np.random.default_rng(3))
    faulty = Sensors(cfg, 3, np.random.default_rng(3))
    for k in range(20):
        a = plain.measure(k * 0.1, still_state(), 0.1).gyro_rad_s
        b = faulty.measure(k * 0.1, still_state(), 0.1, gyro_bias_step_rad_s=step).gyro_rad_s
        np.testing.assert_allclose(b - a, step, atol=1e-15)
    quiet_cfg = SensorsConfig(gyro=QUIET_GYRO.model_copy(update={"initial_bias_deg_h": (36.0, 0.0, -72.0)}))
    reading = Sensors(quiet_cfg, 3, np.random.default_rng(3)).measure(0.0, still_state(omega=(0.1, 0.2, 0.3)), 0.1)
    deg_h = math.pi / 180 / 3600
    np.testing.assert_allclose(reading.gyro_rad_s, [0.1 + 36 * deg_h, 0.2, 0.3 - 72 * deg_h], rtol=1e-12)


def test_wheel_tachometer_noise_matches_config() -> None:
    """Tachometer readings are the true relative speeds plus white noise of the configured sigma (within 10%)."""
    sensors = Sensors(SensorsConfig(wheel_speed_noise_rad_s=0.5), 4, np.random.default_rng(21))
    truth = np.array([100.0, -50.0, 0.0, 900.0])
    state = AttitudeState(q=np.array([0, 0, 0, 1.0]), omega_rad_s=np.zeros(3), wheel_speed_rad_s=truth)
    err = np.array([sensors.measure(k * 0.1, state, 0.1).wheel_speed_rad_s - truth for k in range(10_000)])
    np.testing.assert_allclose(err.std(axis=0), 0.5, rtol=0.1)
    np.testing.assert_allclose(err.mean(axis=0), 0.0, atol=4 * 0.5 / 100)


def test_same_seed_same_readings_other_seed_differs() -> None:
    """Two sensor sets with the same seed and inputs give identical readings; another seed gives different ones."""
    def readings(seed: int) -> list:
        s = Sensors(SensorsConfig(), 3, np.random.default_rng(seed))
        out = []
        for k in range(30):
            r = s.measure(k * 0.1, still_state(omega=(0.01, 0, 0)), 0.1, star_tracker_out=10 <= k < 15)
            out.append((r.star_tracker_q, r.gyro_rad_s, r.wheel_speed_rad_s))
        return out

    a, b, c = readings(4), readings(4), readings(5)
    for ra, rb in zip(a, b):
        for xa, xb in zip(ra, rb):
            assert (xa is None and xb is None) or np.array_equal(xa, xb)
    assert not np.array_equal(a[0][1], c[0][1])


@settings(max_examples=50, deadline=None)
@given(p=st.tuples(*[st.floats(-3.0, 3.0)] * 3), q=st.tuples(*[st.floats(-3.0, 3.0)] * 3))
def test_the_star_trackers_error_rotation_matches_scipy(p, q) -> None:
    """The tracker's reading, the true attitude turned by its error's rotation vector about the body axes, agrees
    with scipy's Rotation product (up to sign)."""
    rp, rq = Rotation.from_rotvec(p), Rotation.from_rotvec(q)
    mine = np.empty(4)
    star_tracker_q(rp.as_quat(), np.array(q), np.zeros(3), np.zeros(3), mine)
    ref = (rp * rq).as_quat()
    assert min(np.abs(mine - ref).max(), np.abs(mine + ref).max()) < 1e-12


def test_bad_inputs_raise() -> None:
    """Non-positive dt and wrong wheel count raise SensorError naming the field."""
    sensors = Sensors(SensorsConfig(), 3, np.random.default_rng(0))
    with pytest.raises(SensorError, match="dt_s"):
        sensors.measure(0.0, still_state(), 0.0)
    with pytest.raises(SensorError, match="wheel_speed_rad_s"):
        sensors.measure(0.0, still_state(wheels=(0.0, 0.0, 0.0, 0.0)), 0.1)
