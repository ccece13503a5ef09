"""The on-board flyby model against closed forms, finite differences and geometric identities."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pydantic import ValidationError

from obsw.trajectory import NominalTrajectory


def _trajectory(ca_time: float = 100.0, d_km: float = 55.0, v_km_s: float = 7.0) -> NominalTrajectory:
    return NominalTrajectory(
        ca_time_obt_s=ca_time,
        ca_distance_km=d_km,
        speed_km_s=v_km_s,
        approach_direction=(1.0, 2.0, -0.5),
        ca_direction=(0.3, 0.1, 1.0),
    )


def test_directions_are_stored_orthonormal() -> None:
    """The validator normalises e_v and makes e_ca a unit vector orthogonal to it."""
    t = _trajectory()
    assert np.linalg.norm(t.e_v) == pytest.approx(1.0, abs=1e-15)
    assert np.linalg.norm(t.e_ca) == pytest.approx(1.0, abs=1e-15)
    assert float(t.e_v @ t.e_ca) == pytest.approx(0.0, abs=1e-15)
    assert np.allclose(t.e_v, np.array([1.0, 2.0, -0.5]) / np.linalg.norm([1.0, 2.0, -0.5]))


def test_parallel_directions_are_rejected() -> None:
    """A C/A direction parallel to the approach direction has no flyby plane and is refused."""
    with pytest.raises(ValidationError, match="ca_direction"):
        NominalTrajectory(
            ca_time_obt_s=0.0,
            ca_distance_km=55.0,
            speed_km_s=7.0,
            approach_direction=(1.0, 0.0, 0.0),
            ca_direction=(-2.0, 0.0, 0.0),
        )


def test_position_at_ca_is_distance_along_ca_direction() -> None:
    """At C/A the spacecraft is d along e_ca, the LOS is -e_ca and theta is 90 deg."""
    t = _trajectory()
    assert np.allclose(t.position_m(100.0), 55e3 * t.e_ca, atol=1e-9)
    assert np.allclose(t.los_inertial(100.0), -t.e_ca, atol=1e-15)
    assert t.theta_rad(100.0) == pytest.approx(np.pi / 2, abs=1e-15)
    assert t.range_m(100.0) == pytest.approx(55e3)


@settings(max_examples=50, deadline=None)
@given(st.floats(-600.0, 600.0))
def test_theta_is_the_angle_between_velocity_and_los(obt_s: float) -> None:
    """theta equals arccos(e_v . los) and the LOS stays in the flyby plane."""
    t = _trajectory()
    los = t.los_inertial(obt_s)
    assert np.linalg.norm(los) == pytest.approx(1.0, abs=1e-12)
    expected = np.arctan2(np.linalg.norm(np.cross(t.e_v, los)), float(t.e_v @ los))
    assert t.theta_rad(obt_s) == pytest.approx(expected, abs=1e-12)
    assert float(los @ t.plane_normal) == pytest.approx(0.0, abs=1e-12)


@settings(max_examples=50, deadline=None)
@given(st.floats(-400.0, 400.0), st.floats(30.0, 80.0))
def test_los_rate_matches_finite_difference_of_the_los(obt_s: float, d_km: float) -> None:
    """The closed-form rate equals the turn rate of los_inertial (central difference) about plane_normal."""
    t = _trajectory(d_km=d_km)
    h = 1e-3
    dl = (t.los_inertial(obt_s + h) - t.los_inertial(obt_s - h)) / (2 * h)
    omega = np.cross(t.los_inertial(obt_s), dl)
    rate = t.los_rate_rad_s(obt_s)
    assert np.allclose(omega, rate * t.plane_normal, atol=1e-7 * (1 + rate))


@settings(max_examples=50, deadline=None)
@given(st.floats(-400.0, 400.0))
def test_los_accel_matches_finite_difference_of_the_rate(obt_s: float) -> None:
    """The closed-form angular acceleration is the derivative of the closed-form rate."""
    t = _trajectory(d_km=40.0)
    h = 1e-3
    numeric = (t.los_rate_rad_s(obt_s + h) - t.los_rate_rad_s(obt_s - h)) / (2 * h)
    assert t.los_accel_rad_s2(obt_s) == pytest.approx(numeric, rel=1e-5, abs=1e-10)


def test_peak_rate_and_accel_of_the_worst_case_flyby() -> None:
    """At 40 km, 7 km/s: peak rate v/d (10 deg/s), peak accel 3 sqrt(3)/8 (v/d)^2 at v tau = -d/sqrt 3."""
    t = _trajectory(ca_time=0.0, d_km=40.0)
    w = 7.0 / 40.0
    grid = np.linspace(-300.0, 300.0, 600001)
    assert np.max(t.los_rate_rad_s(grid)) == pytest.approx(w, rel=1e-12)
    assert np.degrees(w) == pytest.approx(10.03, abs=0.01)
    accel = t.los_accel_rad_s2(grid)
    assert np.max(accel) == pytest.approx(3 * np.sqrt(3) / 8 * w**2, rel=1e-6)
    assert grid[np.argmax(accel)] == pytest.approx(-40.0 / (7.0 * np.sqrt(3)), abs=2e-3)


def test_vectorised_calls_match_scalar_calls() -> None:
    """Every method accepts an array of times and returns the stacked scalar results."""
    t = _trajectory()
    times = np.array([-50.0, 0.0, 100.0, 250.0])
    assert np.allclose(t.los_inertial(times), np.stack([t.los_inertial(x) for x in times]))
    assert np.allclose(t.theta_rad(times), [t.theta_rad(x) for x in times])
    assert np.allclose(t.los_rate_rad_s(times), [t.los_rate_rad_s(x) for x in times])


def test_with_ca_changes_only_time_and_distance() -> None:
    """with_ca keeps directions, speed and sigmas; a non-positive distance is rejected."""
    t = _trajectory()
    u = t.with_ca(130.0, 48.0)
    assert (u.ca_time_obt_s, u.ca_distance_km) == (130.0, 48.0)
    assert u.approach_direction == t.approach_direction and u.ca_direction == t.ca_direction
    assert (u.speed_km_s, u.ca_time_sigma_s, u.ca_distance_sigma_km) == (7.0, 10.0, 5.0)
    assert u.theta_rad(130.0) == pytest.approx(np.pi / 2)
    with pytest.raises(ValidationError, match="ca_distance_km"):
        t.with_ca(0.0, -1.0)


@settings(max_examples=200, deadline=None)
@given(st.floats(-1e6, 1e6), st.floats(-1e4, 1e4), st.floats(0.1, 1e4))
def test_the_line_of_sight_at_one_time_is_the_array_paths_to_the_last_bit(t: float, ca_time: float,
                                                                            d_km: float) -> None:
    """los_inertial of one time (plain floats) equals the same time's row of the array evaluation exactly."""
    traj = _trajectory(ca_time=ca_time, d_km=d_km)
    assert traj.los_inertial(t).tolist() == traj.los_inertial(np.array([t]))[0].tolist()
