"""The camera renders what a pinhole camera would see: geometry, photometry, smear, noise and faults."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from scipy import ndimage, stats
from scipy.spatial.transform import Rotation

from universe.camera import (
    NORMAL_QUANTILES,
    Body,
    RenderError,
    Scene,
    StarCatalogue,
    _body_box,
    _cell_stars,
    _merged_boxes,
    _tan_multiples,
    focal_length_px,
    frame_to_png8,
    normal_codes,
    plume_cross_section_m2,
    project_inertial,
    psf_kernel,
    quat_matrix,
    render_frame,
    scene_electrons,
    sky_stars,
)
from universe.config import CameraConfig, PlumeConfig
from universe.shapes import ShapeModel, fibonacci_sphere

SPHERE = ShapeModel(irregularity=0.0)
IDENTITY = np.array([0.0, 0.0, 0.0, 1.0])
F_1024 = 512.0 / math.tan(math.radians(2.9) / 2.0)  # closed-form focal length of the default camera, px
C_1024 = 511.5


def scene(bodies: tuple[Body, ...] = (), sun=(0.0, 0.0, -1.0), **kw) -> Scene:
    """Camera at the origin, body axes = inertial axes (boresight +Z), at rest."""
    base = dict(
        camera_position_m=np.zeros(3),
        q_body_to_inertial=IDENTITY,
        body_rate_rad_s=np.zeros(3),
        exposure_s=0.01,
        bodies=bodies,
        sun_direction=np.array(sun),
    )
    base.update(kw)
    return Scene(**base)


def lit_pixels(frame: np.ndarray, cfg: CameraConfig, level_dn: float) -> np.ndarray:
    """Mask of pixels above the dark level by more than ``level_dn``."""
    dark = cfg.dark_offset_dn + cfg.dark_current_e_s * 0.01 / cfg.gain_e_per_dn
    return frame.astype(float) - dark > level_dn


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


def test_psf_kernel_moments_match_gaussian_plus_line() -> None:
    """The smeared kernel sums to 1, is centred, and has variance sigma^2 + L^2/12 along the smear."""
    sigma, lx, ly = 1.2, 9.0, -4.0
    k = psf_kernel(sigma, (lx, ly)).astype(float)
    h = k.shape[0] // 2
    y, x = np.mgrid[-h : h + 1, -h : h + 1]
    assert k.sum() == pytest.approx(1.0, abs=1e-6)
    assert (k * x).sum() == pytest.approx(0.0, abs=1e-6) and (k * y).sum() == pytest.approx(0.0, abs=1e-6)
    length = math.hypot(lx, ly)
    along = (x * lx + y * ly) / length
    across = (-x * ly + y * lx) / length
    assert (k * along**2).sum() == pytest.approx(sigma**2 + length**2 / 12, rel=0.02)
    assert (k * across**2).sum() == pytest.approx(sigma**2, rel=0.02)


@pytest.mark.parametrize("rate_deg_s", [(0.0, 1.5, 0.0), (-0.8, 0.6, 0.0)])
def test_star_streak_length_is_rate_times_exposure_over_ifov(rate_deg_s: tuple[float, float, float]) -> None:
    """A star's streak has length |omega| T / IFOV and runs along (-omega_y, omega_x) in the image."""
    cfg = CameraConfig(hot_pixel_count=0, psf_sigma_px=0.8)
    omega = np.deg2rad(rate_deg_s)
    exposure = 0.05
    star = StarCatalogue(np.array([[0.0, 0.0, 1.0]]), np.array([0.5]))
    s = scene(body_rate_rad_s=omega, exposure_s=exposure, star_catalogue=star)
    frame = render_frame(s, cfg, PlumeConfig(), np.random.default_rng(2)).astype(float)
    dark = cfg.dark_offset_dn + cfg.dark_current_e_s * exposure / cfg.gain_e_per_dn
    win = frame[512 - 40 : 512 + 40, 512 - 40 : 512 + 40] - dark
    y, x = np.mgrid[-40:40, -40:40] + 512 - C_1024
    # keep the streak and its PSF wings (dilated bright core), drop the read noise elsewhere
    win = np.where(ndimage.binary_dilation(win > 15, iterations=3), win, 0.0)
    xc, yc = (win * x).sum() / win.sum(), (win * y).sum() / win.sum()
    dx, dy = x - xc, y - yc
    cov = np.array([[(win * dx * dx).sum(), (win * dx * dy).sum()], [(win * dx * dy).sum(), (win * dy * dy).sum()]])
    cov /= win.sum()
    evals, evecs = np.linalg.eigh(cov)
    length = math.sqrt(12 * (evals[1] - cfg.psf_sigma_px**2))
    expected = np.linalg.norm(omega[:2]) * exposure * F_1024
    assert length == pytest.approx(expected, rel=0.05)
    direction = np.array([-omega[1], omega[0]]) / np.linalg.norm(omega[:2])
    assert abs(evecs[:, 1] @ direction) > 0.999
    assert math.hypot(xc, yc) < 0.3  # the geometry is at mid-exposure


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


def test_same_seed_same_frame_other_seed_other_noise() -> None:
    """Rendering is deterministic for a seed; another seed changes the noise only."""
    cfg = CameraConfig()
    s = scene((Body(np.array([0.0, 0.0, 55_000.0]), 390.0, ShapeModel(seed=4)),), sun=(0.5, 0.0, -1.0), star_seed=1)
    a = render_frame(s, cfg, PlumeConfig(), np.random.default_rng(11))
    b = render_frame(s, cfg, PlumeConfig(), np.random.default_rng(11))
    c = render_frame(s, cfg, PlumeConfig(), np.random.default_rng(12))
    assert np.array_equal(a, b)
    diff = a.astype(float) - c.astype(float)
    assert np.count_nonzero(diff) > 0.5 * diff.size
    assert abs(diff.mean()) < 0.05


@settings(max_examples=12, deadline=None)
@given(bit_depth=st.integers(8, 16), exposure_s=st.floats(1e-4, 1.0), seed=st.integers(0, 2**32 - 1))
def test_values_stay_within_the_bit_depth(bit_depth: int, exposure_s: float, seed: int) -> None:
    """Every pixel is within [0, 2^bit_depth - 1], from underexposed to saturated scenes."""
    cfg = CameraConfig(bit_depth=bit_depth, resolution_px=1024)
    s = scene(
        (Body(np.array([0.0, 0.0, 55_000.0]), 390.0, ShapeModel(seed=seed % 100)),),
        sun=(0.3, 0.0, -1.0),
        exposure_s=exposure_s,
        star_seed=seed,
    )
    frame = render_frame(s, cfg, PlumeConfig(), np.random.default_rng(seed))
    assert frame.dtype == np.uint16 and frame.shape == (1024, 1024)
    assert int(frame.max()) <= 2**bit_depth - 1


def test_photon_transfer_of_a_uniform_disc() -> None:
    """Inside a zero-phase Lommel-Seeliger disc: mean = offset + (S + dark)/g, var = (S + dark + read^2)/g^2 + 1/12."""
    cfg = CameraConfig(hot_pixel_count=0, lommel_seeliger_weight=1.0, body_signal_e_s=1.0e6)
    s = scene((Body(np.array([0.0, 0.0, 20_000.0]), 390.0, SPHERE),), sun=(0.0, 0.0, -1.0))
    frame = render_frame(s, cfg, PlumeConfig(), np.random.default_rng(5)).astype(float)
    inner = frame[462:562, 462:562]  # well within the 1280 px disc
    signal_e, dark_e = 1.0e6 * 0.01, cfg.dark_current_e_s * 0.01
    g = cfg.gain_e_per_dn
    assert inner.mean() == pytest.approx(cfg.dark_offset_dn + (signal_e + dark_e) / g, abs=0.2)
    assert inner.var() == pytest.approx((signal_e + dark_e + cfg.read_noise_e**2) / g**2 + 1 / 12, rel=0.04)


def test_blank_frame_is_dark_noise_and_hot_pixels_at_fixed_places() -> None:
    """A blank frame holds only bias, dark and read noise, and the same hot pixels whatever the noise seed."""
    cfg = CameraConfig(hot_pixel_count=30)
    s = scene((Body(np.array([0.0, 0.0, 55_000.0]), 390.0, SPHERE),), star_seed=3, blank=True)
    a = render_frame(s, cfg, PlumeConfig(), np.random.default_rng(1)).astype(float)
    b = render_frame(s, cfg, PlumeConfig(), np.random.default_rng(2)).astype(float)
    dark_e = cfg.dark_current_e_s * 0.01
    sigma_dn = math.sqrt(dark_e + cfg.read_noise_e**2) / cfg.gain_e_per_dn
    hot_a = np.flatnonzero(a > cfg.dark_offset_dn + 20 * sigma_dn)
    hot_b = np.flatnonzero(b > cfg.dark_offset_dn + 20 * sigma_dn)
    assert len(hot_a) == 30 and np.array_equal(hot_a, hot_b)
    rest = np.delete(a.ravel(), hot_a)
    assert rest.mean() == pytest.approx(cfg.dark_offset_dn + dark_e / cfg.gain_e_per_dn, abs=0.01)
    assert rest.std() == pytest.approx(math.sqrt(sigma_dn**2 + 1 / 12), rel=0.01)


def test_saturated_frame_is_full_scale() -> None:
    """The saturated fault gives every pixel 2^bit_depth - 1."""
    cfg = CameraConfig(bit_depth=12)
    frame = render_frame(scene(saturated=True), cfg, PlumeConfig(), np.random.default_rng(0))
    assert np.all(frame == 4095)


def test_normal_codes_give_standard_normal_deviates() -> None:
    """Inverse-CDF deviates from 16-bit codes: KS-indistinguishable from N(0, 1), uncorrelated between draws."""
    rng = np.random.default_rng(123)
    z1 = NORMAL_QUANTILES[normal_codes(rng, (200_000,))].astype(float)
    z2 = NORMAL_QUANTILES[normal_codes(rng, (200_000,))].astype(float)
    assert stats.kstest(z1, "norm").pvalue > 0.01
    assert abs(z1.mean()) < 0.01 and z1.std() == pytest.approx(1.0, abs=0.01)
    assert abs(np.corrcoef(z1, z2)[0, 1]) < 0.01
    assert abs(np.corrcoef(z1[:-1], z1[1:])[0, 1]) < 0.01


def test_sky_star_count_follows_the_star_count_law() -> None:
    """Stars brighter than the limit in the field average 4800 * 10^(0.46 (m - 6)) / 41253 per square degree."""
    cfg = CameraConfig(star_limiting_mag=10.0)
    rng = np.random.default_rng(8)
    counts = []
    f = focal_length_px(cfg)
    for q in Rotation.random(60, random_state=rng).as_quat():
        c2i = Rotation.from_quat(q).as_matrix()
        dirs, mags = sky_stars(1, c2i, cfg)
        v = dirs @ c2i
        with np.errstate(divide="ignore", invalid="ignore"):
            col = C_1024 + f * v[:, 0] / v[:, 2]
            row = C_1024 + f * v[:, 1] / v[:, 2]
        inside = (v[:, 2] > 0) & (np.abs(col - C_1024) < 512) & (np.abs(row - C_1024) < 512)
        counts.append(int(inside.sum()))
        assert np.all(mags <= 10.0)
    per_field = 4800 * 10 ** (0.46 * 4) / 41253 * (2 * math.degrees(math.atan(512 / f))) ** 2
    assert np.mean(counts) == pytest.approx(per_field, abs=4 * math.sqrt(per_field / len(counts)))


def test_star_field_is_fixed_on_the_sky() -> None:
    """The same seed gives the same inertial stars whatever the pointing that asked for them."""
    cfg = CameraConfig()
    a_dirs, a_mags = sky_stars(4, np.eye(3), cfg)
    tilt = Rotation.from_rotvec([0.0, math.radians(1.0), 0.0]).as_matrix()
    b_dirs, b_mags = sky_stars(4, tilt, cfg)
    common = {tuple(np.round(d, 12)) for d in a_dirs} & {tuple(np.round(d, 12)) for d in b_dirs}
    assert len(common) > 0.5 * len(a_dirs) > 5


def test_star_renders_at_its_pinhole_position_with_its_flux() -> None:
    """A catalogue star's light is centred on its projection and sums to mag0 flux * 10^(-0.4 m) * T / gain."""
    cfg = CameraConfig(hot_pixel_count=0)
    col, row = 300.3, 700.8
    d = np.array([(col - C_1024) / F_1024, (row - C_1024) / F_1024, 1.0])
    star = StarCatalogue(d[None, :], np.array([2.0]))
    frame = render_frame(scene(star_catalogue=star), cfg, PlumeConfig(), np.random.default_rng(6)).astype(float)
    dark = cfg.dark_offset_dn + cfg.dark_current_e_s * 0.01 / cfg.gain_e_per_dn
    win = frame[690:712, 290:312] - dark
    y, x = np.mgrid[690:712, 290:312]
    assert (win * x).sum() / win.sum() == pytest.approx(col, abs=0.1)
    assert (win * y).sum() / win.sum() == pytest.approx(row, abs=0.1)
    expected_dn = cfg.star_mag0_e_s * 10 ** (-0.4 * 2.0) * 0.01 / cfg.gain_e_per_dn
    assert win.sum() == pytest.approx(expected_dn, rel=0.03)


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


def test_frame_to_png8_is_a_monotonic_8_bit_stretch() -> None:
    """The display stretch gives uint8 and never inverts the order of two pixel values."""
    rng = np.random.default_rng(0)
    frame = rng.integers(0, 4096, size=(64, 64)).astype(np.uint16)
    out = frame_to_png8(frame, 12)
    assert out.dtype == np.uint8 and out.shape == frame.shape
    order = np.argsort(frame.ravel(), kind="stable")
    assert np.all(np.diff(out.ravel()[order].astype(int)) >= 0)
    assert out.max() == 255


def test_bad_inputs_raise_named_errors() -> None:
    """Invalid scene fields raise RenderError naming the field."""
    with pytest.raises(RenderError, match="exposure_s"):
        scene(exposure_s=0.0)
    with pytest.raises(RenderError, match="sun_direction"):
        scene(sun=(0.0, 0.0, 0.0))
    with pytest.raises(RenderError, match="plume_body_index"):
        scene(plume_body_index=0)
    with pytest.raises(RenderError, match="radius_m"):
        Body(np.zeros(3), -1.0)
    with pytest.raises(RenderError, match="inside"):
        render_frame(
            scene((Body(np.array([0.0, 0.0, 100.0]), 390.0, SPHERE),)), CameraConfig(), PlumeConfig(),
            np.random.default_rng(0),
        )


# ------------------------------------------------------------------------------------------------ shapes


def test_zero_irregularity_unit_axes_is_a_sphere() -> None:
    """With no bumps and equal axes the radius is 1 everywhere and the normal is radial."""
    u = fibonacci_sphere(500)
    r, n = SPHERE.radius_and_normal(u)
    assert np.allclose(r, 1.0) and np.allclose(n, u)


def test_shape_irregularity_is_the_rms_radius_perturbation() -> None:
    """For equal axes, the RMS of r - 1 over the sphere equals the requested irregularity."""
    shape = ShapeModel(seed=5, irregularity=0.1)
    r = shape.radius(fibonacci_sphere(30000))
    assert np.sqrt(np.mean((r - 1.0) ** 2)) == pytest.approx(0.1, rel=0.03)
    assert r.min() >= shape.min_radius() and r.max() <= shape.max_radius()


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 1000), irr=st.floats(0.0, 0.2))
def test_shape_normal_is_orthogonal_to_the_surface(seed: int, irr: float) -> None:
    """The analytic normal is orthogonal to finite-difference tangents of the surface r(u) u."""
    shape = ShapeModel(seed=seed, irregularity=irr, axis_ratios=(1.2, 1.0, 0.9))
    u = fibonacci_sphere(50)
    u = u[np.abs(u[:, 2]) < 0.95]
    r, n = shape.radius_and_normal(u)
    t1 = np.cross(u, [0.0, 0.0, 1.0])
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(u, t1)
    eps = 1e-6
    for t in (t1, t2):
        ua = (u + eps * t) / np.linalg.norm(u + eps * t, axis=1, keepdims=True)
        ub = (u - eps * t) / np.linalg.norm(u - eps * t, axis=1, keepdims=True)
        tangent = shape.radius(ua)[:, None] * ua - shape.radius(ub)[:, None] * ub
        tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
        assert np.all(np.abs(np.sum(tangent * n, axis=1)) < 1e-5)


def test_shape_table_lookup_matches_direct_evaluation() -> None:
    """The interpolated table radius agrees with the analytic radius to 1e-3 of the mean radius."""
    shape = ShapeModel(seed=2, irregularity=0.12, axis_ratios=(1.1, 1.0, 0.95))
    u = fibonacci_sphere(5000)
    look = shape.lookup(u[:, 0].reshape(50, 100), u[:, 1].reshape(50, 100), u[:, 2].reshape(50, 100))
    assert np.max(np.abs(look[..., 0].ravel() - shape.radius(u))) < 1e-3


def test_rotated_ellipsoid_matches_closed_form_ray_intersection() -> None:
    """An ellipsoid (no bumps) matches the closed-form ray/ellipsoid silhouette and lunar-Lambert shading."""
    cfg = CameraConfig(hot_pixel_count=0, phase_slope_mag_deg=0.0, read_noise_e=0.0, dark_current_e_s=0.0,
                       body_signal_e_s=1.0e6, psf_sigma_px=0.31)
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
        hot_pixel_count=0, read_noise_e=0.0, dark_current_e_s=0.0, lommel_seeliger_weight=1.0, body_signal_e_s=1e5
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


# ------------------------------------------------------------------------------------------------ fast paths


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 90), st.integers(1, 40), st.integers(0, 90), st.integers(1, 40)), max_size=8))
def test_merged_boxes_are_disjoint_and_cover_every_box(raw: list[tuple[int, int, int, int]]) -> None:
    """Merged boxes do not overlap, each input box lies in one of them, and each is the bounding box of its inputs."""
    boxes = [(r, r + h, c, c + w) for r, h, c, w in raw]
    merged = _merged_boxes(boxes)
    for i, a in enumerate(merged):
        for b in merged[i + 1 :]:
            assert not (a[0] < b[1] and b[0] < a[1] and a[2] < b[3] and b[2] < a[3])
    for b in boxes:
        assert sum(m[0] <= b[0] and b[1] <= m[1] and m[2] <= b[2] and b[3] <= m[3] for m in merged) == 1
    for m in merged:
        inside = [b for b in boxes if m[0] <= b[0] and b[1] <= m[1] and m[2] <= b[2] and b[3] <= m[3]]
        assert (min(b[0] for b in inside), max(b[1] for b in inside)) == (m[0], m[1])
        assert (min(b[2] for b in inside), max(b[3] for b in inside)) == (m[2], m[3])


@pytest.mark.parametrize("range_m", [120_000.0, 9_000.0])
def test_frame_moments_follow_the_detector_model_pixel_by_pixel(range_m: float) -> None:
    """(DN - offset - (S + dark)/g) / sqrt((S + dark + read^2)/g^2 + 1/12) has mean 0 and variance 1 over the frame.

    S is the scene's expected electrons per pixel; at 120 km the body fills a small box (dark look-up table elsewhere),
    at 9 km it fills the frame (one full-frame pass).
    """
    cfg = CameraConfig(hot_pixel_count=0)
    body = Body(np.array([30.0, -20.0, range_m]), 390.0, ShapeModel(seed=6))
    s = scene((body,), sun=(0.4, 0.2, -1.0), star_seed=2)
    expected_e = scene_electrons(s, cfg, PlumeConfig())
    lit = (expected_e > 100).mean()
    assert lit < 0.02 if range_m > 1e5 else lit > 0.9  # a small box / the whole frame
    frame = render_frame(s, cfg, PlumeConfig(), np.random.default_rng(21)).astype(float)
    dark_e = cfg.dark_current_e_s * 0.01
    g = cfg.gain_e_per_dn
    mean = cfg.dark_offset_dn + (expected_e + dark_e) / g
    sd = np.sqrt((expected_e + dark_e + cfg.read_noise_e**2) / g**2 + 1 / 12)
    z = (frame - mean) / sd
    assert abs(z.mean()) < 0.005
    assert z.var() == pytest.approx(1.0, abs=0.01)


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
    box = _body_box(centre, radius_m, f, cx, cy, 1024, 0)
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


def test_sky_stars_hold_every_catalogue_star_in_the_field() -> None:
    """For random attitudes, every star of the whole seeded sky that projects into the frame is in sky_stars."""
    cfg = CameraConfig(star_limiting_mag=8.0)
    k = 32
    whole = [_cell_stars(3, face, i, j, 8.0)[0] for face in range(6) for i in range(k) for j in range(k)]
    sky = np.concatenate([d for d in whole if len(d)])
    for q in Rotation.random(25, random_state=np.random.default_rng(4)).as_quat():
        c2i = Rotation.from_quat(q).as_matrix()
        v = sky @ c2i
        front = v[:, 2] > 0
        col = C_1024 + F_1024 * v[front, 0] / v[front, 2]
        row = C_1024 + F_1024 * v[front, 1] / v[front, 2]
        in_field = sky[front][(np.abs(col - C_1024) < 520) & (np.abs(row - C_1024) < 520)]
        dirs, _ = sky_stars(3, c2i, cfg)
        have = {tuple(np.round(d, 12)) for d in dirs}
        assert all(tuple(np.round(d, 12)) in have for d in in_field)


def test_tan_multiples_match_tan() -> None:
    """The rotation recurrence gives tan(frac_j * angle) for angles up to 89.9 deg."""
    angle = np.linspace(0.0, math.radians(89.9), 500)
    frac = (np.arange(8) + 0.5) / 8
    assert np.allclose(_tan_multiples(angle, frac), np.tan(frac[:, None] * angle[None]), rtol=1e-9, atol=1e-12)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-1.0, 1.0), min_size=4, max_size=4))
def test_quat_matrix_matches_scipy(q: list[float]) -> None:
    """quat_matrix of a unit quaternion is scipy's Rotation.as_matrix for it."""
    v = np.array(q)
    assume(np.linalg.norm(v) > 0.1)
    v /= np.linalg.norm(v)
    assert np.allclose(quat_matrix(v), Rotation.from_quat(v).as_matrix(), atol=1e-12)
