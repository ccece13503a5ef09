"""Compiled kernels of the imaging chain (Numba): for the FPGA stages, one pass over the frame for the binning block
sums, maxima and the histogram of the binned image (the frame's range check included, and each row of blocks' largest
excess of its brightest pixel, by which the outlier filter passes rows over), one over the blocks for those
the outlier filter examines, the outlier test of their pixels, the corrections of the blocks' sums, and the
histogram's statistics (median and MAD, the 8-bit histogram, Otsu's threshold: a handful of numpy calls on small
arrays each cost more than their arithmetic); for the software's labelling, the runs of a binary image joined into
8-connected components with their raw moments (``obsw.imaging_labelling`` turns them into the statistics), the
foreground pixels' 8-bit values, and each region's brightness: the sum, peak and histogram of its pixels' 8-bit values
(``obsw.imaging_identification``).

They do what the FPGA does pixel by pixel, as the universe's readout kernel (``universe.camera.readout``) does for the
detector; ``obsw.imaging_filtering`` defines the arithmetic and is checked against OpenCV.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def block_statistics(frame: np.ndarray, f: int, sums: np.ndarray, maxima: np.ndarray, binned: np.ndarray,
                     hist: np.ndarray, row_top: np.ndarray) -> int:
    """Fill ``sums`` (int32), ``maxima`` and ``binned`` (n, n) with the sum, the largest value and the rounded mean
    floor(sum / f^2 + 1/2) of each f x f block of ``frame`` (n f, n f), ``row_top`` (n,) with each row of blocks'
    largest excess f^2 max - sum (what ``standing_out`` passes rows over by), and count each rounded mean in ``hist``;
    return the frame's largest value. A value beyond ``hist`` (a frame deeper than its bit depth) leaves ``hist``
    uncounted: the caller refuses the frame on the returned value (the frame is read once, its check included)."""
    n = sums.shape[0]
    area = f * f
    half = area // 2
    peak = np.int64(0)
    if f == 2:
        # the 1024 -> 512 case, unrolled: a block row's pixels read in pairs as 32-bit words (sum and maximum do not
        # care which half is which column, so the byte order does not matter), in 32-bit arithmetic (four 16-bit
        # values cannot overflow it): loads and arithmetic the compiler vectorises, 0.5 -> 0.3 ms a frame
        words = np.ascontiguousarray(frame).view(np.uint32)
        for bi in range(n):
            r0 = words[2 * bi]
            r1 = words[2 * bi + 1]
            s_row = sums[bi]
            m_row = maxima[bi]
            b_row = binned[bi]
            top_m = np.int32(0)
            top_x = np.int32(0)
            for bj in range(n):
                x = r0[bj]
                y = r1[bj]
                a = np.int32(x & 0xFFFF)
                b = np.int32(x >> 16)
                c = np.int32(y & 0xFFFF)
                d = np.int32(y >> 16)
                s = a + b + c + d
                m = max(max(a, b), max(c, d))
                s_row[bj] = s
                m_row[bj] = m
                b_row[bj] = (s + 2) >> 2
                top_m = max(top_m, m)
                top_x = max(top_x, 4 * m - s)
            peak = max(peak, np.int64(top_m))
            row_top[bi] = top_x
    else:
        for bi in range(n):
            top_x = np.int64(0)
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
                peak = max(peak, m)
                binned[bi, bj] = (s + half) // area
                top_x = max(top_x, area * m - s)
            row_top[bi] = top_x
    if peak >= hist.size:
        return peak
    for bi in range(n):
        b_row = binned[bi]
        for bj in range(n):
            hist[b_row[bj]] += 1
    return peak


@njit(cache=True, nogil=True)
def standing_out(sums: np.ndarray, maxima: np.ndarray, area: int, margin: float, ratio: float, background: float,
                 row_top: np.ndarray) -> np.ndarray:
    """Flat indices of the blocks whose brightest pixel M exceeds the mean m of the others by more than
    ``margin`` + (``ratio`` - 1) max(m - ``background``, 0): in integers times (area - 1),
    area M - sum > (area - 1) margin + (ratio - 1) max(sum - M - (area - 1) background, 0).

    ``row_top`` (n,) bounds each row of blocks' area M - sum from above (``block_statistics``'s): a row whose bound
    is within the margin has no such block and is passed over (most rows). A bound taken before some blocks' sums
    were corrected still bounds the other blocks; the caller examines the corrected ones whatever this finds."""
    n = sums.shape[0]
    out = np.empty(n * n, dtype=np.int64)
    base = (area - 1) * margin
    limit = np.int64(np.floor(base))  # the relative term is >= 0: an integer test first, the full one when it passes
    floor = (area - 1) * background
    slope = ratio - 1.0
    k = 0
    for i in range(n):
        if row_top[i] <= limit:
            continue
        s_row = sums[i]
        m_row = maxima[i]
        for j in range(n):
            m = np.int64(m_row[j])
            s = np.int64(s_row[j])
            excess = area * m - s
            if excess > limit and excess > base + slope * max(s - m - floor, 0.0):
                out[k] = i * n + j
                k += 1
    return out[:k]


@njit(cache=True, nogil=True)
def median_mad(hist: np.ndarray) -> tuple[int, int]:
    """(lower median, lower median absolute deviation) of the values a histogram counts (bin i = value i); (-1, -1)
    for an empty histogram."""
    total = np.int64(0)
    for v in range(hist.size):
        total += hist[v]
    if total <= 0:
        return -1, -1
    half = (total + 1) // 2
    seen = np.int64(0)
    median = hist.size - 1
    for v in range(hist.size):
        seen += hist[v]
        if seen >= half:
            median = v
            break
    # the values at distance d from the median, d growing: the bins on either side of it
    seen = np.int64(0)
    mad = hist.size - 1
    for d in range(hist.size):
        if median - d >= 0:
            seen += hist[median - d]
        if d > 0 and median + d < hist.size:
            seen += hist[median + d]
        if seen >= half:
            mad = d
            break
    return median, mad


@njit(cache=True, nogil=True)
def add_to_blocks(sums: np.ndarray, binned: np.ndarray, hist: np.ndarray, blocks: np.ndarray, delta: np.ndarray,
                  area: int) -> None:
    """Add ``delta[k]`` to the sum of block ``blocks[k]`` (flat ``sums``; a block may repeat), then set each changed
    block's rounded mean in the flat ``binned`` and move its count in ``hist``."""
    half = area // 2
    for k in range(blocks.size):
        sums[blocks[k]] += delta[k]
    for k in range(blocks.size):
        b = blocks[k]
        new = (np.int64(sums[b]) + half) // area
        old = np.int64(binned[b])
        if new != old:  # a repeated block is updated at its first entry
            hist[old] -= 1
            hist[new] += 1
            binned[b] = new


@njit(cache=True, nogil=True)
def union_sorted(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The sorted union of two sorted arrays of distinct integers."""
    out = np.empty(a.size + b.size, dtype=np.int64)
    i = j = k = 0
    while i < a.size or j < b.size:
        if j >= b.size or (i < a.size and a[i] < b[j]):
            out[k] = a[i]
            i += 1
        elif i >= a.size or b[j] < a[i]:
            out[k] = b[j]
            j += 1
        else:
            out[k] = a[i]
            i += 1
            j += 1
        k += 1
    return out[:k]


@njit(cache=True, nogil=True)
def histogram_8bit(table: np.ndarray, hist: np.ndarray) -> np.ndarray:
    """The 8-bit histogram of an image whose raw histogram is ``hist``, through the compression ``table``."""
    out = np.zeros(256, dtype=np.int64)
    for v in range(hist.size):
        out[table[v]] += hist[v]
    return out


@njit(cache=True, nogil=True)
def otsu(hist: np.ndarray) -> int:
    """Otsu's threshold of an integer histogram (``imaging_binarisation.otsu_threshold``): the class probabilities and
    first moments as cumulative sums in order, in double precision, the first split of largest between-class variance
    among those leaving both classes at least float32's epsilon of the total."""
    total = 0.0
    for v in range(hist.size):
        total += float(hist[v])  # integer counts: exact in any order
    if total <= 0.0:
        return 0
    eps = float(np.finfo(np.float32).eps)
    q1 = 0.0
    m1 = 0.0
    mu = 0.0
    for v in range(hist.size):
        mu += (hist[v] / total) * float(v)
    best = -1.0
    arg = 0
    found = False
    for v in range(hist.size):
        p = hist[v] / total
        q1 += p
        m1 += p * float(v)
        q2 = 1.0 - q1
        sigma = -1.0
        if min(q1, q2) >= eps and max(q1, q2) <= 1.0 - eps:
            found = True
            d = m1 / q1 - (mu - m1) / q2
            sigma = q1 * q2 * (d * d)
        if sigma > best:
            best = sigma
            arg = v
    return arg if found else 0


# The two sorts below are written out: Numba's generic quicksort behind ``ndarray.sort`` and ``np.sort`` took a
# seventh of the flight software's compile time; integers sort to the same order by any method.
@njit(cache=True, nogil=True)
def _insertion_sort(a: np.ndarray) -> None:
    """Sort a short int64 array in place (the nine values of a 3x3 window)."""
    for i in range(1, a.size):
        v = a[i]
        j = i - 1
        while j >= 0 and a[j] > v:
            a[j + 1] = a[j]
            j -= 1
        a[j + 1] = v


@njit(cache=True, nogil=True)
def _merge_sorted(a: np.ndarray) -> np.ndarray:
    """A sorted copy of an int64 array (bottom-up merge sort: n log n for any order)."""
    n = a.size
    src = a.copy()
    dst = np.empty(n, dtype=np.int64)
    width = 1
    while width < n:
        for lo in range(0, n, 2 * width):
            mid, hi = min(lo + width, n), min(lo + 2 * width, n)
            i, j = lo, mid
            for k in range(lo, hi):
                if i < mid and (j >= hi or src[i] <= src[j]):
                    dst[k] = src[i]
                    i += 1
                else:
                    dst[k] = src[j]
                    j += 1
        src, dst = dst, src
        width *= 2
    return src


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
            # the window row's columns never decrease (the border replicated), so one search finds its first bad
            # pixel and a pointer walks the rest
            pos = np.searchsorted(bad_pixels, r * side + max(c0, 0)) if nb else 0
            for c in range(w):
                cc = min(max(c0 + c, 0), side - 1)
                v = np.int64(frame[r, cc])
                if nb:
                    idx = r * side + cc
                    while pos < nb and bad_pixels[pos] < idx:
                        pos += 1
                    if pos < nb and bad_pixels[pos] == idx:
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
                _insertion_sort(neigh)
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
    return _merge_sorted(found[:n_found]), delta[:n_changed], changed[:n_changed]


@njit(cache=True, nogil=True)
def label_runs(mask: np.ndarray, words: np.ndarray, index_out: np.ndarray, component_out: np.ndarray
               ) -> tuple[np.ndarray, ...]:
    """The 8-connected components of a 2-D boolean image, by runs (maximal horizontal segments of foreground);
    ``words``: the mask's rows as 64-bit words (``mask.view(np.uint64)``, eight pixels each) to pass over empty
    stretches eight pixels at a time, or an array of no columns when the width is not a multiple of eight;
    ``index_out``, ``component_out``: where to write the pixels' indices and components (the returned arrays are
    their first elements) when they are large enough, else new arrays.

    Returns, components numbered in raster order of their first pixel: the flat index of every foreground pixel in
    raster order and its component; per component its area and raw moments (sums over its pixels, each run added in
    raster order: column, row, column^2, row^2, row x column, as the run formulas give them), its first row, leftmost
    and rightmost column and last row. A run joins the runs of the row above that touch it (8-connectivity: columns
    within one), each set's root being its first run, so numbering roots in order numbers components."""
    height, width = mask.shape
    packed = words.shape[1] * 8 == width and width > 0
    cap = height * ((width + 1) // 2) + 1
    run_row = np.empty(cap, np.int64)
    run_c0 = np.empty(cap, np.int64)
    run_c1 = np.empty(cap, np.int64)
    parent = np.empty(cap, np.int64)
    n = 0
    above_first = 0  # runs of the previous row: [above_first, above_end)
    above_end = 0
    for r in range(height):
        row = mask[r]
        row_first = n
        c = 0
        j = above_first
        row_words = words[r] if packed else words[0]
        while c < width:
            if not row[c]:
                # most of a frame is background: a whole empty word at a time where one starts
                if packed and c & 7 == 0 and row_words[c >> 3] == 0:
                    c += 8
                else:
                    c += 1
                continue
            c0 = c
            while c < width and row[c]:
                c += 1
            c1 = c - 1
            run_row[n] = r
            run_c0[n] = c0
            run_c1[n] = c1
            parent[n] = n
            # the runs above touching [c0 - 1, c1 + 1]; they are sorted and disjoint, so a pointer moves forward
            while j < above_end and run_c1[j] < c0 - 1:
                j += 1
            k = j
            while k < above_end and run_c0[k] <= c1 + 1:
                a = k  # union of the sets of runs k and n: the larger root hooks onto the smaller
                while parent[a] != a:
                    parent[a] = parent[parent[a]]  # path halving: the walk stays short on any mask
                    a = parent[a]
                b = n
                while parent[b] != b:
                    parent[b] = parent[parent[b]]
                    b = parent[b]
                if a < b:
                    parent[b] = a
                elif b < a:
                    parent[a] = b
                k += 1
            n += 1
        above_first, above_end = row_first, n
    comp_of_root = np.empty(n, np.int64)
    run_comp = np.empty(n, np.int64)
    k_count = 0
    total = 0
    for i in range(n):
        a = i
        while parent[a] != a:
            a = parent[a]
        parent[i] = a  # compress: roots precede their runs, so a root's own entry is final
        if a == i:
            comp_of_root[i] = k_count
            k_count += 1
        run_comp[i] = comp_of_root[a]
        total += run_c1[i] - run_c0[i] + 1
    area = np.zeros(k_count, np.float64)
    sum_col = np.zeros(k_count, np.float64)
    sum_row = np.zeros(k_count, np.float64)
    sum_col2 = np.zeros(k_count, np.float64)
    sum_row2 = np.zeros(k_count, np.float64)
    sum_row_col = np.zeros(k_count, np.float64)
    top = np.empty(k_count, np.int64)
    left = np.full(k_count, width, np.int64)
    right = np.zeros(k_count, np.int64)
    bottom = np.zeros(k_count, np.int64)
    pixel_index = index_out[:total] if index_out.size >= total else np.empty(total, np.int64)
    pixel_component = component_out[:total] if component_out.size >= total else np.empty(total, np.int64)
    p = 0
    for i in range(n):
        q = run_comp[i]
        c0 = run_c0[i]
        c1 = run_c1[i]
        rr = run_row[i]
        length = float(c1 - c0 + 1)
        rowf = float(rr)
        s_col = (c0 + c1) * length * 0.5
        x1 = float(c1)
        x0 = c0 - 1.0
        area[q] += length
        sum_col[q] += s_col
        sum_row[q] += rowf * length
        sum_col2[q] += x1 * (x1 + 1) * (2 * x1 + 1) / 6.0 - x0 * (x0 + 1) * (2 * x0 + 1) / 6.0
        sum_row2[q] += rowf * rowf * length
        sum_row_col[q] += rowf * s_col
        if parent[i] == i:
            top[q] = rr
        left[q] = min(left[q], c0)
        right[q] = max(right[q], c1)
        bottom[q] = max(bottom[q], rr)
        for cc in range(c0, c1 + 1):
            pixel_index[p] = rr * width + cc
            pixel_component[p] = q
            p += 1
    return (pixel_index, pixel_component, area, sum_col, sum_row, sum_col2, sum_row2, sum_row_col, top, left, right,
            bottom)


@njit(cache=True, nogil=True)
def values_at(image: np.ndarray, pixel_index: np.ndarray, table: np.ndarray) -> np.ndarray:
    """``table[image[pixel_index]]`` (a flat image, a look-up table of uint8), in one pass: the foreground pixels'
    8-bit values."""
    out = np.empty(pixel_index.size, np.uint8)
    for i in range(pixel_index.size):
        out[i] = table[image[pixel_index[i]]]
    return out


@njit(cache=True, nogil=True)
def region_values(component: np.ndarray, values8: np.ndarray, k: int, row: np.ndarray, n_rows: int
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Of k regions, from each foreground pixel's region (0-based) and 8-bit value: each region's sum of values and
    its peak value, and the 256-bin histograms of the regions with a ``row`` (>= 0) in a table of ``n_rows``."""
    sums = np.zeros(k, np.float64)
    peak = np.zeros(k, np.int64)
    hist = np.zeros((n_rows, 256), np.int64)
    for i in range(component.size):
        q = component[i]
        v = np.int64(values8[i])
        sums[q] += v
        if v > peak[q]:
            peak[q] = v
        r = row[q]
        if r >= 0:
            hist[r, v] += 1
    return sums, peak, hist


@njit(cache=True, nogil=True)
def top_light(counts: np.ndarray, n: int, threshold_dn8: int) -> np.ndarray:
    """Of each row of 256-bin histograms (K, 256): the sum of its n largest values less ``threshold_dn8``, over n
    (fewer values than n count the rest as 0)."""
    out = np.empty(counts.shape[0], np.float64)
    for r in range(counts.shape[0]):
        left = np.int64(n)
        total = np.int64(0)
        for v in range(255, -1, -1):
            if left <= 0:
                break
            take = min(counts[r, v], left)
            total += take * (v - threshold_dn8)
            left -= take
        out[r] = total / n
    return out


@njit(cache=True, nogil=True)
def surface_count(values8: np.ndarray, n: int, threshold_dn8: int) -> int:
    """How many of ``values8`` are at least ``threshold_dn8`` + (m - ``threshold_dn8``) / 2, m the median of their n
    largest (1 <= n <= their number; of an even n, the mean of the middle two)."""
    hist = np.zeros(256, np.int64)
    for i in range(values8.size):
        hist[values8[i]] += 1
    # the n largest, ascending, are the last n of the sorted values: their middle one(s) at ranks (from the top)
    # (n - 1) // 2 and n // 2, counted from 0
    lo_rank = n // 2
    hi_rank = (n - 1) // 2
    lo = -1
    hi = -1
    seen = 0
    for v in range(255, -1, -1):
        seen += hist[v]
        if hi < 0 and seen > hi_rank:
            hi = v
        if seen > lo_rank:
            lo = v
            break
    typical = (hi + lo) / 2.0 if n % 2 == 0 else float(hi)
    level = threshold_dn8 + 0.5 * (typical - threshold_dn8)
    count = 0
    for v in range(256):
        if v >= level:
            count += hist[v]
    return count


@njit(cache=True, nogil=True)
def single_peak(box: np.ndarray) -> bool:
    """Whether the pixels of ``box`` (2-D, int; -1: not the region's) hold at most one regional maximum: an
    8-connected plateau of equal values none of whose pixels has a higher neighbour. Every 8-connected part of the
    pixels at or above any level holds one (its highest plateau), and a regional maximum's part at its own value is
    the plateau alone; so one regional maximum is exactly no level parting the pixels."""
    h, w = box.shape
    seen = np.zeros((h, w), np.bool_)
    stack = np.empty(h * w, np.int64)
    maxima = 0
    for r0 in range(h):
        for c0 in range(w):
            v = box[r0, c0]
            if v < 0 or seen[r0, c0]:
                continue
            # flood the plateau of value v holding (r0, c0), noting whether any of its pixels has a higher neighbour
            seen[r0, c0] = True
            stack[0] = r0 * w + c0
            n = 1
            higher = False
            while n > 0:
                n -= 1
                r, c = divmod(stack[n], w)
                for dr in range(-1, 2):
                    for dc in range(-1, 2):
                        rr = r + dr
                        cc = c + dc
                        if rr < 0 or rr >= h or cc < 0 or cc >= w:
                            continue
                        u = box[rr, cc]
                        if u > v:
                            higher = True
                        elif u == v and not seen[rr, cc]:
                            seen[rr, cc] = True
                            stack[n] = rr * w + cc
                            n += 1
            if not higher:
                maxima += 1
                if maxima > 1:
                    return False
    return True


@njit(cache=True, nogil=True)
def grouped_positions(component: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """The positions 0..N-1 grouped by ``component`` (0-based, N), each group in ascending order from
    ``starts[c]`` (each group's first slot, K + 1 long): a counting sort, ``np.argsort(component, kind="stable")``."""
    order = np.empty(component.size, np.int64)
    cursor = starts[:-1].copy()
    for i in range(component.size):
        c = component[i]
        order[cursor[c]] = i
        cursor[c] += 1
    return order


def warm_up() -> None:
    """Compile (or load from the cache) the kernels now, for the frame types the camera gives."""
    frame = np.zeros((4, 4), np.uint16)
    sums = np.zeros((2, 2), np.int32)
    maxima = np.zeros((2, 2), np.uint16)
    hist = np.zeros(4096, np.int64)
    top = np.zeros(2, np.int64)
    block_statistics(frame, 2, sums, maxima, np.zeros((2, 2), np.uint16), hist, top)
    standing_out(sums, maxima, 4, 1.0, 2.0, 0.0, top)
    empty = np.zeros(0, np.int64)
    outliers(frame, np.zeros(1, np.int64), 2, 1.0, 2.0, 0, empty, empty)
    label_runs(np.zeros((2, 2), np.bool_), np.zeros((1, 0), np.uint64), empty, empty)
    label_runs(np.zeros((2, 8), np.bool_), np.zeros((2, 1), np.uint64), empty, empty)
    one = np.zeros(1, np.int64)
    region_values(one, np.zeros(1, np.uint8), 1, one, 1)
    values_at(np.zeros(4, np.uint16), one, np.zeros(4096, np.uint8))
    top_light(np.zeros((1, 256), np.int64), 1, 0)
    surface_count(np.zeros(1, np.uint8), 1, 0)
    single_peak(np.zeros((1, 1), np.int16))
    grouped_positions(one, np.array([0, 1], np.int64))
    median_mad(hist)
    add_to_blocks(sums.reshape(-1), maxima.reshape(-1), hist, one, one, 4)
    union_sorted(one, empty)
    table = np.zeros(4096, np.uint8)
    otsu(histogram_8bit(table, hist))
