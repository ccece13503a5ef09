"""The compiled truth geometry agrees with the NumPy forms of its formulas to rounding, at any time and attitude."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from universe.config import BodiesConfig, FlybyConfig
from universe.dynamics import body_to_inertial_matrices
from universe.geometry import FlybyGeometry, camera_axes_body


def _angles(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    c = np.cross(a, b)
    return np.arctan2(np.linalg.norm(c, axis=-1), np.sum(a * b, axis=-1))


def _numpy_truth(g: FlybyGeometry, t: np.ndarray, q: np.ndarray, boresight: np.ndarray,
                 fov_deg: float) -> dict[str, np.ndarray]:
    """The truth samples in NumPy, from the geometry's own positions and velocities."""
    r_sc = g.spacecraft_position_m(t)
    to_dim = g.dimorphos_position_m(t) - r_sc
    to_did = g.didymos_position_m(t) - r_sc
    los_dim = to_dim / np.linalg.norm(to_dim, axis=1)[:, None]
    los_did = to_did / np.linalg.norm(to_did, axis=1)[:, None]
    rot = body_to_inertial_matrices(q)
    axes = camera_axes_body(boresight)
    los_body = np.einsum("nji,nj->ni", rot, los_dim)
    los_cam = los_body @ axes.T
    half_tan = np.tan(np.radians(fov_deg) / 2.0)
    return {
        "range_to_dimorphos_m": np.linalg.norm(to_dim, axis=1), "range_to_didymos_m": np.linalg.norm(to_did, axis=1),
        "los_dimorphos_inertial": los_dim, "los_didymos_inertial": los_did, "los_dimorphos_body": los_body,
        "los_dimorphos_camera": los_cam,
        "theta_rad": _angles(g.spacecraft_velocity_m_s(t) - g.dimorphos_velocity_m_s(t), los_dim),
        "phase_angle_deg": np.degrees(_angles(np.broadcast_to(g.sun_direction(), los_dim.shape), -los_dim)),
        "pointing_error_rad": _angles(rot @ axes[2], los_dim),
        "target_in_fov": (los_cam[:, 2] > 0) & (np.abs(los_cam[:, 0]) <= half_tan * los_cam[:, 2])
        & (np.abs(los_cam[:, 1]) <= half_tan * los_cam[:, 2]),
    }


_unit = st.floats(-1.0, 1.0, allow_nan=False)


@settings(max_examples=100, deadline=None)
@given(times=st.lists(st.floats(-400.0, 400.0), min_size=1, max_size=12),
       quats=st.lists(st.lists(_unit, min_size=4, max_size=4), min_size=12, max_size=12),
       boresight=st.lists(_unit, min_size=3, max_size=3), phase_deg=st.floats(0.0, 360.0),
       fov_deg=st.floats(1.0, 60.0))
def test_truth_samples_agree_with_the_numpy_forms(times: list[float], quats: list[list[float]],
                                                  boresight: list[float], phase_deg: float, fov_deg: float) -> None:
    """Every field of ``truth_samples`` within 1e-12 (relative for ranges) of NumPy's evaluation of the same
    formulas; the in-field flag equal wherever the centre is not within 1e-12 of the field's edge."""
    g = FlybyGeometry(FlybyConfig(), BodiesConfig(orbit_phase_deg=phase_deg))
    t = np.array(times)
    q = np.array([v if np.linalg.norm(v) > 0.1 else [0.0, 0.0, 0.0, 1.0] for v in quats[:t.size]])
    q = q / np.linalg.norm(q, axis=1)[:, None]
    b = np.array(boresight) if np.linalg.norm(boresight) > 0.1 else np.array([0.0, 0.0, 1.0])
    got = g.truth_samples(t, q, b, fov_deg)
    want = _numpy_truth(g, t, q, b, fov_deg)
    for name in ("range_to_dimorphos_m", "range_to_didymos_m"):
        np.testing.assert_allclose(getattr(got, name), want[name], rtol=1e-13, err_msg=name)
    for name in ("los_dimorphos_inertial", "los_didymos_inertial", "los_dimorphos_body", "los_dimorphos_camera",
                 "theta_rad", "pointing_error_rad"):
        np.testing.assert_allclose(getattr(got, name), want[name], rtol=0, atol=1e-12, err_msg=name)
    np.testing.assert_allclose(got.phase_angle_deg, want["phase_angle_deg"], rtol=0, atol=1e-10)
    cam = want["los_dimorphos_camera"]
    edge = np.tan(np.radians(fov_deg) / 2.0) * cam[:, 2]
    clear = (np.abs(cam[:, 2]) > 1e-12) & (np.abs(np.abs(cam[:, 0]) - edge) > 1e-12) & \
        (np.abs(np.abs(cam[:, 1]) - edge) > 1e-12)
    assert np.array_equal(got.target_in_fov[clear], want["target_in_fov"][clear])
