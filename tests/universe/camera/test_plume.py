"""The ejecta plume: its cross-section law and where it shows after the impact."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tests.universe.camera.common import C_1024, F_1024, SPHERE, scene
from universe.camera import Body, plume_cross_section_m2, render_frame, scene_electrons
from universe.config import CameraConfig, PlumeConfig


def test_plume_cross_section_law() -> None:
    """A(t) = A0 (1 - exp(-t/rise)) exp(-t/fade), zero before the impact."""
    p = PlumeConfig(cross_section_m2=5e6, rise_time_s=3.0, fade_time_s=100.0)
    assert plume_cross_section_m2(p, -1.0) == 0.0
    for t in (0.5, 3.0, 50.0):
        assert plume_cross_section_m2(p, t) == pytest.approx(5e6 * (1 - math.exp(-t / 3)) * math.exp(-t / 100))


def test_plume_appears_after_impact_along_its_axis() -> None:
    """No plume before the impact; after it, the extra light lies on the side of the projected cone axis."""
    cfg = CameraConfig(hot_pixel_count=0)
    plume = PlumeConfig(axis_inertial=(0.0, 1.0, 0.0), speed_m_s=50.0)
    dim = Body(np.array([0.0, 0.0, 55_000.0]), 82.0, SPHERE)
    kw = dict(sun=(0.0, 0.0, -1.0), plume_body_index=0)
    before = render_frame(scene((dim,), time_since_impact_s=None, **kw), cfg, plume, np.random.default_rng(1))
    at_zero = render_frame(scene((dim,), time_since_impact_s=-5.0, **kw), cfg, plume, np.random.default_rng(1))
    after = render_frame(scene((dim,), time_since_impact_s=20.0, **kw), cfg, plume, np.random.default_rng(1))
    assert np.array_equal(before, at_zero)
    extra = after.astype(float) - before.astype(float)
    rows = np.nonzero(extra > 20)[0]
    assert rows.size > 500
    assert np.median(rows) > C_1024 + 5  # the axis is inertial +Y, image rows
    reach_px = F_1024 * 50.0 * 20.0 / 55_000.0
    assert rows.max() < C_1024 + reach_px + 5


def test_from_inside_the_cloud_a_line_of_sight_counts_only_what_lies_ahead() -> None:
    """On the cone axis 3 km from the source, inside a 6 km cloud, looking outward along the axis: the optical depth
    is the 1/r^2 density integrated from the camera to the front only, A / (Omega R b) (atan(R/b) - atan(D/b)) with
    b the source's half radius (the density's core), not through the whole cloud behind."""
    cfg = CameraConfig(phase_slope_mag_deg=0.0)
    plume = PlumeConfig(axis_inertial=(0.0, 0.0, 1.0))
    t_s, dist = 120.0, 3_000.0
    src = Body(np.array([0.0, 0.0, -dist]), 82.0, SPHERE)
    s = scene((src,), sun=(0.0, 0.0, 1.0), plume_body_index=0, time_since_impact_s=t_s)
    e = scene_electrons(s, cfg, plume)
    front, b = plume.speed_m_s * t_s, 0.5 * src.radius_m
    omega = 2 * math.pi * (1 - math.cos(math.radians(plume.half_angle_deg)))
    tau = plume_cross_section_m2(plume, t_s) / (omega * front * b) * (math.atan(front / b) - math.atan(dist / b))
    expected = cfg.body_signal_e_s * -math.expm1(-tau) * 0.01
    assert e[508:516, 508:516].mean() == pytest.approx(expected, rel=0.01)
