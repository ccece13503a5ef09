"""The bodies seen through the camera: silhouette, shading, occultation, smear and their pixel boxes."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from scipy import ndimage
from scipy.spatial.transform import Rotation

from tests.universe.camera.common import NO_DEFECTS, C_1024, F_1024, SPHERE, lit_pixels, scene
from universe.camera import Body, project_inertial, render_frame, scene_electrons
from universe.camera.bodies import body_box, render_scale
from universe.config import CameraConfig, PlumeConfig
from universe.shapes import ShapeModel, fibonacci_sphere


@pytest.mark.parametrize("offset_px", [(0.0, 0.0), (137.3, -211.6)])
def test_sphere_centroid_and_diameter_at_zero_phase(offset_px: tuple[float, float]) -> None:
    """A sphere at zero phase: centroid within 0.3 px of its pinhole centre, diameter within 1 px of 2 f atan(R/d)."""
    cfg = CameraConfig(hot_pixel_count=0, lommel_seeliger_weight=1.0)
    rng_m, radius = 55_000.0, 390.0
    direction = np.array([offset_px[0] / F_1024, offset_px[1] / F_1024, 1.0])
    centre = direction / np.linalg.norm(direction) * rng_m
    s = scene((Body(centre, radius, SPHERE),), sun=-centre / rng_m)
    frame = render_frame(s, cfg, PlumeConfig(), np.random.default_rng(1)).astype(float)
    dark = cfg.dark_offset_dn + cfg.dark_current_e_s * 0.01 / cfg.gain_e_per_dn
    excess = np.clip(frame - dark, 0, None)
    rows, cols = np.mgrid[0:1024, 0:1024]
    x0, y0 = C_1024 + offset_px[0], C_1024 + offset_px[1]
    window = np.hypot(cols - x0, rows - y0) < 200  # keeps the background noise out of the centroid
    w = excess * window
    assert (w * cols).sum() / w.sum() == pytest.approx(x0, abs=0.3)
    assert (w * rows).sum() / w.sum() == pytest.approx(y0, abs=0.3)
    plateau = np.median(excess[np.hypot(cols - x0, rows - y0) < 50])
    area = np.count_nonzero((excess > plateau / 2) & window)
    # the projected disc is a slightly elliptical off-axis; its area-equivalent diameter is f*2*atan(R/d)/cos^1.5
    off_axis = math.atan(math.hypot(*offset_px) / F_1024)
    expected = 2 * F_1024 * math.atan(radius / rng_m) / math.cos(off_axis) ** 1.5
    assert 2 * math.sqrt(area / math.pi) == pytest.approx(expected, abs=1.0)


def test_body_outside_field_leaves_frame_identical_to_empty_scene() -> None:
    """A body whose bounding sphere lies 20 px beyond the frame edge changes no pixel (same noise seed, stars on)."""
    cfg = CameraConfig()
    radius, rng_m = 390.0, 55_000.0
    reach = radius * ShapeModel(seed=3).max_radius()
    edge_angle = math.atan(532.0 / F_1024) + math.asin(reach / rng_m)
    centre = rng_m * np.array([math.sin(edge_angle), 0.0, math.cos(edge_angle)])
    sun = (-1.0, 0.0, -1.0)
    with_body = render_frame(
        scene((Body(centre, radius, ShapeModel(seed=3)),), sun=sun, star_seed=5), cfg, PlumeConfig(),
        np.random.default_rng(9),
    )
    empty = render_frame(scene((), sun=sun, star_seed=5), cfg, PlumeConfig(), np.random.default_rng(9))
    assert np.array_equal(with_body, empty)
    # the same body moved 40 px into the frame does show up
    inside_angle = edge_angle - math.atan(60.0 / F_1024)
    centre_in = rng_m * np.array([math.sin(inside_angle), 0.0, math.cos(inside_angle)])
    seen = render_frame(
        scene((Body(centre_in, radius, ShapeModel(seed=3)),), sun=sun, star_seed=5), cfg, PlumeConfig(),
        np.random.default_rng(9),
    )
    assert np.count_nonzero(seen != empty) > 1000


def test_terminator_at_90_deg_phase_lights_half_the_disc_on_the_sun_side() -> None:
    """At 90 deg phase about half the disc is lit, the half towards the projected Sun (+X here)."""
    cfg = CameraConfig(hot_pixel_count=0, phase_slope_mag_deg=0.0)
    rng_m, radius = 55_000.0, 390.0
    s = scene((Body(np.array([0.0, 0.0, rng_m]), radius, SPHERE),), sun=(1.0, 0.0, 0.0))
    frame = render_frame(s, cfg, PlumeConfig(), np.random.default_rng(4))
    lit = lit_pixels(frame, cfg, 30.0)
    disc_area = math.pi * (F_1024 * math.atan(radius / rng_m)) ** 2
    assert lit.sum() / disc_area == pytest.approx(0.5, abs=0.04)
    cols = np.nonzero(lit)[1]
    assert np.all(cols >= C_1024 - 3)  # nothing lit beyond the terminator


def test_body_behind_another_is_hidden_and_in_front_is_seen() -> None:
    """Occultation by depth: a small bright body behind a big one changes nothing; in front, it shows."""
    cfg = CameraConfig()
    big = Body(np.array([0.0, 0.0, 55_000.0]), 390.0, ShapeModel(seed=1), reflectance_factor=0.3)
    small_behind = Body(np.array([50.0, 30.0, 56_190.0]), 82.0, ShapeModel(seed=2))
    small_front = Body(np.array([50.0, 30.0, 53_810.0]), 82.0, ShapeModel(seed=2))
    sun = (0.0, 0.0, -1.0)
    alone = render_frame(scene((big,), sun=sun), cfg, PlumeConfig(), np.random.default_rng(3))
    behind = render_frame(scene((big, small_behind), sun=sun), cfg, PlumeConfig(), np.random.default_rng(3))
    front = render_frame(scene((small_front, big), sun=sun), cfg, PlumeConfig(), np.random.default_rng(3))
    assert np.array_equal(alone, behind)
    c, r = project_inertial(scene(), cfg, small_front.centre_inertial_m)
    patch = (slice(round(r) - 3, round(r) + 4), slice(round(c) - 3, round(c) + 4))
    assert front[patch].mean() > 2.0 * alone[patch].mean()


def test_rotated_ellipsoid_matches_closed_form_ray_intersection() -> None:
    """An ellipsoid (no bumps) matches the closed-form ray/ellipsoid silhouette and lunar-Lambert shading."""
    cfg = CameraConfig(hot_pixel_count=0, phase_slope_mag_deg=0.0, read_noise_e=0.0, dark_current_e_s=0.0,
                       body_signal_e_s=1.0e6, psf_sigma_px=0.31, **NO_DEFECTS)
    axes = np.array([1.3, 1.0, 0.8])
    radius, rng_m = 390.0, 40_000.0
    q_ast = Rotation.from_rotvec([0.3, -0.5, 0.2]).as_quat()
    centre = np.array([0.0, 0.0, rng_m])
    sun = np.array([0.6, -0.3, -1.0]) / np.linalg.norm([0.6, -0.3, -1.0])
    body = Body(centre, radius, ShapeModel(irregularity=0.0, axis_ratios=tuple(axes)), q_ast)
    frame = render_frame(scene((body,), sun=tuple(sun)), cfg, PlumeConfig(), np.random.default_rng(0))
    signal_e = (frame.astype(float) - cfg.dark_offset_dn) * cfg.gain_e_per_dn
    # closed form: rays from the origin through pixel centres against x^T A x = 1 in the body frame
    semi = radius * axes / np.prod(axes) ** (1 / 3)
    to_body = Rotation.from_quat(q_ast).as_matrix()  # columns: body axes in inertial
    rows, cols = np.mgrid[0:1024, 0:1024]
    d = np.stack([(cols - C_1024) / F_1024, (rows - C_1024) / F_1024, np.ones((1024, 1024))], axis=-1)
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    db, o = d @ to_body, -centre @ to_body
    a = np.sum((db / semi) ** 2, -1)
    b = 2 * np.sum(db * o / semi**2, -1)
    c = np.sum((o / semi) ** 2) - 1
    disc = b * b - 4 * a * c
    hit = disc >= 0
    t = (-b - np.sqrt(np.where(hit, disc, 0))) / (2 * a)
    x = o + t[..., None] * db
    n = (x / semi**2) @ to_body.T
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    mu0 = np.clip(n @ sun, 0, None)
    mu = np.clip(-np.sum(n * d, -1), 0, None)
    w = cfg.lommel_seeliger_weight
    expected = np.where(hit, 1.0e6 * 0.01 * (w * 2 * mu0 / np.maximum(mu0 + mu, 1e-12) + (1 - w) * mu0), 0.0)
    lit = expected > 0.2 * expected.max()
    seen = signal_e > 0.1 * expected.max()
    assert np.count_nonzero(lit & ~seen) + np.count_nonzero(seen & ~hit) < 0.005 * hit.sum()
    interior = ndimage.binary_erosion(lit, iterations=3)
    rel = np.abs(signal_e[interior] - expected[interior]) / expected.max()
    assert np.median(rel) < 0.005 and np.percentile(rel, 99) < 0.03


def test_camera_motion_smears_a_body_by_v_t_over_range() -> None:
    """A camera moving at v across the line of sight stretches a body's image variance by (v T f / range)^2 / 12."""
    cfg = CameraConfig(
        hot_pixel_count=0, read_noise_e=0.0, dark_current_e_s=0.0, lommel_seeliger_weight=1.0, body_signal_e_s=1e5,
        **NO_DEFECTS
    )
    rng_m, exposure = 55_000.0, 0.05
    body = Body(np.array([0.0, 0.0, rng_m]), 100.0, SPHERE)
    still = scene((body,), exposure_s=exposure)
    moving = scene((body,), exposure_s=exposure, camera_velocity_m_s=np.array([0.0, 300.0, 0.0]))
    moments = []
    for s in (still, moving):
        img = render_frame(s, cfg, PlumeConfig(), np.random.default_rng(0)).astype(float) - cfg.dark_offset_dn
        rows = np.arange(1024)[:, None]
        m = img.sum()
        yc = (img * rows).sum() / m
        moments.append((yc, (img * (rows - yc) ** 2).sum() / m))
    length_px = 300.0 * exposure / rng_m * F_1024
    assert moments[1][1] - moments[0][1] == pytest.approx(length_px**2 / 12, rel=0.05)
    assert moments[1][0] == pytest.approx(moments[0][0], abs=0.05)


@settings(max_examples=40, deadline=None)
@given(
    direction=st.tuples(st.floats(-0.05, 0.05), st.floats(-0.05, 0.05)),
    range_m=st.floats(2e3, 2e6),
    radius_m=st.floats(10.0, 1000.0),
)
def test_body_box_holds_the_projection_of_its_bounding_sphere(
    direction: tuple[float, float], range_m: float, radius_m: float
) -> None:
    """Every pinhole projection of a point of the sphere lies in the box, and the box is at most 4 px wider per side."""
    assume(radius_m < 0.5 * range_m)
    f, (cx, cy) = F_1024, (C_1024, C_1024)
    centre = np.array([direction[0], direction[1], 1.0])
    centre = centre / np.linalg.norm(centre) * range_m
    box = body_box(centre, radius_m, f, cx, cy, 1024, 0)
    pts = centre + radius_m * fibonacci_sphere(4000)
    col = cx + f * pts[:, 0] / pts[:, 2]
    row = cy + f * pts[:, 1] / pts[:, 2]
    seen = (col > -0.5) & (col < 1023.5) & (row > -0.5) & (row < 1023.5)
    if box is None:
        assert not seen.any()
        return
    r0, r1, c0, c1 = box
    ic, ir = np.rint(col[seen]), np.rint(row[seen])
    assert np.all((ir >= r0) & (ir < r1) & (ic >= c0) & (ic < c1))
    if seen.all():  # the whole sphere in the frame: the box is tight
        assert r0 >= ir.min() - 4 and r1 <= ir.max() + 5 and c0 >= ic.min() - 4 and c1 <= ic.max() + 5


def test_a_streak_too_long_for_the_frame_s_pixels_keeps_the_light_and_the_closed_form_length() -> None:
    """A body smeared 600 px (rendered at 1/4 resolution and resampled): the same total light as unsmeared, the
    image variance along the motion grown by L^2 / 12, across it by less than the 4 px of the coarser pixels."""
    cfg = CameraConfig(hot_pixel_count=0, read_noise_e=0.0, dark_current_e_s=0.0, lommel_seeliger_weight=1.0,
                       **NO_DEFECTS)
    rng_m, exposure, length_px = 55_000.0, 0.05, 600.0
    speed = length_px * rng_m / (exposure * F_1024)
    assert render_scale(cfg.psf_sigma_px, length_px) == 4
    body = Body(np.array([0.0, 0.0, rng_m]), 100.0, SPHERE)
    moments = []
    for v in (0.0, speed):
        e = scene_electrons(scene((body,), exposure_s=exposure, camera_velocity_m_s=np.array([0.0, v, 0.0])), cfg,
                            PlumeConfig()).astype(float)
        rows, cols = np.mgrid[0:1024, 0:1024]
        m = e.sum()
        yc, xc = (e * rows).sum() / m, (e * cols).sum() / m
        moments.append((m, yc, (e * (rows - yc) ** 2).sum() / m, (e * (cols - xc) ** 2).sum() / m))
    (m0, y0, along0, across0), (m1, y1, along1, across1) = moments
    assert m1 == pytest.approx(m0, rel=0.01)
    assert y1 == pytest.approx(y0, abs=0.5)
    assert along1 - along0 == pytest.approx(length_px**2 / 12, rel=0.01)
    assert 0.0 <= across1 - across0 < 16.0
