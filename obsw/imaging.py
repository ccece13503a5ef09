"""Imaging subsystem: from a raw 12-bit frame to the offsets of Didymos and Dimorphos from the image centre.

Emulates the LICIACube pipeline (paper, "Imaging Subsystem"): steps 1-3 are the FPGA's, step 4 the OBSW's.

1. Filtering: bin the 1024x1024 (or 2048x2048) frame to 512x512 by the rounded mean of 2x2 (4x4) blocks, which
   keeps the raw bit depth, then compress to 8 bit through a monotonic look-up table (``ImagingConfig``:
   square-root companding by default, or a plain shift).
2. Binarisation: the threshold comes from the 8-bit luminance histogram. It is the larger of Otsu's threshold
   (the split that maximises the between-class variance) and a noise floor, background median + k robust
   sigmas (1.4826 x the median absolute deviation, both read off the histogram). Otsu separates the lit
   bodies from the background and the diffuse plume when the bodies fill enough pixels; when they fill only
   a few pixels, or none (blank frame), Otsu falls inside the background noise and the floor takes over.
   Stars and hot pixels are a negligible part of the histogram, so they move neither statistic; they survive
   binarisation and are rejected by identification. A pixel is foreground when its 8-bit value is above
   the threshold (OpenCV THRESH_BINARY semantics).
3. Object detection: 8-connected component labelling by run-length encoding and a vectorised union-find of
   overlapping runs of adjacent rows; labels are numbered in raster order of each component's first pixel.
4. Feature extraction and identification: area, region centroid (mean pixel position, pixel centres at
   integer coordinates, as OpenCV's connectedComponentsWithStats), bounding box, second-moment elongation,
   mean and peak 8-bit brightness of every blob. A large blob whose pixels are mostly faint (the ejecta plume,
   possibly merged with the bodies) is replaced by its cores above the Otsu threshold of its own pixels
   (``split_diffuse_blobs``). Each blob's position (``Blob.centroid_col_row``) is the binary centroid of its
   core, its pixels at or above ``core_peak_fraction`` of its peak above the background (``core_level_dn8``):
   a lit surface keeps most of its pixels, while the dense ejecta leaving Dimorphos, which make its blob
   several times larger than the body a few pixels across, are fainter and stay out, so the position is not
   pulled along the plume. Then Didymos and Dimorphos are told from stars, hot pixels, the plume and pieces of
   a thin crescent by core area, compactness, brightness, geometry and continuity with the last frame that saw
   both (see ``identify_bodies``); when in doubt, Dimorphos is not reported rather than a wrong body.

Image x (columns) is body +X, image y (rows) body +Y, the boresight body +Z; the image centre is at
((n - 1) / 2, (n - 1) / 2) in pixel-centre coordinates of the n x n binned image.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from contracts.messages import CentroidMeasurement
from obsw.config import CameraKnowledge, ImagingConfig

MAD_TO_SIGMA = 1.4826  # one Gaussian sigma per median absolute deviation


class FrameError(ValueError):
    """A frame cannot be processed: wrong shape, type or pixel values for the imaging configuration."""


@dataclass(frozen=True, slots=True)
class Blob:
    """One 8-connected region of the binarised 512x512 image."""

    label: int  # 1-based, raster order of the region's first pixel (OpenCV numbering)
    area_px: int
    centroid_col_row: tuple[float, float]  # binary centroid of the core (the body's position), px at binned scale
    bbox_col_row_w_h: tuple[int, int, int, int]  # left column, top row, width, height, px
    mean_dn8: float  # mean 8-bit brightness of the region's pixels
    peak_dn8: int
    elongation: float  # major/minor axis ratio from the second central moments (1 for a disc)
    threshold_dn8: int  # the region is the 8-connected set of pixels above this 8-bit value
    core_area_px: int  # pixels of the region at or above its core level (see core_level_dn8)
    region_centroid_col_row: tuple[float, float]  # binary centroid of all the region's pixels, px at binned scale
    split_from: int = 0  # label of the diffuse blob this core was cut out of (0: not split)

    @property
    def diameter_px(self) -> int:
        """Largest side of the bounding box: the apparent diameter of a body, even a crescent."""
        return max(self.bbox_col_row_w_h[2], self.bbox_col_row_w_h[3])


@dataclass(frozen=True, slots=True)
class Detections:
    """What the imaging subsystem reports for one frame."""

    blobs: tuple[Blob, ...]
    didymos: Blob | None
    dimorphos: Blob | None
    didymos_offset_px: tuple[float, float] | None  # (col, row) offset from the image centre, 512 scale
    dimorphos_offset_px: tuple[float, float] | None
    didymos_offset_rad: tuple[float, float] | None  # (atan(col offset / f_px), atan(row offset / f_px)), rad
    dimorphos_offset_rad: tuple[float, float] | None
    threshold_dn8: int  # foreground is above this 8-bit value
    background_dn8: int  # median of the 8-bit histogram
    noise_sigma_dn8: float  # robust sigma of the background
    binned_size_px: int
    # the latest (didymos, dimorphos) seen together, kept through frames without Dimorphos for continuity
    pair: tuple[Blob, Blob] | None = None
    pair_age_frames: int = 0  # frames since ``pair`` was seen (0: in this frame)


@dataclass(frozen=True, slots=True)
class Binarisation:
    """The threshold chosen on the 8-bit histogram and the statistics it came from."""

    threshold_dn8: int
    otsu_dn8: int
    background_dn8: int
    noise_sigma_dn8: float


def compression_lut(cfg: ImagingConfig, bit_depth: int) -> np.ndarray:
    """Return the uint8 look-up table, one entry per raw value, of the configured 12->8 bit law (monotonic)."""
    vmax = (1 << bit_depth) - 1
    values = np.arange(vmax + 1, dtype=np.float64)
    if cfg.compression_law == "sqrt":
        return np.floor(255.0 * np.sqrt(values / vmax) + 0.5).astype(np.uint8)
    return (np.arange(vmax + 1, dtype=np.int64) >> (bit_depth - 8)).astype(np.uint8)


_LUT_CACHE: dict[tuple[int, str], np.ndarray] = {}


def _lut(cfg: ImagingConfig, bit_depth: int) -> np.ndarray:
    """Return the compression table of ``cfg``, built once per law (it is a constant of the FPGA)."""
    key = (bit_depth, cfg.compression_law)
    lut = _LUT_CACHE.get(key)
    if lut is None:
        lut = compression_lut(cfg, bit_depth)
        lut.setflags(write=False)
        _LUT_CACHE[key] = lut
    return lut


def binned(frame: np.ndarray, cfg: ImagingConfig, bit_depth: int) -> np.ndarray:
    """Return the frame binned to cfg.binned_size_px by the rounded mean of square blocks (raw bit depth)."""
    if frame.ndim != 2 or frame.shape[0] != frame.shape[1]:
        raise FrameError(f"frame must be a square 2-D array, got shape {frame.shape}")
    if frame.dtype.kind not in "ui":
        raise FrameError(f"frame must hold integers, got dtype {frame.dtype}")
    n = cfg.binned_size_px
    side = frame.shape[0]
    if side % n != 0:
        raise FrameError(f"frame side {side} px is not a multiple of binned_size_px {n}")
    f = side // n
    vmax = (1 << bit_depth) - 1
    # a value beyond the bit depth would wrap the block sums: refuse it rather than alias it
    if int(frame.max(initial=0)) > vmax or (frame.dtype.kind == "i" and int(frame.min(initial=0)) < 0):
        raise FrameError(f"frame pixel values exceed the {bit_depth}-bit range 0..{vmax}")
    acc = np.uint16 if vmax * f * f <= 0xFFFF else np.uint32
    a = frame if frame.dtype == acc else frame.astype(acc)
    if f == 1:
        return a.copy()
    # sum the f rows of each block (consecutive slices of a reshaped row), then its f columns
    rows = a.reshape(n, f * side)
    s = rows[:, :side] + rows[:, side : 2 * side]
    for k in range(2, f):
        s += rows[:, k * side : (k + 1) * side]
    cols = s.reshape(n, n, f)
    out = cols[:, :, 0] + cols[:, :, 1]
    for k in range(2, f):
        out += cols[:, :, k]
    area = f * f
    out += area // 2
    if area & (area - 1) == 0:
        out >>= area.bit_length() - 1
    else:
        out //= area
    return out


def compressed_8bit(binned_image: np.ndarray, cfg: ImagingConfig, bit_depth: int) -> np.ndarray:
    """Return the 8-bit image of the configured compression law (for display and downlink)."""
    return np.take(_lut(cfg, bit_depth), binned_image)


def otsu_threshold(hist: np.ndarray) -> int:
    """Return Otsu's threshold t of a histogram: classes v <= t and v > t with the largest between-class variance.

    Same definition as OpenCV's THRESH_OTSU: 0 when no split leaves both classes non-empty, first maximum on ties.
    """
    h = np.asarray(hist, dtype=np.float64)
    total = h.sum()
    if total <= 0:
        return 0
    p = h / total
    levels = np.arange(h.size, dtype=np.float64)
    q1 = np.cumsum(p)
    m1 = np.cumsum(p * levels)
    mu = m1[-1]
    q2 = 1.0 - q1
    eps = float(np.finfo(np.float32).eps)
    valid = (np.minimum(q1, q2) >= eps) & (np.maximum(q1, q2) <= 1.0 - eps)
    if not valid.any():
        return 0
    with np.errstate(divide="ignore", invalid="ignore"):
        mu1 = m1 / q1
        mu2 = (mu - m1) / q2
        sigma = q1 * q2 * (mu1 - mu2) ** 2
    sigma = np.where(valid, sigma, -1.0)
    return int(np.argmax(sigma))


def binarisation(hist8: np.ndarray, cfg: ImagingConfig) -> Binarisation:
    """Return the threshold of an 8-bit histogram: max(Otsu, background median + k robust sigma)."""
    h = np.asarray(hist8, dtype=np.int64)
    total = int(h.sum())
    if total <= 0:
        raise FrameError("empty histogram: the frame has no pixels")
    cum = np.cumsum(h)
    median = int(np.searchsorted(cum, (total + 1) // 2))
    # histogram of |v - median|: fold the histogram about the median
    levels = np.arange(h.size)
    dev_hist = np.bincount(np.abs(levels - median), weights=h, minlength=h.size)
    mad = int(np.searchsorted(np.cumsum(dev_hist), (total + 1) // 2))
    sigma = MAD_TO_SIGMA * mad
    floor = median + max(math.ceil(cfg.noise_k_sigma * sigma), cfg.min_threshold_margin_dn8)
    otsu = otsu_threshold(h)
    return Binarisation(
        threshold_dn8=int(max(otsu, floor)), otsu_dn8=otsu, background_dn8=median, noise_sigma_dn8=float(sigma)
    )


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


def focal_length_px(fov_deg: float, width_px: int) -> float:
    """Return the pinhole focal length in pixels of an image width_px wide spanning fov_deg horizontally."""
    if not 0.0 < fov_deg < 180.0:
        raise ValueError(f"fov_deg must be in (0, 180), got {fov_deg}")
    if width_px <= 0:
        raise ValueError(f"width_px must be positive, got {width_px}")
    return 0.5 * width_px / math.tan(math.radians(0.5 * fov_deg))


def los_body(offset_col_px: float, offset_row_px: float, fov_deg: float, width_px: int) -> np.ndarray:
    """Return the unit line of sight in body axes of an image offset from the centre (boresight +Z).

    Columns run along body +X and rows along body +Y, so the pinhole ray is (col, row, f_px) normalised.
    """
    f = focal_length_px(fov_deg, width_px)
    v = np.array([offset_col_px, offset_row_px, f], dtype=np.float64)
    return v / np.linalg.norm(v)


def offset_rad(offset_px: tuple[float, float], fov_deg: float, width_px: int) -> tuple[float, float]:
    """Return the pinhole angles atan(offset / f_px) of a (col, row) pixel offset from the image centre."""
    f = focal_length_px(fov_deg, width_px)
    return (math.atan(offset_px[0] / f), math.atan(offset_px[1] / f))


def _distance(a: tuple[float, float], b: tuple[float, float]) -> float:
    """Return the Euclidean distance between two (col, row) points."""
    return math.hypot(a[0] - b[0], a[1] - b[1])


def _separation(blob: Blob, point: tuple[float, float]) -> float:
    """Return the distance from a point to a body blob: to its centroid, or to its box for a plume core, whose
    centroid is pulled along the plume while Dimorphos, the source, is at one end of it."""
    if not blob.split_from:
        return _distance(blob.centroid_col_row, point)
    x, y, w, h = blob.bbox_col_row_w_h
    dx = max(x - point[0], 0.0, point[0] - (x + w - 1))
    dy = max(y - point[1], 0.0, point[1] - (y + h - 1))
    return math.hypot(dx, dy)


def _relative(blob: Blob, origin: Blob) -> tuple[float, float]:
    """Return the centroid of ``blob`` relative to the centroid of ``origin``."""
    return (
        blob.centroid_col_row[0] - origin.centroid_col_row[0],
        blob.centroid_col_row[1] - origin.centroid_col_row[1],
    )


def _continues_dimorphos_alone(blob: Blob, prev_did: Blob, prev_dim: Blob, cfg: ImagingConfig) -> bool:
    """Return whether ``blob`` is Dimorphos seen without Didymos: Dimorphos-like area, Didymos's centre off-image."""
    area_vs_dim = abs(math.log(blob.area_px / prev_dim.area_px))
    area_vs_did = abs(math.log(blob.area_px / prev_did.area_px))
    rel = _relative(prev_dim, prev_did)
    col = blob.centroid_col_row[0] - rel[0]
    row = blob.centroid_col_row[1] - rel[1]
    last = cfg.binned_size_px - 1
    return area_vs_dim < area_vs_did and not (0.0 <= col <= last and 0.0 <= row <= last)


def _relative_jump_px(didymos: Blob, cfg: ImagingConfig) -> float:
    """Return the largest change between frames of the Dimorphos offset from this Didymos, px."""
    return cfg.dimorphos_max_relative_jump_didymos_diameters * didymos.diameter_px + cfg.centroid_noise_px


def _box_gap_px(a: Blob, b: Blob) -> int:
    """Return the number of pixels between two bounding boxes along the axis that separates them most (0: touching
    or overlapping)."""
    ax, ay, aw, ah = a.bbox_col_row_w_h
    bx, by, bw, bh = b.bbox_col_row_w_h
    gap_col = max(bx - (ax + aw), ax - (bx + bw), 0)
    gap_row = max(by - (ay + ah), ay - (by + bh), 0)
    return max(gap_col, gap_row)


def _piece_of_crescent(blob: Blob, didymos: Blob, cfg: ImagingConfig) -> bool:
    """Return whether ``blob`` may be a piece of Didymos's thin crescent broken off at the threshold: Didymos is
    elongated and the blob lies within a few pixels of its box."""
    return didymos.elongation >= cfg.crescent_min_elongation and _box_gap_px(blob, didymos) <= cfg.crescent_gap_px


def _largest(blobs: list[Blob]) -> Blob:
    """Return the blob of largest core area, the larger region then the brighter peak breaking ties."""
    return max(blobs, key=lambda b: (b.core_area_px, b.area_px, b.peak_dn8, -b.label))


def reference_pair(previous: Detections | None, cfg: ImagingConfig) -> tuple[Blob | None, Blob | None]:
    """Return the (didymos, dimorphos) that continuity refers to: the previous frame's pair, or the last pair seen
    when the frames since saw no Dimorphos, for at most ``cfg.pair_memory_frames`` frames and while Didymos is at
    most ``cfg.pair_memory_max_didymos_px`` across (far enough for the offset to change slowly); else (None, None)."""
    if previous is None:
        return None, None
    if previous.didymos is not None and previous.dimorphos is not None:
        return previous.didymos, previous.dimorphos
    if (
        previous.dimorphos is None
        and previous.pair is not None
        and previous.pair_age_frames < cfg.pair_memory_frames
        and previous.pair[0].diameter_px <= cfg.pair_memory_max_didymos_px
    ):
        return previous.pair
    return None, None


def identify_bodies(
    blobs: tuple[Blob, ...] | list[Blob], cfg: ImagingConfig, previous: Detections | None = None
) -> tuple[Blob | None, Blob | None]:
    """Return (didymos, dimorphos) among the blobs, either None when not seen.

    Body candidates are blobs of at least ``min_body_area_px`` (rejects hot pixels, noise and faint stars) and
    at most ``max_body_elongation`` (rejects plume rays and smeared stars). "Largest" ranks by core area (see
    ``core_level_dn8``), so Dimorphos inflated by its ejecta does not outgrow Didymos. "Previous" is the pair of
    ``reference_pair``: the previous frame's, or the last seen together, across frames where Dimorphos was not
    seen (merged with Didymos and its ejecta), while they are far.
    Didymos is the largest candidate, unless the previous frame saw both bodies and this candidate continues
    Dimorphos with Didymos out of the field: its area is nearer the previous Dimorphos area than the previous
    Didymos one (in ratio) and the previous Didymos-to-Dimorphos offset puts Didymos's centre outside the image
    (near C/A while tracking Dimorphos). Otherwise, with both seen before, Didymos is the largest candidate that
    has another candidate where the previous Didymos-to-Dimorphos offset predicts Dimorphos (so a plume core
    grown larger than Didymos is not taken for it). Continuity is on relative offsets, which pointing motion
    does not change.
    Dimorphos is a smaller candidate (area at most ``dimorphos_max_area_fraction`` of Didymos, peak at least
    ``dimorphos_min_peak_fraction`` of Didymos's) within ``dimorphos_max_separation_didymos_diameters`` of
    Didymos and not a piece of its thin crescent (``crescent_gap_px`` of a Didymos at least
    ``crescent_min_elongation``); among those, the one whose offset from Didymos continues the previous one (stars move relative to
    Didymos at the tracking rate; this one may exceed the area limit), else the largest. A core cut out of the
    plume may also exceed it, and is gated by its box rather than its centroid: the ejecta leave Dimorphos, so
    after the impact its blob is Dimorphos with the dense ejecta around it, and its centroid is their common
    photocentre. Before Dimorphos is resolved (merged with Didymos or below the minimum area) it is None.
    """
    candidates = [
        b for b in blobs if b.area_px >= cfg.min_body_area_px and b.elongation <= cfg.max_body_elongation
    ]
    if not candidates:
        return None, None
    prev_did, prev_dim = reference_pair(previous, cfg)
    didymos = _largest(candidates)
    if prev_did is not None and prev_dim is not None:
        if previous is not None and previous.dimorphos is prev_dim and _continues_dimorphos_alone(
            didymos, prev_did, prev_dim, cfg
        ):
            return None, didymos
        # prefer a Didymos with a companion where the previous relative offset puts Dimorphos
        predicted = _relative(prev_dim, prev_did)
        paired = [
            c
            for c in candidates
            if any(
                d is not c and _distance(_relative(d, c), predicted) <= _relative_jump_px(c, cfg) for d in candidates
            )
        ]
        if paired:
            didymos = _largest(paired)
    gate = cfg.dimorphos_max_separation_didymos_diameters * didymos.diameter_px + cfg.centroid_noise_px
    in_gate = [
        b
        for b in candidates
        if b is not didymos
        and b.peak_dn8 >= cfg.dimorphos_min_peak_fraction * didymos.peak_dn8
        and _separation(b, didymos.centroid_col_row) <= gate
        and not _piece_of_crescent(b, didymos, cfg)
    ]
    if prev_did is not None and prev_dim is not None:
        predicted = _relative(prev_dim, prev_did)
        jump = _relative_jump_px(didymos, cfg)
        continuing = [b for b in in_gate if _distance(_relative(b, didymos), predicted) <= jump]
        if continuing:
            # a continuing Dimorphos may outgrow the area limit: the plume's dense core grows around it
            return didymos, min(continuing, key=lambda b: _distance(_relative(b, didymos), predicted))
    sized = [b for b in in_gate if b.area_px <= cfg.dimorphos_max_area_fraction * didymos.area_px or b.split_from]
    return didymos, (_largest(sized) if sized else None)


def core_level_dn8(peak_dn8: np.ndarray, background_dn8: int, fraction: float) -> np.ndarray:
    """Return the core level of each region: background + ceil(fraction x (peak - background)), 8-bit DN.

    A lit surface is nearly uniform, so most of a body's pixels reach it; the diffuse ejecta fade away from
    their source, so few of theirs do, and a body's core is the body without the dust around it.
    """
    above = np.maximum(np.asarray(peak_dn8, dtype=np.int64) - background_dn8, 0)
    return background_dn8 + np.ceil(fraction * above - 1e-9).astype(np.int64)


def blobs_of(
    components: Components,
    values8: np.ndarray,
    threshold_dn8: int,
    background_dn8: int,
    width: int,
    cfg: ImagingConfig,
    first_label: int = 1,
    offset_col_row: tuple[int, int] = (0, 0),
    split_from: int = 0,
) -> list[Blob]:
    """Return the Blob records of labelled components, with brightness from the 8-bit foreground pixel values.

    ``width`` is the width of the labelled image; labels run from ``first_label``; ``offset_col_row`` shifts
    coordinates of components found in a crop. Each region's core is the set of its pixels at or above its
    ``core_level_dn8`` (``cfg.core_peak_fraction``).
    """
    k = components.area_px.size
    if k == 0:
        return []
    comp = components.pixel_component
    mean = np.bincount(comp, weights=values8, minlength=k) / components.area_px
    peak = np.zeros(k, dtype=np.int64)
    np.maximum.at(peak, comp, values8)
    level = core_level_dn8(peak, background_dn8, cfg.core_peak_fraction)
    in_core = np.flatnonzero(values8 >= level[comp])
    core_comp = comp[in_core]
    core_row, core_col = np.divmod(components.pixel_index[in_core], width)
    core_area = np.bincount(core_comp, minlength=k)
    core_c = np.bincount(core_comp, weights=core_col, minlength=k) / core_area
    core_r = np.bincount(core_comp, weights=core_row, minlength=k) / core_area
    dx, dy = offset_col_row
    return [
        Blob(
            label=first_label + i,
            area_px=area,
            centroid_col_row=(cc + dx, cr + dy),
            bbox_col_row_w_h=(x + dx, y + dy, w, h),
            mean_dn8=m,
            peak_dn8=p,
            elongation=e,
            threshold_dn8=threshold_dn8,
            core_area_px=ca,
            region_centroid_col_row=(c + dx, r + dy),
            split_from=split_from,
        )
        for i, (area, c, r, x, y, w, h, m, p, e, ca, cc, cr) in enumerate(
            zip(
                components.area_px.tolist(),
                components.centroid_col.tolist(),
                components.centroid_row.tolist(),
                components.left.tolist(),
                components.top.tolist(),
                components.width.tolist(),
                components.height.tolist(),
                mean.tolist(),
                peak.tolist(),
                components.elongation.tolist(),
                core_area.tolist(),
                core_c.tolist(),
                core_r.tolist(),
                strict=True,
            )
        )
    ]


def is_diffuse(values8: np.ndarray, background_dn8: int, cfg: ImagingConfig) -> bool:
    """Return whether a blob's pixels are mostly faint, as in the ejecta plume rather than a lit surface.

    Faint means below half of the blob's 95th-percentile level above the background (lower order statistic).
    A lit surface is nearly uniform (lunar-Lambert) with a dim rim along the terminator only; the plume fades
    smoothly away from its source, so most of its pixels are faint.
    """
    above = values8.astype(np.int64) - background_dn8
    k95 = (95 * (above.size - 1)) // 100
    level = int(np.partition(above, k95)[k95])
    return bool(np.count_nonzero(2 * above < level) > cfg.plume_faint_fraction * above.size)


def split_diffuse_blobs(
    blobs: list[Blob], components: Components, values8: np.ndarray, background_dn8: int, width: int, cfg: ImagingConfig
) -> list[Blob]:
    """Return the blobs with every large diffuse blob (plume, possibly merged with the bodies) replaced by the
    8-connected cores above the Otsu threshold of its own pixels: the bodies and the plume's densest part."""
    big = [b.label - 1 for b in blobs if b.area_px >= cfg.plume_min_area_px]
    if not big:
        return blobs
    order = np.argsort(components.pixel_component, kind="stable")
    ends = np.cumsum(components.area_px)
    out = list(blobs)
    replaced: set[int] = set()
    next_label = len(blobs) + 1
    for i in big:
        sel = order[ends[i] - components.area_px[i] : ends[i]]
        vals = values8[sel]
        if not is_diffuse(vals, background_dn8, cfg):
            continue
        t2 = otsu_threshold(np.bincount(vals, minlength=256))
        keep = vals > t2
        pix = components.pixel_index[sel][keep]
        rows, cols = np.divmod(pix, width)
        left, top = int(components.left[i]), int(components.top[i])
        h, w = int(components.height[i]), int(components.width[i])
        crop_vals = np.zeros((h, w), dtype=np.uint8)
        crop_vals[rows - top, cols - left] = vals[keep]
        crop_mask = np.zeros((h, w), dtype=bool)
        crop_mask[rows - top, cols - left] = True
        sub = connected_components(crop_mask)
        cores = blobs_of(
            sub, crop_vals.ravel()[sub.pixel_index], t2, background_dn8, w, cfg, next_label, (left, top), i + 1
        )
        next_label += len(cores)
        out.extend(cores)
        replaced.add(i + 1)
    return [b for b in out if b.label not in replaced]


def _offsets(blob: Blob | None, fov_deg: float, n: int) -> tuple[tuple[float, float] | None, tuple[float, float] | None]:
    """(px, rad) offsets of a blob's centroid from the centre of the n x n binned image; (None, None) without one."""
    if blob is None:
        return None, None
    centre = 0.5 * (n - 1)
    px = (blob.centroid_col_row[0] - centre, blob.centroid_col_row[1] - centre)
    return px, offset_rad(px, fov_deg, n)


def measured_detections(m: CentroidMeasurement, cfg: ImagingConfig, camera: CameraKnowledge = CameraKnowledge()
                        ) -> Detections:
    """The detections of a frame at centroid-level fidelity: the bodies the measurement reports, binned like pixels.

    A full-resolution position x becomes (x - (b - 1) / 2) / b at binning b, an area a becomes a / b^2; a body is a
    blob of that area whose core is the whole blob (the measurement has no brightness, so those fields are 0).
    """
    n = cfg.binned_size_px
    b = camera.resolution_px / n

    def blob(label: int, col_row: tuple[float, float] | None, area_full_px: float) -> Blob | None:
        if col_row is None:
            return None
        c = ((col_row[0] - (b - 1) / 2) / b, (col_row[1] - (b - 1) / 2) / b)
        area = max(1, round(area_full_px / (b * b)))
        side = max(1, round(math.sqrt(area)))
        box = (math.floor(c[0] - side / 2), math.floor(c[1] - side / 2), side, side)
        return Blob(label=label, area_px=area, centroid_col_row=c, bbox_col_row_w_h=box, mean_dn8=0.0, peak_dn8=0,
                    elongation=1.0, threshold_dn8=0, core_area_px=area, region_centroid_col_row=c)

    didymos = blob(1, m.didymos_col_row, m.didymos_area_px)
    dimorphos = blob(2, m.dimorphos_col_row, m.dimorphos_area_px)

    did_px, did_rad = _offsets(didymos, camera.fov_deg, n)
    dim_px, dim_rad = _offsets(dimorphos, camera.fov_deg, n)
    return Detections(blobs=tuple(x for x in (didymos, dimorphos) if x is not None), didymos=didymos,
                      dimorphos=dimorphos, didymos_offset_px=did_px, dimorphos_offset_px=dim_px,
                      didymos_offset_rad=did_rad, dimorphos_offset_rad=dim_rad, threshold_dn8=0, background_dn8=0,
                      noise_sigma_dn8=0.0, binned_size_px=n,
                      pair=(didymos, dimorphos) if didymos is not None and dimorphos is not None else None)


def process_frame(frame: np.ndarray, cfg: ImagingConfig, previous: Detections | None = None,
                  camera: CameraKnowledge = CameraKnowledge()) -> Detections:
    """Return the blobs of a raw frame and the identified Didymos and Dimorphos with their offsets from centre."""
    image = binned(frame, cfg, camera.bit_depth)
    n = cfg.binned_size_px
    lut = _lut(cfg, camera.bit_depth)
    hist_raw = np.bincount(image.ravel(), minlength=lut.size)
    hist8 = np.bincount(lut, weights=hist_raw, minlength=256)
    thr = binarisation(hist8, cfg)
    # lut[v] > T  <=>  v >= first raw value mapped above T (the table is monotonic): threshold the raw image
    first_above = int(np.searchsorted(lut, thr.threshold_dn8, side="right"))
    components = connected_components(image >= first_above)
    values8 = lut[image.ravel()[components.pixel_index]]
    blobs = split_diffuse_blobs(
        blobs_of(components, values8, thr.threshold_dn8, thr.background_dn8, n, cfg), components, values8, thr.background_dn8, n, cfg
    )
    didymos, dimorphos = identify_bodies(blobs, cfg, previous)
    pair: tuple[Blob, Blob] | None = None
    age = 0
    if didymos is not None and dimorphos is not None:
        pair = (didymos, dimorphos)
    elif dimorphos is None and previous is not None and previous.pair is not None:
        # Dimorphos hidden (merged with Didymos or the plume): keep the last pair so it is found again by continuity
        pair, age = previous.pair, previous.pair_age_frames + 1
    did_px, did_rad = _offsets(didymos, camera.fov_deg, n)
    dim_px, dim_rad = _offsets(dimorphos, camera.fov_deg, n)
    return Detections(
        blobs=tuple(blobs),
        didymos=didymos,
        dimorphos=dimorphos,
        didymos_offset_px=did_px,
        dimorphos_offset_px=dim_px,
        didymos_offset_rad=did_rad,
        dimorphos_offset_rad=dim_rad,
        threshold_dn8=thr.threshold_dn8,
        background_dn8=thr.background_dn8,
        noise_sigma_dn8=thr.noise_sigma_dn8,
        binned_size_px=n,
        pair=pair,
        pair_age_frames=age,
    )
