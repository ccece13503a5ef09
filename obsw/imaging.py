"""Imaging subsystem: from a raw 12-bit frame to the offsets of Didymos and Dimorphos from the image centre.

Emulates the LICIACube pipeline (paper, "Imaging Subsystem"), one module per step; ``process_frame`` runs them in
order, a frame in, detections out:

1. Filtering (FPGA, ``obsw.imaging_filtering``): the uploaded bad-pixel map and the outlier filter (hot pixels,
   cosmic-ray streaks) correct the frame's defects; the frame is binned from 1024x1024 (or 2048x2048) to 512x512 by
   the rounded mean of 2x2 (4x4) blocks at the raw bit depth, and compressed to 8 bit through a monotonic look-up
   table (square-root companding by default).
2. Binarisation (FPGA, ``obsw.imaging_binarisation``): max(Otsu, background median + k robust sigmas) on the 8-bit
   luminance histogram.
3. Object detection (``obsw.imaging_labelling``): 8-connected component labelling.
4. Feature extraction and identification (OBSW, ``obsw.imaging_identification``): area, region centroid, box,
   elongation and brightness of every blob; Didymos and Dimorphos told from stars, defects, the plume and pieces of
   a thin crescent by area, shape, the frame's predicted geometry (``obsw.imaging_geometry``) and continuity with
   earlier frames; ejecta merged with a body trimmed off; each body's centroid corrected for the phase angle, and
   Dimorphos's, when it was cut out of a region it shares with Didymos or the plume, taken from its limb
   (``obsw.imaging_limb``).

Image x (columns) is body +X, image y (rows) body +Y, the boresight body +Z; the image centre is at
((n - 1) / 2, (n - 1) / 2) in pixel-centre coordinates of the n x n binned image.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from contracts.messages import CentroidMeasurement
from obsw.config import CameraKnowledge, ImagingConfig
from obsw.imaging_binarisation import Binarisation, binarisation, binarised, otsu_threshold
from obsw.imaging_filtering import (
    BadPixelMap,
    Filtered,
    FrameError,
    binned,
    check_frame,
    compressed_8bit,
    compression_lut,
    filtered,
    linear_values,
    lut,
    working_buffers,
)
from obsw.imaging_geometry import FramePrediction, focal_length_px, los_body, offset_rad, predict_frame
from obsw.imaging_identification import Blob, Regions, identify, identify_bodies, phase_corrected
from obsw.imaging_kernels import values_at
from obsw.imaging_labelling import Components, connected_components
from obsw.imaging_limb import limb_corrected

__all__ = [
    "BadPixelMap", "Binarisation", "Blob", "Components", "Detections", "Filtered", "FrameError", "FramePrediction",
    "binarisation", "binned", "compressed_8bit", "compression_lut", "connected_components", "focal_length_px",
    "identify_bodies", "los_body", "measured_detections", "offset_rad", "otsu_threshold", "predict_frame",
    "process_frame",
]


@dataclass(frozen=True, slots=True)
class Detections:
    """What the imaging subsystem reports for one frame."""

    blobs: tuple[Blob, ...]  # the regions of at least min_body_area_px, then the parts cut out for the bodies
    didymos: Blob | None
    dimorphos: Blob | None
    didymos_offset_px: tuple[float, float] | None  # (col, row) offset of the body's centre from the image centre
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
    bad_pixels: int = 0  # pixels the bad-pixel map replaced
    outliers: int = 0  # pixels the outlier filter replaced
    regions: int = 0  # 8-connected regions of the binarised image, the small ones included
    limb_samples: int = 0  # gradient samples the limb fit of Dimorphos took (obsw.imaging_limb; 0: not fitted)
    # the probability that the Didymos identified is Didymos (below cfg.didymos_min_report_probability: not reported)
    didymos_probability: float = 1.0


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
    blob of that area (the measurement has no brightness, so those fields are 0).
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
                    elongation=1.0, threshold_dn8=0, region_centroid_col_row=c)

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
                  camera: CameraKnowledge = CameraKnowledge(), *, bad_pixels: BadPixelMap | None = None,
                  prediction: FramePrediction | None = None) -> Detections:
    """Return the blobs of a raw frame and the identified Didymos and Dimorphos with their offsets from centre.

    ``previous``: the previous frame's detections (continuity); ``bad_pixels``: the uploaded bad-pixel map;
    ``prediction``: the frame's expected geometry (``predict_frame``; without it Dimorphos is searched within
    ``dimorphos_max_separation_didymos_diameters`` of Didymos, no ejecta are trimmed, no phase correction).
    FrameError when the frame is not a raw frame of this camera.
    """
    check_frame(frame, camera.resolution_px, camera.bit_depth, values=False)  # the filtering reads the values
    n = cfg.binned_size_px
    # FPGA: defect correction, binning, 8-bit compression and binarisation
    # the binned image and the mask live in the thread's working buffers: neither outlives this frame's processing
    image = filtered(frame, cfg, camera.bit_depth, bad_pixels, working=True)
    mask, thr = binarised(image, cfg, camera.bit_depth, working=True)
    # software: labelling, features, identification
    components = connected_components(mask, working_buffers(n)[4:])
    values8 = values_at(image.binned.reshape(-1), components.pixel_index, lut(cfg, camera.bit_depth))
    regions = Regions(components, values8, n, thr.threshold_dn8, linear8=linear_values(cfg, camera.bit_depth))
    # a region smaller than a body (noise, a defect the filter left) is counted, not described
    blobs = regions.blobs(min_area_px=cfg.min_body_area_px)
    didymos, dimorphos, probability, deblended = identify(blobs, cfg, previous, prediction, regions)
    pair: tuple[Blob, Blob] | None = None
    age = 0
    if didymos is not None and dimorphos is not None:
        pair = (didymos, dimorphos)
    elif dimorphos is None and previous is not None and previous.pair is not None:
        # Dimorphos hidden (merged with Didymos or the plume): keep the last pair so it is found again by continuity
        pair, age = previous.pair, previous.pair_age_frames + 1
    r_did = None if prediction is None else prediction.didymos_radius_px
    r_dim = None if prediction is None else prediction.dimorphos_radius_px
    didymos = phase_corrected(didymos, r_did, prediction, cfg, camera.fov_deg)
    dimorphos = phase_corrected(dimorphos, r_dim, prediction, cfg, camera.fov_deg)
    limb_samples = 0
    if not deblended:  # a deblended object is a peak of its own, not a cut beside the body: no limb sought for it
        dimorphos, limb_samples = limb_corrected(dimorphos, image.binned, prediction, cfg, camera.fov_deg, didymos)
        if dimorphos is None and pair is not None and age == 0:  # the cut refused: as if Dimorphos were hidden
            pair = None if previous is None or previous.pair is None else previous.pair
            age = 0 if pair is None else previous.pair_age_frames + 1  # type: ignore[union-attr]
    if pair is not None and age == 0:
        pair = (didymos, dimorphos)  # type: ignore[assignment]
    if probability < cfg.didymos_min_report_probability:
        didymos = None  # a point source as likely a star: not reported; the pair keeps it for continuity
    did_px, did_rad = _offsets(didymos, camera.fov_deg, n)
    dim_px, dim_rad = _offsets(dimorphos, camera.fov_deg, n)
    extra = tuple(b for b in (didymos, dimorphos) if b is not None and b.trimmed_from)
    return Detections(
        blobs=tuple(blobs) + extra,
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
        bad_pixels=image.bad_pixels,
        outliers=int(image.outliers.size),
        regions=int(components.area_px.size),
        limb_samples=limb_samples,
        didymos_probability=probability,
    )
