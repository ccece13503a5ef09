"""The 8-bit display stretch."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

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


@pytest.mark.parametrize("seed, bit_depth, n, size", [(1, 12, 2048, 512), (2, 12, 1024, 512), (3, 16, 512, 256),
                                                      (4, 10, 300, 100), (5, 12, 512, 512), (6, 12, 500, 128),
                                                      (7, 12, 128, 512)])
def test_display_png8_equals_opencv_area_resampling_of_the_stretch(seed: int, bit_depth: int, n: int,
                                                                   size: int) -> None:
    """The saved frames' display image is OpenCV's area resampling (nearest pixel to grow) of the 8-bit stretch, octet
    for octet, for whole and fractional shrink factors alike."""
    import cv2

    from universe.camera import display_png8

    rng = np.random.default_rng(seed)
    top = (1 << bit_depth) - 1
    frame = rng.normal(150, 20, size=(n, n))
    lit = rng.random((n, n)) < 0.02
    frame[lit] = rng.uniform(300, top, size=int(lit.sum()))
    frame = np.clip(np.rint(frame), 0, top).astype(np.uint16)
    img = frame_to_png8(frame, bit_depth)
    expected = img if size == n else cv2.resize(
        img, (size, size), interpolation=cv2.INTER_AREA if size < n else cv2.INTER_NEAREST)
    assert np.array_equal(display_png8(frame, bit_depth, size), expected)


@settings(max_examples=60, deadline=None)
@given(size=st.integers(1, 96), factor=st.integers(1, 6), extra=st.integers(0, 3), bit_depth=st.integers(8, 16),
       seed=st.integers(0, 2**32 - 1), lit=st.floats(0.05, 1.0))
def test_display_png8_equals_opencv_for_any_size_and_factor(size: int, factor: int, extra: int, bit_depth: int,
                                                            seed: int, lit: float) -> None:
    """For any square frame of digital numbers, shrunk by a whole factor or not (``extra`` px more), the display
    image is OpenCV's area resampling of the 8-bit stretch, octet for octet."""
    import cv2

    from universe.camera import display_png8

    n = size * factor + extra
    rng = np.random.default_rng(seed)
    top = (1 << bit_depth) - 1
    frame = np.clip(rng.normal(0.05 * top, 0.01 * top + 1, size=(n, n)), 0, top)
    bright = rng.random((n, n)) < lit
    frame[bright] = rng.uniform(0, top, size=int(bright.sum()))
    frame = np.rint(frame).astype(np.uint16)
    img = frame_to_png8(frame, bit_depth)
    expected = img if n == size else cv2.resize(img, (size, size), interpolation=cv2.INTER_AREA)
    assert np.array_equal(display_png8(frame, bit_depth, size), expected)
