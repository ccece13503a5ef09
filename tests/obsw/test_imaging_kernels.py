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
