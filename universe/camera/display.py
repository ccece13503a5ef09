"""Display of a frame: the 8-bit stretch of the saved PNGs and the operator's views."""

from __future__ import annotations

import math

import cv2
import numpy as np
from numba import njit

from universe.camera.scene import RenderError

_SOFT = 20.0  # asinh knee: faint signal gets most of the 8-bit range
_TOP_PERCENT = 99.99  # the stretch's white point, percentile of the frame


def frame_to_png8(frame: np.ndarray, bit_depth: int) -> np.ndarray:
    """8-bit display stretch of a frame: asinh between the median background and the brightest pixels."""
    if frame.ndim != 2:
        raise RenderError(f"frame_to_png8: frame must be 2-D, got shape {frame.shape}")
    if not 1 <= bit_depth <= 16:
        raise RenderError(f"frame_to_png8: bit_depth must be within [1, 16], got {bit_depth}")
    if frame.dtype.kind == "u" and frame.dtype.itemsize <= 2 and frame.size:
        return _stretch_table(frame, bit_depth)[frame]
    sample = frame[:: max(1, frame.shape[0] // 256), :: max(1, frame.shape[1] // 256)]
    lo = float(np.median(sample.astype(np.float32)))
    x = frame.astype(np.float32)
    hi = max(float(np.percentile(x, _TOP_PERCENT)), lo + 1.0)
    return _stretch(x, lo, hi)


def display_png8(frame: np.ndarray, bit_depth: int, size_px: int) -> np.ndarray:
    """``frame_to_png8`` resampled to ``size_px`` square: area averaging to shrink (OpenCV's ``INTER_AREA``), nearest
    pixel to grow. A frame of digital numbers shrunk by a whole factor takes one compiled pass for the histogram and
    one for the table and the averaging, octet for octet OpenCV's (its rounding of each block's mean):
    a saved PNG's image costs 1.9 ms a 1024 px frame instead of 5.6 (8 instead of 30 at 2048 px), and the passes
    release the GIL the universe's loop runs under (``bench/speed.py``)."""
    if frame.ndim != 2:
        raise RenderError(f"display_png8: frame must be 2-D, got shape {frame.shape}")
    if size_px < 1:
        raise RenderError(f"display_png8: size_px must be at least 1, got {size_px}")
    h, w = frame.shape
    factor = h // size_px
    whole = h == w and factor >= 1 and factor * size_px == h
    if whole and frame.dtype.kind == "u" and frame.dtype.itemsize <= 2 and 1 <= bit_depth <= 16:
        return _block_means(np.ascontiguousarray(frame), _stretch_table(frame, bit_depth), factor)
    img = frame_to_png8(frame, bit_depth)
    if img.shape != (size_px, size_px):
        shrink = size_px < img.shape[0]
        img = cv2.resize(img, (size_px, size_px), interpolation=cv2.INTER_AREA if shrink else cv2.INTER_NEAREST)
    return img


def _stretch_table(frame: np.ndarray, bit_depth: int) -> np.ndarray:
    """The stretch of a non-empty frame of digital numbers as a table of every value up to its largest: the
    percentile from their histogram, the same numbers as the float path at a tenth of its cost (no partition or
    arcsinh over a million pixels)."""
    sample = frame[:: max(1, frame.shape[0] // 256), :: max(1, frame.shape[1] // 256)]
    lo = float(np.median(sample.astype(np.float32)))
    counts, top = _counts_and_top(np.ascontiguousarray(frame))
    values = max(1 << bit_depth, int(top) + 1)
    hi = max(_percentile_of_counts(counts[:values], _TOP_PERCENT), lo + 1.0)
    return _stretch(np.arange(values, dtype=np.float32), lo, hi)


@njit(cache=True, nogil=True)
def _counts_and_top(frame: np.ndarray) -> tuple[np.ndarray, int]:
    """How many pixels hold each value (0 to 65535), and the largest value."""
    counts = np.zeros(1 << 16, np.int64)
    top = 0
    for v in frame.ravel():
        counts[v] += 1
        top = max(top, v)
    return counts, top


@njit(cache=True, nogil=True)
def _block_means(frame: np.ndarray, table: np.ndarray, factor: int) -> np.ndarray:
    """Each ``factor`` x ``factor`` block's mean of ``table[frame]``, rounded as OpenCV's area resampling rounds it:
    half up for 2 x 2 blocks (its own path), half to even for larger ones."""
    n_rows, n_cols = frame.shape[0] // factor, frame.shape[1] // factor
    out = np.empty((n_rows, n_cols), np.uint8)
    inv_area = 1.0 / (factor * factor)
    for i in range(n_rows):
        for j in range(n_cols):
            total = 0
            for a in range(i * factor, (i + 1) * factor):
                for b in range(j * factor, (j + 1) * factor):
                    total += table[frame[a, b]]
            out[i, j] = np.uint8((total + 2) // 4) if factor == 2 else np.uint8(np.rint(total * inv_area))
    return out


def warm_up() -> None:
    """Compile (or load from the cache) the display passes now."""
    display_png8(np.zeros((4, 4), dtype=np.uint16), 12, 2)


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
