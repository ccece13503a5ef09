"""The stars: the seeded sky follows the star-count law and stays fixed; a star lands where it projects."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import ndimage
from scipy.spatial.transform import Rotation

from tests.universe.camera.common import C_1024, F_1024, scene
from universe.camera import StarCatalogue, focal_length_px, render_frame, scene_electrons, sky_stars
from universe.camera.stars import _add_star_trails, _cell_stars
from universe.config import CameraConfig, PlumeConfig


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


def test_a_trail_of_point_images_matches_the_closed_form_streak() -> None:
    """The long-streak method (point images half a sigma apart along the true path) draws a 60 px streak as the closed
    form (Gaussian times a line) does: the same light in every pixel to 1 % of the peak, the same total to 0.5 %."""
    cfg = CameraConfig(psf_sigma_px=1.2)
    omega = np.array([0.0, math.radians(17.0), math.radians(5.0)])  # 60 px in 0.01 s, roll included
    d = np.array([[(300.3 - C_1024) / F_1024, (640.8 - C_1024) / F_1024, 1.0]])
    d /= np.linalg.norm(d)
    closed = scene_electrons(scene(body_rate_rad_s=omega, star_catalogue=StarCatalogue(d, np.array([1.0]))),
                             cfg, PlumeConfig())
    trail = np.zeros((1024, 1024), dtype=np.float32)
    _add_star_trails(d, np.array([1.0]), 0.01, cfg, omega, F_1024, C_1024, C_1024, trail, [])
    assert np.max(np.abs(trail - closed)) < 0.01 * closed.max()
    assert trail.sum() == pytest.approx(closed.sum(), rel=5e-3)


def test_a_streak_longer_than_the_stamps_is_a_uniform_line_of_the_star_s_light() -> None:
    """Turning 0.04 rad in the exposure (an 809 px streak): the star's whole light, centred on its mid-exposure
    pixel, spread along |omega| T f with the variance of a uniform segment, L^2/12 + sigma^2."""
    cfg = CameraConfig(hot_pixel_count=0)
    omega = np.array([0.8, 0.6, 0.0]) * 4.0
    exposure = 0.01
    s = scene(body_rate_rad_s=omega, exposure_s=exposure,
              star_catalogue=StarCatalogue(np.array([[0.0, 0.0, 1.0]]), np.array([-1.0])))
    e = scene_electrons(s, cfg, PlumeConfig()).astype(float)
    flux = cfg.star_mag0_e_s * 10 ** 0.4 * exposure
    assert e.sum() == pytest.approx(flux, rel=2e-3)
    rows, cols = np.mgrid[0:1024, 0:1024]
    x, y = cols - C_1024, rows - C_1024
    assert abs((e * x).sum() / flux) < 0.5 and abs((e * y).sum() / flux) < 0.5
    along = (-x * omega[1] + y * omega[0]) / np.linalg.norm(omega[:2])  # image motion runs along (-w_y, w_x)
    length = np.linalg.norm(omega) * exposure * F_1024
    assert (e * along**2).sum() / flux == pytest.approx(length**2 / 12 + cfg.psf_sigma_px**2, rel=0.01)
