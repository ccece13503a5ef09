"""Pinhole geometry of the camera: focal length, principal point, camera axes, projection and image motion.

``fov_deg`` spans the full width, pixels are square, the principal point is the frame centre ``((W-1)/2, (H-1)/2)``,
the boresight is ``CameraConfig.boresight_body`` (body +Z by default); image columns increase along camera +X (body
+X by default), rows along camera +Y.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from scipy.spatial.transform import Rotation

from universe.camera.scene import RenderError, Scene
from universe.config import CameraConfig


def focal_length_px(cfg: CameraConfig) -> float:
    """Focal length in pixels: ``fov_deg`` spans the full frame width."""
    return 0.5 * cfg.resolution_px / math.tan(math.radians(cfg.fov_deg) / 2.0)


def principal_point_px(cfg: CameraConfig) -> tuple[float, float]:
    """(col, row) of the principal point: the frame centre."""
    c = (cfg.resolution_px - 1) / 2.0
    return c, c


@lru_cache(maxsize=64)
def _camera_to_body(boresight: tuple[float, float, float]) -> np.ndarray:
    b = np.asarray(boresight, dtype=np.float64)
    b = b / np.linalg.norm(b)
    if np.allclose(b, [0.0, 0.0, 1.0]):
        return np.eye(3)
    if np.allclose(b, [0.0, 0.0, -1.0]):
        return Rotation.from_rotvec([np.pi, 0.0, 0.0]).as_matrix()
    # minimal rotation taking camera +Z onto the boresight
    axis = np.cross([0.0, 0.0, 1.0], b)
    angle = math.atan2(float(np.linalg.norm(axis)), float(b[2]))
    return Rotation.from_rotvec(axis / np.linalg.norm(axis) * angle).as_matrix()


def camera_to_inertial_matrix(scene: Scene, cfg: CameraConfig) -> np.ndarray:
    """3x3 matrix taking camera-frame vectors to the inertial frame."""
    return camera_to_inertial(scene.q_body_to_inertial, cfg)


def camera_to_inertial(q_body_to_inertial: np.ndarray, cfg: CameraConfig) -> np.ndarray:
    """3x3 matrix taking camera-frame vectors to the inertial frame, in the attitude of a unit [x, y, z, w]."""
    # ndarray.dot: the same product as matmul's (tested to the bit), without the generalised ufunc's set-up
    return quat_matrix(q_body_to_inertial).dot(_camera_to_body(tuple(cfg.boresight_body)))


def project_inertial(scene: Scene, cfg: CameraConfig, point_inertial: np.ndarray) -> tuple:
    """Pinhole (col, row) of inertial point(s) (3,) or (N, 3) in metres; NaN for points behind the camera."""
    p = np.asarray(point_inertial, dtype=np.float64)
    if p.shape[-1:] != (3,):
        raise RenderError(f"project_inertial: point_inertial must have shape (3,) or (N, 3), got {p.shape}")
    return project_camera((p - scene.camera_position_m) @ camera_to_inertial_matrix(scene, cfg), cfg)


def project_camera(v: np.ndarray, cfg: CameraConfig) -> tuple:
    """Pinhole (col, row) of camera-frame vector(s) (3,) or (N, 3) from the camera; NaN for points behind it."""
    f = focal_length_px(cfg)
    cx, cy = principal_point_px(cfg)
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(v[..., 2] > 0, v[..., 2], np.nan)
        col = cx + f * v[..., 0] / z
        row = cy + f * v[..., 1] / z
    if v.ndim == 1:
        return float(col), float(row)
    return col, row


def image_velocity_px_s(v_c: np.ndarray, dv_c: np.ndarray, f: float) -> np.ndarray:
    """Image-plane velocity (dcol/dt, drow/dt) of camera-frame vectors ``v_c`` moving at ``dv_c`` (..., 3)."""
    z = v_c[..., 2]
    return np.stack(
        [
            f * (dv_c[..., 0] * z - v_c[..., 0] * dv_c[..., 2]) / (z * z),
            f * (dv_c[..., 1] * z - v_c[..., 1] * dv_c[..., 2]) / (z * z),
        ],
        axis=-1,
    )

def quat_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrix of a unit quaternion [x, y, z, w] (scipy's order), without Rotation's ~50 us of overhead."""
    x, y, z, w = float(q[0]), float(q[1]), float(q[2]), float(q[3])
    return np.array([
        [1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - z * w), 2.0 * (x * z + y * w)],
        [2.0 * (x * y + z * w), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - x * w)],
        [2.0 * (x * z - y * w), 2.0 * (y * z + x * w), 1.0 - 2.0 * (x * x + y * y)],
    ])


def cross3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross product of two 3-vectors (np.cross costs ~50 us of argument handling)."""
    a0, a1, a2 = float(a[0]), float(a[1]), float(a[2])
    b0, b1, b2 = float(b[0]), float(b[1]), float(b[2])
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def view_basis(e3: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    helper = np.array([1.0, 0.0, 0.0]) if abs(e3[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = cross3(helper, e3)
    e1 /= math.sqrt(float(e1 @ e1))
    return e1, cross3(e3, e1)

