"""Trials of the imaging chain on independent frames (``frame_generator``) against the truth and the OpenCV reference.

Shared by the tests (a few dozen frames) and ``bench/imaging.py`` (hundreds). Each trial renders a scene, gives the
chain the on-board prediction it would have (``prediction_for``: the true range and orbit radius with an error, the
Sun's direction, and Dimorphos's place when the trajectory is recognised) and a bad-pixel map (the scene's dead
pixels and columns and half its hot pixels, as ground's calibration would know them), runs ``process_frame`` and the
OpenCV pipeline on the same frame, and compares:

- identity: which true body each reported body is (the body whose pixels its region holds most of, its centroid
  within that body's radius + 15 px; -1 for a star, a defect or the plume);
- the reported blob's region centroid against the OpenCV region centroid of the same blob (for a blob trimmed to its
  brightest part, the same part of the OpenCV blob);
- the reported (phase-corrected) centre and the uncorrected region centroid against the true centre.

Then the same scene with one more defect (a saturated hot pixel or a 6 px cosmic ray, on a body, beside it or
anywhere) and the same noise: the identity of both bodies must not change.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from scipy.ndimage import binary_dilation

from obsw.config import ImagingConfig
from obsw.imaging import BadPixelMap, Blob, Detections, FramePrediction, process_frame
from obsw.imaging_filtering import lut
from obsw.imaging_geometry import focal_length_px
from obsw.imaging_identification import Without
from tests.obsw.frame_generator import ORBIT_RADIUS_M, Frame, Scene, noiseless_binned, render, with_defect
from tests.obsw.opencv_reference import (
    ReferenceResult,
    reference_components,
    reference_label,
    reference_parts,
    reference_pipeline,
)

CFG = ImagingConfig()
PAPER_LIMIT_PX = 15.0  # the paper's pass limit, binned px
MAX_SHAPE_RATIO = 1.5  # the on-board knowledge of the bodies' shapes (TargetKnowledge.max_axis_ratio)
# a body is detectable when its brightest binned pixel is 10 sigma above the background: the threshold is 5 sigma
# (ImagingConfig.noise_k_sigma) and the pixel must clear it by another 5 sigma of noise
MIN_SNR = 10.0
NOISE_FLOOR_SIGMA = 5.0  # the noise floor of a threshold (ImagingConfig.noise_k_sigma)
RANGE_ERROR = 0.1  # the prediction's range is off by up to this fraction (3 sigma of the early approach)


def scaled(scene: Scene, plume_brightness: float = 1.0, dimorphos_radiance: float = 1.0) -> Scene:
    """The scene with its plume (which it must have) and Dimorphos this many times as bright: a bench frame's
    variants."""
    assert scene.plume is not None
    did, dim = scene.bodies
    return replace(scene, bodies=(did, replace(dim, radiance_dn=dim.radiance_dn * dimorphos_radiance)),
                   plume=replace(scene.plume, brightness_dn=scene.plume.brightness_dn * plume_brightness))


def prediction_for(scene: Scene, rng: np.random.Generator, place_sigma_px: float | None) -> FramePrediction:
    """What the flight software would expect of this frame: radii and orbit radius from a range off by up to 10 %,
    the bodies' mean radii, the Sun; Dimorphos's place within ``place_sigma_px`` (one sigma, binned px, truncated at
    the stated uncertainty of 3 sigma; None: not known, as before the trajectory is recognised)."""
    e = 1.0 + rng.uniform(-RANGE_ERROR, RANGE_ERROR)
    f = scene.size_px // 512
    f512 = focal_length_px(2.9, 512)
    did, dim = scene.bodies[0], scene.bodies[1]
    place = unc = None
    if place_sigma_px is not None:
        c = ((dim.col - 0.5 * (f - 1)) / f, (dim.row - 0.5 * (f - 1)) / f)
        unc = 3.0 * place_sigma_px
        # the error within the stated uncertainty, as the flight software's is (the image of the trajectory's
        # 3-sigma box, predict_frame): a 2-D normal is beyond 3 sigma once in 90 draws
        while True:
            err = (rng.normal(0.0, place_sigma_px), rng.normal(0.0, place_sigma_px))
            if math.hypot(*err) <= unc:
                break
        place = (c[0] + err[0], c[1] + err[1])
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


def body_pixels_512(frame: Frame) -> np.ndarray:
    """The binned owner map: at each 512-scale pixel, the body seen on most of its full-resolution pixels (-1: none)."""
    f = frame.scene.size_px // 512
    blocks = frame.body_map.reshape(512, f, 512, f)
    counts = np.stack([(blocks == i).sum(axis=(1, 3)) for i in range(len(frame.truth))])
    return np.where(counts.max(axis=0) * 2 >= f * f, counts.argmax(axis=0), -1)


def identity(blob: Blob | None, frame: Frame, mask: np.ndarray | None = None) -> int | None:
    """Which true body a reported blob is: the body whose pixels (the frame's owner map) the blob's ``mask`` (512 x
    512) holds most of, provided the blob's centroid is within that body's radius x 1.5 + 15 px of its centre; of bodies
    too small to own a pixel, the larger whose centre the blob holds, else the nearest within that distance; -1 for
    anything else (a star, a defect, the plume);
    None for no blob. A blob holding two merged bodies is the one it holds more of. Without a mask, the nearest
    centre within the same distance."""
    if blob is None:
        return None

    def near(i: int) -> bool:
        t = frame.truth[i]
        return math.dist(blob.region_centroid_col_row, t.centre_512) <= t.radius_512_px * MAX_SHAPE_RATIO + PAPER_LIMIT_PX

    if mask is not None:
        owners = body_pixels_512(frame)
        held = np.bincount(owners[mask & (owners >= 0)], minlength=len(frame.truth))
        if held.any():
            best = int(held.argmax())
            return best if near(best) else -1
        unresolved = [i for i in range(len(frame.truth)) if not (owners == i).any() and near(i)]
        if not unresolved:
            return -1

        def inside(i: int) -> bool:
            c, r = (round(v) for v in frame.truth[i].centre_512)
            return 0 <= r < mask.shape[0] and 0 <= c < mask.shape[1] and bool(mask[r, c])

        held_centres = [i for i in unresolved if inside(i)]
        if held_centres:  # unresolved bodies in one blob: the larger, as for resolved ones
            return max(held_centres, key=lambda i: frame.truth[i].radius_512_px)
        return min(unresolved, key=lambda i: math.dist(blob.region_centroid_col_row, frame.truth[i].centre_512))
    best, dist = -1, math.inf
    for i, t in enumerate(frame.truth):
        d = math.dist(blob.region_centroid_col_row, t.centre_512)
        if near(i) and d < dist:
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


def reference_blob(det: Detections, blob: Blob, ref: ReferenceResult
                   ) -> tuple[np.ndarray, tuple[float, float]] | None:
    """The OpenCV region of a reported blob, (mask, region centroid): the OpenCV region with the same area and box,
    or for a part cut out of a region, the OpenCV region cut the same way (each cut keeping the part that holds the
    reported blob); None when OpenCV has no such region."""
    if not blob.trimmed_from:
        label = reference_label(ref, blob.area_px, blob.bbox_col_row_w_h)
        if not label:
            return None
        c = ref.centroids[label - 1]
        return ref.labels == label, (float(c[0]), float(c[1]))
    root = next(b for b in det.blobs if b.label == blob.trimmed_from)
    label = reference_label(ref, root.area_px, root.bbox_col_row_w_h)
    if not label:
        return None
    inside = ref.labels == label
    x, y, w, h = blob.bbox_col_row_w_h
    pick = None
    for n in blob.cuts:
        if isinstance(n, Without):  # the region without the part of its brightest pixels holding a pixel
            held = [p for p in reference_parts(ref, inside, n.n_pixels) if p[3][n.row, n.col]]
            parts = reference_components(inside & ~held[0][3])
        elif isinstance(n, tuple):  # its pixels within a disc (Regions.within)
            rows, cols = np.indices(inside.shape)
            parts = reference_parts(ref, inside & (np.hypot(cols - n[0], rows - n[1]) <= n[2]), inside.size)
        else:
            parts = reference_parts(ref, inside, n)
        # the part that holds the reported blob: the most of its box
        pick = max(parts, key=lambda p: int(p[3][y:y + h, x:x + w].sum()))
        inside = pick[3]
    assert pick is not None
    return pick[3], pick[1]


def _body(det: Detections, blob: Blob | None, index: int, frame: Frame, ref: ReferenceResult) -> BodyResult:
    if blob is None:
        return BodyResult(None, None, None, None, False)
    region = reference_blob(det, blob, ref)
    who = identity(blob, frame, None if region is None else region[0])
    truth = frame.truth[index].centre_512 if who is None or who < 0 else frame.truth[who].centre_512
    return BodyResult(truth_index=who,
                      opencv_px=math.inf if region is None else math.dist(blob.region_centroid_col_row, region[1]),
                      error_px=math.dist(blob.centroid_col_row, truth) if who == index else math.inf,
                      uncorrected_error_px=math.dist(blob.region_centroid_col_row, truth) if who == index else math.inf,
                      trimmed=bool(blob.trimmed_from))


def reference_for(scene: Scene, pixels: np.ndarray) -> ReferenceResult:
    """The OpenCV pipeline on a frame of the scene, with the bad pixels ground's map holds (``ground_map``)."""
    d = scene.defects
    return reference_pipeline(pixels, bad_pixels=([(c, r) for c, r, _ in d.hot[: len(d.hot) // 2]] + list(d.dead),
                                                  d.dead_columns))


def run_trial(scene: Scene, seed: int, prediction: FramePrediction, cfg: ImagingConfig = CFG) -> Trial:
    """Render the scene with noise from ``seed`` and run both pipelines on it (the chain with ``cfg``)."""
    frame = render(scene, np.random.default_rng(seed))
    bad = ground_map(scene)
    det = process_frame(frame.pixels, cfg, bad_pixels=bad, prediction=prediction)
    ref = reference_for(scene, frame.pixels)
    return Trial(frame, det, _body(det, det.didymos, 0, frame, ref), _body(det, det.dimorphos, 1, frame, ref),
                 prediction)


def perturbed_identities(scene: Scene, seed: int, prediction: FramePrediction, kind: str, target: int | None,
                         rng: np.random.Generator) -> tuple[int | None, int | None]:
    """Identities of (Didymos, Dimorphos) as reported on the scene with one more defect and the same noise."""
    t = run_trial(with_defect(scene, rng, kind, target), seed, prediction)
    return t.didymos.truth_index, t.dimorphos.truth_index


def visible(frame: Frame, index: int, min_size_px: float = 3.0, require_snr: bool = True,
            require_apart: bool = True) -> bool:
    """A body the chain must find: its lit part at least ``min_size_px`` binned px across (the diameter of a disc of
    its lit area in the frame), at most 10 % of its lit surface hidden by the other body, at least half of it in the
    frame; with ``require_snr``, bright enough to be told from the noise (``peak_snr`` at least ``MIN_SNR``); with
    ``require_apart``, not swallowed by the other body (``swallowed``)."""
    t = frame.truth[index]
    total = t.lit_px + t.hidden_px + t.off_frame_px
    lit_512 = t.lit_px / (frame.scene.size_px / 512) ** 2
    seen = 2.0 * math.sqrt(lit_512 / math.pi) >= min_size_px and total > 0 and t.hidden_px <= 0.1 * total \
        and t.off_frame_px <= 0.5 * total
    return seen and (not require_snr or peak_snr(frame, index) >= MIN_SNR) \
        and (not require_apart or not swallowed(frame, index))


def swallowed(frame: Frame, index: int) -> bool:
    """Whether a body is the smaller of a pair whose images are one region at the noise floor: their noise-free
    binned signals, each cut at ``NOISE_FLOOR_SIGMA`` binned noise sigmas, overlap or touch (8-connected). The body
    is then seen against the other's lit surface (a transit) or its limb: the same albedo gives no edge between
    them, and a threshold and a labelling (the paper's imaging chain) find one blob, the larger body."""
    other = 1 - index
    if frame.truth[index].lit_px >= frame.truth[other].lit_px:
        return False
    floor = NOISE_FLOOR_SIGMA * frame.scene.read_noise_dn / (frame.scene.size_px // 512)
    mine = noiseless_binned(frame.scene, index) > floor
    theirs = noiseless_binned(frame.scene, other) > floor
    return bool((binary_dilation(mine, structure=np.ones((3, 3), dtype=bool)) & theirs).any())


def peak_snr(frame: Frame, index: int) -> float:
    """A body's signal-to-noise: the peak of its noise-free binned signal over the binned background noise (the read
    noise over the binning factor, the background having no shot noise above the bias)."""
    f = frame.scene.size_px // 512
    return float(noiseless_binned(frame.scene, index).max()) / (frame.scene.read_noise_dn / f)


def _near_star_or_defect(col_row: tuple[float, float], scene: Scene, limit_px: float = 3.0) -> str | None:
    """'star' or 'defect' when a star, a hot pixel or a cosmic-ray streak lies within ``limit_px`` (512 scale)."""
    f = scene.size_px / 512

    def d(c: float, r: float) -> float:
        return math.dist(col_row, ((c - 0.5 * (f - 1)) / f, (r - 0.5 * (f - 1)) / f))

    if any(d(c, r) <= limit_px for c, r, _ in scene.stars):
        return "star"
    hot = any(d(c, r) <= limit_px for c, r, _ in scene.defects.hot)
    streak = any(min(d(c0 + s * (c1 - c0), r0 + s * (r1 - r0)) for s in np.linspace(0.0, 1.0, 9)) <= limit_px
                 for c0, r0, c1, r1, _ in scene.defects.cosmic_rays)
    return "defect" if hot or streak else None


def failure_classes(trial: Trial, index: int) -> tuple[str, ...]:
    """The classes of a body's miss or wrong report: its conditions ('small' under 5 px lit, 'faint' under 20 of
    ``peak_snr``, 'phase' at 90 deg or more, 'edge', 'close pair' when the other body's disc is within 3 px of its
    own, 'plume' when the plume is above the threshold within 3 px of its disc, 'unrecognised' with a place known to
    90 px only) and what was reported instead ('none', 'other body', 'star', 'defect', 'plume or noise')."""
    frame, det = trial.frame, trial.detections
    scene = frame.scene
    t = frame.truth[index]
    other = frame.truth[1 - index]
    tags = []
    lit_d = 2.0 * math.sqrt(t.lit_px / (scene.size_px / 512) ** 2 / math.pi)
    if lit_d < 5.0:
        tags.append("small")
    if peak_snr(frame, index) < 20.0:
        tags.append("faint")
    if scene.phase_deg >= 90.0:
        tags.append("phase")
    if t.touches_edge:
        tags.append("edge")
    if math.dist(t.centre_512, other.centre_512) <= t.radius_512_px + other.radius_512_px + 3.0:
        tags.append("close pair")
    if scene.plume is not None:
        plume = noiseless_binned(scene, "plume")
        c, r = t.centre_512
        reach = t.radius_512_px + 3.0
        rows, cols = np.ogrid[:512, :512]
        near = (cols - c) ** 2 + (rows - r) ** 2 <= reach * reach
        first_above = int(np.searchsorted(lut(CFG, scene.bit_depth), det.threshold_dn8, side="right"))
        if near.any() and plume[near].max() >= first_above - scene.bias_dn:
            tags.append("plume")
    unc = trial.prediction.dimorphos_uncertainty_px
    if unc is None or unc > 30.0:
        tags.append("unrecognised")
    result = trial.didymos if index == 0 else trial.dimorphos
    blob = det.didymos if index == 0 else det.dimorphos
    if result.truth_index is None:
        tags.append("reported: none")
    elif result.truth_index >= 0 and result.truth_index != index:
        tags.append("reported: other body")
    elif result.truth_index < 0 and blob is not None:
        tags.append("reported: " + (_near_star_or_defect(blob.region_centroid_col_row, scene) or "plume or noise"))
    return tuple(tags)
