"""Flyby geometry against closed forms: straight-line flyby, circular binary orbit, camera field of view."""

from __future__ import annotations

import numpy as np
import pytest
from pydantic import ValidationError
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import brentq
from scipy.spatial.transform import Rotation

from universe.config import BodiesConfig, FlybyConfig, UncertaintyConfig
from universe.geometry import (
    FlybyGeometry,
    GeometryError,
    barycentre_flyby,
    camera_axes_body,
    dimorphos_line,
    nominal_ca,
)

# A binary so tight that Dimorphos sits on the barycentre: closed forms about the barycentre then hold for it.
POINT_BODIES = BodiesConfig(orbit_radius_m=1e-6)

unit_vectors = st.tuples(*[st.floats(-1.0, 1.0)] * 3).filter(lambda v: sum(c * c for c in v) > 0.05)


def rotation_taking(a: np.ndarray, b: np.ndarray) -> Rotation:
    """Return the rotation that maps unit vector a onto unit vector b (independent of the code under test)."""
    axis = np.cross(a, b)
    s = np.linalg.norm(axis)
    if s < 1e-12:
        return Rotation.identity()
    return Rotation.from_rotvec(axis / s * np.arctan2(s, float(a @ b)))


@settings(max_examples=40, deadline=None)
@given(
    approach=unit_vectors,
    ca=unit_vectors,
    d_km=st.floats(10.0, 200.0),
    v_km_s=st.floats(1.0, 15.0),
    t_ca=st.floats(-500.0, 500.0),
)
def test_range_at_ca_is_ca_distance_and_minimum(approach, ca, d_km, v_km_s, t_ca) -> None:
    """The range to the barycentre equals d_ca at t_ca and exceeds it at every other time (sqrt(d^2 + v^2 dt^2))."""
    a, c = np.array(approach), np.array(ca)
    if np.linalg.norm(np.cross(a, c)) / (np.linalg.norm(a) * np.linalg.norm(c)) < np.sin(np.radians(1.0)):
        return  # within 1 deg of parallel: refused by the config, tested separately
    geo = FlybyGeometry(
        FlybyConfig(
            ca_time_s=t_ca, ca_distance_km=d_km, speed_km_s=v_km_s, approach_direction=approach, ca_direction=ca
        ),
        BodiesConfig(),
    )
    assert np.linalg.norm(geo.spacecraft_position_m(t_ca)) == pytest.approx(d_km * 1e3, rel=1e-12)
    ts = t_ca + np.linspace(-300.0, 300.0, 601)
    ranges = np.linalg.norm(geo.spacecraft_position_m(ts), axis=1)
    expected = np.hypot(d_km * 1e3, v_km_s * 1e3 * (ts - t_ca))
    np.testing.assert_allclose(ranges, expected, rtol=1e-12)
    assert np.argmin(ranges) == 300
    velocity = v_km_s * 1e3 * a / np.linalg.norm(a)
    np.testing.assert_allclose(geo.spacecraft_velocity_m_s(0.0), velocity, rtol=1e-12, atol=1e-9)


def test_los_angular_rate_at_ca_is_v_over_d() -> None:
    """The line of sight turns at v/d at C/A: 7 km/s at 55 km gives 7.292 deg/s."""
    geo = FlybyGeometry(FlybyConfig(), BodiesConfig())
    h = 1e-4
    r1 = geo.spacecraft_position_m(168.0 - h)
    r2 = geo.spacecraft_position_m(168.0 + h)
    angle = np.arctan2(np.linalg.norm(np.cross(r1, r2)), r1 @ r2)
    rate_deg_s = np.degrees(angle / (2 * h))
    assert rate_deg_s == pytest.approx(np.degrees(7.0 / 55.0), rel=1e-8)
    assert rate_deg_s == pytest.approx(7.2923, abs=1e-3)


def test_theta_follows_closed_form() -> None:
    """Theta(t) = atan2(d, -v (t - t_ca)): 0 far before C/A, 90 deg at C/A, 180 deg far after."""
    flyby = FlybyConfig(ca_time_s=168.0, ca_distance_km=55.0, speed_km_s=7.0)
    geo = FlybyGeometry(flyby, POINT_BODIES)
    ts = np.linspace(-132.0, 468.0, 1201)
    expected = np.arctan2(55e3, -7e3 * (ts - 168.0))
    np.testing.assert_allclose(geo.theta_rad(ts), expected, atol=1e-9)
    sample = geo.truth_sample(168.0, np.array([0, 0, 0, 1.0]), np.array([0, 0, 1.0]), 2.9)
    assert sample.theta_rad == pytest.approx(np.pi / 2, abs=1e-9)


def test_theta_uses_velocity_relative_to_dimorphos() -> None:
    """With the real binary, cos(theta) = (v_sc - v_dim) . los / |v_sc - v_dim| with v_dim = n a/(1+q)."""
    geo = FlybyGeometry(FlybyConfig(), BodiesConfig(orbit_phase_deg=37.0))
    t = 100.0
    s = geo.truth_sample(t, np.array([0, 0, 0, 1.0]), np.array([0, 0, 1.0]), 2.9)
    b = BodiesConfig(orbit_phase_deg=37.0)
    n = 2 * np.pi / (b.orbit_period_h * 3600)
    ph = np.radians(37.0) + n * t
    v_dim = b.orbit_radius_m / (1 + b.mass_ratio) * n * np.array([-np.sin(ph), np.cos(ph), 0.0])
    v_rel = np.array([7e3, 0, 0]) - v_dim
    assert np.cos(s.theta_rad) == pytest.approx(v_rel @ s.los_dimorphos_inertial / np.linalg.norm(v_rel), abs=1e-12)


def test_dimorphos_orbit_radius_period_and_barycentre() -> None:
    """Dimorphos stays orbit_radius_m from Didymos, returns after one period, and the mass-weighted centre is 0."""
    bodies = BodiesConfig(orbit_phase_deg=20.0, mass_ratio=0.0093, orbit_normal=(0.3, -0.2, 1.0))
    geo = FlybyGeometry(FlybyConfig(), bodies)
    period_s = 11.92 * 3600
    ts = np.linspace(0.0, period_s, 97)
    dim, did = geo.dimorphos_position_m(ts), geo.didymos_position_m(ts)
    np.testing.assert_allclose(np.linalg.norm(dim - did, axis=1), 1190.0, rtol=1e-12)
    np.testing.assert_allclose(dim * 0.0093 + did, 0.0, atol=1e-9)
    np.testing.assert_allclose(dim[0], dim[-1], atol=1e-9)
    normal = np.array([0.3, -0.2, 1.0]) / np.linalg.norm([0.3, -0.2, 1.0])
    np.testing.assert_allclose(dim @ normal, 0.0, atol=1e-9)
    # Prograde about the normal, at the mean motion 2 pi / P.
    h = 1.0
    r1, r2 = geo.dimorphos_position_m(500.0 - h), geo.dimorphos_position_m(500.0 + h)
    turn = np.cross(r1, r2)
    assert turn @ normal > 0
    assert np.arctan2(np.linalg.norm(turn), r1 @ r2) / (2 * h) == pytest.approx(2 * np.pi / period_s, rel=1e-9)
    v_numeric = (r2 - r1) / (2 * h)
    np.testing.assert_allclose(geo.dimorphos_velocity_m_s(500.0), v_numeric, rtol=1e-6)


def test_default_orbit_phase_zero_is_inertial_x() -> None:
    """With the default XY orbit plane, phase 0 puts Dimorphos on +X and phase 90 deg on +Y."""
    geo0 = FlybyGeometry(FlybyConfig(), BodiesConfig(orbit_phase_deg=0.0))
    geo90 = FlybyGeometry(FlybyConfig(), BodiesConfig(orbit_phase_deg=90.0))
    a = 1190.0 / 1.0093
    np.testing.assert_allclose(geo0.dimorphos_position_m(0.0), [a, 0, 0], atol=1e-9)
    np.testing.assert_allclose(geo90.dimorphos_position_m(0.0), [0, a, 0], atol=1e-9)


def test_vectorised_equals_scalar() -> None:
    """Positions over an array of times equal the scalar calls, row by row."""
    geo = FlybyGeometry(FlybyConfig(), BodiesConfig(orbit_phase_deg=10.0))
    ts = np.array([-100.0, 0.0, 168.0, 250.5])
    for method in (geo.spacecraft_position_m, geo.dimorphos_position_m, geo.didymos_position_m):
        many = method(ts)
        assert many.shape == (4, 3)
        for i, t in enumerate(ts):
            np.testing.assert_array_equal(many[i], method(float(t)))
    assert geo.theta_rad(ts).shape == (4,)


def test_ca_direction_is_made_orthogonal_and_parallel_rejected() -> None:
    """A slanted ca_direction is Gram-Schmidt'ed onto the plane normal to the velocity; a parallel one is an error."""
    geo = FlybyGeometry(FlybyConfig(approach_direction=(2.0, 0, 0), ca_direction=(1.0, 1.0, 0)), BodiesConfig())
    np.testing.assert_allclose(geo.spacecraft_position_m(168.0), [0, 55e3, 0], atol=1e-9)
    with pytest.raises(ValidationError, match="ca_direction: is 0 deg from parallel"):
        FlybyConfig(approach_direction=(1, 1, 0), ca_direction=(-2, -2, 0))
    unchecked = FlybyConfig.model_construct(approach_direction=(1, 1, 0), ca_direction=(-2, -2, 0))
    with pytest.raises(GeometryError, match="ca_direction"):
        FlybyGeometry(unchecked, BodiesConfig())


def test_pointing_error_and_square_fov() -> None:
    """Boresight on the LOS gives zero error; 1.4 deg off one image axis is inside the 2.9 deg FOV, 1.5 deg is out."""
    geo = FlybyGeometry(FlybyConfig(), BodiesConfig())
    t = 150.0
    los = geo.truth_sample(t, np.array([0, 0, 0, 1.0]), np.array([0, 0, 1.0]), 2.9).los_dimorphos_inertial
    aligned = rotation_taking(np.array([0, 0, 1.0]), los)
    s0 = geo.truth_sample(t, aligned.as_quat(), np.array([0, 0, 1.0]), 2.9)
    assert s0.pointing_error_rad < 1e-9 and s0.target_in_fov
    np.testing.assert_allclose(s0.los_dimorphos_body, [0, 0, 1.0], atol=1e-9)
    for off_deg, inside in ((1.4, True), (1.5, False)):
        for axis in ([1.0, 0, 0], [0, 1.0, 0]):
            q = (aligned * Rotation.from_rotvec(np.radians(off_deg) * np.array(axis))).as_quat()
            s = geo.truth_sample(t, q, np.array([0, 0, 1.0]), 2.9)
            assert s.pointing_error_rad == pytest.approx(np.radians(off_deg), abs=1e-9)
            assert s.target_in_fov is inside
    # Along the diagonal a square FOV reaches further than along an axis: 1.9 deg off diagonally is inside.
    diag = (aligned * Rotation.from_rotvec(np.radians(1.9) * np.array([1.0, 1.0, 0]) / np.sqrt(2))).as_quat()
    assert geo.truth_sample(t, diag, np.array([0, 0, 1.0]), 2.9).target_in_fov
    behind = (aligned * Rotation.from_rotvec([np.pi, 0, 0])).as_quat()
    assert not geo.truth_sample(t, behind, np.array([0, 0, 1.0]), 2.9).target_in_fov


def test_image_axes_follow_body_axes() -> None:
    """A target displaced towards body +X appears at positive camera x (columns), towards +Y at positive camera y."""
    geo = FlybyGeometry(FlybyConfig(), BodiesConfig())
    t = 100.0
    los = geo.truth_sample(t, np.array([0, 0, 0, 1.0]), np.array([0, 0, 1.0]), 2.9).los_dimorphos_inertial
    aligned = rotation_taking(np.array([0, 0, 1.0]), los)
    # Rotating the body by -0.5 deg about +Y moves the target towards body +X.
    s = geo.truth_sample(t, (aligned * Rotation.from_rotvec([0, -0.0087, 0])).as_quat(), np.array([0, 0, 1.0]), 2.9)
    assert s.los_dimorphos_camera[0] > 0 and abs(s.los_dimorphos_camera[1]) < 1e-9
    s = geo.truth_sample(t, (aligned * Rotation.from_rotvec([0.0087, 0, 0])).as_quat(), np.array([0, 0, 1.0]), 2.9)
    assert s.los_dimorphos_camera[1] > 0 and abs(s.los_dimorphos_camera[0]) < 1e-9


@settings(max_examples=50, deadline=None)
@given(b=unit_vectors)
def test_camera_axes_are_right_handed_orthonormal(b) -> None:
    """Camera axes are orthonormal, right-handed, with z the boresight; +Z boresight gives the body axes."""
    m = camera_axes_body(np.array(b))
    np.testing.assert_allclose(m @ m.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(m) == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_allclose(m[2], np.array(b) / np.linalg.norm(b), atol=1e-12)
    np.testing.assert_allclose(camera_axes_body(np.array([0, 0, 2.0])), np.eye(3), atol=1e-15)


def test_phase_angle_closed_forms() -> None:
    """At C/A with the Sun behind the spacecraft the phase angle is 0; with the Sun along the velocity, 90 deg."""
    flyby = FlybyConfig(approach_direction=(1, 0, 0), ca_direction=(0, 1, 0))
    q, b = np.array([0, 0, 0, 1.0]), np.array([0, 0, 1.0])
    behind = FlybyGeometry(flyby, BodiesConfig(orbit_radius_m=1e-6, sun_direction=(0, 1, 0)))
    assert behind.truth_sample(168.0, q, b, 2.9).phase_angle_deg == pytest.approx(0.0, abs=1e-6)
    side = FlybyGeometry(flyby, BodiesConfig(orbit_radius_m=1e-6, sun_direction=(1, 0, 0)))
    assert side.truth_sample(168.0, q, b, 2.9).phase_angle_deg == pytest.approx(90.0, abs=1e-6)
    # Long before C/A the spacecraft comes from -X: with the Sun on +X the target is seen at full phase (180 deg).
    far = side.truth_sample(168.0 - 1e6, q, b, 2.9)
    assert far.phase_angle_deg == pytest.approx(180.0, abs=0.01)


def test_truth_sample_rejects_non_unit_quaternion() -> None:
    """A non-unit quaternion is an error naming the argument."""
    geo = FlybyGeometry(FlybyConfig(), BodiesConfig())
    with pytest.raises(GeometryError, match="q_body_to_inertial"):
        geo.truth_sample(0.0, np.array([0, 0, 0, 2.0]), np.array([0, 0, 1.0]), 2.9)


def test_nominal_ca_offsets_are_exact_corners() -> None:
    """With offset_sigma set, the nominal is truth + k sigma exactly, whatever the generator."""
    unc = UncertaintyConfig(ca_time_offset_sigma=2.0, ca_distance_offset_sigma=-2.0)
    t, d = nominal_ca(FlybyConfig(), unc, np.random.default_rng(5))
    assert t == pytest.approx(168.0 + 20.0) and d == pytest.approx(55.0 - 10.0)


def test_nominal_ca_draws_match_sigmas_and_are_deterministic() -> None:
    """Random nominals have the configured mean and sigma (10^4 draws, 10%) and repeat with the seed."""
    flyby, unc = FlybyConfig(), UncertaintyConfig()
    rng = np.random.default_rng(42)
    draws = np.array([nominal_ca(flyby, unc, rng) for _ in range(10_000)])
    assert draws[:, 0].mean() == pytest.approx(168.0, abs=0.5)
    assert draws[:, 1].mean() == pytest.approx(55.0, abs=0.25)
    assert draws[:, 0].std() == pytest.approx(10.0, rel=0.1)
    assert draws[:, 1].std() == pytest.approx(5.0, rel=0.1)
    assert nominal_ca(flyby, unc, np.random.default_rng(7)) == nominal_ca(flyby, unc, np.random.default_rng(7))


def test_nominal_ca_one_corner_keeps_other_draw() -> None:
    """Fixing the time corner leaves the distance draw of the same seed unchanged."""
    flyby = FlybyConfig()
    _, d_free = nominal_ca(flyby, UncertaintyConfig(), np.random.default_rng(3))
    _, d_corner = nominal_ca(flyby, UncertaintyConfig(ca_time_offset_sigma=3.0), np.random.default_rng(3))
    assert d_free == d_corner


def test_nominal_ca_rejects_non_positive_distance() -> None:
    """A corner that puts C/A at or below zero distance is an error naming the sigma field."""
    with pytest.raises(GeometryError, match="ca_distance_sigma_km"):
        nominal_ca(FlybyConfig(), UncertaintyConfig(ca_distance_offset_sigma=-12.0), np.random.default_rng(0))


@settings(max_examples=40, deadline=None)
@given(unit_vectors, unit_vectors, st.floats(2.0, 200.0), st.floats(1.0, 20.0), st.floats(0.0, 360.0))
def test_dimorphos_line_is_the_closest_approach_to_dimorphos(approach, ca, d_km, v_km_s, phase_deg) -> None:
    """The straight flyby of Dimorphos has the C/A time, distance and direction of the true closest approach to
    Dimorphos (the root of d|r|^2/dt of the true positions, by bisection), and moves along the spacecraft's velocity
    relative to Dimorphos: Dimorphos's orbit bends the relative motion by micrometres over the seconds between."""
    if abs(float(np.dot(approach, ca))) > 0.99 * float(np.linalg.norm(approach) * np.linalg.norm(ca)):
        return
    bodies = BodiesConfig(orbit_phase_deg=phase_deg)
    flyby = FlybyConfig(ca_distance_km=d_km, speed_km_s=v_km_s, approach_direction=tuple(approach),
                        ca_direction=tuple(ca))
    line = dimorphos_line(flyby, bodies)
    g = FlybyGeometry(flyby, bodies)

    def rel(t: float) -> np.ndarray:
        return g.spacecraft_position_m(t) - g.dimorphos_position_m(t)

    def closing(t: float) -> float:
        return float(rel(t) @ (g.spacecraft_velocity_m_s(t) - g.dimorphos_velocity_m_s(t)))

    span = 2.0 * bodies.orbit_radius_m / (v_km_s * 1e3)  # Dimorphos's C/A is within its arm along the track
    t_ca = brentq(closing, g.ca_time_s - span, g.ca_time_s + span, xtol=1e-12)
    r = rel(t_ca)
    assert line.ca_time_s == pytest.approx(t_ca, abs=1e-6)
    assert line.ca_distance_km * 1e3 == pytest.approx(float(np.linalg.norm(r)), abs=1e-3)
    assert np.allclose(line.ca_direction, r / np.linalg.norm(r), atol=1e-7)
    v = g.spacecraft_velocity_m_s(t_ca) - g.dimorphos_velocity_m_s(t_ca)
    assert np.allclose(line.speed_km_s * 1e3 * np.asarray(line.approach_direction), v, atol=1e-4)


@settings(max_examples=40, deadline=None)
@given(unit_vectors, unit_vectors, st.floats(2.0, 200.0), st.floats(1.0, 20.0), st.floats(0.0, 360.0))
def test_barycentre_flyby_inverts_dimorphos_line(approach, ca, d_km, v_km_s, phase_deg) -> None:
    """The barycentre's flyby found for a flyby of Dimorphos has that flyby as its Dimorphos line."""
    if abs(float(np.dot(approach, ca))) > 0.99 * float(np.linalg.norm(approach) * np.linalg.norm(ca)):
        return
    bodies = BodiesConfig(orbit_phase_deg=phase_deg)
    target = dimorphos_line(FlybyConfig(ca_distance_km=d_km, speed_km_s=v_km_s, approach_direction=tuple(approach),
                                        ca_direction=tuple(ca)), bodies)
    back = dimorphos_line(barycentre_flyby(target, bodies), bodies)
    assert back.ca_time_s == pytest.approx(target.ca_time_s, abs=1e-9)
    assert back.ca_distance_km == pytest.approx(target.ca_distance_km, abs=1e-9)
    assert np.allclose(back.ca_direction, target.ca_direction, atol=1e-12)
    assert np.allclose(back.approach_direction, target.approach_direction, atol=1e-12)


def test_dimorphos_line_through_dimorphos_is_refused() -> None:
    """A spacecraft aimed at Dimorphos's centre has no C/A direction: GeometryError naming the flyby."""
    bodies = BodiesConfig(orbit_phase_deg=90.0, mass_ratio=0.0, orbit_period_h=1e9)  # Dimorphos still at +Y
    flyby = FlybyConfig(ca_distance_km=bodies.orbit_radius_m / 1e3, ca_direction=(0.0, 1.0, 0.0))
    with pytest.raises(GeometryError, match="flyby of Dimorphos"):
        dimorphos_line(flyby, bodies)
