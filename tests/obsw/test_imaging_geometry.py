"""The frame's predicted geometry and the phase-angle centroid correction against closed forms."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from obsw.config import CameraKnowledge, ImagingConfig, TargetKnowledge
from obsw.imaging import focal_length_px, predict_frame
from obsw.imaging_geometry import LIT_CENTROID_FACTOR, LosKnowledge, matrix_of_quaternion, phase_offset_px
from obsw.trajectory import NominalTrajectory

CFG = ImagingConfig()
CAMERA = CameraKnowledge()
TRAJ = NominalTrajectory(ca_time_obt_s=1000.0, ca_distance_km=55.0, speed_km_s=7.0,
                         approach_direction=(1.0, 0.0, 0.0), ca_direction=(0.0, 1.0, 0.0),
                         ca_time_sigma_s=10.0, ca_distance_sigma_km=5.0)


def _lit_region_centroid(radius: float, phase_rad: float, grid: int = 801) -> float:
    """Centroid, along the Sun's side of the image, of the lit part of a disc of ``radius`` seen at ``phase_rad``:
    the half disc on the Sun's side (x > 0) joined to, or cut by, the half ellipse of semi-axes (r |cos g|, r) of the
    terminator, rasterised finely (an independent computation of the region, not of the formula)."""
    x = np.linspace(-radius, radius, grid)
    xx, yy = np.meshgrid(x, x)
    disc = xx * xx + yy * yy <= radius * radius
    c = math.cos(phase_rad)
    inside_ellipse = (xx / max(abs(c) * radius, 1e-12)) ** 2 + (yy / radius) ** 2 <= 1.0
    lit = disc & ((xx >= 0) | inside_ellipse) if c >= 0 else disc & (xx >= 0) & ~inside_ellipse
    return float(xx[lit].mean())


@settings(max_examples=25, deadline=None)
@given(phase_deg=st.floats(5.0, 150.0), radius=st.floats(3.0, 120.0))
def test_phase_offset_is_the_centroid_of_the_lit_part_of_a_disc(phase_deg: float, radius: float) -> None:
    """At the image centre, the offset is the lit region's centroid: (4 / 3 pi) r (1 - cos g) towards the Sun."""
    g = math.radians(phase_deg)
    az = 0.7
    sun = (math.sin(g) * math.cos(az), math.sin(g) * math.sin(az), -math.cos(g))
    c = 0.5 * (CFG.binned_size_px - 1)
    dc, dr = phase_offset_px(sun, (c, c), radius, CAMERA.fov_deg, CFG.binned_size_px)
    assert math.hypot(dc, dr) == pytest.approx(_lit_region_centroid(radius, g), rel=0.01, abs=0.02)
    assert math.atan2(dr, dc) == pytest.approx(az)
    assert math.hypot(dc, dr) == pytest.approx(LIT_CENTROID_FACTOR * radius * (1.0 - math.cos(g)))


def test_no_offset_with_the_sun_behind_the_camera() -> None:
    """At zero phase the whole disc is lit: no offset."""
    c = 0.5 * (CFG.binned_size_px - 1)
    assert phase_offset_px((0.0, 0.0, -1.0), (c, c), 30.0, CAMERA.fov_deg, CFG.binned_size_px) == (0.0, 0.0)


def _attitude_towards(los: np.ndarray) -> np.ndarray:
    """Body +Z along ``los``, body +X in the inertial XY plane (scalar-last body->inertial quaternion)."""
    z = los / np.linalg.norm(los)
    x = np.cross([0.0, 0.0, 1.0], z)
    x /= np.linalg.norm(x)
    return Rotation.from_matrix(np.column_stack([x, np.cross(z, x), z])).as_quat()


@pytest.mark.parametrize("t", [800.0, 970.0, 995.0, 1000.0, 1030.0])
def test_prediction_is_the_pinhole_image_of_the_trajectory(t: float) -> None:
    """Pointed 0.2 deg off the trajectory's line of sight: the predicted place is the pinhole projection of that line
    of sight, the radii f R / range, the orbit's largest radius f a / (the nearest of the 3-sigma corners' ranges),
    the uncertainty reaches the corners' places, and the Sun is turned into camera axes."""
    los = TRAJ.los_inertial(t)
    q = (Rotation.from_quat(_attitude_towards(los)) * Rotation.from_rotvec([0.0, math.radians(0.2), 0.0])).as_quat()
    targets = TargetKnowledge()
    p = predict_frame(q, targets, CAMERA, CFG, TRAJ, t)
    f = focal_length_px(CAMERA.fov_deg, CFG.binned_size_px)
    v = Rotation.from_quat(q).inv().apply(los)
    c = 0.5 * (CFG.binned_size_px - 1)
    assert p.dimorphos_col_row == pytest.approx((c + f * v[0] / v[2], c + f * v[1] / v[2]))
    rng = float(TRAJ.range_m(t))
    assert p.didymos_radius_px == pytest.approx(f * 390.0 / rng)
    assert p.dimorphos_radius_px == pytest.approx(f * 82.0 / rng)
    corners = [TRAJ.with_ca(TRAJ.ca_time_obt_s + a * 30.0, TRAJ.ca_distance_km + b * 15.0)
               for a in (-1, 1) for b in (-1, 1)]
    nearest = min([rng] + [float(k.range_m(t)) for k in corners])
    assert p.orbit_radius_max_px == pytest.approx(f * 1190.0 / nearest)
    assert p.radius_factor_max == pytest.approx(targets.max_axis_ratio * rng / nearest)
    for k in corners:
        w = Rotation.from_quat(q).inv().apply(k.los_inertial(t))
        assert math.dist((c + f * w[0] / w[2], c + f * w[1] / w[2]), p.dimorphos_col_row) \
            <= p.dimorphos_uncertainty_px + 1e-9
    sun = np.asarray(targets.sun_direction_inertial) / np.linalg.norm(targets.sun_direction_inertial)
    assert np.asarray(p.sun_camera) == pytest.approx(Rotation.from_quat(q).inv().apply(sun))


@pytest.mark.parametrize("t", [800.0, 970.0, 1000.0, 1060.0])
@pytest.mark.parametrize("bound_deg", [0.001, 0.05, 5.0])
def test_a_known_line_of_sight_places_dimorphos_with_its_bound(t: float, bound_deg: float) -> None:
    """Given the estimate's line of sight and its bound, Dimorphos's place is that line of sight's pinhole image and
    its uncertainty the bound in px (f tan is f times the angle to 1e-6 here), before and after C/A, whether or not
    the 3-sigma corners' spread is tighter. Sizes never change."""
    los = TRAJ.los_inertial(t)
    q = _attitude_towards(los)
    across = np.cross(los, [0.0, 0.0, 1.0])
    seen = Rotation.from_rotvec(math.radians(0.1) * across / np.linalg.norm(across)).apply(los)  # 0.1 deg off
    plain = predict_frame(q, TargetKnowledge(), CAMERA, CFG, TRAJ, t)
    p = predict_frame(q, TargetKnowledge(), CAMERA, CFG, TRAJ, t,
                      LosKnowledge(los_inertial=tuple(seen), bound_rad=math.radians(bound_deg)))
    f = focal_length_px(CAMERA.fov_deg, CFG.binned_size_px)
    v = Rotation.from_quat(q).inv().apply(seen)
    c = 0.5 * (CFG.binned_size_px - 1)
    assert p.dimorphos_col_row == pytest.approx((c + f * v[0] / v[2], c + f * v[1] / v[2]))
    assert plain.dimorphos_col_row is not None
    assert math.dist(p.dimorphos_col_row, plain.dimorphos_col_row) == pytest.approx(
        f * math.tan(math.radians(0.1)), rel=1e-3)
    assert p.dimorphos_uncertainty_px == pytest.approx(f * math.radians(bound_deg))
    assert (p.didymos_radius_px, p.dimorphos_radius_px, p.orbit_radius_max_px) == (
        plain.didymos_radius_px, plain.dimorphos_radius_px, plain.orbit_radius_max_px)


@pytest.mark.parametrize("after_s", [60.0, 120.0])
def test_after_ca_a_misaligned_camera_stays_within_the_stated_uncertainty(after_s: float) -> None:
    """After C/A the corners of a well-recognised trajectory converge on the departure direction, while a camera
    misaligned to the star tracker moves every line of sight by a fixed angle (solved by the estimate as its
    offsets): the true place lies within the stated uncertainty, which the corners alone would break."""
    traj = TRAJ.model_copy(update={"ca_time_sigma_s": 0.01, "ca_distance_sigma_km": 0.05})
    t = traj.ca_time_obt_s + after_s
    los = traj.los_inertial(t)
    axis = np.cross(los, [0.0, 0.0, 1.0])
    truth = Rotation.from_rotvec(math.radians(0.03) * axis / np.linalg.norm(axis)).apply(los)
    q = _attitude_towards(truth)
    f = focal_length_px(CAMERA.fov_deg, CFG.binned_size_px)
    c = 0.5 * (CFG.binned_size_px - 1)
    v = Rotation.from_quat(q).inv().apply(truth)
    where = (c + f * v[0] / v[2], c + f * v[1] / v[2])
    plain = predict_frame(q, TargetKnowledge(), CAMERA, CFG, traj, t)
    assert plain.dimorphos_col_row is not None and plain.dimorphos_uncertainty_px is not None
    assert math.dist(where, plain.dimorphos_col_row) > plain.dimorphos_uncertainty_px  # the corners alone miss it
    p = predict_frame(q, TargetKnowledge(), CAMERA, CFG, traj, t,
                      LosKnowledge(los_inertial=tuple(truth), bound_rad=math.radians(0.05)))
    assert p.dimorphos_col_row is not None and p.dimorphos_uncertainty_px is not None
    assert math.dist(where, p.dimorphos_col_row) <= p.dimorphos_uncertainty_px


def test_without_a_trajectory_only_the_sun_is_predicted() -> None:
    """Before the trajectory is loaded the prediction holds the Sun's direction alone."""
    p = predict_frame(np.array([0.0, 0.0, 0.0, 1.0]), TargetKnowledge(), CAMERA, CFG)
    assert p.didymos_radius_px is None and p.dimorphos_col_row is None and p.orbit_radius_max_px is None
    assert math.hypot(*p.sun_camera) == pytest.approx(1.0)


_component = st.floats(-1.0, 1.0, allow_nan=False)


@settings(max_examples=300, deadline=None)
@given(st.tuples(_component, _component, _component, _component).filter(lambda q: sum(c * c for c in q) > 1e-6),
       st.floats(1e-3, 1e3), st.tuples(_component, _component, _component))
def test_the_quaternion_matrix_turns_vectors_as_scipy_does_to_the_last_bit(
        q: tuple[float, float, float, float], scale: float, v: tuple[float, float, float]) -> None:
    """matrix_of_quaternion(q) @ v equals SciPy's Rotation.from_quat(q).apply(v) bit for bit, q of any norm, and
    its contiguous transpose the inverse's apply."""
    quat = np.array(q) * scale
    vec = np.array(v)
    m = matrix_of_quaternion(quat)
    rotation = Rotation.from_quat(quat)
    assert np.array_equal(m, rotation.as_matrix())
    assert np.array_equal(m @ vec, rotation.apply(vec))
    # the inverse turn: the transpose, made contiguous (a strided transpose sums in another order)
    assert np.array_equal(np.ascontiguousarray(m.T) @ vec, rotation.inv().apply(vec))


def test_a_zero_quaternion_is_refused_by_name() -> None:
    """A zero quaternion has no rotation: a ValueError naming it, as SciPy refuses it."""
    with pytest.raises(ValueError, match="quaternion must not be zero"):
        matrix_of_quaternion(np.zeros(4))
