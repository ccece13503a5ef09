"""Independent OpenCV implementation of the imaging pipeline, and a synthetic scene drawer, for tests and bench.

The reference follows the same definitions as obsw.imaging with OpenCV doing the work: cv2.resize INTER_AREA
binning, cv2.sqrt companding, cv2.calcHist and cv2.threshold(THRESH_OTSU) for the threshold, and
cv2.connectedComponentsWithStats (8-connectivity) for the blobs, and per blob cv2.minMaxLoc (peak) and cv2.moments
of its pixels at or above its core level (background + ceil(fraction x (peak - background))) for its core.
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

    binned: np.ndarray  # raw bit depth, n x n
    image8: np.ndarray  # uint8, n x n
    otsu_dn8: int
    threshold_dn8: int
    areas: np.ndarray  # (K,) int, background excluded
    centroids: np.ndarray  # (K, 2) col, row
    bboxes: np.ndarray  # (K, 4) left, top, width, height
    core_areas: np.ndarray  # (K,) int, pixels of each blob at or above its core level
    core_centroids: np.ndarray  # (K, 2) col, row of those pixels


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


def reference_threshold(image8: np.ndarray, k_sigma: float, margin_dn8: int) -> tuple[int, int, int]:
    """Return (threshold, otsu, median): max(OpenCV Otsu, lower median + max(ceil(k 1.4826 MAD), margin))."""
    otsu, _ = cv2.threshold(image8, 0, 255, cv2.THRESH_BINARY | cv2.THRESH_OTSU)
    hist = cv2.calcHist([image8], [0], None, [256], [0, 256]).ravel()
    half = (image8.size + 1) // 2
    median = int(np.argmax(np.cumsum(hist) >= half))
    deviation = cv2.absdiff(image8, np.full_like(image8, median))
    dev_hist = cv2.calcHist([deviation], [0], None, [256], [0, 256]).ravel()
    mad = int(np.argmax(np.cumsum(dev_hist) >= half))
    floor = median + max(math.ceil(k_sigma * MAD_TO_SIGMA * mad), margin_dn8)
    return int(max(otsu, floor)), int(otsu), median


def reference_cores(
    labels: np.ndarray, stats: np.ndarray, image8: np.ndarray, median: int, fraction: float
) -> tuple[np.ndarray, np.ndarray]:
    """Return (core areas, core centroids col/row) of the labelled blobs 1..K, each in its bounding box."""
    areas = np.zeros(len(stats) - 1, dtype=np.int64)
    cents = np.zeros((len(stats) - 1, 2))
    for k in range(1, len(stats)):
        x, y, w, h = (int(v) for v in stats[k, :4])
        inside = (labels[y : y + h, x : x + w] == k).astype(np.uint8)
        values = image8[y : y + h, x : x + w]
        peak = cv2.minMaxLoc(values, mask=inside)[1]
        level = median + math.ceil(fraction * max(peak - median, 0.0) - 1e-9)
        core = cv2.bitwise_and(inside, (values >= level).astype(np.uint8))
        m = cv2.moments(core, binaryImage=True)
        areas[k - 1] = int(m["m00"])
        cents[k - 1] = (x + m["m10"] / m["m00"], y + m["m01"] / m["m00"])
    return areas, cents


def reference_pipeline(
    frame: np.ndarray,
    size_px: int = 512,
    bit_depth: int = 12,
    law: str = "sqrt",
    k_sigma: float = 5.0,
    margin_dn8: int = 3,
    plume_min_area_px: int = 50,
    plume_faint_fraction: float = 0.4,
    threshold_dn8: int | None = None,
    core_peak_fraction: float = 0.65,
) -> ReferenceResult:
    """Run the OpenCV pipeline on a raw frame; threshold_dn8 forces the threshold instead of computing it.

    Blobs of at least plume_min_area_px whose pixels are more than plume_faint_fraction below half their
    95th-percentile level above background are replaced by the components above their own Otsu threshold.
    """
    binned = reference_binned(frame, size_px)
    image8 = reference_8bit(binned, bit_depth, law)
    thr, otsu, median = reference_threshold(image8, k_sigma, margin_dn8)
    if threshold_dn8 is not None:
        thr = threshold_dn8
    _, mask = cv2.threshold(image8, thr, 255, cv2.THRESH_BINARY)
    _, labels, stats, centroids = cv2.connectedComponentsWithStats(mask, connectivity=8)
    areas = [stats[1:, cv2.CC_STAT_AREA]]
    cents = [centroids[1:]]
    boxes = [stats[1:, :4]]
    core_a, core_c = reference_cores(labels, stats, image8, median, core_peak_fraction)
    core_areas = [core_a]
    core_cents = [core_c]
    keep = np.ones(len(stats) - 1, dtype=bool)
    for k in np.flatnonzero(stats[1:, cv2.CC_STAT_AREA] >= plume_min_area_px) + 1:
        inside = labels == k
        values = image8[inside]
        above = np.sort(values.astype(np.int64) - median)
        level = above[(95 * (above.size - 1)) // 100]
        if np.count_nonzero(2 * above < level) <= plume_faint_fraction * above.size:
            continue
        core_t, _ = cv2.threshold(values.reshape(1, -1), 0, 255, cv2.THRESH_BINARY | cv2.THRESH_OTSU)
        core = (inside & (image8 > core_t)).astype(np.uint8)
        _, l2, s2, c2 = cv2.connectedComponentsWithStats(core, connectivity=8)
        a2, cc2 = reference_cores(l2, s2, image8, median, core_peak_fraction)
        core_areas.append(a2)
        core_cents.append(cc2.reshape(-1, 2))
        areas.append(s2[1:, cv2.CC_STAT_AREA])
        cents.append(c2[1:])
        boxes.append(s2[1:, :4])
        keep[k - 1] = False
    areas[0], cents[0], boxes[0] = areas[0][keep], cents[0][keep], boxes[0][keep]
    core_areas[0], core_cents[0] = core_areas[0][keep], core_cents[0][keep]
    return ReferenceResult(
        binned=binned,
        image8=image8,
        otsu_dn8=otsu,
        threshold_dn8=thr,
        areas=np.concatenate(areas).astype(np.int64),
        centroids=np.concatenate(cents),
        bboxes=np.concatenate(boxes).astype(np.int64),
        core_areas=np.concatenate(core_areas).astype(np.int64),
        core_centroids=np.concatenate(core_cents).reshape(-1, 2),
    )


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
