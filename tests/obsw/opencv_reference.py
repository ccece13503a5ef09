"""Independent OpenCV implementation of the imaging pipeline, and a synthetic scene drawer, for tests and bench.

The reference follows the same definitions as obsw.imaging with OpenCV (and whole-frame numpy) doing the work:
the bad-pixel map by a forward and backward fill of the nearest good pixel of each row, the outlier filter with
cv2.medianBlur (3x3) over the whole frame and the blocks' maxima and sums, cv2.resize INTER_AREA binning, cv2.sqrt
companding, cv2.calcHist and cv2.threshold(THRESH_OTSU) for the threshold, cv2.connectedComponentsWithStats
(8-connectivity) for the blobs, and for a blob trimmed to its brightest pixels, a threshold at its n-th largest value
and cv2.connectedComponentsWithStats of what is left.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

MAD_TO_SIGMA = 1.4826


@dataclass(frozen=True)
class ReferenceResult:
    """What the OpenCV pipeline measures on one frame."""

    corrected: np.ndarray  # the full-resolution frame after the bad-pixel map and the outlier filter
    outliers: np.ndarray  # bool, full resolution: the pixels the outlier filter replaced
    binned: np.ndarray  # raw bit depth, n x n
    image8: np.ndarray  # uint8, n x n
    otsu_dn8: int
    threshold_dn8: int
    labels: np.ndarray  # n x n int32, 0 background, k the k-th component
    areas: np.ndarray  # (K,) int, background excluded
    centroids: np.ndarray  # (K, 2) col, row
    bboxes: np.ndarray  # (K, 4) left, top, width, height


def reference_bad_pixels(frame: np.ndarray, pixels_col_row: list[tuple[int, int]] | tuple = (),
                         columns: list[int] | tuple = ()) -> np.ndarray:
    """The frame (int64) with each listed pixel and every pixel of each listed column replaced by the rounded mean of
    the nearest good pixels left and right in its row (the one that exists; itself if the row has none)."""
    out = frame.astype(np.int64)
    bad = np.zeros(frame.shape, dtype=bool)
    for c, r in pixels_col_row:
        bad[r, c] = True
    bad[:, list(columns)] = True
    if not bad.any():
        return out
    idx = np.broadcast_to(np.arange(frame.shape[1]), frame.shape)
    left = np.maximum.accumulate(np.where(bad, -1, idx), axis=1)
    right = np.minimum.accumulate(np.where(bad, frame.shape[1], idx)[:, ::-1], axis=1)[:, ::-1]
    rows = np.broadcast_to(np.arange(frame.shape[0])[:, None], frame.shape)
    lv = out[rows, np.clip(left, 0, frame.shape[1] - 1)]
    rv = out[rows, np.clip(right, 0, frame.shape[1] - 1)]
    has_l, has_r = left >= 0, right < frame.shape[1]
    value = np.where(has_l & has_r, (lv + rv + 1) // 2, np.where(has_l, lv, np.where(has_r, rv, out)))
    return np.where(bad, value, out)


def _lower_median(values: np.ndarray) -> int:
    v = np.sort(values.ravel())
    return int(v[(v.size - 1) // 2])


def reference_outliers(corrected: np.ndarray, size_px: int, k_sigma: float, ratio: float) -> np.ndarray:
    """Boolean map of the pixels the outlier filter replaces: the frame's 2x2 (f x f) block dominated by its
    brightest pixel (max - mean m of the others > k sigma + (ratio - 1) (m - background)) and the pixel above ratio x
    its 3x3 median (cv2.medianBlur) above the background plus k sigma; background and sigma from the binned frame's
    median and MAD."""
    side = corrected.shape[0]
    f = side // size_px
    binned0 = reference_binned(corrected.astype(np.uint16), size_px)
    background = _lower_median(binned0)
    mad = _lower_median(np.abs(binned0.astype(np.int64) - background))
    sigma = max(f * MAD_TO_SIGMA * mad, 1.0)
    blocks = corrected.reshape(size_px, f, size_px, f)
    b_max = blocks.max(axis=(1, 3))
    b_sum = blocks.sum(axis=(1, 3))
    others = (b_sum - b_max) / (f * f - 1)
    dominated = (b_max - others) > k_sigma * sigma + (ratio - 1.0) * np.maximum(others - background, 0.0)
    dominated_px = np.repeat(np.repeat(dominated, f, axis=0), f, axis=1)
    median = cv2.medianBlur(corrected.astype(np.uint16), 3).astype(np.int64)
    return dominated_px & (corrected - background > ratio * np.maximum(median - background, 0) + k_sigma * sigma)


def reference_pipeline(
    frame: np.ndarray,
    size_px: int = 512,
    bit_depth: int = 12,
    law: str = "sqrt",
    k_sigma: float = 5.0,
    margin_dn8: int = 3,
    threshold_dn8: int | None = None,
    otsu: bool = False,
    bad_pixels: tuple[list[tuple[int, int]] | tuple, list[int] | tuple] = ((), ()),
    outlier_filter: bool = True,
    outlier_k_sigma: float = 5.0,
    outlier_ratio: float = 2.0,
) -> ReferenceResult:
    """Run the OpenCV pipeline on a raw frame; ``bad_pixels`` = (pixels (col, row), dead columns) of the map; ``otsu``
    thresholds at max(Otsu, noise floor); threshold_dn8 forces the threshold instead of computing it."""
    corrected = reference_bad_pixels(frame, *bad_pixels)
    outliers = np.zeros(frame.shape, dtype=bool)
    if outlier_filter and frame.shape[0] > size_px:
        outliers = reference_outliers(corrected, size_px, outlier_k_sigma, outlier_ratio)
        corrected = np.where(outliers, cv2.medianBlur(corrected.astype(np.uint16), 3), corrected)
    binned = reference_binned(corrected.astype(np.uint16), size_px)
    image8 = reference_8bit(binned, bit_depth, law)
    thr, otsu_dn8, _ = reference_threshold(image8, k_sigma, margin_dn8, otsu)
    if threshold_dn8 is not None:
        thr = threshold_dn8
    _, mask = cv2.threshold(image8, thr, 255, cv2.THRESH_BINARY)
    _, labels, stats, centroids = cv2.connectedComponentsWithStats(mask, connectivity=8)
    return ReferenceResult(
        corrected=corrected,
        outliers=outliers,
        binned=binned,
        image8=image8,
        otsu_dn8=otsu_dn8,
        threshold_dn8=thr,
        labels=labels,
        areas=stats[1:, cv2.CC_STAT_AREA].astype(np.int64),
        centroids=centroids[1:],
        bboxes=stats[1:, :4].astype(np.int64),
    )


def reference_parts(ref: ReferenceResult, inside: np.ndarray, n_pixels: int
                    ) -> list[tuple[int, tuple[float, float], tuple[int, int, int, int], np.ndarray]]:
    """The 8-connected parts (area, centroid, box, mask) of the brightest part of a region (boolean mask): its pixels
    at or above its ``n_pixels``-th largest 8-bit value; the region itself when it has no more pixels."""
    values = ref.image8[inside]
    if values.size <= n_pixels:
        m = cv2.moments(inside.astype(np.uint8), binaryImage=True)
        x, y, w, h = cv2.boundingRect(inside.astype(np.uint8))
        return [(int(m["m00"]), (m["m10"] / m["m00"], m["m01"] / m["m00"]), (x, y, w, h), inside)]
    level = int(np.sort(values)[values.size - n_pixels])
    return reference_components(inside & (ref.image8 >= level))


def reference_components(mask: np.ndarray) -> list[tuple[int, tuple[float, float], tuple[int, int, int, int],
                                                          np.ndarray]]:
    """The 8-connected components (area, centroid, box, mask) of a boolean mask, by OpenCV."""
    _, labels, stats, cents = cv2.connectedComponentsWithStats(mask.astype(np.uint8), connectivity=8)
    return [(int(stats[j, cv2.CC_STAT_AREA]), (float(cents[j][0]), float(cents[j][1])),
             tuple(int(v) for v in stats[j, :4]), labels == j) for j in range(1, len(stats))]


def reference_label(ref: ReferenceResult, area: int, bbox: tuple[int, int, int, int]) -> int:
    """The label (1-based) of the reference blob with this area and box; 0 if none."""
    hit = np.flatnonzero((ref.areas == area) & np.all(ref.bboxes == np.asarray(bbox), axis=1))
    return int(hit[0]) + 1 if hit.size else 0


def reference_binned(frame: np.ndarray, size_px: int) -> np.ndarray:
    """Return the frame binned to size_px x size_px by OpenCV's area interpolation."""
    return cv2.resize(frame, (size_px, size_px), interpolation=cv2.INTER_AREA)


def reference_8bit(binned: np.ndarray, bit_depth: int, law: str) -> np.ndarray:
    """Return the 8-bit image of a binned frame: 'sqrt' companding or a 'shift' to the top 8 bits."""
    vmax = float((1 << bit_depth) - 1)
    if law == "sqrt":
        root = cv2.sqrt(binned.astype(np.float32) * np.float32(1.0 / vmax))
        return cv2.convertScaleAbs(root, alpha=255.0)  # rounds to nearest and saturates to uint8
    if law == "shift":
        return cv2.convertScaleAbs(np.right_shift(binned, bit_depth - 8))
    raise ValueError(f"unknown compression law {law!r}")


def reference_threshold(image8: np.ndarray, k_sigma: float, margin_dn8: int, otsu_too: bool = False
                        ) -> tuple[int, int, int]:
    """Return (threshold, otsu, median): the noise floor, lower median + max(ceil(k 1.4826 MAD), margin), or with
    ``otsu_too`` the larger of it and OpenCV's Otsu threshold."""
    otsu, _ = cv2.threshold(image8, 0, 255, cv2.THRESH_BINARY | cv2.THRESH_OTSU)
    hist = cv2.calcHist([image8], [0], None, [256], [0, 256]).ravel()
    half = (image8.size + 1) // 2
    median = int(np.argmax(np.cumsum(hist) >= half))
    deviation = cv2.absdiff(image8, np.full_like(image8, median))
    dev_hist = cv2.calcHist([deviation], [0], None, [256], [0, 256]).ravel()
    mad = int(np.argmax(np.cumsum(dev_hist) >= half))
    floor = median + max(math.ceil(k_sigma * MAD_TO_SIGMA * mad), margin_dn8)
    return int(max(otsu, floor) if otsu_too else floor), int(otsu), median


@dataclass(frozen=True)
class SyntheticBody:
    """A Lambertian sphere in a synthetic frame: centre and radius in pixels of the full-resolution frame."""

    col: float
    row: float
    radius_px: float
    radiance_dn: float  # raw DN of a surface facing both the Sun and the camera


def synthetic_frame(
    rng: np.random.Generator,
    size_px: int = 1024,
    bodies: tuple[SyntheticBody, ...] = (),
    sun_camera: tuple[float, float, float] = (-0.5, 0.3, -0.8),
    background_dn: float = 40.0,
    read_noise_dn: float = 3.0,
    n_stars: int = 15,
    star_peak_dn: tuple[float, float] = (200.0, 3000.0),
    n_hot_pixels: int = 30,
    plume_from: int | None = None,
    plume_peak_dn: float = 600.0,
    plume_length_px: float = 200.0,
    plume_axis_deg: float = 60.0,
    plume_half_angle_deg: float = 35.0,
    bit_depth: int = 12,
) -> np.ndarray:
    """Draw a raw frame: shaded spheres (Lambert, so limb-darkened and phase-cut), an ejecta fan from one body,
    Gaussian-PSF stars, hot pixels, shot and read noise; ``sun_camera`` points to the Sun in camera axes
    (x = columns, y = rows, z = boresight, so the camera looks along +z and sees surfaces with normal z < 0).
    """
    cols = np.arange(size_px, dtype=np.float64)[None, :]
    rows = np.arange(size_px, dtype=np.float64)[:, None]
    signal = np.zeros((size_px, size_px))
    sun = np.asarray(sun_camera, dtype=np.float64)
    sun = sun / np.linalg.norm(sun)
    for b in bodies:
        x = (cols - b.col) / b.radius_px
        y = (rows - b.row) / b.radius_px
        r2 = x * x + y * y
        inside = r2 < 1.0
        z = -np.sqrt(np.clip(1.0 - r2, 0.0, None))  # visible hemisphere faces the camera (-z)
        cos_i = np.clip(x * sun[0] + y * sun[1] + z * sun[2], 0.0, None)
        signal = signal + np.where(inside, b.radiance_dn * cos_i, 0.0)
    if plume_from is not None:
        src = bodies[plume_from]
        dx = cols - src.col
        dy = rows - src.row
        dist = np.hypot(dx, dy)
        axis = math.radians(plume_axis_deg)
        ang = np.abs(np.angle(np.exp(1j * (np.arctan2(dy, dx) - axis))))
        fan = (ang < math.radians(plume_half_angle_deg)) & (dist > src.radius_px) & (dist < plume_length_px)
        falloff = plume_peak_dn * np.exp(-dist / (0.3 * plume_length_px)) * np.cos(
            0.5 * math.pi * ang / math.radians(plume_half_angle_deg)
        )
        signal = signal + np.where(fan, falloff, 0.0)
    if n_stars:
        sc = rng.uniform(10, size_px - 10, n_stars)
        sr = rng.uniform(10, size_px - 10, n_stars)
        peak = rng.uniform(star_peak_dn[0], star_peak_dn[1], n_stars)
        for c, r, p in zip(sc, sr, peak, strict=True):
            c0, r0 = int(c) - 6, int(r) - 6
            patch_c = np.arange(c0, c0 + 13, dtype=np.float64)[None, :]
            patch_r = np.arange(r0, r0 + 13, dtype=np.float64)[:, None]
            signal[r0 : r0 + 13, c0 : c0 + 13] += p * np.exp(-((patch_c - c) ** 2 + (patch_r - r) ** 2) / (2 * 1.2**2))
    vmax = (1 << bit_depth) - 1
    counts = rng.poisson(np.clip(signal, 0.0, None)) + background_dn + rng.normal(0.0, read_noise_dn, signal.shape)
    frame = np.clip(np.rint(counts), 0, vmax).astype(np.uint16)
    if n_hot_pixels:
        hot = rng.integers(0, size_px, (n_hot_pixels, 2))
        frame[hot[:, 0], hot[:, 1]] = vmax
    return frame


@dataclass(frozen=True)
class OpenCvMap:
    """A bad-pixel map prepared for ``opencv_pipeline``: flat indices of the bad pixels and of their left and right
    good neighbours (-1: none), computed once, as a flight map is."""

    bad: np.ndarray
    left: np.ndarray
    right: np.ndarray

    @classmethod
    def of(cls, side: int, pixels_col_row: list[tuple[int, int]] | tuple, columns: list[int] | tuple) -> OpenCvMap:
        """The map of these pixels and dead columns on a side x side frame."""
        mask = np.zeros((side, side), dtype=bool)
        for c, r in pixels_col_row:
            mask[r, c] = True
        mask[:, list(columns)] = True
        idx = np.broadcast_to(np.arange(side), (side, side))
        left = np.maximum.accumulate(np.where(mask, -1, idx), axis=1)
        right = np.minimum.accumulate(np.where(mask, side, idx)[:, ::-1], axis=1)[:, ::-1]
        rows = np.broadcast_to(np.arange(side)[:, None], (side, side))
        bad = np.flatnonzero(mask)
        lf = np.where(left.reshape(-1)[bad] >= 0, rows.reshape(-1)[bad] * side + left.reshape(-1)[bad], -1)
        rt = np.where(right.reshape(-1)[bad] < side, rows.reshape(-1)[bad] * side + right.reshape(-1)[bad], -1)
        return cls(bad=bad, left=lf, right=rt)


def opencv_pipeline(frame: np.ndarray, bad: OpenCvMap | None = None, size_px: int = 512, bit_depth: int = 12,
                    k_sigma: float = 5.0, margin_dn8: int = 3, outlier_k_sigma: float = 5.0,
                    outlier_ratio: float = 2.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The pipeline of ``reference_pipeline`` in OpenCV's fast primitives, for the benchmark's timing: the bad-pixel
    map by index, the outlier filter with cv2.medianBlur, cv2.resize INTER_AREA for the block means, cv2.dilate for
    the block maxima, cv2.calcHist for the statistics, then binning, companding, threshold and
    cv2.connectedComponentsWithStats; (stats, centroids, binned image)."""
    side = frame.shape[0]
    f = side // size_px
    corrected = frame.copy()
    if bad is not None and bad.bad.size:
        flat = corrected.reshape(-1)
        lv = flat[np.maximum(bad.left, 0)].astype(np.int32)
        rv = flat[np.maximum(bad.right, 0)].astype(np.int32)
        has_l, has_r = bad.left >= 0, bad.right >= 0
        flat[bad.bad] = np.where(has_l & has_r, (lv + rv + 1) // 2, np.where(has_l, lv, np.where(has_r, rv,
                                                                                             flat[bad.bad])))
    means = cv2.resize(corrected.astype(np.float32), (size_px, size_px), interpolation=cv2.INTER_AREA)
    binned0 = cv2.resize(corrected, (size_px, size_px), interpolation=cv2.INTER_AREA)
    hist = cv2.calcHist([binned0], [0], None, [1 << bit_depth], [0, 1 << bit_depth]).ravel()
    half = (binned0.size + 1) // 2
    background = int(np.argmax(np.cumsum(hist) >= half))
    dev = cv2.absdiff(binned0, np.full_like(binned0, background))
    mad = int(np.argmax(np.cumsum(cv2.calcHist([dev], [0], None, [1 << bit_depth], [0, 1 << bit_depth]).ravel())
                        >= half))
    sigma = max(f * MAD_TO_SIGMA * mad, 1.0)
    maxima = cv2.dilate(corrected, np.ones((f, f), np.uint8), anchor=(0, 0))[::f, ::f].astype(np.float32)
    area = float(f * f)
    others = (means * area - maxima) / (area - 1.0)
    dominated = (maxima - others) > outlier_k_sigma * sigma + (outlier_ratio - 1.0) * cv2.max(others - background, 0.0)
    dominated_px = cv2.resize(dominated.astype(np.uint8), (side, side), interpolation=cv2.INTER_NEAREST)
    median = cv2.medianBlur(corrected, 3)
    level = outlier_ratio * cv2.max(median.astype(np.float32) - background, 0.0) + outlier_k_sigma * sigma + background
    outliers = (dominated_px > 0) & (corrected.astype(np.float32) > level)
    np.copyto(corrected, median, where=outliers)
    binned = cv2.resize(corrected, (size_px, size_px), interpolation=cv2.INTER_AREA)
    image8 = reference_8bit(binned, bit_depth, "sqrt")
    thr, _, _ = reference_threshold(image8, k_sigma, margin_dn8)
    _, mask = cv2.threshold(image8, thr, 255, cv2.THRESH_BINARY)
    _, _, stats, centroids = cv2.connectedComponentsWithStats(mask, connectivity=8)
    return stats, centroids, binned
