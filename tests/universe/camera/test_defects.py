"""The sensor's fixed defects: maps fixed by its seed, the configured counts and levels, dead pixels at the bias."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pydantic import ValidationError

from tests.universe.camera.common import NO_DEFECTS, scene
from universe.camera import Body, hot_pixels, render_frame, sensor_defects
from universe.config import CameraConfig, PlumeConfig
from universe.shapes import ShapeModel

DEFECTIVE = CameraConfig(dark_current_dsnu_e_s=15.0, warm_pixel_fraction=1e-3, dead_pixel_count=100,
                         dead_column_count=2)


def test_the_maps_are_fixed_by_the_seed() -> None:
    """Recomputed from scratch, the same seed gives the same maps; another seed moves every one of them. Hot pixels
    are those the sensor always had (the legacy seeded draw)."""
    a = sensor_defects(DEFECTIVE)
    sensor_defects.cache_clear()
    b = sensor_defects(DEFECTIVE)
    c = sensor_defects(DEFECTIVE.model_copy(update={"hot_pixel_seed": 8}))
    for name in ("hot_idx", "hot_e", "warm_idx", "warm_e_s", "dead_idx", "dead_columns", "dark_e_s"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
        assert not np.array_equal(getattr(a, name), getattr(c, name)), name
    idx, level = hot_pixels(7, 50, 1024, 8000.0)
    assert np.array_equal(a.hot_idx, idx) and np.array_equal(a.hot_e, level.astype(np.float32))


def test_counts_and_levels_are_the_configured_ones() -> None:
    """1e-3 of the pixels are warm, each at 20-100 % of the largest excess; 100 dead pixels and 2 dead columns, all
    distinct; with the defects off, none of them and a uniform dark current."""
    d = sensor_defects(DEFECTIVE)
    assert d.warm_idx.size == round(1e-3 * 1024 * 1024) == np.unique(d.warm_idx).size
    assert np.all((d.warm_e_s >= 0.2 * 2000.0) & (d.warm_e_s <= 2000.0))
    assert np.unique(d.dead_idx).size == 100 and np.unique(d.dead_columns).size == 2
    none = sensor_defects(CameraConfig(**NO_DEFECTS))
    assert none.warm_idx.size == none.dead_idx.size == none.dead_columns.size == 0 and none.dark_e_s is None


def test_dark_current_map_has_the_configured_mean_and_spread() -> None:
    """Each pixel's dark current is positive; over the sensor their mean is dark_current_e_s and their standard
    deviation dark_current_dsnu_e_s (to 3 standard errors of a million lognormal draws)."""
    dark = sensor_defects(DEFECTIVE).dark_e_s.astype(float)
    assert dark.shape == (1024, 1024) and dark.min() > 0
    assert dark.mean() == pytest.approx(50.0, abs=3 * 15.0 / 1024)
    assert dark.std() == pytest.approx(15.0, rel=0.01)


def test_dead_pixels_and_columns_read_the_bias_only() -> None:
    """In a frame lit by a body filling it, with every other effect on, dead pixels and columns read the offset and
    nothing else; the pixels beside them see the body."""
    cfg = DEFECTIVE.model_copy(update={"cosmic_ray_flux_cm2_s": 5.0})
    body = Body(np.array([0.0, 0.0, 9_000.0]), 390.0, ShapeModel(seed=6))
    frame = render_frame(scene((body,), sun=(0.4, 0.2, -1.0), star_seed=2), cfg, PlumeConfig(),
                         np.random.default_rng(8), np.random.default_rng(9))
    d = sensor_defects(cfg)
    assert np.all(frame.ravel()[d.dead_idx] == 64)
    assert np.all(frame[:, d.dead_columns] == 64)
    beside = np.setdiff1d(d.dead_columns + 1, d.dead_columns)
    beside = beside[beside < 1024]
    assert np.median(frame[:, beside]) > 64 + 200


def test_hot_and_warm_pixels_stay_put_from_frame_to_frame() -> None:
    """Two long dark exposures with different noise show their hot and warm pixels at the same places: the map's."""
    cfg = CameraConfig(**{**NO_DEFECTS, "warm_pixel_fraction": 1e-4}, read_noise_e=2.0)
    d = sensor_defects(cfg)
    s = scene(exposure_s=1.0, blank=True)
    found = []
    for seed in (1, 2):
        frame = render_frame(s, cfg, PlumeConfig(), np.random.default_rng(seed)).astype(float)
        # the dimmest warm pixel adds 400 e- (100 DN) over a dark level of 50 e- with ~8 e- of noise
        found.append(np.flatnonzero(frame > 64 + 50 / 4 + 40))
    expected = np.union1d(d.hot_idx, d.warm_idx)
    assert np.array_equal(found[0], expected) and np.array_equal(found[1], expected)


@pytest.mark.parametrize("update, field", [
    ({"dead_column_count": 1025}, "dead_column_count"),
    ({"dead_pixel_count": 1024 * 1024 + 1}, "dead_pixel_count"),
    ({"dark_current_e_s": 0.0, "dark_current_dsnu_e_s": 5.0}, "dark_current_dsnu_e_s"),
])
def test_impossible_defects_are_refused_naming_the_field(update: dict, field: str) -> None:
    """More dead columns or pixels than the sensor has, or a spread about a zero dark current: refused, named."""
    with pytest.raises(ValidationError, match=field):
        CameraConfig(**update)


def test_warm_pixels_grow_with_the_exposure_hot_pixels_do_not() -> None:
    """A warm pixel's excess is its dark current times the exposure; a hot pixel's is the same in every frame."""
    cfg = CameraConfig(**{**NO_DEFECTS, "warm_pixel_fraction": 1e-4}, read_noise_e=0.0, dark_current_e_s=0.0)
    d = sensor_defects(cfg)
    excess = []
    for exposure in (0.5, 1.0):
        frame = render_frame(scene(exposure_s=exposure, blank=True), cfg, PlumeConfig(), np.random.default_rng(1))
        excess.append((frame.astype(float) - 64) * cfg.gain_e_per_dn)
    warm = excess[1].ravel()[d.warm_idx] / excess[0].ravel()[d.warm_idx]
    hot = excess[1].ravel()[d.hot_idx] / excess[0].ravel()[d.hot_idx]
    # shot noise of ~1000 e-: a few per cent per pixel
    assert np.median(warm) == pytest.approx(2.0, rel=0.02)
    assert np.median(hot) == pytest.approx(1.0, rel=0.02)
    assert math.isclose(float(np.median(excess[1].ravel()[d.warm_idx] / d.warm_e_s)), 1.0, rel_tol=0.02)
