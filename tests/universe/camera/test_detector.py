"""The detector: noise statistics, bit depth, hot pixels, blank and saturated frames, readout paths."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats

from tests.universe.camera.common import NO_DEFECTS, SPHERE, scene
from scenario import compose
from scenario.model import Scenario
from universe.camera import NORMAL_QUANTILES, Body, dark_frame, normal_codes, render_frame, scene_electrons
from universe.camera.detector import merged_boxes
from universe.config import CameraConfig, PlumeConfig, UniverseConfig
from universe.shapes import ShapeModel


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


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 90), st.integers(1, 40), st.integers(0, 90), st.integers(1, 40)), max_size=8))
def test_merged_boxes_are_disjoint_and_cover_every_box(raw: list[tuple[int, int, int, int]]) -> None:
    """Merged boxes do not overlap, each input box lies in one of them, and each is the bounding box of its inputs."""
    boxes = [(r, r + h, c, c + w) for r, h, c, w in raw]
    merged = merged_boxes(boxes)
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
    cfg = CameraConfig(hot_pixel_count=0, **NO_DEFECTS)
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


def test_dark_frame_statistics_follow_the_dark_current_and_its_non_uniformity() -> None:
    """A 20 s dark frame: mean offset + m T / g, variance (s T / g)^2 + (m T + read^2) / g^2 + 1/12 for a dark current
    of mean m and pixel-to-pixel spread s (no scene, no hot or warm pixels): the spread recovered to 2 %."""
    cfg = CameraConfig(hot_pixel_count=0, **{**NO_DEFECTS, "dark_current_dsnu_e_s": 15.0})
    exposure, g, m, s = 20.0, cfg.gain_e_per_dn, cfg.dark_current_e_s, 15.0
    frame = dark_frame(cfg, exposure, np.random.default_rng(4)).astype(float)
    assert frame.mean() == pytest.approx(cfg.dark_offset_dn + m * exposure / g, abs=0.05)
    shot_read = (m * exposure + cfg.read_noise_e**2) / g**2 + 1 / 12
    assert frame.var() == pytest.approx((s * exposure / g) ** 2 + shot_read, rel=0.02)
    assert math.sqrt(frame.var() - shot_read) * g / exposure == pytest.approx(s, rel=0.02)


def test_dark_frame_is_a_blank_frame_and_the_universe_keeps_one_per_run() -> None:
    """dark_frame is the frame of a blank scene with the same generators; the universe's dark frame is drawn once
    from its own stream (the same on every call, the same for the same seed) and leaves the camera's stream alone."""
    cfg = CameraConfig(dark_current_dsnu_e_s=15.0, warm_pixel_fraction=1e-3, dead_column_count=1,
                       cosmic_ray_flux_cm2_s=5.0)
    a = dark_frame(cfg, 0.5, np.random.default_rng(1), np.random.default_rng(2))
    b = render_frame(scene(exposure_s=0.5, blank=True), cfg, PlumeConfig(), np.random.default_rng(1),
                     np.random.default_rng(2))
    assert np.array_equal(a, b)
    sc = Scenario(name="dark", seed=5, universe=UniverseConfig(camera=cfg))
    u, v = compose.universe(sc), compose.universe(sc)
    camera_state = u.rng["camera"].bit_generator.state
    first = u.dark_frame(0.5)
    assert u.dark_frame(0.5) is first and np.array_equal(first, v.dark_frame(0.5))
    assert u.rng["camera"].bit_generator.state == camera_state
    assert not np.array_equal(u.dark_frame(), first)  # another exposure, another frame
    assert first.dtype == np.uint16 and first.shape == (1024, 1024) and int(first.max()) <= 4095
