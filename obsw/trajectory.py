"""The on-board model of the flyby: a straight line past the asteroid, in on-board time (OBT).

The spacecraft position relative to the asteroid is ``r(t) = d e_ca + v (t - t_ca) e_v``. The line of sight
(spacecraft -> asteroid) is ``-r / |r|``; it turns in the flyby plane about ``n = e_ca x e_v`` by the angle
``theta(t) = atan2(d, -v (t - t_ca))`` measured from the relative velocity (paper, "Trajectory Recognition").
Only ``t_ca`` and ``d / v`` shape ``theta``; the speed is taken as known from ground.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from pydantic import Field, model_validator

from contracts.model import Frozen

Vec3 = tuple[float, float, float]
FloatOrArray = float | NDArray[np.float64]

_DEGENERATE = 1e-9


def _unit_and_orthogonal(e_v: ArrayLike, e_ca: ArrayLike) -> tuple[Vec3, Vec3]:
    """Return the normalised approach direction and the C/A direction made orthogonal to it (Gram-Schmidt)."""
    v = np.asarray(e_v, dtype=float)
    c = np.asarray(e_ca, dtype=float)
    if v.shape != (3,) or c.shape != (3,):
        raise ValueError(f"approach_direction and ca_direction must be 3-vectors, got {v.shape} and {c.shape}")
    nv = float(np.linalg.norm(v))
    if abs(nv - 1.0) < 1e-12 and abs(float(np.linalg.norm(c)) - 1.0) < 1e-12 and abs(float(v @ c)) < 1e-12:
        # already orthonormal: keep the bits so that re-validating a trajectory (with_ca) is an exact copy
        return (float(v[0]), float(v[1]), float(v[2])), (float(c[0]), float(c[1]), float(c[2]))
    if nv < _DEGENERATE:
        raise ValueError(f"approach_direction {tuple(v)} must be a non-zero vector")
    v = v / nv
    c = c - float(c @ v) * v
    nc = float(np.linalg.norm(c))
    if nc < _DEGENERATE:
        given = tuple(np.asarray(e_ca, dtype=float))
        raise ValueError(f"ca_direction {given} must not be parallel to approach_direction")
    c = c / nc
    return (float(v[0]), float(v[1]), float(v[2])), (float(c[0]), float(c[1]), float(c[2]))


class NominalTrajectory(Frozen):
    """A straight-line flyby in OBT, as uploaded by ground (or as recognised on board)."""

    ca_time_obt_s: float = Field(description="on-board time of closest approach, OBT s")
    ca_distance_km: float = Field(gt=0, description="distance at closest approach, km")
    speed_km_s: float = Field(gt=0, description="relative speed, km/s")
    approach_direction: Vec3 = Field(
        description="direction of the spacecraft velocity relative to the asteroid, inertial (stored normalised)"
    )
    ca_direction: Vec3 = Field(
        description="direction asteroid -> spacecraft at C/A, inertial (stored normalised, orthogonal to the approach)"
    )
    ca_time_sigma_s: float = Field(10.0, ge=0, description="one-sigma uncertainty of the C/A time, s")
    ca_distance_sigma_km: float = Field(5.0, ge=0, description="one-sigma uncertainty of the C/A distance, km")

    @model_validator(mode="before")
    @classmethod
    def _orthonormal_directions(cls, data: Any) -> Any:
        """Normalise e_v and orthogonalise e_ca against it, so every method can rely on an orthonormal pair."""
        if isinstance(data, dict) and "approach_direction" in data and "ca_direction" in data:
            e_v, e_ca = _unit_and_orthogonal(data["approach_direction"], data["ca_direction"])
            data = {**data, "approach_direction": e_v, "ca_direction": e_ca}
        return data

    # --- geometry -----------------------------------------------------------------------------------------------

    @property
    def e_v(self) -> NDArray[np.float64]:
        """Unit approach direction (relative velocity), inertial."""
        return np.asarray(self.approach_direction, dtype=float)

    @property
    def e_ca(self) -> NDArray[np.float64]:
        """Unit direction asteroid -> spacecraft at C/A, inertial."""
        return np.asarray(self.ca_direction, dtype=float)

    @property
    def plane_normal(self) -> NDArray[np.float64]:
        """Unit normal of the flyby plane, ``e_ca x e_v``: the axis about which the line of sight turns (+theta)."""
        (cx, cy, cz), (vx, vy, vz) = self.ca_direction, self.approach_direction
        return np.array([cy * vz - cz * vy, cz * vx - cx * vz, cx * vy - cy * vx])

    @property
    def speed_m_s(self) -> float:
        """Relative speed, m/s."""
        return self.speed_km_s * 1e3

    @property
    def ca_distance_m(self) -> float:
        """C/A distance, m."""
        return self.ca_distance_km * 1e3

    def position_m(self, obt_s: ArrayLike) -> NDArray[np.float64]:
        """Spacecraft position relative to the asteroid, inertial, m: shape (3,) or (N, 3) for N times."""
        tau = np.asarray(obt_s, dtype=float) - self.ca_time_obt_s
        return self.ca_distance_m * self.e_ca + (self.speed_m_s * tau)[..., None] * self.e_v

    def range_m(self, obt_s: ArrayLike) -> FloatOrArray:
        """Distance spacecraft-asteroid, m."""
        tau = np.asarray(obt_s, dtype=float) - self.ca_time_obt_s
        return np.hypot(self.ca_distance_m, self.speed_m_s * tau)

    def los_inertial(self, obt_s: ArrayLike) -> NDArray[np.float64]:
        """Unit line of sight spacecraft -> asteroid, inertial: shape (3,) or (N, 3)."""
        if isinstance(obt_s, float):  # one time, in plain floats: the operations of the array path, a tenth of its cost
            d, vt = self.ca_distance_m, self.speed_m_s * (obt_s - self.ca_time_obt_s)
            (cx, cy, cz), (vx, vy, vz) = self.ca_direction, self.approach_direction
            rx, ry, rz = d * cx + vt * vx, d * cy + vt * vy, d * cz + vt * vz
            norm = math.sqrt(rx * rx + ry * ry + rz * rz)
            return np.array([-rx / norm, -ry / norm, -rz / norm])
        r = self.position_m(obt_s)
        return -r / np.linalg.norm(r, axis=-1, keepdims=True)

    def theta_rad(self, obt_s: ArrayLike) -> FloatOrArray:
        """Angle between the relative velocity and the line of sight, rad, in [0, pi] (pi/2 at C/A)."""
        tau = np.asarray(obt_s, dtype=float) - self.ca_time_obt_s
        return np.arctan2(self.ca_distance_m, -self.speed_m_s * tau)

    def los_rate_rad_s(self, obt_s: ArrayLike) -> FloatOrArray:
        """d theta / dt = v d / (d^2 + v^2 tau^2), rad/s; the LOS turns about ``plane_normal`` (peak v/d at C/A)."""
        tau = np.asarray(obt_s, dtype=float) - self.ca_time_obt_s
        d, v = self.ca_distance_m, self.speed_m_s
        return v * d / (d * d + (v * tau) ** 2)

    def los_accel_rad_s2(self, obt_s: ArrayLike) -> FloatOrArray:
        """d^2 theta / dt^2 = -2 v^3 d tau / (d^2 + v^2 tau^2)^2, rad/s^2 (peak 3 sqrt(3)/8 (v/d)^2)."""
        tau = np.asarray(obt_s, dtype=float) - self.ca_time_obt_s
        d, v = self.ca_distance_m, self.speed_m_s
        return -2.0 * v**3 * d * tau / (d * d + (v * tau) ** 2) ** 2

    def with_ca(self, ca_time_obt_s: float, ca_distance_km: float) -> NominalTrajectory:
        """The same flyby (directions, speed, sigmas) with another C/A time and distance."""
        # validated construction (not model_copy) so a non-positive distance is rejected
        return NominalTrajectory(
            **{**self.model_dump(), "ca_time_obt_s": float(ca_time_obt_s), "ca_distance_km": float(ca_distance_km)}
        )
