"""What the imaging chain expects of a frame, and the pinhole geometry between image offsets and lines of sight.

Image x (columns) is body +X, image y (rows) body +Y, the boresight body +Z; the image centre is at
((n - 1) / 2, (n - 1) / 2) in pixel-centre coordinates of the n x n binned image.

``FramePrediction`` is the flight software's expectation of one frame, from what is on board only: the Sun's
direction in camera axes (the Sun direction of ``TargetKnowledge`` turned by the attitude at the exposure), and,
once a trajectory is loaded, the range to the target at the exposure with its uncertainty, hence the apparent radii
of Didymos and Dimorphos, the largest apparent radius of Dimorphos's orbit, and where the trajectory puts Dimorphos
in the image. The imaging chain uses it to search for Dimorphos (``imaging_identification``) and to correct the
centroid of a lit body for the phase angle (``phase_offset_px``).

The phase correction (beyond the paper) models a body as a sphere: the lit part of its disc is a half disc on the
Sun's side and a half ellipse of semi-minor axis r |cos g| (the terminator seen at phase angle g), whose centroid
lies (4 / (3 pi)) r (1 - cos g) from the centre towards the Sun's side of the image, whatever the shading law. The
binary centroid of the body's region is moved back by that much.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from obsw.config import CameraKnowledge, ImagingConfig, TargetKnowledge
from obsw.trajectory import NominalTrajectory

LIT_CENTROID_FACTOR = 4.0 / (3.0 * math.pi)  # centroid of a half disc, in radii from its centre


def focal_length_px(fov_deg: float, width_px: int) -> float:
    """Return the pinhole focal length in pixels of an image width_px wide spanning fov_deg horizontally."""
    if not 0.0 < fov_deg < 180.0:
        raise ValueError(f"fov_deg must be in (0, 180), got {fov_deg}")
    if width_px <= 0:
        raise ValueError(f"width_px must be positive, got {width_px}")
    return 0.5 * width_px / math.tan(math.radians(0.5 * fov_deg))


def los_body(offset_col_px: float, offset_row_px: float, fov_deg: float, width_px: int) -> np.ndarray:
    """Return the unit line of sight in body axes of an image offset from the centre (boresight +Z).

    Columns run along body +X and rows along body +Y, so the pinhole ray is (col, row, f_px) normalised.
    """
    f = focal_length_px(fov_deg, width_px)
    v = np.array([offset_col_px, offset_row_px, f], dtype=np.float64)
    return v / np.linalg.norm(v)


def matrix_of_quaternion(q: np.ndarray) -> np.ndarray:
    """Body-to-inertial rotation matrix of a scalar-last quaternion, normalised first:
    ``Rotation.from_quat(q).as_matrix()`` to the last bit, at a twentieth of its cost; ``m @ v`` is then
    ``Rotation.from_quat(q).apply(v)`` to the last bit (the same operations in SciPy's order)."""
    x, y, z, w = np.asarray(q, dtype=np.float64).tolist()
    norm = math.sqrt(x * x + y * y + z * z + w * w)
    if norm == 0.0:
        raise ValueError(f"quaternion must not be zero, got {q}")
    x, y, z, w = x / norm, y / norm, z / norm, w / norm
    x2, y2, z2, w2 = x * x, y * y, z * z, w * w
    xy, zw, xz, yw, yz, xw = x * y, z * w, x * z, y * w, y * z, x * w
    return np.array([[x2 - y2 - z2 + w2, 2 * (xy - zw), 2 * (xz + yw)],
                     [2 * (xy + zw), -x2 + y2 - z2 + w2, 2 * (yz - xw)],
                     [2 * (xz - yw), 2 * (yz + xw), -x2 - y2 + z2 + w2]])


def offset_rad(offset_px: tuple[float, float], fov_deg: float, width_px: int) -> tuple[float, float]:
    """Return the pinhole angles atan(offset / f_px) of a (col, row) pixel offset from the image centre."""
    f = focal_length_px(fov_deg, width_px)
    return (math.atan(offset_px[0] / f), math.atan(offset_px[1] / f))


@dataclass(frozen=True, slots=True)
class FramePrediction:
    """The flight software's expectation of one frame (binned px); sizes and place are None without a trajectory."""

    sun_camera: tuple[float, float, float]  # unit vector to the Sun, camera (body) axes
    didymos_radius_px: float | None = None  # apparent radius at the predicted range
    dimorphos_radius_px: float | None = None
    radius_factor_max: float = 1.0  # apparent radii are at most this many times the predicted ones
    orbit_radius_max_px: float | None = None  # largest apparent distance of Dimorphos from Didymos's centre
    dimorphos_col_row: tuple[float, float] | None = None  # where the trajectory puts Dimorphos in the image
    dimorphos_uncertainty_px: float | None = None  # radius of the region around it Dimorphos is expected in


def _camera_px(v_camera: np.ndarray, f_px: float, n: int) -> tuple[float, float] | None:
    """Image position (col, row) of a camera-frame direction, or None behind the camera."""
    if v_camera[2] <= 1e-9:
        return None
    c = 0.5 * (n - 1)
    return (c + f_px * v_camera[0] / v_camera[2], c + f_px * v_camera[1] / v_camera[2])


@dataclass(frozen=True, slots=True)
class LosKnowledge:
    """The target's line of sight at the exposure as the trajectory estimate predicts it, with the constant offsets
    of the measured line of sight it solves, and the angle around it the line of sight is expected in: the lock
    gate's count of one-sigmas of that prediction (the estimate's covariance, C/A time and distance correlated, and
    the attitude's knowledge); the imaging chain adds the body's radius and the centroid's noise, as the gate does."""

    los_inertial: tuple[float, float, float]  # unit vector
    bound_rad: float


def predict_frame(q_body_to_inertial: np.ndarray, targets: TargetKnowledge, camera: CameraKnowledge,
                  cfg: ImagingConfig, trajectory: NominalTrajectory | None = None, obt_s: float | None = None,
                  los: LosKnowledge | None = None) -> FramePrediction:
    """The expectation of a frame exposed at ``obt_s`` with the attitude ``q_body_to_inertial``: the Sun's direction,
    and with a trajectory, the target's range (its corners at +-``cfg.prediction_sigma`` in C/A time and distance
    bound the sizes and the place), the apparent radii, the orbit's largest apparent radius and Dimorphos's
    predicted position. With ``los`` (the trajectory's own estimate's line of sight, with the constant offsets of the
    measured line of sight it solves), Dimorphos's place is that line of sight and its uncertainty that bound. The
    corners bound only the trajectory's own line of sight: far before C/A they overstate its spread (a later C/A at a
    larger distance points nearly the same way: run 345 of the Monte Carlo campaign at C/A-152 s, 40 px for the
    corners, 2.1 px for the bound), and after C/A, where they converge on the departure direction, they leave out the
    offsets (run 13 of the nominal image-level campaign, a camera misaligned by 0.034 deg: 4-6 px off with 0.2-0.5 px
    stated; with the estimate's line of sight 0.5-3.6 px off, each within the 3-6 px stated)."""
    n = cfg.binned_size_px
    # inertial -> camera: the transpose, contiguous (then ``@`` is SciPy's ``inv().apply`` to the last bit)
    to_camera = np.ascontiguousarray(matrix_of_quaternion(q_body_to_inertial).T)
    sun = np.asarray(targets.sun_direction_inertial, dtype=float)
    sun_c = to_camera @ (sun / np.linalg.norm(sun))
    sun_t = (float(sun_c[0]), float(sun_c[1]), float(sun_c[2]))
    if trajectory is None or obt_s is None:
        return FramePrediction(sun_camera=sun_t)
    f = focal_length_px(camera.fov_deg, n)
    rng = float(trajectory.range_m(obt_s))
    k = cfg.prediction_sigma
    corners = [trajectory.with_ca(trajectory.ca_time_obt_s + dt * k * trajectory.ca_time_sigma_s,
                                  max(trajectory.ca_distance_km + dd * k * trajectory.ca_distance_sigma_km,
                                      1e-3 * trajectory.ca_distance_km))
               for dt in (-1.0, 1.0) for dd in (-1.0, 1.0)]
    nearest = min([rng] + [float(c.range_m(obt_s)) for c in corners])
    place = _camera_px(to_camera @ trajectory.los_inertial(obt_s), f, n)
    spread = 0.0
    if los is not None and place is not None \
            and (seen := _camera_px(to_camera @ np.asarray(los.los_inertial, dtype=float), f, n)) is not None:
        place, spread = seen, los.bound_rad * f
    elif place is not None:  # the corners' spread, needed only without the estimate's line of sight
        for c in corners:
            p = _camera_px(to_camera @ c.los_inertial(obt_s), f, n)
            spread = max(spread, math.inf if p is None else math.dist(p, place))
    return FramePrediction(
        sun_camera=sun_t,
        didymos_radius_px=f * 0.5 * targets.didymos_diameter_m / rng,
        dimorphos_radius_px=f * 0.5 * targets.dimorphos_diameter_m / rng,
        radius_factor_max=targets.max_axis_ratio * rng / nearest,
        orbit_radius_max_px=f * targets.orbit_radius_m / nearest,
        dimorphos_col_row=place,
        dimorphos_uncertainty_px=spread if place is not None else None,
    )


def _los_at(col_row: tuple[float, float], fov_deg: float, n: int) -> np.ndarray:
    """The unit line of sight, body axes, of an image position (col, row) of the n x n binned image."""
    return los_body(col_row[0] - 0.5 * (n - 1), col_row[1] - 0.5 * (n - 1), fov_deg, n)


def _cos_phase(sun: np.ndarray, los: np.ndarray) -> float:
    """Cosine of the phase angle at a body seen along ``los``, lit from ``sun`` (unit vectors, same axes)."""
    return float(np.clip(-(sun @ los), -1.0, 1.0))


def phase_angle_deg(sun_camera: tuple[float, float, float], col_row: tuple[float, float], fov_deg: float,
                    n: int) -> float:
    """The phase angle, deg, between the Sun and the camera seen from a body at image position ``col_row``."""
    return math.degrees(math.acos(_cos_phase(np.asarray(sun_camera, dtype=float), _los_at(col_row, fov_deg, n))))


def phase_offset_px(sun_camera: tuple[float, float, float], col_row: tuple[float, float], radius_px: float,
                    fov_deg: float, n: int) -> tuple[float, float]:
    """The (col, row) offset of the lit centroid of a spherical body of apparent radius ``radius_px`` seen at
    ``col_row`` from its centre: (4 / (3 pi)) r (1 - cos g) along the Sun's direction in the image, g the phase
    angle between the Sun and the camera seen from the body. Zero when the Sun is along the line of sight."""
    los = _los_at(col_row, fov_deg, n)
    sun = np.asarray(sun_camera, dtype=float)
    cos_g = _cos_phase(sun, los)
    # the Sun's direction across the line of sight, projected on the image axes
    across = sun - (sun @ los) * los
    d = math.hypot(across[0], across[1])
    if d < 1e-12:
        return (0.0, 0.0)
    shift = LIT_CENTROID_FACTOR * radius_px * (1.0 - cos_g)
    return (shift * across[0] / d, shift * across[1] / d)
