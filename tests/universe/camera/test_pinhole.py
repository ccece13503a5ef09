"""The pinhole model: focal length from the field of view, projection, camera axes."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from tests.universe.camera.common import C_1024, F_1024, scene
from universe.camera import focal_length_px, project_inertial, quat_matrix
from universe.config import CameraConfig


def test_pinhole_focal_length_matches_fov() -> None:
    """f = (W/2) / tan(fov/2) for 1024 and 2048 px frames."""
    assert focal_length_px(CameraConfig()) == pytest.approx(F_1024, rel=1e-12)
    assert focal_length_px(CameraConfig(resolution_px=2048)) == pytest.approx(2 * F_1024, rel=1e-12)


@settings(max_examples=40, deadline=None)
@given(
    q=st.lists(st.floats(-1, 1), min_size=4, max_size=4).filter(lambda v: sum(x * x for x in v) > 0.1),
    col=st.floats(0, 1023),
    row=st.floats(0, 1023),
    depth=st.floats(1e3, 1e7),
)
def test_project_inertial_inverts_the_body_frame_ray(q: list[float], col: float, row: float, depth: float) -> None:
    """A point along the body-frame ray ((c - cx)/f, (r - cy)/f, 1), rotated to inertial, projects to (c, r)."""
    cam = np.array([1e5, -2e4, 3e3])
    s = scene(camera_position_m=cam, q_body_to_inertial=np.array(q))
    ray_body = np.array([(col - C_1024) / F_1024, (row - C_1024) / F_1024, 1.0]) * depth
    point = cam + Rotation.from_quat(q).apply(ray_body)
    c, r = project_inertial(s, CameraConfig(), point)
    assert c == pytest.approx(col, abs=1e-6) and r == pytest.approx(row, abs=1e-6)


def test_point_behind_camera_projects_to_nan() -> None:
    """A point behind the image plane has no pixel."""
    c, r = project_inertial(scene(), CameraConfig(), np.array([0.0, 0.0, -10.0]))
    assert math.isnan(c) and math.isnan(r)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-1.0, 1.0), min_size=4, max_size=4))
def test_quat_matrix_matches_scipy(q: list[float]) -> None:
    """quat_matrix of a unit quaternion is scipy's Rotation.as_matrix for it."""
    v = np.array(q)
    assume(np.linalg.norm(v) > 0.1)
    v /= np.linalg.norm(v)
    assert np.allclose(quat_matrix(v), Rotation.from_quat(v).as_matrix(), atol=1e-12)
