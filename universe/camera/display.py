"""Display of a frame: the 8-bit stretch of the saved PNGs and the operator's views."""

from __future__ import annotations

import math

import numpy as np

from universe.camera.scene import RenderError

_SOFT = 20.0  # asinh knee: faint signal gets most of the 8-bit range
_TOP_PERCENT = 99.99  # the stretch's white point, percentile of the frame


def frame_to_png8(frame: np.ndarray, bit_depth: int) -> np.ndarray:
    """8-bit display stretch of a frame: asinh between the median background and the brightest pixels."""
    if frame.ndim != 2:
        raise RenderError(f"frame_to_png8: frame must be 2-D, got shape {frame.shape}")
    if not 1 <= bit_depth <= 16:
        raise RenderError(f"frame_to_png8: bit_depth must be within [1, 16], got {bit_depth}")
    sample = frame[:: max(1, frame.shape[0] // 256), :: max(1, frame.shape[1] // 256)]
    lo = float(np.median(sample.astype(np.float32)))
    if frame.dtype.kind == "u" and frame.dtype.itemsize <= 2 and frame.size:
        # digital numbers: the percentile from their histogram and the stretch as a table of every value, the same
        # numbers as the float path at a tenth of its cost (no partition or arcsinh over a million pixels)
        hi = max(_percentile_of_counts(np.bincount(frame.ravel(), minlength=1 << bit_depth), _TOP_PERCENT), lo + 1.0)
        table = _stretch(np.arange(max(1 << bit_depth, int(frame.max()) + 1), dtype=np.float32), lo, hi)
        return table[frame]
    x = frame.astype(np.float32)
    hi = max(float(np.percentile(x, _TOP_PERCENT)), lo + 1.0)
    return _stretch(x, lo, hi)


def _stretch(x: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """The asinh stretch of float32 values between ``lo`` and ``hi``, to uint8."""
    y = np.arcsinh(np.clip((x - lo) / (hi - lo), 0.0, None) * _SOFT) / math.asinh(_SOFT)
    return np.clip(np.rint(y * 255.0), 0, 255).astype(np.uint8)


def _percentile_of_counts(counts: np.ndarray, percent: float) -> float:
    """``float(numpy.percentile(values.astype(float32), percent))`` of the values whose histogram is ``counts``
    (value v occurring counts[v] times): numpy's linear method, order statistics found in the cumulative counts."""
    n = int(counts.sum())
    virtual = (n - 1) * (percent / 100.0)
    below = min(max(int(math.floor(virtual)), 0), n - 1)
    above = min(below + 1, n - 1)
    cumulative = np.cumsum(counts)
    a, b = (np.float32(np.searchsorted(cumulative, k, side="right")) for k in (below, above))
    gamma = virtual - below
    # numpy's interpolation in the values' precision: from below, or from above past the midpoint
    diff = b - a
    return float(b - diff * (1 - gamma) if gamma >= 0.5 else a + diff * gamma)
