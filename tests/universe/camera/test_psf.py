"""The point-spread function with motion smear."""

from __future__ import annotations

import math

import numpy as np
import pytest

from universe.camera import psf_kernel


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
