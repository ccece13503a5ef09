"""Step 3 of the imaging chain, object detection: 8-connected component labelling of the binarised image.

Run-length encoding and a union-find of touching runs of adjacent rows (compiled: ``imaging_kernels.label_runs``);
labels are numbered in raster order of each component's first pixel (OpenCV's ``connectedComponentsWithStats``
numbering), with per component the area, the binary centroid (pixel centres at integer coordinates), the bounding
box and the elongation from the second central moments.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from obsw.imaging_filtering import FrameError
from obsw.imaging_kernels import label_runs


@dataclass(frozen=True, slots=True)
class Components:
    """Per-component statistics of a binary image, components in raster order of their first pixel."""

    area_px: np.ndarray  # int64 (K,)
    centroid_col: np.ndarray  # float64 (K,)
    centroid_row: np.ndarray
    left: np.ndarray  # int64 (K,)
    top: np.ndarray
    width: np.ndarray
    height: np.ndarray
    elongation: np.ndarray  # float64 (K,)
    pixel_index: np.ndarray  # flat indices of the foreground pixels, raster order (N,)
    pixel_component: np.ndarray  # component (0-based) of each foreground pixel (N,)


def _with_words(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The mask as a contiguous boolean array and its rows as 64-bit words (none when the width is not a multiple of
    eight): ``label_runs``'s arguments."""
    m = np.ascontiguousarray(mask, dtype=np.bool_)
    if m.shape[1] % 8 or m.shape[1] == 0:
        return m, np.zeros((1, 0), dtype=np.uint64)
    return m, m.view(np.uint64)


_NONE = np.zeros(0, dtype=np.int64)


def connected_components(mask: np.ndarray, working: tuple[np.ndarray, np.ndarray] | None = None) -> Components:
    """Return the 8-connected components of a 2-D boolean image with their area, centroid, box and shape;
    ``working``: two int64 buffers of the mask's size (``imaging_filtering.working_buffers``) that the pixels' indices
    and components are written into, valid until the thread's next frame (else new arrays)."""
    if mask.ndim != 2:
        raise FrameError(f"mask must be 2-D, got shape {mask.shape}")
    index_out, component_out = working if working is not None else (_NONE, _NONE)
    (pixel_index, pixel_component, area, sum_col, sum_row, sum_col2, sum_row2, sum_row_col, top, left, right,
     bottom) = label_runs(*_with_words(mask), index_out, component_out)
    cc = sum_col / area
    cr = sum_row / area
    # second central moments from raw moments, each pixel a unit square (variance 1/12 per axis)
    mu20 = sum_col2 / area - cc * cc + 1.0 / 12.0
    mu02 = sum_row2 / area - cr * cr + 1.0 / 12.0
    mu11 = sum_row_col / area - cc * cr
    half_sum = 0.5 * (mu20 + mu02)
    root_term = np.sqrt(0.25 * (mu20 - mu02) ** 2 + mu11 * mu11)
    elongation = np.sqrt((half_sum + root_term) / np.maximum(half_sum - root_term, 1.0 / 12.0))
    return Components(
        area_px=area.astype(np.int64),
        centroid_col=cc,
        centroid_row=cr,
        left=left,
        top=top,
        width=right - left + 1,
        height=bottom - top + 1,
        elongation=elongation,
        pixel_index=pixel_index,
        pixel_component=pixel_component,
    )
