"""The 8-bit display stretch."""

from __future__ import annotations

import math

import numpy as np
import pytest

from universe.camera import frame_to_png8


def test_frame_to_png8_is_a_monotonic_8_bit_stretch() -> None:
    """The display stretch gives uint8 and never inverts the order of two pixel values."""
    rng = np.random.default_rng(0)
    frame = rng.integers(0, 4096, size=(64, 64)).astype(np.uint16)
    out = frame_to_png8(frame, 12)
    assert out.dtype == np.uint8 and out.shape == frame.shape
    order = np.argsort(frame.ravel(), kind="stable")
    assert np.all(np.diff(out.ravel()[order].astype(int)) >= 0)
    assert out.max() == 255


@pytest.mark.parametrize("seed, bit_depth, shape", [(1, 12, (256, 256)), (2, 12, (1024, 1024)), (3, 16, (97, 131)),
                                                    (4, 10, (300, 200)), (5, 12, (1, 1))])
def test_frame_to_png8_of_digital_numbers_equals_the_float_stretch(seed: int, bit_depth: int,
                                                                   shape: tuple[int, int]) -> None:
    """The stretch of uint16 frames (by histogram and table) gives the octets of the stretch in float32 computed
    with numpy's percentile over every pixel, on dark sky with a few bright targets."""
    rng = np.random.default_rng(seed)
    top = (1 << bit_depth) - 1
    frame = rng.normal(100, 8, size=shape)
    lit = rng.random(shape) < 0.01
    frame[lit] = rng.uniform(200, top, size=int(lit.sum()))
    frame = np.clip(np.rint(frame), 0, top).astype(np.uint16)
    x = frame.astype(np.float32)
    lo = float(np.median(x[:: max(1, x.shape[0] // 256), :: max(1, x.shape[1] // 256)]))
    hi = max(float(np.percentile(x, 99.99)), lo + 1.0)
    y = np.arcsinh(np.clip((x - lo) / (hi - lo), 0.0, None) * 20.0) / math.asinh(20.0)
    expected = np.clip(np.rint(y * 255.0), 0, 255).astype(np.uint8)
    assert np.array_equal(frame_to_png8(frame, bit_depth), expected)
