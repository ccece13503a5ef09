"""The 8-bit display stretch."""

from __future__ import annotations

import numpy as np

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
