"""Display of a frame: the 8-bit stretch of the saved PNGs and the operator's views."""

from __future__ import annotations

import math

import numpy as np

from universe.camera.scene import RenderError


def frame_to_png8(frame: np.ndarray, bit_depth: int) -> np.ndarray:
    """8-bit display stretch of a frame: asinh between the median background and the brightest pixels."""
    if frame.ndim != 2:
        raise RenderError(f"frame_to_png8: frame must be 2-D, got shape {frame.shape}")
    if not 1 <= bit_depth <= 16:
        raise RenderError(f"frame_to_png8: bit_depth must be within [1, 16], got {bit_depth}")
    x = frame.astype(np.float32)
    lo = float(np.median(x[:: max(1, x.shape[0] // 256), :: max(1, x.shape[1] // 256)]))
    hi = max(float(np.percentile(x, 99.99)), lo + 1.0)
    soft = 20.0  # asinh knee: faint signal gets most of the 8-bit range
    y = np.arcsinh(np.clip((x - lo) / (hi - lo), 0.0, None) * soft) / math.asinh(soft)
    return np.clip(np.rint(y * 255.0), 0, 255).astype(np.uint8)
