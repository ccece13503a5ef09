"""Floating-point results computed two ways, compared in units in the last place (ulps).

A compiled kernel repeats NumPy's arithmetic in the same order, and gives its bits where NumPy sums small dot and
matrix products in index order; on some processors (AVX-512 among them) NumPy dispatches those to SIMD kernels with
fused multiply-adds, which round a few values one or two ulps apart. The tests hold such pairs to a few ulps of the
largest magnitude compared, not to their bits.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike


def assert_within_ulps(got: ArrayLike, want: ArrayLike, ulps: float = 4.0, magnitude: float = 0.0) -> None:
    """``got`` equals ``want`` (same shape) within ``ulps`` units in the last place of the largest magnitude of
    either, or of ``magnitude`` when larger (the terms a result was computed from: a difference of nearly equal terms
    keeps their rounding, not its own); non-finite values must match exactly."""
    g, w = np.asarray(got, dtype=float), np.asarray(want, dtype=float)
    assert g.shape == w.shape, (g.shape, w.shape)
    finite = np.isfinite(g) & np.isfinite(w)
    assert np.array_equal(g[~finite], w[~finite], equal_nan=True), (g.tolist(), w.tolist())
    if not finite.any():
        return
    scale = float(np.spacing(max(float(np.abs(g[finite]).max()), float(np.abs(w[finite]).max()), abs(magnitude),
                                 np.finfo(float).tiny)))
    worst = float(np.abs(g[finite] - w[finite]).max())
    assert worst <= ulps * scale, f"{worst / scale:.1f} ulps apart: {g.tolist()} vs {w.tolist()}"
