"""The imaging subsystem agrees with an independent OpenCV pipeline and finds Didymos and Dimorphos."""

from __future__ import annotations

import dataclasses
import math

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from scipy.spatial.transform import Rotation
from tests.obsw.opencv_reference import (
    ReferenceResult,
    SyntheticBody,
    reference_8bit,
    reference_binned,
    reference_pipeline,
    synthetic_frame,
)

from contracts.messages import CentroidMeasurement
from obsw import imaging_kernels as kernels
from obsw.imaging_filtering import filtered
from obsw.config import CameraKnowledge, ImagingConfig, ObswConfig, TargetKnowledge
from obsw.imaging import (
    Blob,
    Detections,
    FrameError,
    FramePrediction,
    binarisation,
    binned,
    compressed_8bit,
    compression_lut,
    connected_components,
    focal_length_px,
    identify_bodies,
    los_body,
    measured_detections,
    offset_rad,
    otsu_threshold,
    predict_frame,
    process_frame,
)
from obsw.trajectory import NominalTrajectory
from universe.camera import Body, Scene, project_inertial, render_frame
from universe.config import BodiesConfig, FlybyConfig, PlumeConfig, UniverseConfig
from universe.geometry import FlybyGeometry
from universe.shapes import ShapeModel

CFG = ImagingConfig()
FOV_DEG = ObswConfig().camera.fov_deg


def _sorted_stats(areas: np.ndarray, cc: np.ndarray, cr: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """Return component statistics as rows sorted lexicographically, so label numbering does not matter."""
    table = np.column_stack([areas, cc, cr, boxes]).astype(np.float64)
    return table[np.lexsort(table.T[::-1])]


def _ours(mask: np.ndarray) -> np.ndarray:
    c = connected_components(mask)
    boxes = np.column_stack([c.left, c.top, c.width, c.height]) if c.area_px.size else np.zeros((0, 4))
    return _sorted_stats(c.area_px, c.centroid_col, c.centroid_row, boxes)


def _opencv(mask: np.ndarray) -> np.ndarray:
    _, _, stats, cent = cv2.connectedComponentsWithStats(mask.astype(np.uint8), connectivity=8)
    return _sorted_stats(stats[1:, 4], cent[1:, 0], cent[1:, 1], stats[1:, :4])


def _assert_blobs_equal_reference(det: Detections, ref: ReferenceResult) -> None:
    """Every region of ours equals one of OpenCV's of at least min_body_area_px and back: same area, box and region
    centroid; the smaller ones are counted alike."""
    ours = np.array([(b.area_px, *b.region_centroid_col_row, *b.bbox_col_row_w_h) for b in det.blobs
                     if not b.trimmed_from], dtype=np.float64).reshape(-1, 7)
    big = ref.areas >= CFG.min_body_area_px
    theirs = np.column_stack([ref.areas, ref.centroids, ref.bboxes.reshape(-1, 4)])[big].astype(np.float64)
    assert det.regions == ref.areas.size
    assert det.threshold_dn8 == ref.threshold_dn8
    np.testing.assert_allclose(ours[np.lexsort(ours.T[::-1])], theirs[np.lexsort(theirs.T[::-1])], rtol=0, atol=1e-9)


def test_binning_1024_equals_opencv_inter_area() -> None:
    """2x2 rounded-mean binning equals cv2.resize INTER_AREA pixel for pixel."""
    frame = np.random.default_rng(0).integers(0, 4096, (1024, 1024), dtype=np.uint16)
    np.testing.assert_array_equal(binned(frame, CFG, 12), reference_binned(frame, 512))


def test_binning_2048_is_the_rounded_block_mean() -> None:
    """4x4 binning is floor(mean + 1/2) of each block, and within 1 DN of cv2 INTER_AREA."""
    frame = np.random.default_rng(1).integers(0, 4096, (2048, 2048), dtype=np.uint16)
    ours = binned(frame, CFG, 12)
    exact = np.floor(frame.reshape(512, 4, 512, 4).mean(axis=(1, 3)) + 0.5)
    np.testing.assert_array_equal(ours, exact)
    assert np.abs(ours.astype(np.int64) - reference_binned(frame, 512)).max() <= 1


def test_2048_frame_of_replicated_pixels_gives_the_1024_detections() -> None:
    """A 2048 frame whose 2x2 blocks repeat a 1024 frame's pixels bins to the same image and the same blobs (outlier
    filter off: a defect one pixel wide at 1024 is two wide at 2048)."""
    bodies = _pair(500.0, 520.0, 40.0, (110.0, 40.0))
    small = synthetic_frame(np.random.default_rng(3), bodies=bodies)
    large = np.kron(small, np.ones((2, 2), dtype=np.uint16))
    np.testing.assert_array_equal(binned(large, CFG, 12), binned(small, CFG, 12))
    cfg = ImagingConfig(outlier_filter=False)
    assert process_frame(large, cfg, camera=CameraKnowledge(resolution_px=2048)) == process_frame(small, cfg)


@pytest.mark.parametrize("law", ["sqrt", "shift"])
def test_compression_equals_opencv_law(law: str) -> None:
    """The 8-bit table equals the OpenCV computation of the same law on every 12-bit value, and is monotonic."""
    cfg = ImagingConfig(compression_law=law)
    values = np.arange(4096, dtype=np.uint16).reshape(64, 64)
    np.testing.assert_array_equal(compressed_8bit(values, cfg, 12), reference_8bit(values, 12, law))
    lut = compression_lut(cfg, 12)
    assert lut[0] == 0 and lut[-1] == 255 and np.all(np.diff(lut.astype(int)) >= 0)


def _between_class_variance(hist: np.ndarray, t: int) -> float:
    """Return the Otsu criterion w0 w1 (mu0 - mu1)^2 of splitting a histogram into v <= t and v > t."""
    p = hist / hist.sum()
    v = np.arange(p.size)
    w0, w1 = p[: t + 1].sum(), p[t + 1 :].sum()
    if w0 == 0 or w1 == 0:
        return 0.0
    return float(w0 * w1 * ((p[: t + 1] * v[: t + 1]).sum() / w0 - (p[t + 1 :] * v[t + 1 :]).sum() / w1) ** 2)


def _otsu_array_form(hist: np.ndarray) -> int:
    """Otsu's threshold as numpy array operations (the chain's earlier form): cumulative sums of the class
    probabilities and moments, splits leaving both classes at least float32's epsilon, the first largest variance."""
    h = np.asarray(hist, dtype=np.float64)
    total = h.sum()
    if total <= 0:
        return 0
    p = h / total
    q1 = np.cumsum(p)
    m1 = np.cumsum(p * np.arange(h.size, dtype=np.float64))
    q2 = 1.0 - q1
    eps = float(np.finfo(np.float32).eps)
    valid = (np.minimum(q1, q2) >= eps) & (np.maximum(q1, q2) <= 1.0 - eps)
    if not valid.any():
        return 0
    with np.errstate(divide="ignore", invalid="ignore"):
        sigma = q1 * q2 * (m1 / q1 - (m1[-1] - m1) / q2) ** 2
    return int(np.argmax(np.where(valid, sigma, -1.0)))


@settings(max_examples=60, deadline=None)
@given(
    image=hnp.arrays(np.uint8, st.tuples(st.integers(1, 40), st.integers(1, 40)), elements=st.integers(0, 255))
)
def test_otsu_threshold_matches_opencv(image: np.ndarray) -> None:
    """Our Otsu threshold (compiled) equals its array form and reaches OpenCV's maximum between-class variance (equal
    thresholds up to ties)."""
    cv_t, _ = cv2.threshold(image, 0, 255, cv2.THRESH_BINARY | cv2.THRESH_OTSU)
    hist = np.bincount(image.ravel(), minlength=256)
    ours = otsu_threshold(hist)
    assert kernels.otsu(hist) == ours == _otsu_array_form(hist)  # the compiled loop: the array form's threshold
    assert _between_class_variance(hist, ours) == pytest.approx(_between_class_variance(hist, int(cv_t)), rel=1e-9)


@settings(max_examples=60, deadline=None)
@given(values=hnp.arrays(np.uint8, st.integers(1, 500), elements=st.integers(0, 255)))
def test_background_median_and_mad_are_the_sample_statistics(values: np.ndarray) -> None:
    """The histogram median and MAD equal the lower sample median and lower median absolute deviation."""
    hist = np.bincount(values, minlength=256)
    b = binarisation(hist, CFG)
    k = (values.size - 1) // 2
    median = int(np.partition(values, k)[k])
    mad = int(np.partition(np.abs(values.astype(int) - median), k)[k])
    assert b.background_dn8 == median
    assert b.noise_sigma_dn8 == pytest.approx(1.4826 * mad)
    floor = median + max(math.ceil(CFG.noise_k_sigma * 1.4826 * mad), CFG.min_threshold_margin_dn8)
    assert b.threshold_dn8 == floor
    assert binarisation(hist, ImagingConfig(otsu_threshold=True)).threshold_dn8 == max(floor, b.otsu_dn8)


@settings(max_examples=80, deadline=None)
@given(
    mask=hnp.arrays(np.bool_, st.tuples(st.integers(1, 48), st.integers(1, 48)), elements=st.booleans())
)
def test_labelling_matches_opencv_on_random_images(mask: np.ndarray) -> None:
    """Same components as cv2.connectedComponentsWithStats (8-conn): count, areas, centroids, boxes."""
    np.testing.assert_allclose(_ours(mask), _opencv(mask), rtol=0, atol=1e-9)


@pytest.mark.parametrize("density", [0.05, 0.45, 0.75])
def test_labelling_matches_opencv_full_size(density: float) -> None:
    """On 512x512 random images from sparse to percolating, the components equal OpenCV's."""
    mask = np.random.default_rng(int(density * 100)).random((512, 512)) < density
    np.testing.assert_allclose(_ours(mask), _opencv(mask), rtol=0, atol=1e-9)


@settings(max_examples=80, deadline=None)
@given(seed=st.integers(0, 2**31), height=st.integers(1, 64), words=st.integers(1, 16), extra=st.sampled_from([0, 3]),
       density=st.sampled_from([0.002, 0.02, 0.1]))
def test_labelling_matches_opencv_on_sparse_images(seed: int, height: int, words: int, extra: int,
                                                   density: float) -> None:
    """Sparse images, whose empty stretches the labelling passes eight pixels at a time (widths a multiple of eight
    or not), with runs across the words' edges: the components equal OpenCV's."""
    rng = np.random.default_rng(seed)
    mask = rng.random((height, 8 * words + extra)) < density
    mask |= np.roll(mask, 1, axis=1) & (rng.random(mask.shape) < 0.5)  # short runs, some across a word's edge
    np.testing.assert_allclose(_ours(mask), _opencv(mask), rtol=0, atol=1e-9)


def test_labels_are_numbered_in_raster_order() -> None:
    """Components are numbered by their first pixel in raster order (a U shape is one component)."""
    mask = np.zeros((6, 8), dtype=bool)
    mask[0, 5] = True  # first in raster order
    mask[1, 0] = True
    mask[2:5, 2] = mask[2:5, 5] = True
    mask[4, 2:6] = True  # U joined at the bottom
    c = connected_components(mask)
    assert c.area_px.tolist() == [1, 1, 8]
    assert (c.top.tolist(), c.left.tolist()) == ([0, 1, 2], [5, 0, 2])


@pytest.mark.parametrize(("w", "h"), [(1, 1), (7, 1), (9, 3), (4, 12)])
def test_elongation_of_rectangles_is_side_ratio(w: int, h: int) -> None:
    """A w x h block of unit pixels has variances w^2/12 and h^2/12, so elongation max(w,h)/min(w,h)."""
    mask = np.zeros((20, 20), dtype=bool)
    mask[3 : 3 + h, 5 : 5 + w] = True
    c = connected_components(mask)
    assert c.elongation[0] == pytest.approx(max(w, h) / min(w, h))


def test_focal_length_and_offsets_are_pinhole() -> None:
    """An offset of half the width is at half the FOV; los_body is (x, y, f) normalised with +Z boresight."""
    f = focal_length_px(2.9, 512)
    assert math.degrees(offset_rad((256.0, -256.0), 2.9, 512)[0]) == pytest.approx(1.45)
    assert math.degrees(offset_rad((256.0, -256.0), 2.9, 512)[1]) == pytest.approx(-1.45)
    np.testing.assert_allclose(los_body(0.0, 0.0, 2.9, 512), [0.0, 0.0, 1.0])
    v = los_body(30.0, -40.0, 2.9, 512)
    np.testing.assert_allclose(v, np.array([30.0, -40.0, f]) / math.sqrt(2500.0 + f * f))


@settings(max_examples=50, deadline=None)
@given(col=st.floats(-256, 256), row=st.floats(-256, 256), fov=st.floats(0.5, 60))
def test_los_body_agrees_with_offset_angles(col: float, row: float, fov: float) -> None:
    """los_body is a unit vector whose x/z and y/z tangents are the tangents of offset_rad."""
    v = los_body(col, row, fov, 512)
    ax, ay = offset_rad((col, row), fov, 512)
    assert np.linalg.norm(v) == pytest.approx(1.0)
    assert v[2] > 0
    assert v[0] / v[2] == pytest.approx(math.tan(ax), abs=1e-12)
    assert v[1] / v[2] == pytest.approx(math.tan(ay), abs=1e-12)


@settings(max_examples=50, deadline=None)
@given(col=st.floats(0, 1023), row=st.floats(0, 1023), side=st.sampled_from([1024, 2048]))
def test_a_measurement_gives_the_line_of_sight_of_its_full_resolution_pixel(col: float, row: float, side: int) -> None:
    """A measured full-resolution centroid, binned, gives the pinhole line of sight of that pixel of the full frame,
    and binned areas are the full-resolution areas over the binning factor squared."""
    col, row = col * side / 1024, row * side / 1024
    camera = CameraKnowledge(resolution_px=side)
    det = measured_detections(CentroidMeasurement(dimorphos_col_row=(col, row), dimorphos_area_px=400.0,
                                                  didymos_col_row=None, didymos_area_px=0.0), ImagingConfig(), camera)
    assert det.didymos is None and det.dimorphos is not None and det.binned_size_px == 512
    centre = (side - 1) / 2
    expected = los_body(col - centre, row - centre, camera.fov_deg, side)
    got = los_body(*det.dimorphos_offset_px, camera.fov_deg, det.binned_size_px)
    np.testing.assert_allclose(got, expected, atol=1e-12)
    assert det.dimorphos.area_px == round(400.0 / (side / 512) ** 2)


def _pair(did_col: float, did_row: float, radius: float, rel: tuple[float, float]) -> tuple[SyntheticBody, ...]:
    """Didymos and a Dimorphos 4.75 times smaller at ``rel`` (px, 1024 scale) from it."""
    return (
        SyntheticBody(did_col, did_row, radius, 2500.0),
        SyntheticBody(did_col + rel[0], did_row + rel[1], radius / 4.75, 2500.0),
    )


def _truth_512(b: SyntheticBody) -> tuple[float, float]:
    """Centre of a synthetic body at the binned scale (pixel centres at integers at both scales)."""
    return ((b.col - 0.5) / 2.0, (b.row - 0.5) / 2.0)


SCENES = [
    # (Didymos radius px at 1024, Dimorphos offset px at 1024 (within the 1.53 diameters of the real orbit),
    #  plume peak DN (0: none), seed)
    (16.0, (40.0, -20.0), 0.0, 10),
    (40.0, (110.0, 40.0), 600.0, 11),
    (40.0, (110.0, 40.0), 2500.0, 11),  # a fan as bright as the surface at its source: merged, then split
    (90.0, (-220.0, 60.0), 600.0, 12),
    (150.0, (330.0, -120.0), 600.0, 13),
]


SUN_CAMERA = (-0.5, 0.3, -0.8)  # synthetic_frame's default Sun direction, camera axes


def _pair_prediction(bodies: tuple[SyntheticBody, ...], sun: tuple[float, float, float] = SUN_CAMERA
                     ) -> FramePrediction:
    """What the flight software would expect of a synthetic pair: the radii (binned px), the orbit radius (1.19 km
    over Didymos's 0.39 km radius), Dimorphos's place within 5 px, the Sun."""
    s = np.asarray(sun) / np.linalg.norm(sun)
    did, dim = bodies
    return FramePrediction(sun_camera=(float(s[0]), float(s[1]), float(s[2])), didymos_radius_px=did.radius_px / 2,
                           dimorphos_radius_px=dim.radius_px / 2, radius_factor_max=1.2,
                           orbit_radius_max_px=1.1 * 1190.0 / 390.0 * did.radius_px / 2,
                           dimorphos_col_row=_truth_512(dim), dimorphos_uncertainty_px=5.0)


@pytest.mark.parametrize(("radius", "rel", "plume_dn", "seed"), SCENES)
def test_bodies_found_and_centroids_match_opencv(
    radius: float, rel: tuple[float, float], plume_dn: float, seed: int
) -> None:
    """On synthetic frames with stars, hot pixels, noise and a plume, every region equals the OpenCV pipeline's,
    and both bodies are identified near their true centres (Dimorphos cut out of the plume when merged with it)."""
    bodies = _pair(500.0, 520.0, radius, rel)
    frame = synthetic_frame(
        np.random.default_rng(seed),
        bodies=bodies,
        plume_from=1 if plume_dn else None,
        plume_peak_dn=plume_dn,
        plume_length_px=6.0 * radius,
        plume_axis_deg=math.degrees(math.atan2(rel[1], rel[0])),
    )
    det = process_frame(frame, CFG, prediction=_pair_prediction(bodies))
    _assert_blobs_equal_reference(det, reference_pipeline(frame))
    assert det.didymos is not None and det.dimorphos is not None
    did_truth, dim_truth = _truth_512(bodies[0]), _truth_512(bodies[1])
    assert math.dist(det.didymos.centroid_col_row, did_truth) < bodies[0].radius_px / 4.0
    if det.dimorphos.trimmed_from:
        # merged with a fan as bright as its surface, then cut to the brightest pixels of its size: they hold it
        x, y, w, h = det.dimorphos.bbox_col_row_w_h
        assert x <= dim_truth[0] < x + w and y <= dim_truth[1] < y + h
    else:
        assert math.dist(det.dimorphos.centroid_col_row, dim_truth) < bodies[1].radius_px / 4.0
    assert det.dimorphos.trimmed_from or plume_dn < 2000.0


def test_offsets_follow_the_image_axes() -> None:
    """A body right of and below the centre has positive (col, row) offsets in px and rad, pinhole-consistent."""
    body = SyntheticBody(511.5 + 160.0, 511.5 + 60.0, 30.0, 2500.0)
    frame = synthetic_frame(
        np.random.default_rng(5), bodies=(body,), sun_camera=(0.0, 0.0, -1.0), n_stars=0, n_hot_pixels=0
    )
    det = process_frame(frame, CFG)
    assert det.didymos is not None and det.didymos_offset_px is not None and det.didymos_offset_rad is not None
    assert det.didymos_offset_px == pytest.approx((80.0, 30.0), abs=0.2)
    f = focal_length_px(FOV_DEG, 512)
    assert det.didymos_offset_rad == pytest.approx(
        (math.atan(det.didymos_offset_px[0] / f), math.atan(det.didymos_offset_px[1] / f))
    )


@pytest.mark.parametrize("value", [0, 40, 4095])
def test_uniform_frames_have_no_blobs(value: int) -> None:
    """A blank or saturated frame gives no blob and no body (the noise floor is above every pixel)."""
    det = process_frame(np.full((1024, 1024), value, dtype=np.uint16), CFG)
    assert det.blobs == () and det.didymos is None and det.dimorphos is None


def test_noise_only_frame_has_no_body() -> None:
    """Background noise, stars and hot pixels alone give no Didymos (nothing of body size and brightness)."""
    frame = synthetic_frame(np.random.default_rng(6), bodies=(), n_stars=0, n_hot_pixels=40)
    det = process_frame(frame, CFG)
    assert det.didymos is None and all(b.area_px == 1 for b in det.blobs)


@pytest.mark.parametrize(
    ("frame", "message"),
    [
        (np.zeros((0, 0), dtype=np.uint16), "empty"),
        (np.zeros((1024,), dtype=np.uint16), "square"),
        (np.zeros((1024, 512), dtype=np.uint16), "square"),
        (np.zeros((1000, 1000), dtype=np.uint16), "not the camera's 1024 px"),
        (np.zeros((2048, 2048), dtype=np.uint16), "not the camera's 1024 px"),
        (np.zeros((1024, 1024), dtype=np.float32), "integers"),
        (np.zeros((1024, 1024), dtype=np.uint8), "8-bit"),
        (np.full((1024, 1024), 4096, dtype=np.uint16), "12-bit"),
        (np.pad(np.full((1, 1), 65535, dtype=np.uint16), ((1023, 0), (0, 1023))), "12-bit"),
        (np.full((1024, 1024), -1, dtype=np.int32), "12-bit"),
    ],
)
def test_bad_frames_raise_frame_error(frame: np.ndarray, message: str) -> None:
    """An empty frame, one of the wrong shape or type, an 8-bit image given for the 12-bit camera, or values out of
    range raise FrameError naming what is wrong."""
    with pytest.raises(FrameError, match=message):
        process_frame(frame, CFG)


def test_working_buffers_do_not_carry_one_frame_into_another() -> None:
    """The chain bins and binarises in the thread's working buffers: a frame gives the same detections before and
    after another frame, and a binned image asked for outside the chain is not overwritten by the next frame."""
    a = synthetic_frame(np.random.default_rng(9), bodies=_pair(500.0, 520.0, 30.0, (80.0, 20.0)))
    b = synthetic_frame(np.random.default_rng(10), bodies=_pair(300.0, 700.0, 50.0, (-60.0, 40.0)))
    first = process_frame(a, CFG)
    kept = filtered(a, CFG, 12)
    copy = kept.binned.copy()
    assert process_frame(b, CFG) != first
    np.testing.assert_array_equal(kept.binned, copy)
    assert process_frame(a, CFG) == first


def test_a_frame_of_another_integer_type_is_taken_by_value() -> None:
    """The same pixel values as int32 or uint32 give the same detections as uint16."""
    frame = synthetic_frame(np.random.default_rng(8), bodies=_pair(500.0, 520.0, 30.0, (80.0, 20.0)))
    want = process_frame(frame, CFG)
    assert process_frame(frame.astype(np.int32), CFG) == want == process_frame(frame.astype(np.uint32), CFG)


def _blob(label: int, col: float, row: float, area: int, diameter: int, peak: int = 200) -> Blob:
    """A compact blob for identification tests."""
    return Blob(label, area, (col, row), (int(col), int(row), diameter, diameter), 150.0, peak, 1.1, 60, (col, row))


def _detections(didymos: Blob | None, dimorphos: Blob | None) -> Detections:
    blobs = tuple(b for b in (didymos, dimorphos) if b is not None)
    return Detections(blobs, didymos, dimorphos, None, None, None, None, 100, 20, 1.0, 512)


def test_continuity_prefers_the_true_dimorphos_over_a_bigger_star() -> None:
    """A star larger than Dimorphos inside the gate wins without history, loses to the continuing Dimorphos."""
    did = _blob(1, 256.0, 256.0, 300, 20)
    dim = _blob(2, 280.0, 250.0, 12, 4)
    star = _blob(3, 240.0, 275.0, 20, 5)
    assert identify_bodies([did, dim, star], CFG) == (did, star)
    prev = _detections(_blob(1, 255.0, 255.0, 290, 20), _blob(2, 278.5, 249.0, 11, 4))
    assert identify_bodies([did, dim, star], CFG, prev) == (did, dim)


def test_dimorphos_alone_when_didymos_leaves_the_field() -> None:
    """A Dimorphos-sized blob whose previous offset puts Didymos off-image is Dimorphos alone, else Didymos."""
    prev = _detections(_blob(1, 15.0, 256.0, 1500, 40), _blob(2, 250.0, 260.0, 700, 30))
    now = _blob(1, 230.0, 258.0, 720, 30)  # Didymos predicted at col -5: out of the field
    assert identify_bodies([now], CFG, prev) == (None, now)
    assert identify_bodies([now], CFG) == (now, None)
    inside = _blob(1, 250.0, 258.0, 720, 30)  # Didymos predicted at col 15: in the field, so this is Didymos
    assert identify_bodies([inside], CFG, prev) == (inside, None)


def test_pointing_jitter_does_not_swap_the_bodies() -> None:
    """Both bodies shifted together by 40 px (pointing motion) keep their identities."""
    prev = _detections(_blob(1, 200.0, 250.0, 300, 20), _blob(2, 225.0, 250.0, 12, 4))
    did = _blob(1, 225.0, 250.0, 310, 20)  # now where Dimorphos was
    dim = _blob(2, 250.0, 250.5, 12, 4)
    assert identify_bodies([dim, did], CFG, prev) == (did, dim)


def test_stars_far_from_didymos_and_dim_or_elongated_blobs_are_not_dimorphos() -> None:
    """Dimorphos must be within the separation gate, bright enough, compact and smaller than Didymos."""
    did = _blob(1, 256.0, 256.0, 300, 20)
    far = _blob(2, 256.0, 320.0, 12, 4)  # 64 px away, gate is 2 x 20 + 2 px
    dim_faint = _blob(3, 270.0, 256.0, 12, 4, peak=40)
    ray = Blob(4, 30, (250.0, 270.0), (240, 268, 30, 3), 150.0, 200, 12.0, 60, (250.0, 270.0))
    assert identify_bodies([did, far, dim_faint, ray], CFG) == (did, None)


def test_default_config_is_reachable_from_obsw_config() -> None:
    """ObswConfig carries the imaging and camera-knowledge defaults (paper: 512 px binned, 2.9 deg FOV, 12 bit)."""
    cfg = ObswConfig()
    assert (cfg.imaging.binned_size_px, cfg.camera.fov_deg, cfg.camera.bit_depth) == (512, 2.9, 12)


# ---------------------------------------------------------------------------------------------------------------
# Frames rendered by the universe camera along the flyby


DIDYMOS_SHAPE = ShapeModel(seed=1)  # built once: a shape caches its surface tables
DIMORPHOS_SHAPE = ShapeModel(seed=2, axis_ratios=(1.3, 1.0, 0.85))


def _attitude_towards(los_inertial: np.ndarray) -> np.ndarray:
    """Scalar-last quaternion body->inertial with body +Z along the line of sight and body +X in the XY plane."""
    z = los_inertial / np.linalg.norm(los_inertial)
    x = np.cross([0.0, 0.0, 1.0], z)
    x /= np.linalg.norm(x)
    return Rotation.from_matrix(np.column_stack([x, np.cross(z, x), z])).as_quat()


def _onboard_prediction(uc: UniverseConfig, q: Rotation, t: float) -> FramePrediction:
    """The flight software's prediction of a frame exposed at ``t`` (s, used as on-board time) with attitude ``q``:
    the true flyby as its trajectory (known to 1 s and 0.5 km), the true bodies and Sun as its knowledge."""
    f, b = uc.flyby, uc.bodies
    traj = NominalTrajectory(ca_time_obt_s=f.ca_time_s, ca_distance_km=f.ca_distance_km, speed_km_s=f.speed_km_s,
                             approach_direction=f.approach_direction, ca_direction=f.ca_direction,
                             ca_time_sigma_s=1.0, ca_distance_sigma_km=0.5)
    targets = TargetKnowledge(didymos_diameter_m=b.didymos_diameter_m, dimorphos_diameter_m=b.dimorphos_diameter_m,
                              orbit_radius_m=b.orbit_radius_m, sun_direction_inertial=b.sun_direction)
    return predict_frame(q.as_quat(), targets, CameraKnowledge(), CFG, traj, t)


def _flyby_run(
    uc: UniverseConfig, times: np.ndarray, seed: int, jitter_rad: float
) -> list[tuple[Detections, object, dict]]:
    """Render frames pointed at Dimorphos with seeded pointing jitter; process them in order with continuity and the
    on-board prediction (``_onboard_prediction``).

    Returns per frame the detections, the OpenCV reference result and the truth (projected centres at the
    512 scale, apparent radii in px at 512, true line of sight to Dimorphos in body axes).
    """
    rng = np.random.default_rng(seed)
    geo = FlybyGeometry(uc.flyby, uc.bodies)
    f512 = focal_length_px(uc.camera.fov_deg, 512)
    out = []
    previous = None
    for t in times:
        sc = geo.spacecraft_position_m(t)
        did, dim = geo.didymos_position_m(t), geo.dimorphos_position_m(t)
        q = (Rotation.from_rotvec(rng.normal(0.0, jitter_rad, 3)) * Rotation.from_quat(_attitude_towards(dim - sc)))
        scene = Scene(
            camera_position_m=sc,
            q_body_to_inertial=q.as_quat(),
            body_rate_rad_s=np.zeros(3),
            exposure_s=uc.camera.exposure_s,
            bodies=(
                Body(did, uc.bodies.didymos_diameter_m / 2.0, DIDYMOS_SHAPE),
                Body(dim, uc.bodies.dimorphos_diameter_m / 2.0, DIMORPHOS_SHAPE),
            ),
            sun_direction=geo.sun_direction(),
            time_since_impact_s=float(t - uc.bodies.impact_time_s),
            star_seed=3,
            camera_velocity_m_s=geo.spacecraft_velocity_m_s(t),
            plume_body_index=1,
        )
        frame = render_frame(scene, uc.camera, uc.plume, rng)
        det = process_frame(frame, CFG, previous, prediction=_onboard_prediction(uc, q, float(t)))
        previous = det
        truth = {
            "did": tuple((c - 0.5) / 2.0 for c in project_inertial(scene, uc.camera, did)),
            "dim": tuple((c - 0.5) / 2.0 for c in project_inertial(scene, uc.camera, dim)),
            "did_r": f512 * uc.bodies.didymos_diameter_m / 2.0 / float(np.linalg.norm(did - sc)),
            "dim_r": f512 * uc.bodies.dimorphos_diameter_m / 2.0 / float(np.linalg.norm(dim - sc)),
            "dim_los_body": q.inv().apply((dim - sc) / np.linalg.norm(dim - sc)),
        }
        out.append((det, reference_pipeline(frame), truth))
    return out


MIN_DIMORPHOS_DIAMETER_PX = 2.0  # at 512: from here on Dimorphos spans enough pixels to be a target (paper: 30-45)


def test_camera_nominal_flyby_finds_both_bodies_once_dimorphos_is_resolved() -> None:
    """Nominal flyby rendered by the universe camera (Dimorphos beside Didymos, no plume, 1 mrad jitter): every
    blob equals OpenCV's and, once Dimorphos spans 2 px, both bodies are found at their true places in every
    frame; Dimorphos's line of sight from los_body is within 2 px of the truth."""
    uc = UniverseConfig(bodies=BodiesConfig(orbit_phase_deg=90.0), plume=PlumeConfig(enabled=False))
    run = _flyby_run(uc, np.arange(40.0, 166.0, 2.0), seed=21, jitter_rad=1e-3)
    resolved = [r for r in run if 2.0 * r[2]["dim_r"] >= MIN_DIMORPHOS_DIAMETER_PX]
    assert len(resolved) >= 40
    ifov = math.radians(FOV_DEG) / 512
    for det, ref, truth in run:
        _assert_blobs_equal_reference(det, ref)
    for det, _, truth in resolved:
        assert det.didymos is not None and det.dimorphos is not None
        assert math.dist(det.didymos.centroid_col_row, truth["did"]) <= max(0.5 * truth["did_r"], 1.5)
        assert math.dist(det.dimorphos.centroid_col_row, truth["dim"]) <= max(0.5 * truth["dim_r"], 1.5)
        assert det.dimorphos_offset_px is not None
        los = los_body(*det.dimorphos_offset_px, FOV_DEG, 512)
        angle = math.acos(min(1.0, float(los @ truth["dim_los_body"])))
        assert angle <= max(0.5 * truth["dim_r"], 2.0) * ifov


def test_camera_worst_case_flyby_with_plume() -> None:
    """Worst case (C/A 50 km, ejecta plume, 2 mrad jitter, frames 3 s apart): every blob equals OpenCV's, Didymos
    is found at its true place and Dimorphos, merged with the plume's dense core, holds its true centre."""
    uc = UniverseConfig(
        flyby=FlybyConfig(ca_distance_km=50.0),
        bodies=BodiesConfig(orbit_phase_deg=90.0),
        plume=PlumeConfig(cross_section_m2=1.0e6),
    )
    run = _flyby_run(uc, np.arange(60.0, 162.0, 3.0), seed=22, jitter_rad=2e-3)
    for det, ref, truth in run:
        _assert_blobs_equal_reference(det, ref)
        assert det.didymos is not None and det.dimorphos is not None
        assert math.dist(det.didymos.centroid_col_row, truth["did"]) <= max(0.5 * truth["did_r"], 1.5)
        x, y, w, h = det.dimorphos.bbox_col_row_w_h
        assert x - 1 <= truth["dim"][0] <= x + w and y - 1 <= truth["dim"][1] <= y + h


def test_dimorphos_centroid_within_15_px_of_the_truth_with_the_plume_on() -> None:
    """Scenario universe (plume, noise, 1 mrad jitter) from C/A-150 s, when the dense ejecta surround a Dimorphos
    a few pixels across, to C/A-80 s and around C/A: every blob equals OpenCV's, and every reported Dimorphos
    centroid is within the paper's 15 px of the true projection of its centre (reported in most frames)."""
    uc = UniverseConfig()
    ca = uc.flyby.ca_time_s
    plume_window = np.arange(ca - 150.0, ca - 80.0, 3.0)
    near_ca = np.arange(ca - 12.0, ca + 48.0, 3.0)
    reported = 0
    for times, seed in ((plume_window, 23), (near_ca, 24)):
        for det, ref, truth in _flyby_run(uc, times, seed=seed, jitter_rad=1e-3):
            _assert_blobs_equal_reference(det, ref)
            if det.dimorphos is not None:
                reported += times is plume_window
                assert math.dist(det.dimorphos.centroid_col_row, truth["dim"]) <= 15.0
    assert reported >= 0.8 * plume_window.size


def test_ejecta_merged_with_dimorphos_are_trimmed_off() -> None:
    """Dimorphos at the apex of a fan of ejecta (1500 DN against its 2500 DN surface, seen at zero phase): its region
    is pulled along the fan by more than 4 px; trimmed to its brightest pixels of the expected area, it is within a
    pixel of the body's centre."""
    bodies = (SyntheticBody(460.0, 520.0, 14.25, 2500.0), SyntheticBody(500.0, 520.0, 3.0, 2500.0))
    frame = synthetic_frame(
        np.random.default_rng(7), bodies=bodies, sun_camera=(0.0, 0.0, -1.0), n_stars=0, n_hot_pixels=0,
        plume_from=1, plume_peak_dn=1500.0, plume_length_px=60.0, plume_axis_deg=0.0,
    )
    det = process_frame(frame, CFG, prediction=_pair_prediction(bodies, (0.0, 0.0, -1.0)))
    assert det.dimorphos is not None and det.dimorphos.trimmed_from
    region = next(b for b in det.blobs if b.label == det.dimorphos.trimmed_from)
    truth = _truth_512(bodies[1])
    assert region.region_centroid_col_row[0] - truth[0] > 4.0  # pulled along the fan (+col)
    assert math.dist(det.dimorphos.centroid_col_row, truth) <= 1.0


@pytest.mark.parametrize("diameter_px", [7, 10, 20])
def test_last_pair_bridges_frames_without_dimorphos(diameter_px: int) -> None:
    """After frames where Dimorphos merged (not seen), the last pair still tells Didymos from a plume-inflated
    Dimorphos with the larger core, for pair_memory_frames when Didymos spanned pair_memory_max_didymos_px and
    longer in proportion to the range for a smaller one (its offset changes as the range does); once older, the
    larger core wins."""
    assert CFG.pair_memory_frames == 20 and CFG.pair_memory_max_didymos_px == 20.0  # the figures below
    last_frame = {7: 57, 10: 39, 20: 19}[diameter_px]  # 20 frames x 20 px / diameter, the last age below it
    did_then = _blob(1, 260.0, 256.0, 40, diameter_px)
    dim_then = _blob(2, 249.0, 256.0, 6, 3)
    merged = _detections(_blob(1, 257.0, 256.0, 120, 20), None)
    did = _blob(1, 261.0, 257.0, 40, 7)
    dim_plume = _blob(2, 250.0, 256.5, 60, 8)  # Dimorphos and its ejecta: larger than Didymos
    for age in range(last_frame + 1):
        prev = dataclasses.replace(merged, pair=(did_then, dim_then), pair_age_frames=age)
        assert identify_bodies([did, dim_plume], CFG, prev) == (did, dim_plume)
    stale = dataclasses.replace(merged, pair=(did_then, dim_then), pair_age_frames=last_frame + 1)
    assert identify_bodies([did, dim_plume], CFG, stale) == (dim_plume, None)


def test_a_piece_of_didymos_crescent_is_not_dimorphos() -> None:
    """Two pieces of a thin crescent (areas 9 and 4) are Didymos and nothing: a first-found Dimorphos is at most
    dimorphos_max_area_fraction of Didymos (the real ratio is 0.044); at 2 px the small one is Dimorphos."""
    piece = _blob(1, 227.4, 257.6, 9, 8)
    other = _blob(2, 226.8, 250.5, 4, 4)
    assert identify_bodies([piece, other], CFG) == (piece, None)
    small = _blob(2, 226.8, 250.5, 2, 2)
    assert identify_bodies([piece, small], CFG) == (piece, small)


def test_a_blob_beside_a_thin_crescent_is_a_piece_of_it() -> None:
    """A 2 px blob 1 px beyond the end of a thin Didymos crescent (elongation 6) is not Dimorphos; 10 px away it
    is, and beside a round Didymos it is."""
    crescent = Blob(1, 12, (226.7, 255.8), (226, 251, 2, 10), 53.0, 55, 6.2, 50, (226.7, 255.8))
    piece = _blob(2, 225.0, 262.5, 2, 2)
    assert identify_bodies([crescent, piece], CFG) == (crescent, None)
    apart = _blob(2, 225.0, 272.5, 2, 2)
    assert identify_bodies([crescent, apart], CFG) == (crescent, apart)
    round_did = crescent._replace(elongation=1.2)
    assert identify_bodies([round_did, piece], CFG) == (round_did, piece)


@pytest.mark.parametrize(("peak_dn", "axis_deg", "separation_px", "seed"), [
    (6000.0, -60.0, 23.0, 0), (6000.0, -75.0, 20.0, 1),  # Didymos's piece among the region's brightest parts
    (8000.0, -60.0, 20.0, 2), (12000.0, -75.0, 20.0, 3), (12000.0, -60.0, 23.0, 4),  # none of it there
])
def test_didymos_beside_a_fan_brighter_than_it_is_found_by_the_remembered_pair(
        peak_dn: float, axis_deg: float, separation_px: float, seed: int) -> None:
    """A 9 px Didymos merged with the fan of a Dimorphos 10-12 px away, the fan's root 2.4-5 times as bright as
    Didymos's surface (held-out run 626 of worst-late-near at 1000 km): with the last pair remembered and Dimorphos's
    place known to 5 px, Didymos is reported within 2 px of its centre, not at the fan's root (8.5-10 px off before,
    with or without the pair)."""
    sun = (-0.67, 0.0, -0.74)
    did = SyntheticBody(540.0, 512.0, 8.0, 2500.0)
    dim = SyntheticBody(540.0 - separation_px, 512.0, 8.0 / 4.75, 2500.0)
    frame = synthetic_frame(np.random.default_rng(seed), bodies=(did, dim), sun_camera=sun, n_stars=0,
                            n_hot_pixels=0, plume_from=1, plume_peak_dn=peak_dn, plume_length_px=60.0,
                            plume_axis_deg=axis_deg, plume_half_angle_deg=40.0)
    td, tm = _truth_512(did), _truth_512(dim)
    previous = _detections(_blob(1, td[0] + 0.5, td[1], 45, 8), _blob(2, tm[0] + 0.5, tm[1] - 1.0, 3, 2))
    det = process_frame(frame, CFG, previous, prediction=_pair_prediction((did, dim), sun))
    assert det.didymos is not None
    assert math.dist(det.didymos.centroid_col_row, td) <= 2.0, det.didymos


def test_last_pair_is_not_remembered_near_closest_approach() -> None:
    """A remembered pair whose Didymos spanned more than pair_memory_max_didymos_px does not gate the next frame."""
    did_then = _blob(1, 260.0, 256.0, 2000, 60)
    dim_then = _blob(2, 200.0, 256.0, 90, 12)
    prev = dataclasses.replace(_detections(_blob(1, 250.0, 256.0, 2200, 62), None), pair=(did_then, dim_then))
    assert CFG.pair_memory_max_didymos_px < 60
    big_plume = _blob(1, 205.0, 256.0, 2500, 70)  # a plume core larger than Didymos, where Dimorphos was
    did = _blob(2, 262.0, 256.0, 2100, 60)
    assert identify_bodies([big_plume, did], CFG, prev)[0] is big_plume
    near = dataclasses.replace(prev, pair=(did_then._replace(bbox_col_row_w_h=(230, 226, 18, 18)), dim_then))
    assert identify_bodies([big_plume, did], CFG, near)[0] is did
