"""Step 1 of the imaging chain, the FPGA's filtering: defect correction, binning and the 12->8 bit look-up table.

Before the frame is binned, the detector's defects are taken out, as a flight imaging subsystem does:

- **Bad-pixel map.** The pixels and columns ground found bad in its calibration (hot and warm pixels of a dark frame,
  dead pixels and columns of a flat field) and uploaded (``pus.LoadBadPixelMap``) are each replaced by the mean of
  the nearest good pixels left and right of it in its row (a dead column by its two neighbouring columns).
- **Outlier filter.** What the map does not know, new hot pixels and the streaks of cosmic rays, is sharp: charge in
  one pixel and not in its neighbours, where light from the scene is spread by the optics over several pixels. A
  pixel ``v`` is an outlier when its 2x2 binning block (f x f at 2048) is dominated by one pixel, the block's
  brightest exceeding the mean m of the others by ``outlier_k_sigma`` noise sigmas plus (``outlier_ratio`` - 1)
  times m above the background, and ``v`` itself exceeds ``outlier_ratio`` times the median of its 3x3
  neighbourhood (itself included, as OpenCV's ``medianBlur``) above the background plus ``outlier_k_sigma`` sigmas.
  Both tests scale with the local signal, so a lit surface's shot noise does not pass for a defect. An outlier is replaced by that median. A streak one pixel wide
  leaves at most four of the nine pixels of a neighbourhood lit, so the median is the background's and the streak
  goes; a lit surface keeps its pixels (a limb pixel has half its neighbourhood lit). All decisions are taken on the
  frame after the map's correction, and all outliers are replaced at once. The block test is what makes the filter
  cheap: only the blocks it selects (defects, stars, limbs of bodies) are examined pixel by pixel.

Background and noise come from the binned image after the map's correction: its median, and the per-pixel noise
sigma f x 1.4826 x its median absolute deviation (the binned pixel is the mean of f^2 pixels; at least 1 DN).
Binning is the rounded mean of f x f blocks at the raw bit depth (cv2.resize INTER_AREA for 1024 -> 512); the
corrections enter the block sums, so the frame itself is never copied or changed.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field

import numpy as np

from obsw import imaging_kernels as kernels
from obsw.config import ImagingConfig

MAD_TO_SIGMA = 1.4826  # one Gaussian sigma per median absolute deviation


class FrameError(ValueError):
    """A frame cannot be processed: wrong shape, type or pixel values for the imaging configuration."""


@dataclass(frozen=True, eq=False)
class BadPixelMap:
    """The on-board map of bad pixels of a side x side sensor, with each pixel's replacement neighbours.

    ``pixels`` are the flat indices (row * side + column) of every bad pixel, the pixels of dead columns included,
    sorted; ``left`` and ``right`` the flat index of the nearest good pixel on each side in the same row (-1: none).
    """

    side: int
    pixels: np.ndarray
    left: np.ndarray
    right: np.ndarray
    columns: tuple[int, ...]  # dead columns as uploaded
    _blocks: dict[int, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict, init=False, repr=False)

    @classmethod
    def build(cls, side: int, pixels_col_row: tuple[tuple[int, int], ...] | list[tuple[int, int]],
              columns: tuple[int, ...] | list[int] = ()) -> BadPixelMap:
        """The map of these (column, row) pixels and whole columns; ValueError naming the first one off the sensor."""
        if side <= 0:
            raise ValueError(f"side must be positive, got {side}")
        for c, r in pixels_col_row:
            if not (0 <= c < side and 0 <= r < side):
                raise ValueError(f"bad pixel (col {c}, row {r}) is outside the {side}x{side} sensor")
        for c in columns:
            if not 0 <= c < side:
                raise ValueError(f"dead column {c} is outside the {side}x{side} sensor")
        flat = [np.asarray([r * side + c for c, r in pixels_col_row], dtype=np.int64)]
        rows = np.arange(side, dtype=np.int64)
        flat += [rows * side + c for c in columns]
        every = np.unique(np.concatenate(flat)) if flat else np.zeros(0, dtype=np.int64)
        left = np.full(every.size, -1, dtype=np.int64)
        right = np.full(every.size, -1, dtype=np.int64)
        if every.size:
            # runs of adjacent bad pixels in one row share their good neighbours: the pixel before the run's first
            # and after its last, when those are still in the row
            starts = np.r_[True, np.diff(every) != 1] | (every % side == 0)
            run = np.cumsum(starts) - 1
            first = every[starts]
            ends = np.r_[starts[1:], True]
            last = every[ends]
            lo, hi = first - 1, last + 1
            left = np.where(first % side > 0, lo, -1)[run]
            right = np.where(last % side < side - 1, hi, -1)[run]
        for a in (every, left, right):
            a.setflags(write=False)
        return cls(side=side, pixels=every, left=left, right=right, columns=tuple(int(c) for c in columns))

    def __len__(self) -> int:
        return int(self.pixels.size)

    def blocks(self, f: int) -> tuple[np.ndarray, np.ndarray]:
        """The f x f binning blocks holding bad pixels (sorted flat indices at the binned scale) and, for each bad
        pixel, the position of its block among them; computed once per binning (the map is a constant between
        uploads)."""
        got = self._blocks.get(f)
        if got is None:
            n = self.side // f
            rows, cols = np.divmod(self.pixels, self.side)
            got = np.unique((rows // f) * n + cols // f, return_inverse=True)
            for a in got:
                a.setflags(write=False)
            self._blocks[f] = got
        return got

    def replacement(self, flat_frame: np.ndarray) -> np.ndarray:
        """The replacement value (int64) of each bad pixel in a flattened frame: the rounded mean of its good
        neighbours in the row, the one that exists, or its own value when the whole row is bad."""
        own = flat_frame[self.pixels].astype(np.int64)
        lv = flat_frame[np.maximum(self.left, 0)].astype(np.int64)
        rv = flat_frame[np.maximum(self.right, 0)].astype(np.int64)
        has_l, has_r = self.left >= 0, self.right >= 0
        return np.where(has_l & has_r, (lv + rv + 1) // 2, np.where(has_l, lv, np.where(has_r, rv, own)))


@dataclass(frozen=True, slots=True)
class Filtered:
    """The binned image of a frame after defect correction, with what the filtering found."""

    binned: np.ndarray  # (n, n), raw bit depth
    hist: np.ndarray  # histogram of the binned values, one bin per raw value
    background_dn: int  # median of the binned image before the outlier filter, raw DN
    noise_sigma_dn: float  # per-pixel noise sigma at full resolution used by the outlier filter, raw DN
    bad_pixels: int  # pixels replaced by the map
    outliers: np.ndarray  # flat indices (full resolution) of the pixels the outlier filter replaced


def check_frame(frame: np.ndarray, side: int, bit_depth: int, values: bool = True) -> None:
    """Raise FrameError unless ``frame`` is a side x side array of unsigned integers of at least ``bit_depth`` bits
    whose values fit that depth (``values``: False leaves the values to ``filtered``, which reads them anyway)."""
    if not isinstance(frame, np.ndarray):
        raise FrameError(f"frame must be a numpy array, got {type(frame).__name__}")
    if frame.size == 0:
        raise FrameError(f"frame is empty (shape {frame.shape})")
    if frame.ndim != 2 or frame.shape[0] != frame.shape[1]:
        raise FrameError(f"frame must be a square 2-D array, got shape {frame.shape}")
    if frame.dtype.kind not in "ui":
        raise FrameError(f"frame must hold integers, got dtype {frame.dtype}")
    if frame.dtype.itemsize * 8 < bit_depth:
        raise FrameError(f"frame dtype {frame.dtype} holds {frame.dtype.itemsize * 8}-bit values; the camera's "
                         f"frames are {bit_depth}-bit (an 8-bit image is not a raw frame)")
    if frame.shape[0] != side:
        raise FrameError(f"frame side {frame.shape[0]} px is not the camera's {side} px")
    vmax = (1 << bit_depth) - 1
    # a value beyond the bit depth would alias another: refuse it (a uint16 frame's values: ``filtered`` refuses them)
    if (values or frame.dtype != np.uint16) and (
            int(frame.max()) > vmax or (frame.dtype.kind == "i" and int(frame.min()) < 0)):
        raise FrameError(_RANGE.format(bit_depth=bit_depth, vmax=vmax))


_RANGE = "frame pixel values exceed the {bit_depth}-bit range 0..{vmax}"


def _block_sums_and_maxima(frame: np.ndarray, n: int, acc: type) -> tuple[np.ndarray, np.ndarray]:
    """(sums, maxima) of the f x f blocks of a square frame, (n, n) each in ``acc`` (f = side / n)."""
    side = frame.shape[0]
    f = side // n
    a = frame if frame.dtype == acc else frame.astype(acc)
    # the f rows of each block are consecutive slices of a reshaped row; then the f columns of each block
    rows = a.reshape(n, f * side)
    s = rows[:, :side] + rows[:, side : 2 * side] if f > 1 else rows.copy()
    m = np.maximum(rows[:, :side], rows[:, side : 2 * side]) if f > 1 else rows
    for k in range(2, f):
        s += rows[:, k * side : (k + 1) * side]
        np.maximum(m, rows[:, k * side : (k + 1) * side], out=m)
    if f == 1:
        return s, m
    cols_s = s.reshape(n, n, f)
    cols_m = m.reshape(n, n, f)
    out_s = cols_s[:, :, 0] + cols_s[:, :, 1]
    out_m = np.maximum(cols_m[:, :, 0], cols_m[:, :, 1])
    for k in range(2, f):
        out_s += cols_s[:, :, k]
        np.maximum(out_m, cols_m[:, :, k], out=out_m)
    return out_s, out_m


def _rounded_mean(sums: np.ndarray, area: int) -> np.ndarray:
    """floor(sum / area + 1/2) in place."""
    sums += area // 2
    if area & (area - 1) == 0:
        sums >>= area.bit_length() - 1
    else:
        sums //= area
    return sums


def histogram_median_mad(hist: np.ndarray) -> tuple[int, int]:
    """(lower median, lower median absolute deviation) of the values a histogram counts (bin i = value i)."""
    median, mad = kernels.median_mad(np.asarray(hist, dtype=np.int64))
    if median < 0:
        raise FrameError("empty histogram: the frame has no pixels")
    return int(median), int(mad)


def filtered(frame: np.ndarray, cfg: ImagingConfig, bit_depth: int, bad: BadPixelMap | None = None,
             working: bool = False) -> Filtered:
    """Correct the frame's defects and bin it (see the module docstring); the frame must have passed ``check_frame``.
    ``working``: the binned image is the thread's working buffer (``working_buffers``), valid until the thread's next
    frame (the chain's use: a fresh half-megabyte image every frame costs as many page faults as it has pages).

    The corrections are computed on the blocks that need them and added to the block sums, so the frame is read once
    (``imaging_kernels.block_statistics``) and then only around the defects.
    """
    n = cfg.binned_size_px
    side = frame.shape[0]
    if side % n != 0:
        raise FrameError(f"frame side {side} px is not a multiple of binned_size_px {n}")
    f = side // n
    area = f * f
    vmax = (1 << bit_depth) - 1
    if area * vmax > np.iinfo(np.int32).max:
        raise FrameError(f"{f} x {f} blocks of {bit_depth}-bit pixels overflow the binning's 32-bit sums: "
                         f"binned_size_px {n} is too small for a {side} px frame")
    pixels = frame if frame.dtype == np.uint16 else frame.astype(np.uint16)
    sums, maxima, binned_image = working_buffers(n)[:3]
    if not working:
        binned_image = np.empty((n, n), dtype=np.uint16)
    hist = np.zeros(vmax + 1, dtype=np.int64)
    row_top = np.empty(n, dtype=np.int64)
    if kernels.block_statistics(pixels, f, sums, maxima, binned_image, hist, row_top) > vmax:
        raise FrameError(_RANGE.format(bit_depth=bit_depth, vmax=vmax))
    flat_sums = sums.reshape(-1)
    flat_binned = binned_image.reshape(-1)
    flat_frame = pixels.reshape(-1)
    replaced = 0
    bad_blocks = bad_pixels = bad_values = np.zeros(0, dtype=np.int64)
    if bad is not None and len(bad):
        if bad.side != side:
            raise FrameError(f"the bad-pixel map is for a {bad.side} px sensor, the frame is {side} px")
        bad_pixels, bad_values = bad.pixels, bad.replacement(flat_frame)
        delta = bad_values - flat_frame[bad_pixels].astype(np.int64)
        bad_blocks, inverse = bad.blocks(f)
        kernels.add_to_blocks(flat_sums, flat_binned, hist, bad_blocks[inverse], delta, area)
        replaced = int(bad.pixels.size)
    background, mad = histogram_median_mad(hist)
    sigma = max(f * MAD_TO_SIGMA * mad, 1.0)
    outliers = np.zeros(0, dtype=np.int64)
    if cfg.outlier_filter and f > 1:
        # blocks whose brightest pixel stands out; a block's corrected sum keeps the test exact where the map changed
        # nothing, and the blocks the map changed are examined anyway
        blocks = kernels.standing_out(sums, maxima, area, cfg.outlier_k_sigma * sigma, cfg.outlier_ratio,
                                      float(background), row_top)
        if bad_blocks.size:
            blocks = kernels.union_sorted(blocks, bad_blocks)
        if blocks.size:
            outliers, block_delta, changed = kernels.outliers(
                pixels, blocks, f, cfg.outlier_k_sigma * sigma, cfg.outlier_ratio,
                int(background), bad_pixels, bad_values)
            if changed.size:
                kernels.add_to_blocks(flat_sums, flat_binned, hist, changed, block_delta, area)
    return Filtered(binned=binned_image, hist=hist, background_dn=background, noise_sigma_dn=float(sigma),
                    bad_pixels=replaced, outliers=outliers)


_SCRATCH = threading.local()


def working_buffers(n: int) -> tuple[np.ndarray, ...]:
    """The working memory of an n x n binning, allocated once per thread (fresh megabytes every frame would cost more
    page faults than the work): the block sums (int32: a block of up to 181 x 181 16-bit pixels) and maxima (uint16),
    the binned image (uint16), the foreground mask (bool), and the foreground pixels' indices and components (int64,
    n^2 each: ``imaging_labelling.connected_components``)."""
    buf = getattr(_SCRATCH, "blocks", None)
    if buf is None or buf[0].shape != (n, n):
        buf = (np.empty((n, n), dtype=np.int32), np.empty((n, n), dtype=np.uint16),
               np.empty((n, n), dtype=np.uint16), np.empty((n, n), dtype=np.bool_),
               np.empty(n * n, dtype=np.int64), np.empty(n * n, dtype=np.int64))
        _SCRATCH.blocks = buf
    return buf


def compression_lut(cfg: ImagingConfig, bit_depth: int) -> np.ndarray:
    """Return the uint8 look-up table, one entry per raw value, of the configured 12->8 bit law (monotonic)."""
    vmax = (1 << bit_depth) - 1
    values = np.arange(vmax + 1, dtype=np.float64)
    if cfg.compression_law == "sqrt":
        return np.floor(255.0 * np.sqrt(values / vmax) + 0.5).astype(np.uint8)
    return (np.arange(vmax + 1, dtype=np.int64) >> (bit_depth - 8)).astype(np.uint8)


_LUT_CACHE: dict[tuple[int, str], np.ndarray] = {}


def lut(cfg: ImagingConfig, bit_depth: int) -> np.ndarray:
    """Return the compression table of ``cfg``, built once per law (it is a constant of the FPGA)."""
    key = (bit_depth, cfg.compression_law)
    table = _LUT_CACHE.get(key)
    if table is None:
        table = compression_lut(cfg, bit_depth)
        table.setflags(write=False)
        _LUT_CACHE[key] = table
    return table


_LINEAR_CACHE: dict[tuple[int, str], np.ndarray] = {}


def linear_values(cfg: ImagingConfig, bit_depth: int) -> np.ndarray:
    """The raw value (float, 256 entries) each 8-bit code stands for: the mean of the raw values the compression table
    maps to it, interpolated between neighbours for a code no raw value maps to (the table's inverse)."""
    key = (bit_depth, cfg.compression_law)
    table = _LINEAR_CACHE.get(key)
    if table is None:
        codes = lut(cfg, bit_depth)
        count = np.bincount(codes, minlength=256)
        total = np.bincount(codes, weights=np.arange(codes.size, dtype=np.float64), minlength=256)
        hit = count > 0
        table = np.interp(np.arange(256.0), np.flatnonzero(hit), total[hit] / count[hit])
        table.setflags(write=False)
        _LINEAR_CACHE[key] = table
    return table


def binned(frame: np.ndarray, cfg: ImagingConfig, bit_depth: int) -> np.ndarray:
    """Return the frame binned to cfg.binned_size_px by the rounded mean of square blocks (raw bit depth), without
    defect correction."""
    check_frame(frame, frame.shape[0] if frame.ndim == 2 else -1, bit_depth)
    n = cfg.binned_size_px
    if frame.shape[0] % n != 0:
        raise FrameError(f"frame side {frame.shape[0]} px is not a multiple of binned_size_px {n}")
    vmax = (1 << bit_depth) - 1
    area = (frame.shape[0] // n) ** 2
    acc = np.uint16 if vmax * area <= 0xFFFF else np.uint32
    return _rounded_mean(_block_sums_and_maxima(frame, n, acc)[0], area)


def compressed_8bit(binned_image: np.ndarray, cfg: ImagingConfig, bit_depth: int) -> np.ndarray:
    """Return the 8-bit image of the configured compression law (for display and downlink)."""
    return np.take(lut(cfg, bit_depth), binned_image)
