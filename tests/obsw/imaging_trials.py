"""Trials of the imaging chain on independent frames (``frame_generator``) against the truth and the OpenCV reference.

Shared by the tests (a few dozen frames) and ``bench/imaging.py`` (hundreds). Each trial renders a scene, gives the
chain the on-board prediction it would have (``prediction_for``: the true range and orbit radius with an error, the
Sun's direction, and Dimorphos's place when the trajectory is recognised) and a bad-pixel map (the scene's dead
pixels and columns and half its hot pixels, as ground's calibration would know them), runs ``process_frame`` and the
OpenCV pipeline on the same frame, and compares:

- identity: which true body each reported body is (the nearest true centre within its radius + 15 px; -1 for a
  star, a defect or the plume);
- the reported blob's region centroid against the OpenCV region centroid of the same blob (for a blob trimmed to its
  brightest part, the same part of the OpenCV blob);
- the reported (phase-corrected) centre and the uncorrected region centroid against the true centre.

Then the same scene with one more defect (a saturated hot pixel or a 6 px cosmic ray, on a body, beside it or
anywhere) and the same noise: the identity of both bodies must not change.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from obsw.config import ImagingConfig
from obsw.imaging import BadPixelMap, Blob, Detections, FramePrediction, process_frame
from obsw.imaging_geometry import focal_length_px
from tests.obsw.frame_generator import ORBIT_RADIUS_M, Frame, Scene, render, with_defect
from tests.obsw.opencv_reference import ReferenceResult, reference_label, reference_parts, reference_pipeline

CFG = ImagingConfig()
PAPER_LIMIT_PX = 15.0  # the paper's pass limit, binned px
MAX_SHAPE_RATIO = 1.5  # the on-board knowledge of the bodies' shapes (TargetKnowledge.max_axis_ratio)
RANGE_ERROR = 0.1  # the prediction's range is off by up to this fraction (3 sigma of the early approach)


def prediction_for(scene: Scene, rng: np.random.Generator, place_sigma_px: float | None) -> FramePrediction:
    """What the flight software would expect of this frame: radii and orbit radius from a range off by up to 10 %,
    the bodies' mean radii, the Sun; Dimorphos's place within ``place_sigma_px`` (one sigma, binned px; None: not
    known, as before the trajectory is recognised)."""
    e = 1.0 + rng.uniform(-RANGE_ERROR, RANGE_ERROR)
    f = scene.size_px // 512
    f512 = focal_length_px(2.9, 512)
    did, dim = scene.bodies[0], scene.bodies[1]
    place = unc = None
    if place_sigma_px is not None:
        c = ((dim.col - 0.5 * (f - 1)) / f, (dim.row - 0.5 * (f - 1)) / f)
        place = (c[0] + rng.normal(0.0, place_sigma_px), c[1] + rng.normal(0.0, place_sigma_px))
        unc = 3.0 * place_sigma_px
    s = tuple(float(v) for v in scene.sun_camera)
    return FramePrediction(
        sun_camera=(s[0], s[1], s[2]),
        didymos_radius_px=did.mean_radius_px / f / e,
        dimorphos_radius_px=dim.mean_radius_px / f / e,
        radius_factor_max=MAX_SHAPE_RATIO / (1.0 - RANGE_ERROR),
        orbit_radius_max_px=f512 * ORBIT_RADIUS_M / (scene.range_m * (1.0 - RANGE_ERROR)),
        dimorphos_col_row=place,
        dimorphos_uncertainty_px=unc,
    )


def ground_map(scene: Scene) -> BadPixelMap:
    """The bad-pixel map ground would upload: the dead pixels and columns and the first half of the hot pixels."""
    d = scene.defects
    pixels = [(c, r) for c, r, _ in d.hot[: len(d.hot) // 2]] + list(d.dead)
    return BadPixelMap.build(scene.size_px, pixels, d.dead_columns)


def identity(blob: Blob | None, frame: Frame) -> int | None:
    """Which true body a reported blob is: the index of the nearest true centre within its radius + 15 px, -1 for
    anything else, None for no blob."""
    if blob is None:
        return None
    best, dist = -1, math.inf
    for i, t in enumerate(frame.truth):
        d = math.dist(blob.region_centroid_col_row, t.centre_512)
        if d <= t.radius_512_px * MAX_SHAPE_RATIO + PAPER_LIMIT_PX and d < dist:
            best, dist = i, d
    return best


@dataclass(frozen=True)
class BodyResult:
    """One reported body of one trial."""

    truth_index: int | None  # identity (None: not reported)
    opencv_px: float | None  # distance of the region centroid from the OpenCV region centroid of the same blob
    error_px: float | None  # distance of the reported (phase-corrected) centre from the true centre
    uncorrected_error_px: float | None  # same for the region centroid, before the phase correction
    trimmed: bool


@dataclass(frozen=True)
class Trial:
    """One frame's outcome: detections, both bodies' results, and the frame."""

    frame: Frame
    detections: Detections
    didymos: BodyResult
    dimorphos: BodyResult
    prediction: FramePrediction


def _opencv_centroid(det: Detections, blob: Blob, ref: ReferenceResult) -> float:
    """Distance of a reported blob's region centroid from the OpenCV region centroid of the same blob: the OpenCV
    region with the same area and box, or for a part cut out of a region, the OpenCV region cut the same way (each
    cut keeping the part that holds the reported blob)."""
    if not blob.trimmed_from:
        label = reference_label(ref, blob.area_px, blob.bbox_col_row_w_h)
        if not label:
            return math.inf
        c = ref.centroids[label - 1]
        return math.dist(blob.region_centroid_col_row, (float(c[0]), float(c[1])))
    root = next(b for b in det.blobs if b.label == blob.trimmed_from)
    label = reference_label(ref, root.area_px, root.bbox_col_row_w_h)
    if not label:
        return math.inf
    inside = ref.labels == label
    x, y, w, h = blob.bbox_col_row_w_h
    pick = None
    for n in blob.cuts:
        parts = reference_parts(ref, inside, n)
        # the part that holds the reported blob: the most of its box
        pick = max(parts, key=lambda p: int(p[3][y:y + h, x:x + w].sum()))
        inside = pick[3]
    assert pick is not None
    return math.dist(blob.region_centroid_col_row, pick[1])


def _body(det: Detections, blob: Blob | None, index: int, frame: Frame, ref: ReferenceResult,
          prediction: FramePrediction) -> BodyResult:
    who = identity(blob, frame)
    if blob is None:
        return BodyResult(None, None, None, None, False)
    truth = frame.truth[index].centre_512 if who is None or who < 0 else frame.truth[who].centre_512
    return BodyResult(truth_index=who, opencv_px=_opencv_centroid(det, blob, ref),
                      error_px=math.dist(blob.centroid_col_row, truth) if who == index else math.inf,
                      uncorrected_error_px=math.dist(blob.region_centroid_col_row, truth) if who == index else math.inf,
                      trimmed=bool(blob.trimmed_from))


def run_trial(scene: Scene, seed: int, prediction: FramePrediction, with_reference: bool = True) -> Trial:
    """Render the scene with noise from ``seed`` and run both pipelines on it."""
    frame = render(scene, np.random.default_rng(seed))
    bad = ground_map(scene)
    det = process_frame(frame.pixels, CFG, bad_pixels=bad, prediction=prediction)
    if not with_reference:
        empty = BodyResult(identity(det.didymos, frame), None, None, None, False)
        return Trial(frame, det, empty, BodyResult(identity(det.dimorphos, frame), None, None, None, False),
                     prediction)
    d = scene.defects
    ref = reference_pipeline(frame.pixels, bad_pixels=([(c, r) for c, r, _ in d.hot[: len(d.hot) // 2]]
                                                       + list(d.dead), d.dead_columns))
    return Trial(frame, det, _body(det, det.didymos, 0, frame, ref, prediction),
                 _body(det, det.dimorphos, 1, frame, ref, prediction), prediction)


def perturbed_identities(scene: Scene, seed: int, prediction: FramePrediction, kind: str, target: int | None,
                         rng: np.random.Generator) -> tuple[int | None, int | None]:
    """Identities of (Didymos, Dimorphos) as reported on the scene with one more defect and the same noise."""
    t = run_trial(with_defect(scene, rng, kind, target), seed, prediction, with_reference=False)
    return t.didymos.truth_index, t.dimorphos.truth_index


def visible(frame: Frame, index: int, min_size_px: float = 3.0) -> bool:
    """A body the chain must find: its lit part at least ``min_size_px`` binned px across (the diameter of a disc of
    its lit area in the frame), at most 10 % of its lit surface hidden by the other body and at least half of it in
    the frame."""
    t = frame.truth[index]
    total = t.lit_px + t.hidden_px + t.off_frame_px
    lit_512 = t.lit_px / (frame.scene.size_px / 512) ** 2
    return 2.0 * math.sqrt(lit_512 / math.pi) >= min_size_px and total > 0 and t.hidden_px <= 0.1 * total \
        and t.off_frame_px <= 0.5 * total
