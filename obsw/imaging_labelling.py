"""Step 3 of the imaging chain, object detection: 8-connected component labelling of the binarised image.

Run-length encoding and a vectorised union-find of overlapping runs of adjacent rows; labels are numbered in raster
order of each component's first pixel (OpenCV's ``connectedComponentsWithStats`` numbering), with per component the
area, the binary centroid (pixel centres at integer coordinates), the bounding box and the elongation from the
second central moments.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from obsw.imaging_filtering import FrameError


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


def _root_of_each_run(n_runs: int, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Return, for each run, the smallest run index of its connected set, given the edges (a, b) between runs."""
    parent = np.arange(n_runs, dtype=np.int64)
    if a.size == 0:
        return parent
    while True:
        pa = parent[a]
        pb = parent[b]
        differ = pa != pb
        if not differ.any():
            return parent
        pa = pa[differ]
        pb = pb[differ]
        lo = np.minimum(pa, pb)
        hi = np.maximum(pa, pb)
        # hook each root onto the smallest root it touches; roots only point down, so no cycle can form
        np.minimum.at(parent, hi, lo)
        # pointer jumping until every run points at its root
        while True:
            grand = parent[parent]
            if np.array_equal(grand, parent):
                break
            parent = grand
        a = a[differ]
        b = b[differ]


def _sum_of_squares_to(x: np.ndarray) -> np.ndarray:
    """Return 0^2 + 1^2 + ... + x^2 for each integer x >= -1 (0 for x = -1 and x = 0)."""
    return x * (x + 1) * (2 * x + 1) / 6.0


def connected_components(mask: np.ndarray) -> Components:
    """Return the 8-connected components of a 2-D boolean image with their area, centroid, box and shape."""
    if mask.ndim != 2:
        raise FrameError(f"mask must be 2-D, got shape {mask.shape}")
    height, width = mask.shape
    # runs: maximal horizontal segments of foreground; a zero column after each row (and a zero before the
    # first) makes every run start on a 0->1 and end on a 1->0 step of the flattened padded image
    stride = width + 1
    padded = np.zeros(height * stride + 1, dtype=np.int8)
    padded[1:].reshape(height, stride)[:, :width] = mask
    steps = np.flatnonzero(padded[1:] != padded[:-1])
    starts = steps[0::2]  # flat index, in the padded grid, of each run's first pixel
    ends = steps[1::2] - 1  # ... and of its last pixel
    n_runs = starts.size
    if n_runs == 0:
        empty_i = np.zeros(0, dtype=np.int64)
        empty_f = np.zeros(0, dtype=np.float64)
        return Components(empty_i, empty_f, empty_f, empty_i, empty_i, empty_i, empty_i, empty_f, empty_i, empty_i)
    run_row = starts // stride
    run_c0 = starts - run_row * stride
    run_c1 = ends - run_row * stride
    run_len = run_c1 - run_c0 + 1
    # runs of row r and r+1 touch (8-connectivity) when c0' <= c1 + 1 and c1' >= c0 - 1; in the padded grid
    # these bounds fall on a padding column at worst, never on a run of another row, so two sorted searches
    # find every touching run of the next row
    lo = np.searchsorted(ends, starts + stride - 1, side="left")
    hi = np.searchsorted(starts, ends + stride + 1, side="right")
    count = np.maximum(hi - lo, 0)
    total = int(count.sum())
    if total:
        src = np.repeat(np.arange(n_runs, dtype=np.int64), count)
        offsets = np.cumsum(count) - count
        dst = np.repeat(lo - offsets, count) + np.arange(total, dtype=np.int64)
    else:
        src = dst = np.zeros(0, dtype=np.int64)
    root = _root_of_each_run(n_runs, src, dst)
    # a root is the first run of its component in raster order, so numbering roots in order numbers components
    is_root = root == np.arange(n_runs)
    roots = np.flatnonzero(is_root)
    run_comp = (np.cumsum(is_root) - 1)[root]
    k = roots.size
    lenf = run_len.astype(np.float64)
    rowf = run_row.astype(np.float64)
    area = np.bincount(run_comp, weights=lenf, minlength=k)
    run_sum_col = (run_c0 + run_c1) * lenf * 0.5
    run_sum_col2 = _sum_of_squares_to(run_c1.astype(np.float64)) - _sum_of_squares_to(run_c0 - 1.0)
    cc = np.bincount(run_comp, weights=run_sum_col, minlength=k) / area
    cr = np.bincount(run_comp, weights=rowf * lenf, minlength=k) / area
    # second central moments from raw moments, each pixel a unit square (variance 1/12 per axis)
    mu20 = np.bincount(run_comp, weights=run_sum_col2, minlength=k) / area - cc * cc + 1.0 / 12.0
    mu02 = np.bincount(run_comp, weights=rowf * rowf * lenf, minlength=k) / area - cr * cr + 1.0 / 12.0
    mu11 = np.bincount(run_comp, weights=rowf * run_sum_col, minlength=k) / area - cc * cr
    half_sum = 0.5 * (mu20 + mu02)
    root_term = np.sqrt(0.25 * (mu20 - mu02) ** 2 + mu11 * mu11)
    elongation = np.sqrt((half_sum + root_term) / np.maximum(half_sum - root_term, 1.0 / 12.0))
    left = np.full(k, width, dtype=np.int64)
    np.minimum.at(left, run_comp, run_c0)
    right = np.zeros(k, dtype=np.int64)
    np.maximum.at(right, run_comp, run_c1)
    top = run_row[roots]
    bottom = np.zeros(k, dtype=np.int64)
    np.maximum.at(bottom, run_comp, run_row)
    return Components(
        area_px=area.astype(np.int64),
        centroid_col=cc,
        centroid_row=cr,
        left=left,
        top=top,
        width=right - left + 1,
        height=bottom - top + 1,
        elongation=elongation,
        pixel_index=np.flatnonzero(mask),
        pixel_component=np.repeat(run_comp, run_len),
    )
