"""Flyby geometry: where the spacecraft, Didymos, Dimorphos and the Sun are, and what the camera sees of them.

At 7 km/s and 55 km from a 5e11 kg binary the hyperbola is a straight line to within millimetres, so the
spacecraft moves on r(t) = d_ca e_ca + v (t - t_ca) e_v relative to the Didymos barycentre (inertial frame,
metres). Dimorphos circles Didymos on a circular orbit; both bodies sit about the barycentre by their mass ratio.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from universe.config import BodiesConfig, FlybyConfig, UncertaintyConfig
from universe.geometry_kernels import truth_geometry

ArrayLike = float | np.ndarray


class GeometryError(ValueError):
    """A geometric input is degenerate (parallel directions, zero vectors, non-unit quaternions...)."""


def _unit(v: np.ndarray, name: str) -> np.ndarray:
    """Return v normalised, or raise GeometryError naming the vector if it is (nearly) zero."""
    n = float(np.linalg.norm(v))
    if n < 1e-12:
        raise GeometryError(f"{name} must be a non-zero vector, got {v.tolist()}")
    return v / n


def _orthogonal_unit(v: np.ndarray, reference: np.ndarray, name: str) -> np.ndarray:
    """Return the unit component of v orthogonal to the unit vector reference (Gram-Schmidt)."""
    v = _unit(np.asarray(v, dtype=float), name)
    w = v - float(v @ reference) * reference
    n = float(np.linalg.norm(w))
    if n < 1e-9:
        raise GeometryError(f"{name} {v.tolist()} is parallel to {reference.tolist()}; cannot make it orthogonal")
    return w / n


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Return the cross product of 3-vectors along the last axis (np.cross costs ~30 us per call on small arrays)."""
    return np.stack(
        [
            a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1],
            a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
            a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0],
        ],
        axis=-1,
    )


def camera_axes_body(boresight_body: np.ndarray) -> np.ndarray:
    """Return the 3x3 matrix whose rows are the camera x (image columns), y (image rows) and z (boresight) in body axes.

    Camera x is body +X made orthogonal to the boresight (body +Y if the boresight is along X), camera y = z cross x,
    so the default boresight +Z gives camera axes equal to the body axes.
    """
    return _camera_axes_cached(tuple(float(c) for c in np.asarray(boresight_body, dtype=float).ravel())).copy()


@lru_cache(maxsize=64)
def _camera_axes_cached(boresight_body: tuple[float, ...]) -> np.ndarray:
    """Return camera_axes_body for a boresight given as a tuple (cached: the boresight rarely changes)."""
    if len(boresight_body) != 3:
        raise GeometryError(f"boresight_body must have 3 components, got {list(boresight_body)}")
    z = _unit(np.array(boresight_body), "boresight_body")
    ex = np.array([1.0, 0.0, 0.0])
    ref = ex if abs(float(z @ ex)) < 0.999 else np.array([0.0, 1.0, 0.0])
    x = _orthogonal_unit(ref, z, "camera x reference")
    y = _cross(z, x)
    return np.vstack([x, y, z])


@lru_cache(maxsize=64)
def _tan_half(fov_deg: float) -> float:
    """tan(fov / 2) of a field of view in degrees (cached: the camera's is asked for at every ground step)."""
    return float(np.tan(np.radians(fov_deg) / 2.0))


@dataclass(frozen=True)
class TruthSample:
    """The true geometry at one instant, as the flight software would ideally know it."""

    t_s: float
    range_to_dimorphos_m: float
    range_to_didymos_m: float
    los_dimorphos_inertial: np.ndarray
    """unit vector from the spacecraft to Dimorphos, inertial"""
    los_didymos_inertial: np.ndarray
    """unit vector from the spacecraft to Didymos, inertial"""
    los_dimorphos_body: np.ndarray
    """unit vector from the spacecraft to Dimorphos, body axes"""
    los_dimorphos_camera: np.ndarray
    """unit vector from the spacecraft to Dimorphos, camera axes (x columns, y rows, z boresight)"""
    theta_rad: float
    """paper's angle between the velocity relative to Dimorphos and the line of sight to it: 0 far before C/A,
    pi/2 at C/A, pi far after"""
    phase_angle_deg: float
    """Sun-Dimorphos-spacecraft angle, deg"""
    pointing_error_rad: float
    """angle between the camera boresight (inertial) and the line of sight to Dimorphos"""
    target_in_fov: bool
    """whether the centre of Dimorphos is inside the square field of view"""


@dataclass(frozen=True)
class TruthSamples:
    """``TruthSample`` at N instants: each field an array over them (vectors shape (N, 3))."""

    t_s: np.ndarray
    range_to_dimorphos_m: np.ndarray
    range_to_didymos_m: np.ndarray
    los_dimorphos_inertial: np.ndarray
    los_didymos_inertial: np.ndarray
    los_dimorphos_body: np.ndarray
    los_dimorphos_camera: np.ndarray
    theta_rad: np.ndarray
    phase_angle_deg: np.ndarray
    pointing_error_rad: np.ndarray
    target_in_fov: np.ndarray


class FlybyGeometry:
    """The true positions of the flyby, relative to the Didymos barycentre, inertial frame, metres.

    Every position/velocity method accepts a scalar time or an array of times (shape S) and returns shape S + (3,).
    """

    def __init__(self, flyby: FlybyConfig, bodies: BodiesConfig) -> None:
        self.flyby = flyby
        self.bodies = bodies
        self.e_v = _unit(np.asarray(flyby.approach_direction, dtype=float), "flyby.approach_direction")
        self.e_ca = _orthogonal_unit(np.asarray(flyby.ca_direction, dtype=float), self.e_v, "flyby.ca_direction")
        self.ca_time_s = float(flyby.ca_time_s)
        self.ca_distance_m = float(flyby.ca_distance_km) * 1e3
        self.speed_m_s = float(flyby.speed_km_s) * 1e3
        n = _unit(np.asarray(bodies.orbit_normal, dtype=float), "bodies.orbit_normal")
        ex = np.array([1.0, 0.0, 0.0])
        ref = ex if abs(float(n @ ex)) < 0.999 else np.array([0.0, 1.0, 0.0])
        self.orbit_e1 = _orthogonal_unit(ref, n, "orbit phase reference")
        self.orbit_e2 = _cross(n, self.orbit_e1)
        self.orbit_normal = n
        self.mean_motion_rad_s = 2.0 * np.pi / (float(bodies.orbit_period_h) * 3600.0)
        q = float(bodies.mass_ratio)
        # Barycentric distances: Dimorphos at a/(1+q), Didymos at a q/(1+q) on the other side.
        self.dimorphos_arm_m = float(bodies.orbit_radius_m) / (1.0 + q)
        self.didymos_arm_m = float(bodies.orbit_radius_m) * q / (1.0 + q)
        self._sun = _unit(np.asarray(bodies.sun_direction, dtype=float), "bodies.sun_direction")
        # the constant terms of the positions, computed once (the same values as computed at each call)
        self._ca_point_m = self.ca_distance_m * self.e_ca
        self._orbit_phase0_rad = np.radians(bodies.orbit_phase_deg)
        # what the compiled truth geometry takes (geometry_kernels.truth_geometry)
        self._orbit_constants = np.array([self.ca_time_s, self.ca_distance_m, self.speed_m_s,
                                          float(np.radians(bodies.orbit_phase_deg)), self.mean_motion_rad_s,
                                          self.dimorphos_arm_m, self.didymos_arm_m])

    def spacecraft_position_m(self, t_s: ArrayLike) -> np.ndarray:
        """Return the spacecraft position relative to the barycentre at true time t_s, m."""
        dt = np.asarray(t_s, dtype=float)[..., None] - self.ca_time_s
        return self._ca_point_m + self.speed_m_s * dt * self.e_v

    def spacecraft_velocity_m_s(self, t_s: ArrayLike) -> np.ndarray:
        """Return the spacecraft velocity relative to the barycentre (constant), m/s."""
        if np.ndim(t_s) == 0:  # one time (every frame): a copy of the vector
            return self.speed_m_s * self.e_v
        return np.broadcast_to(self.speed_m_s * self.e_v, np.shape(t_s) + (3,)).copy()

    def _orbit_phase_rad(self, t_s: ArrayLike) -> np.ndarray:
        """Return Dimorphos's orbital phase at t_s, rad, with a trailing axis for broadcasting."""
        t = np.asarray(t_s, dtype=float)[..., None]
        return self._orbit_phase0_rad + self.mean_motion_rad_s * t

    def orbit_unit(self, t_s: ArrayLike) -> np.ndarray:
        """Return the unit vector from Didymos to Dimorphos at t_s (both centres are their arms times it)."""
        ph = self._orbit_phase_rad(t_s)
        return np.cos(ph) * self.orbit_e1 + np.sin(ph) * self.orbit_e2

    def dimorphos_position_m(self, t_s: ArrayLike) -> np.ndarray:
        """Return the Dimorphos centre relative to the barycentre, m."""
        return self.dimorphos_arm_m * self.orbit_unit(t_s)

    def didymos_position_m(self, t_s: ArrayLike) -> np.ndarray:
        """Return the Didymos centre relative to the barycentre, m (opposite Dimorphos, scaled by the mass ratio)."""
        return -self.didymos_arm_m * self.orbit_unit(t_s)

    def dimorphos_velocity_m_s(self, t_s: ArrayLike) -> np.ndarray:
        """Return the Dimorphos velocity relative to the barycentre, m/s."""
        ph = self._orbit_phase_rad(t_s)
        tangent = -np.sin(ph) * self.orbit_e1 + np.cos(ph) * self.orbit_e2
        return self.dimorphos_arm_m * self.mean_motion_rad_s * tangent

    def sun_direction(self) -> np.ndarray:
        """Return the unit vector from the asteroid system to the Sun, inertial."""
        return self._sun.copy()

    def theta_rad(self, t_s: ArrayLike) -> np.ndarray:
        """Return the paper's angle Theta (velocity relative to Dimorphos vs line of sight to it), rad; vectorised."""
        rel = self.dimorphos_position_m(t_s) - self.spacecraft_position_m(t_s)
        vel = self.spacecraft_velocity_m_s(t_s) - self.dimorphos_velocity_m_s(t_s)
        cross = np.linalg.norm(_cross(vel, rel), axis=-1)
        dot = np.sum(vel * rel, axis=-1)
        return np.arctan2(cross, dot)

    def truth_sample(
        self, t_s: float, q_body_to_inertial: np.ndarray, boresight_body: np.ndarray, fov_deg: float
    ) -> TruthSample:
        """Return the true geometry at t_s for an attitude (scalar-last quaternion body -> inertial) and a camera."""
        q = np.asarray(q_body_to_inertial, dtype=float)
        if q.shape != (4,):
            raise GeometryError(f"q_body_to_inertial must be a unit quaternion of shape (4,), got {q.tolist()}")
        s = self.truth_samples(np.array([float(t_s)]), q[None, :], boresight_body, fov_deg)
        return TruthSample(
            t_s=float(t_s), range_to_dimorphos_m=float(s.range_to_dimorphos_m[0]),
            range_to_didymos_m=float(s.range_to_didymos_m[0]), los_dimorphos_inertial=s.los_dimorphos_inertial[0],
            los_didymos_inertial=s.los_didymos_inertial[0], los_dimorphos_body=s.los_dimorphos_body[0],
            los_dimorphos_camera=s.los_dimorphos_camera[0], theta_rad=float(s.theta_rad[0]),
            phase_angle_deg=float(s.phase_angle_deg[0]), pointing_error_rad=float(s.pointing_error_rad[0]),
            target_in_fov=bool(s.target_in_fov[0]),
        )

    def truth_samples(
        self, t_s: np.ndarray, q_body_to_inertial: np.ndarray, boresight_body: np.ndarray, fov_deg: float
    ) -> TruthSamples:
        """``truth_sample`` at N times (shape (N,)) and attitudes (shape (N, 4)) at once: each field an array."""
        t = np.asarray(t_s, dtype=float)
        q = np.asarray(q_body_to_inertial, dtype=float)
        if q.ndim != 2 or q.shape[1] != 4 or t.shape != (q.shape[0],):
            raise GeometryError(f"truth_samples needs N times and N quaternions, got shapes {t.shape} and {q.shape}")
        unit = np.abs(np.sqrt(np.sum(q * q, axis=1)) - 1.0) <= 1e-6
        if not unit.all():
            bad = np.flatnonzero(~unit)
            raise GeometryError(f"q_body_to_inertial must be a unit quaternion of shape (4,), got {q[bad[0]].tolist()}")
        if not 0.0 < fov_deg < 180.0:
            raise GeometryError(f"fov_deg must be in (0, 180), got {fov_deg}")
        # the cached axes themselves, not camera_axes_body's copy: the kernel only reads them
        axes = _camera_axes_cached(tuple(np.asarray(boresight_body, dtype=float).ravel().tolist()))
        scalars, vectors, in_fov = np.empty((t.size, 5)), np.empty((t.size, 4, 3)), np.empty(t.size, dtype=bool)
        truth_geometry(t, np.ascontiguousarray(q), self._orbit_constants, self.e_ca, self.e_v, self.orbit_e1,
                       self.orbit_e2, self._sun, axes, _tan_half(fov_deg), scalars, vectors, in_fov)
        return TruthSamples(
            t_s=t,
            range_to_dimorphos_m=scalars[:, 0],
            range_to_didymos_m=scalars[:, 1],
            los_dimorphos_inertial=vectors[:, 0],
            los_didymos_inertial=vectors[:, 1],
            los_dimorphos_body=vectors[:, 2],
            los_dimorphos_camera=vectors[:, 3],
            theta_rad=scalars[:, 2],
            phase_angle_deg=scalars[:, 3],
            pointing_error_rad=scalars[:, 4],
            target_in_fov=in_fov,
        )

def _line_through(p_m: np.ndarray, v_m_s: np.ndarray, t_s: float, what: str) -> FlybyConfig:
    """The straight flyby through position ``p_m`` with velocity ``v_m_s`` at ``t_s``: its C/A time, distance,
    speed and directions."""
    speed = float(np.linalg.norm(v_m_s))
    e_v = v_m_s / speed
    dt = -float(p_m @ e_v) / speed
    ca = p_m + v_m_s * dt
    d = float(np.linalg.norm(ca))
    if d < 1.0:  # a metre: the spacecraft would pass through the body's centre
        raise GeometryError(f"{what}: the spacecraft passes {d:.3f} m from the centre; no closest approach direction")
    return FlybyConfig(ca_time_s=t_s + dt, ca_distance_km=d / 1e3, speed_km_s=speed / 1e3,
                       approach_direction=tuple(float(c) for c in e_v),
                       ca_direction=tuple(float(c) for c in ca / d))


def dimorphos_line(flyby: FlybyConfig, bodies: BodiesConfig) -> FlybyConfig:
    """The spacecraft's motion relative to Dimorphos as a straight flyby (C/A time and distance, speed, directions),
    for ``flyby`` of the Didymos barycentre: the tangent to the relative motion at the barycentre's C/A. Dimorphos's
    orbit bends it by about a metre over ten minutes. The target's C/A differs from the barycentre's by Dimorphos's
    place on its orbit: along the flyby plane that is a change of C/A time and distance, across it a change of the
    plane itself, which a trajectory of the barycentre leaves out (up to 1.2 deg at a 55 km C/A)."""
    g = FlybyGeometry(flyby, bodies)
    t = g.ca_time_s
    return _line_through(g.spacecraft_position_m(t) - g.dimorphos_position_m(t),
                         g.spacecraft_velocity_m_s(t) - g.dimorphos_velocity_m_s(t), t, "flyby of Dimorphos")


def barycentre_flyby(target: FlybyConfig, bodies: BodiesConfig) -> FlybyConfig:
    """The flyby of the Didymos barycentre whose ``dimorphos_line`` is ``target`` (fixed-point iteration on the
    barycentre's C/A time, where ``dimorphos_line`` takes the tangent; it moves by under a second, then by
    nanoseconds)."""
    line = FlybyGeometry(target, bodies)
    t = line.ca_time_s
    out = target
    for _ in range(4):
        orbit = FlybyGeometry(out, bodies)
        out = _line_through(line.spacecraft_position_m(t) + orbit.dimorphos_position_m(t),
                            line.spacecraft_velocity_m_s(t) + orbit.dimorphos_velocity_m_s(t), t,
                            "flyby of the barycentre")
        if abs(out.ca_time_s - t) < 1e-12:
            break
        t = out.ca_time_s
    return out


def nominal_ca(flyby: FlybyConfig, unc: UncertaintyConfig, rng: np.random.Generator) -> tuple[float, float]:
    """Return the (C/A time s, C/A distance km) that ground believes: truth plus a seeded error.

    Each error is N(0, sigma), or exactly offset_sigma * sigma when the *_offset_sigma field is set (worst-case
    corners). Both normals are always drawn, time first, so fixing one corner does not change the other's draw.
    """
    z_time, z_dist = rng.standard_normal(2)
    k_time = z_time if unc.ca_time_offset_sigma is None else float(unc.ca_time_offset_sigma)
    k_dist = z_dist if unc.ca_distance_offset_sigma is None else float(unc.ca_distance_offset_sigma)
    t_ca = float(flyby.ca_time_s + k_time * unc.ca_time_sigma_s)
    d_ca = float(flyby.ca_distance_km + k_dist * unc.ca_distance_sigma_km)
    if d_ca <= 0.0:
        raise GeometryError(
            f"nominal C/A distance {d_ca:.3f} km is not positive (truth {flyby.ca_distance_km} km, "
            f"{k_dist:+.2f} x uncertainty.ca_distance_sigma_km {unc.ca_distance_sigma_km} km)"
        )
    return t_ca, d_ca
