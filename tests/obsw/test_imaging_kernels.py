"""The identification's compiled brightness statistics against their definitions written here with sorting and
plain numpy (the labelling kernel is checked against OpenCV in test_imaging.py)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from obsw import imaging_kernels as k

seeds = st.integers(0, 2**31)


def _values(rng: np.random.Generator) -> np.ndarray:
    """A region's 8-bit values: a few hundred at most, often many equal (a saturated or flat surface)."""
    size = int(rng.integers(1, 300))
    low = int(rng.integers(0, 256))
    return rng.integers(low, 256, size).astype(np.uint8)


@settings(max_examples=300, deadline=None)
@given(seeds)
def test_top_light_is_the_mean_of_the_n_largest_values_above_the_threshold(seed: int) -> None:
    """top_light: the n largest values less the threshold, summed and divided by n; fewer values than n count as 0."""
    rng = np.random.default_rng(seed)
    regions = [_values(rng) for _ in range(int(rng.integers(1, 5)))]
    thr, n = int(rng.integers(0, 256)), int(rng.integers(1, 400))
    counts = np.stack([np.bincount(v, minlength=256) for v in regions])
    want = [float(np.sum(np.sort(v)[::-1][:n].astype(np.int64) - thr)) / n for v in regions]
    assert k.top_light(counts, n, thr).tolist() == want


@settings(max_examples=300, deadline=None)
@given(seeds)
def test_surface_count_counts_values_halfway_to_the_median_of_the_largest(seed: int) -> None:
    """surface_count: the values at least thr + (m - thr) / 2, m numpy's median of the n largest."""
    rng = np.random.default_rng(seed)
    vals = _values(rng)
    thr, n = int(rng.integers(0, 256)), int(rng.integers(1, vals.size + 1))
    m = float(np.median(np.sort(vals)[vals.size - n:]))
    assert k.surface_count(vals, n, thr) == int(np.sum(vals >= thr + 0.5 * (m - thr)))


@settings(max_examples=200, deadline=None)
@given(seeds)
def test_region_values_sums_peaks_and_histograms(seed: int) -> None:
    """region_values: per region the sum and largest value, and the histogram of the regions given a row."""
    rng = np.random.default_rng(seed)
    regions = int(rng.integers(1, 20))
    comp = rng.integers(0, regions, int(rng.integers(regions, 500)))
    comp[:regions] = np.arange(regions)  # every region has a pixel
    vals = rng.integers(0, 256, comp.size).astype(np.uint8)
    described = np.flatnonzero(rng.random(regions) < 0.5)
    row = np.full(regions, -1, dtype=np.int64)
    row[described] = np.arange(described.size)
    sums, peak, hist = k.region_values(comp, vals, regions, row, described.size)
    for q in range(regions):
        mine = vals[comp == q]
        assert sums[q] == float(mine.astype(np.int64).sum()) and peak[q] == int(mine.max())
    for r, q in enumerate(described):
        assert np.array_equal(hist[r], np.bincount(vals[comp == q], minlength=256))


@settings(max_examples=200, deadline=None)
@given(st.lists(st.integers(-(2**40), 2**40), max_size=300), st.booleans())
def test_the_outlier_filters_sorts_give_numpys_order(values: list[int], short: bool) -> None:
    """_merge_sorted returns numpy's sorted copy (the input untouched); _insertion_sort sorts in place as numpy does."""
    a = np.array(values[:9] if short else values, dtype=np.int64)
    before = a.copy()
    assert k._merge_sorted(a).tolist() == np.sort(before).tolist()
    assert a.tolist() == before.tolist()
    k._insertion_sort(a)
    assert a.tolist() == np.sort(before).tolist()


@settings(max_examples=200, deadline=None)
@given(seeds)
def test_add_to_blocks_keeps_sums_means_and_histogram_consistent(seed: int) -> None:
    """add_to_blocks, blocks repeated in any order: each block's sum gains its deltas, its rounded mean is
    floor(sum / area + 1/2) and the histogram counts the means, as numpy recomputes them from scratch."""
    rng = np.random.default_rng(seed)
    area = int(rng.choice([4, 9, 16]))
    sums = rng.integers(3000, 4095 * area - 3000, 50).astype(np.int32)  # 30 deltas of 100 at most keep it in range
    binned = ((sums.astype(np.int64) + area // 2) // area).astype(np.uint16)
    hist = np.bincount(binned, minlength=4096).astype(np.int64)
    blocks = rng.integers(0, 50, int(rng.integers(0, 30))).astype(np.int64)
    delta = rng.integers(-100, 101, blocks.size).astype(np.int64)
    want = sums.astype(np.int64)
    np.add.at(want, blocks, delta)
    k.add_to_blocks(sums, binned, hist, blocks, delta, area)
    means = (want + area // 2) // area
    np.testing.assert_array_equal(sums, want)
    np.testing.assert_array_equal(binned, means)
    np.testing.assert_array_equal(hist, np.bincount(means, minlength=4096))


@settings(max_examples=200, deadline=None)
@given(st.lists(st.integers(0, 60), unique=True), st.lists(st.integers(0, 60), unique=True))
def test_union_sorted_is_numpys_union(a: list[int], b: list[int]) -> None:
    """union_sorted of two sorted sets of distinct integers: np.union1d."""
    x, y = np.array(sorted(a), dtype=np.int64), np.array(sorted(b), dtype=np.int64)
    np.testing.assert_array_equal(k.union_sorted(x, y), np.union1d(x, y))


@settings(max_examples=200, deadline=None)
@given(seeds)
def test_median_mad_and_8bit_histogram_are_the_sample_statistics(seed: int) -> None:
    """median_mad of a histogram: the lower median and lower median absolute deviation of the values it counts
    (numpy's partition); histogram_8bit: numpy's bincount of the values through the table."""
    rng = np.random.default_rng(seed)
    values = rng.integers(0, int(rng.integers(1, 4096)), int(rng.integers(1, 2000)))
    if rng.random() < 0.3:
        values[: values.size // 2] = values[0]  # a flat background: most values equal
    hist = np.bincount(values, minlength=4096).astype(np.int64)
    m = (values.size - 1) // 2
    median = int(np.partition(values, m)[m])
    assert k.median_mad(hist) == (median, int(np.partition(np.abs(values - median), m)[m]))
    assert k.median_mad(np.zeros(16, np.int64)) == (-1, -1)
    table = np.floor(255.0 * np.sqrt(np.arange(4096) / 4095) + 0.5).astype(np.uint8)
    np.testing.assert_array_equal(k.histogram_8bit(table, hist), np.bincount(table[values], minlength=256))


@settings(max_examples=100, deadline=None)
@given(seeds)
def test_values_at_is_numpys_double_gather(seed: int) -> None:
    """values_at(image, index, table): numpy's table[image[index]]."""
    rng = np.random.default_rng(seed)
    image = rng.integers(0, 4096, int(rng.integers(1, 500))).astype(np.uint16)
    index = rng.integers(0, image.size, int(rng.integers(0, 300))).astype(np.int64)
    table = rng.integers(0, 256, 4096).astype(np.uint8)
    np.testing.assert_array_equal(k.values_at(image, index, table), table[image[index]])


@settings(max_examples=300, deadline=None)
@given(seeds)
def test_single_peak_exactly_when_no_level_parts_the_region(seed: int) -> None:
    """single_peak: true exactly when at every level the region's pixels at or above it form at most one 8-connected
    part (OpenCV's labelling, level by level)."""
    import cv2

    rng = np.random.default_rng(seed)
    h, w = int(rng.integers(1, 14)), int(rng.integers(1, 14))
    rows, cols = np.mgrid[0:h, 0:w]
    img = np.zeros((h, w))
    for _ in range(int(rng.integers(1, 4))):  # blurred point sources, quantised coarsely enough for plateaus
        r0, c0, s = rng.uniform(0, h), rng.uniform(0, w), rng.uniform(0.5, 3.0)
        img += rng.uniform(10, 200) * np.exp(-((rows - r0) ** 2 + (cols - c0) ** 2) / (2 * s * s))
    img += rng.normal(0.0, rng.uniform(0.0, 8.0), img.shape)
    box = np.clip(np.round(img / rng.choice([1, 4, 16])), 0, 255).astype(np.int16)
    box[rng.random((h, w)) < rng.uniform(0.0, 0.4)] = -1  # pixels not the region's
    parted = False
    for level in np.unique(box[box >= 0]).tolist():
        n, _ = cv2.connectedComponents((box >= level).astype(np.uint8), connectivity=8)
        parted = parted or n - 1 >= 2
    assert k.single_peak(box) == (not parted)


@settings(max_examples=200, deadline=None)
@given(seeds)
def test_grouped_positions_is_numpys_stable_argsort(seed: int) -> None:
    """grouped_positions: the positions grouped by component, each group ascending: numpy's stable argsort."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 20))
    component = rng.integers(0, n, int(rng.integers(0, 500))).astype(np.int64)
    starts = np.concatenate(([0], np.cumsum(np.bincount(component, minlength=n)))).astype(np.int64)
    assert k.grouped_positions(component, starts).tolist() == np.argsort(component, kind="stable").tolist()


def _frame(rng: np.random.Generator, f: int) -> np.ndarray:
    """A frame of n f x n f 16-bit pixels: a background with noise, a few sharp defects and a bright patch, sometimes
    values up to the 16-bit limit (the 32-bit arithmetic's worst case), sometimes a view with a row stride."""
    n = int(rng.integers(1, 24))
    frame = rng.integers(90, 130, (n * f, n * f)).astype(np.uint16)
    for _ in range(int(rng.integers(0, 8))):
        frame[rng.integers(0, n * f), rng.integers(0, n * f)] = rng.integers(200, 65536)
    if rng.random() < 0.3:
        frame[: n * f // 2, : n * f // 2] = rng.integers(60000, 65536, (n * f // 2, n * f // 2))
    if rng.random() < 0.3:  # a window into a wider frame: rows not contiguous with each other
        wide = np.zeros((n * f, n * f + 2 * f), np.uint16)
        wide[:, f:-f] = frame
        frame = wide[:, f:-f]
    return frame


def _block_sums_and_maxima(frame: np.ndarray, f: int) -> tuple[np.ndarray, np.ndarray]:
    """Each f x f block's sum and largest value, (n, n) int64, by numpy's reductions."""
    n = frame.shape[0] // f
    blocks = frame.astype(np.int64).reshape(n, f, n, f)
    return blocks.sum(axis=(1, 3)), blocks.max(axis=(1, 3))


@settings(max_examples=300, deadline=None)
@given(seeds, st.sampled_from([2, 3, 4]))
def test_block_statistics_are_the_blocks_sums_maxima_rounded_means_and_row_bounds(seed: int, f: int) -> None:
    """block_statistics: numpy's block sums and maxima, floor(sum / f^2 + 1/2), the histogram of those means, each
    block row's largest f^2 max - sum, and the frame's largest value; beyond the histogram, it is left uncounted."""
    rng = np.random.default_rng(seed)
    frame = _frame(rng, f)
    n = frame.shape[0] // f
    sums, peaks = _block_sums_and_maxima(frame, f)
    means = (sums + f * f // 2) // (f * f)
    got_sums, got_max = np.empty((n, n), np.int32), np.empty((n, n), np.uint16)
    got_means, top = np.empty((n, n), np.uint16), np.empty(n, np.int64)
    hist = np.zeros(65536 if rng.random() < 0.5 else 4096, np.int64)
    peak = k.block_statistics(frame, f, got_sums, got_max, got_means, hist, top)
    assert peak == int(frame.max())
    np.testing.assert_array_equal(got_sums, sums)
    np.testing.assert_array_equal(got_max, peaks)
    np.testing.assert_array_equal(got_means, means)
    np.testing.assert_array_equal(top, np.max(f * f * peaks - sums, axis=1))
    want_hist = np.bincount(means.ravel(), minlength=65536)[: hist.size] if peak < hist.size else 0
    np.testing.assert_array_equal(hist, want_hist)


@settings(max_examples=300, deadline=None)
@given(seeds)
def test_standing_out_finds_the_blocks_its_rule_selects_whatever_rows_it_passes_over(seed: int) -> None:
    """standing_out: the blocks with f^2 M - sum > (f^2 - 1) margin + (ratio - 1) max(sum - M - (f^2 - 1) bg, 0) (bg
    the background), every one of them, when the row bounds are the rows' largest f^2 M - sum, or any larger bound."""
    rng = np.random.default_rng(seed)
    f = int(rng.choice([2, 4]))
    frame = _frame(rng, f)
    n = frame.shape[0] // f
    sums, peaks = _block_sums_and_maxima(frame, f)
    area = f * f
    margin, ratio, background = float(rng.uniform(0, 100)), float(rng.uniform(1, 4)), float(rng.uniform(0, 150))
    excess = area * peaks - sums
    rule = (excess > np.floor((area - 1) * margin)) & (
        excess > (area - 1) * margin + (ratio - 1) * np.maximum(sums - peaks - (area - 1) * background, 0.0))
    bound = np.max(excess, axis=1) + rng.integers(0, 3, n) * rng.integers(0, 1000, n)
    got = k.standing_out(sums.astype(np.int32), peaks.astype(np.uint16), area, margin, ratio, background, bound)
    np.testing.assert_array_equal(got, np.flatnonzero(rule))
