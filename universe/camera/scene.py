"""What one frame depends on: the bodies, the explicit stars and the scene at mid-exposure, checked on creation."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from universe.shapes import ShapeModel


class RenderError(ValueError):
    """A scene or camera parameter makes the frame impossible to render; the message names the field."""


def finite3(name: str, v: object) -> np.ndarray:
    """``v`` as a float 3-vector; RenderError naming ``name`` unless it is one and finite."""
    a = np.asarray(v, dtype=np.float64)
    # three values: Python's test of each costs less than NumPy's reduction (several vectors a frame)
    if a.shape != (3,) or not all(map(math.isfinite, a.tolist())):
        raise RenderError(f"{name} must be a finite 3-vector, got {v!r}")
    return a


def unit3(name: str, v: object) -> np.ndarray:
    """``v`` normalised; RenderError naming ``name`` unless it is a finite non-zero 3-vector."""
    a = finite3(name, v)
    n = math.sqrt(float(a.dot(a)))  # np.linalg.norm's formula, without its overhead (frames are made per period)
    if n < 1e-12:
        raise RenderError(f"{name} must be a non-zero vector, got {v!r}")
    return a / n


def unit_quat(name: str, q: object) -> np.ndarray:
    """``q`` [x, y, z, w] normalised; RenderError naming ``name`` unless it is a finite non-zero quaternion."""
    a = np.asarray(q, dtype=np.float64)
    n = math.sqrt(float(a.dot(a))) if a.shape == (4,) else 0.0
    if a.shape != (4,) or not all(map(math.isfinite, a.tolist())) or n < 1e-12:
        raise RenderError(f"{name} must be a non-zero finite quaternion [x, y, z, w], got {q!r}")
    return a / n


@dataclass(frozen=True, eq=False)
class Body:
    """One asteroid: centre (inertial, m), mean radius (m), shape, orientation (body -> inertial, [x, y, z, w])."""

    centre_inertial_m: np.ndarray
    radius_m: float
    shape: ShapeModel = ShapeModel()
    q_body_to_inertial: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 0.0, 1.0]))
    reflectance_factor: float = 1.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "centre_inertial_m", finite3("Body.centre_inertial_m", self.centre_inertial_m))
        object.__setattr__(self, "q_body_to_inertial", unit_quat("Body.q_body_to_inertial", self.q_body_to_inertial))
        if not (math.isfinite(self.radius_m) and self.radius_m > 0):
            raise RenderError(f"Body.radius_m must be a positive number, got {self.radius_m!r}")
        if not (math.isfinite(self.reflectance_factor) and self.reflectance_factor >= 0):
            raise RenderError(f"Body.reflectance_factor must be >= 0, got {self.reflectance_factor!r}")


@dataclass(frozen=True, eq=False)
class StarCatalogue:
    """Explicit stars: unit directions (N, 3) in the inertial frame and visual magnitudes (N,)."""

    directions_inertial: np.ndarray
    magnitudes: np.ndarray

    def __post_init__(self) -> None:
        d = np.asarray(self.directions_inertial, dtype=np.float64).reshape(-1, 3)
        m = np.asarray(self.magnitudes, dtype=np.float64).reshape(-1)
        if len(d) != len(m):
            raise RenderError(f"StarCatalogue: {len(d)} directions but {len(m)} magnitudes")
        n = np.linalg.norm(d, axis=1)
        if np.any(n < 1e-12) or not np.all(np.isfinite(d)) or not np.all(np.isfinite(m)):
            raise RenderError("StarCatalogue.directions_inertial must be finite non-zero vectors, magnitudes finite")
        object.__setattr__(self, "directions_inertial", d / n[:, None])
        object.__setattr__(self, "magnitudes", m)


@dataclass(frozen=True, eq=False)
class Scene:
    """Everything one frame depends on, at mid-exposure; all vectors inertial unless named otherwise.

    ``camera_velocity_m_s`` is the camera's velocity relative to the bodies (smears them, not the stars);
    ``plume_body_index`` names the body the ejecta leave from (None: no plume); ``star_seed`` selects the seeded
    all-sky star field (None: none), ``star_catalogue`` adds explicit stars.
    """

    camera_position_m: np.ndarray
    q_body_to_inertial: np.ndarray
    body_rate_rad_s: np.ndarray
    exposure_s: float
    bodies: tuple[Body, ...]
    sun_direction: np.ndarray
    time_since_impact_s: float | None = None
    star_seed: int | None = None
    star_catalogue: StarCatalogue | None = None
    blank: bool = False
    saturated: bool = False
    camera_velocity_m_s: np.ndarray = field(default_factory=lambda: np.zeros(3))
    plume_body_index: int | None = None
    plume_brightness_factor: float = 1.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "camera_position_m", finite3("Scene.camera_position_m", self.camera_position_m))
        object.__setattr__(self, "q_body_to_inertial", unit_quat("Scene.q_body_to_inertial", self.q_body_to_inertial))
        object.__setattr__(self, "body_rate_rad_s", finite3("Scene.body_rate_rad_s", self.body_rate_rad_s))
        object.__setattr__(self, "sun_direction", unit3("Scene.sun_direction", self.sun_direction))
        object.__setattr__(self, "camera_velocity_m_s", finite3("Scene.camera_velocity_m_s", self.camera_velocity_m_s))
        object.__setattr__(self, "bodies", tuple(self.bodies))
        if not (math.isfinite(self.exposure_s) and self.exposure_s > 0):
            raise RenderError(f"Scene.exposure_s must be a positive number of seconds, got {self.exposure_s!r}")
        for i, b in enumerate(self.bodies):
            if not isinstance(b, Body):
                raise RenderError(f"Scene.bodies[{i}] must be a Body, got {type(b).__name__}")
        if self.plume_body_index is not None and not 0 <= self.plume_body_index < len(self.bodies):
            raise RenderError(
                f"Scene.plume_body_index {self.plume_body_index} is not an index of the {len(self.bodies)} bodies"
            )
        if not (math.isfinite(self.plume_brightness_factor) and self.plume_brightness_factor >= 0):
            raise RenderError(f"Scene.plume_brightness_factor must be >= 0, got {self.plume_brightness_factor!r}")
        if self.time_since_impact_s is not None and not math.isfinite(self.time_since_impact_s):
            raise RenderError(f"Scene.time_since_impact_s must be finite or None, got {self.time_since_impact_s!r}")

