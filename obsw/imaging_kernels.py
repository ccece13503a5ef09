"""Compiled kernels of the imaging chain's FPGA stages (Numba): one pass over the frame for the binning block sums,
maxima and the histogram of the binned image, one over the blocks for those the outlier filter examines, and the
outlier test of their pixels.

They do what the FPGA does pixel by pixel, as the universe's readout kernel (``universe.camera.readout``) does for the
detector; ``obsw.imaging_filtering`` defines the arithmetic and is checked against OpenCV.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def block_statistics(frame: np.ndarray, f: int, sums: np.ndarray, maxima: np.ndarray, binned: np.ndarray,
                     hist: np.ndarray) -> None:
    """Fill ``sums``, ``maxima`` and ``binned`` (n, n) with the sum, the largest value and the rounded mean
    floor(sum / f^2 + 1/2) of each f x f block of ``frame`` (n f, n f), and count each rounded mean in ``hist``."""
    n = sums.shape[0]
    area = f * f
    half = area // 2
    if f == 2:
        # the 1024 -> 512 case, unrolled: two rows at a time, no loop over the block
        for bi in range(n):
            r0 = frame[2 * bi]
            r1 = frame[2 * bi + 1]
            s_row = sums[bi]
            m_row = maxima[bi]
            b_row = binned[bi]
            for bj in range(n):
                a = np.int64(r0[2 * bj])
                b = np.int64(r0[2 * bj + 1])
                c = np.int64(r1[2 * bj])
                d = np.int64(r1[2 * bj + 1])
                s = a + b + c + d
                s_row[bj] = s
                m_row[bj] = max(max(a, b), max(c, d))
                b_row[bj] = (s + 2) >> 2
    else:
        for bi in range(n):
            for bj in range(n):
                s = np.int64(0)
                m = np.int64(0)
                for di in range(f):
                    row = frame[bi * f + di]
                    for dj in range(f):
                        v = np.int64(row[bj * f + dj])
                        s += v
                        m = max(m, v)
                sums[bi, bj] = s
                maxima[bi, bj] = m
                binned[bi, bj] = (s + half) // area
    for bi in range(n):
        b_row = binned[bi]
        for bj in range(n):
            hist[b_row[bj]] += 1


@njit(cache=True, nogil=True)
def standing_out(sums: np.ndarray, maxima: np.ndarray, area: int, margin: float, ratio: float, background: float
                 ) -> np.ndarray:
    """Flat indices of the blocks whose brightest pixel M exceeds the mean m of the others by more than
    ``margin`` + (``ratio`` - 1) max(m - ``background``, 0): in integers times (area - 1),
    area M - sum > (area - 1) margin + (ratio - 1) max(sum - M - (area - 1) background, 0)."""
    n = sums.shape[0]
    out = np.empty(n * n, dtype=np.int64)
    base = (area - 1) * margin
    limit = np.int64(np.floor(base))  # the relative term is >= 0: an integer test first, the full one when it passes
    floor = (area - 1) * background
    slope = ratio - 1.0
    k = 0
    for i in range(n):
        s_row = sums[i]
        m_row = maxima[i]
        for j in range(n):
            m = np.int64(m_row[j])
            s = s_row[j]
            excess = area * m - s
            if excess > limit and excess > base + slope * max(s - m - floor, 0.0):
                out[k] = i * n + j
                k += 1
    return out[:k]


@njit(cache=True, nogil=True)
def outliers(frame: np.ndarray, blocks: np.ndarray, f: int, k_sigma: float, ratio: float, background: int,
             bad_pixels: np.ndarray, bad_values: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The outlier test (``obsw.imaging_filtering``) of every pixel of ``blocks`` (flat indices of f x f blocks of
    the (n f, n f) uint16 ``frame``), on the frame with the bad pixels ``bad_pixels`` (sorted flat indices) read as
    ``bad_values``: (sorted flat indices of the outliers, each changed block's sum of (median - value), the changed
    blocks). A pixel's neighbourhood is its 3x3 window, borders replicated; integers where the test is in integers,
    double precision where it scales with ``ratio`` or ``k_sigma``."""
    side = frame.shape[0]
    n = side // f
    w = f + 2
    area = f * f
    nb = bad_pixels.size
    win = np.empty(w * w, dtype=np.int64)
    neigh = np.empty(9, dtype=np.int64)
    found = np.empty(blocks.size * area, dtype=np.int64)
    delta = np.empty(blocks.size, dtype=np.int64)
    changed = np.empty(blocks.size, dtype=np.int64)
    n_found = 0
    n_changed = 0
    slope = ratio - 1.0
    base = (area - 1) * k_sigma
    for kb in range(blocks.size):
        b = blocks[kb]
        r0 = (b // n) * f - 1
        c0 = (b % n) * f - 1
        for a in range(w):
            r = min(max(r0 + a, 0), side - 1)
            for c in range(w):
                cc = min(max(c0 + c, 0), side - 1)
                v = np.int64(frame[r, cc])
                if nb:
                    idx = r * side + cc
                    pos = np.searchsorted(bad_pixels, idx)
                    if bad_pixels[min(pos, nb - 1)] == idx:
                        v = bad_values[pos]
                win[a * w + c] = v
        top = np.int64(0)
        total = np.int64(0)
        for i in range(1, f + 1):
            for j in range(1, f + 1):
                v = win[i * w + j]
                total += v
                top = max(top, v)
        rest = total - top
        if not area * top - total > base + slope * max(rest - (area - 1) * background, 0):
            continue
        d = np.int64(0)
        hit = False
        for i in range(1, f + 1):
            for j in range(1, f + 1):
                k = 0
                for di in range(-1, 2):
                    for dj in range(-1, 2):
                        neigh[k] = win[(i + di) * w + j + dj]
                        k += 1
                neigh.sort()
                median = neigh[4]
                v = win[i * w + j]
                if v - background > ratio * max(median - background, 0) + k_sigma:
                    found[n_found] = (r0 + i) * side + c0 + j
                    n_found += 1
                    d += median - v
                    hit = True
        if hit:
            delta[n_changed] = d
            changed[n_changed] = b
            n_changed += 1
    return np.sort(found[:n_found]), delta[:n_changed], changed[:n_changed]


def warm_up() -> None:
    """Compile (or load from the cache) the kernels now, for the frame types the camera gives."""
    frame = np.zeros((4, 4), np.uint16)
    sums = np.zeros((2, 2), np.int64)
    maxima = np.zeros((2, 2), np.uint16)
    hist = np.zeros(4096, np.int64)
    block_statistics(frame, 2, sums, maxima, np.zeros((2, 2), np.uint16), hist)
    standing_out(sums, maxima, 4, 1.0, 2.0, 0.0)
    empty = np.zeros(0, np.int64)
    outliers(frame, np.zeros(1, np.int64), 2, 1.0, 2.0, 0, empty, empty)
