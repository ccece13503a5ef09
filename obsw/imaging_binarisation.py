"""Step 2 of the imaging chain, binarisation (the FPGA's): the threshold from the 8-bit luminance histogram.

The threshold is the larger of Otsu's threshold (the split that maximises the between-class variance) and a noise
floor, background median + k robust sigmas (1.4826 x the median absolute deviation, both read off the histogram).
Otsu separates the lit bodies from the background and the diffuse plume when the bodies fill enough pixels; when
they fill only a few pixels, or none (blank frame), Otsu falls inside the background noise and the floor takes
over. Stars are a negligible part of the histogram, so they move neither statistic. A pixel is foreground when its
8-bit value is above the threshold (OpenCV THRESH_BINARY semantics).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from obsw import imaging_kernels as kernels
from obsw.config import ImagingConfig
from obsw.imaging_filtering import MAD_TO_SIGMA, Filtered, histogram_median_mad, lut, working_buffers


@dataclass(frozen=True, slots=True)
class Binarisation:
    """The threshold chosen on the 8-bit histogram and the statistics it came from."""

    threshold_dn8: int
    otsu_dn8: int
    background_dn8: int
    noise_sigma_dn8: float


def otsu_threshold(hist: np.ndarray) -> int:
    """Return Otsu's threshold t of a histogram of counts: classes v <= t and v > t with the largest between-class
    variance (compiled: ``imaging_kernels.otsu``).

    Same definition as OpenCV's THRESH_OTSU: 0 when no split leaves both classes non-empty, first maximum on ties.
    """
    return int(kernels.otsu(np.asarray(hist, dtype=np.int64)))


def binarisation(hist8: np.ndarray, cfg: ImagingConfig) -> Binarisation:
    """Return the threshold of an 8-bit histogram: max(Otsu, background median + k robust sigma)."""
    h = np.asarray(hist8, dtype=np.int64)
    median, mad = histogram_median_mad(h)
    sigma = MAD_TO_SIGMA * mad
    floor = median + max(math.ceil(cfg.noise_k_sigma * sigma), cfg.min_threshold_margin_dn8)
    otsu = otsu_threshold(h)
    return Binarisation(
        threshold_dn8=int(max(otsu, floor)) if cfg.otsu_threshold else int(floor), otsu_dn8=otsu, background_dn8=median, noise_sigma_dn8=float(sigma)
    )


def binarised(image: Filtered, cfg: ImagingConfig, bit_depth: int, working: bool = False
              ) -> tuple[np.ndarray, Binarisation]:
    """The foreground mask of a filtered frame's binned image and the threshold it was cut at; ``working``: the mask
    is the thread's working buffer (``working_buffers``), valid until the thread's next frame."""
    table = lut(cfg, bit_depth)
    hist8 = kernels.histogram_8bit(table, image.hist)
    thr = binarisation(hist8, cfg)
    # lut[v] > T  <=>  v >= first raw value mapped above T (the table is monotonic): threshold the raw image
    first_above = int(np.searchsorted(table, thr.threshold_dn8, side="right"))
    out = working_buffers(image.binned.shape[0])[3] if working else None
    return np.greater_equal(image.binned, first_above, out=out), thr
