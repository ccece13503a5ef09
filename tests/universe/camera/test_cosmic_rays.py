"""Cosmic rays: a Poisson number of hits over the sensor and the exposure, streaks of an isotropic flux, their charge
on the pixels along them."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from tests.universe.camera.common import NO_DEFECTS, scene
from universe.camera import CosmicRays, cosmic_rays, deposit, render_frame
from universe.config import CameraConfig, PlumeConfig

CFG = CameraConfig(cosmic_ray_flux_cm2_s=5.0)
SENSOR_CM2 = (1024 * 5.5e-4) ** 2  # 1024 pixels of 5.5 um a side


def test_hit_count_is_poisson_with_the_flux_times_area_times_exposure() -> None:
    """Over 4000 exposures of 1.9 s at 5 /cm^2/s on a 0.317 cm^2 sensor: mean and variance of the count both equal
    flux x area x exposure (Poisson), within four standard errors."""
    exposure = 1.9
    rate = 5.0 * SENSOR_CM2 * exposure
    rng = np.random.default_rng(1)
    counts = np.array([cosmic_rays(CFG, exposure, rng).col.size for _ in range(4000)])
    n = counts.size
    assert counts.mean() == pytest.approx(rate, abs=4 * math.sqrt(rate / n))
    assert counts.var(ddof=1) == pytest.approx(rate, abs=4 * math.sqrt((rate + 2 * rate**2) / n))


def test_streaks_have_the_lengths_and_directions_of_an_isotropic_flux() -> None:
    """In-plane directions and positions are uniform; lengths follow P(L <= l) = 1 - 1 / (1 + (l pitch / depth)^2)
    (cos^2 of the zenith angle uniform for an isotropic flux crossing a plane); the charge is the path in silicon
    times the charge per micrometre."""
    rng = np.random.default_rng(2)
    hits = [cosmic_rays(CFG, 200.0, rng) for _ in range(60)]
    angle = np.concatenate([h.angle_rad for h in hits])
    length = np.concatenate([h.length_px for h in hits])
    col = np.concatenate([h.col for h in hits])
    charge = np.concatenate([h.charge_e for h in hits])
    assert angle.size > 15_000
    assert stats.kstest(angle, stats.uniform(0.0, math.pi).cdf).pvalue > 0.01
    assert stats.kstest(col, stats.uniform(-0.5, 1024.0).cdf).pvalue > 0.01
    ratio = CFG.pixel_pitch_um / CFG.cosmic_ray_depth_um
    assert stats.kstest(length, lambda l: 1.0 - 1.0 / (1.0 + (np.asarray(l) * ratio) ** 2)).pvalue > 0.01
    path_um = np.sqrt((length * CFG.pixel_pitch_um) ** 2 + CFG.cosmic_ray_depth_um**2)
    np.testing.assert_allclose(charge, 80.0 * path_um, rtol=1e-12)


def test_a_streak_deposits_its_whole_charge_along_its_line() -> None:
    """A streak inside the sensor leaves all its charge, on pixels within half a diagonal of its line and spanning its
    length; a streak running off the sensor leaves only the part on it."""
    hits = CosmicRays(col=np.array([400.2, 1020.0]), row=np.array([300.7, 50.0]), angle_rad=np.array([0.6, 0.0]),
                      length_px=np.array([37.0, 20.0]), charge_e=np.array([5000.0, 2000.0]))
    flat, electrons = deposit(hits, 1024)
    rows, cols = flat // 1024, flat % 1024
    first = rows > 100
    assert electrons[first].sum() == pytest.approx(5000.0, rel=1e-6)
    e = np.array([math.cos(0.6), math.sin(0.6)])
    dx, dy = cols[first] - 400.2, rows[first] - 300.7
    assert np.all(np.abs(-dx * e[1] + dy * e[0]) <= math.sqrt(0.5) + 1e-9)
    along = dx * e[0] + dy * e[1]
    assert along.min() == pytest.approx(-18.5, abs=1.0) and along.max() == pytest.approx(18.5, abs=1.0)
    # the second runs from column 1010 to 1030: the sensor ends at 1023.5, keeping 13.5 px of its 20
    assert electrons[~first].sum() == pytest.approx(2000.0 * 13.5 / 20, rel=0.02)


def test_cosmic_rays_only_add_charge_where_they_hit() -> None:
    """Drawn from their own generator, cosmic rays leave every other pixel of a frame as it was, and add their charge
    (to within its shot noise) where they hit."""
    quiet = CameraConfig(read_noise_e=0.0, dark_current_e_s=0.0, hot_pixel_count=0, **NO_DEFECTS)
    hit = quiet.model_copy(update={"cosmic_ray_flux_cm2_s": 50.0})
    s = scene(exposure_s=1.0, blank=True)
    a = render_frame(s, quiet, PlumeConfig(), np.random.default_rng(3)).astype(float)
    b = render_frame(s, hit, PlumeConfig(), np.random.default_rng(3), np.random.default_rng(4)).astype(float)
    flat, electrons = deposit(cosmic_rays(hit, 1.0, np.random.default_rng(4)), 1024)
    touched = np.zeros(1024 * 1024, dtype=bool)
    touched[flat] = True
    assert np.array_equal(a.ravel()[~touched], b.ravel()[~touched])
    excess_e = (b - a).sum() * hit.gain_e_per_dn
    total = float(electrons.sum())
    assert total > 1e4
    assert excess_e == pytest.approx(total, abs=5 * math.sqrt(total) + 0.5 * hit.gain_e_per_dn * touched.sum())
