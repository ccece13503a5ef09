"""The imaging chain's defect handling (bad-pixel map, outlier filter) against an independent OpenCV implementation,
on frames of the independent generator."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from tests.obsw.frame_generator import Defects, random_scene, render, with_defect
from tests.obsw.imaging_trials import ground_map, prediction_for
from tests.obsw.opencv_reference import (
    OpenCvMap,
    opencv_pipeline,
    reference_bad_pixels,
    reference_pipeline,
)

from obsw.config import CameraKnowledge, ImagingConfig
from obsw.imaging import BadPixelMap, process_frame
from obsw.imaging_filtering import FrameError, filtered

CFG = ImagingConfig()


def _map_args(scene) -> tuple[list[tuple[int, int]], tuple[int, ...]]:
    """The pixels and columns of ``ground_map`` as the reference takes them."""
    d = scene.defects
    return [(c, r) for c, r, _ in d.hot[: len(d.hot) // 2]] + list(d.dead), d.dead_columns


@pytest.mark.parametrize("seed", range(6))
def test_defect_handling_equals_opencv_pixel_for_pixel(seed: int) -> None:
    """Independent frames with hot pixels, cosmic rays, dead pixels and columns: the outliers replaced and the binned
    image equal the OpenCV implementation's (map by nearest good pixels, cv2.medianBlur, block statistics), and so
    does the fast OpenCV pipeline of the benchmark."""
    rng = np.random.default_rng([41, seed])
    scene = random_scene(rng)
    frame = render(scene, rng).pixels
    ours = filtered(frame, CFG, 12, ground_map(scene))
    ref = reference_pipeline(frame, bad_pixels=_map_args(scene))
    flagged = np.zeros(frame.size, dtype=bool)
    flagged[ours.outliers] = True
    np.testing.assert_array_equal(flagged.reshape(frame.shape), ref.outliers)
    np.testing.assert_array_equal(ours.binned, ref.binned)
    np.testing.assert_array_equal(ours.hist, np.bincount(ref.binned.ravel(), minlength=4096))
    _, _, fast = opencv_pipeline(frame, OpenCvMap.of(1024, *_map_args(scene)))
    np.testing.assert_array_equal(fast, ref.binned)


def test_2048_frames_are_filtered_in_4x4_blocks_like_opencv() -> None:
    """A 2048x2048 frame: 4x4 blocks, the same outliers as the OpenCV implementation and each block the rounded mean
    floor(m + 1/2) of its corrected pixels (cv2.resize INTER_AREA in float, exact for 16 values); OpenCV's integer
    INTER_AREA rounds ties to even, so it is within 1 DN."""
    rng = np.random.default_rng(43)
    scene = random_scene(rng, size_px=2048, didymos_diameter_px=60.0, n_hot=40, n_cosmic=5)
    frame = render(scene, rng).pixels
    ours = filtered(frame, CFG, 12, ground_map(scene))
    ref = reference_pipeline(frame, bad_pixels=_map_args(scene))
    flagged = np.zeros(frame.size, dtype=bool)
    flagged[ours.outliers] = True
    assert ours.outliers.size > 0
    np.testing.assert_array_equal(flagged.reshape(frame.shape), ref.outliers)
    means = cv2.resize(ref.corrected.astype(np.float32), (512, 512), interpolation=cv2.INTER_AREA)
    np.testing.assert_array_equal(ours.binned, np.floor(means.astype(np.float64) + 0.5))
    assert np.abs(ours.binned.astype(np.int64) - ref.binned).max() <= 1


def test_blocks_too_large_for_the_binning_sums_raise_frame_error() -> None:
    """A binning whose f x f blocks of full-scale pixels would overflow the 32-bit block sums is refused, naming the
    binned size, before any sum is taken."""
    frame = np.zeros((1024, 1024), dtype=np.uint16)
    with pytest.raises(FrameError, match="binned_size_px 4 is too small"):
        filtered(frame, ImagingConfig(binned_size_px=4), 16)


@settings(max_examples=60, deadline=None)
@given(data=st.data(), side=st.integers(2, 24))
def test_a_bad_pixel_takes_the_mean_of_its_nearest_good_row_neighbours(data: st.DataObject, side: int) -> None:
    """Any map (runs of adjacent bad pixels, row ends, whole rows, columns): each bad pixel becomes the rounded mean
    of the nearest good pixels left and right in its row, the one that exists, or keeps its value."""
    frame = data.draw(st.lists(st.integers(0, 4095), min_size=side * side, max_size=side * side))
    frame = np.asarray(frame, dtype=np.uint16).reshape(side, side)
    pixels = data.draw(st.lists(st.tuples(st.integers(0, side - 1), st.integers(0, side - 1)), max_size=3 * side))
    columns = data.draw(st.lists(st.integers(0, side - 1), max_size=2, unique=True))
    bad = BadPixelMap.build(side, pixels, columns)
    want = reference_bad_pixels(frame, pixels, columns)
    got = frame.astype(np.int64).reshape(-1)
    got[bad.pixels] = bad.replacement(frame.reshape(-1))
    np.testing.assert_array_equal(got.reshape(side, side), want)


@pytest.mark.parametrize(("pixels", "columns", "message"), [
    ([(1024, 3)], (), "col 1024"),
    ([(3, -1)], (), "row -1"),
    ([], (2000,), "dead column 2000"),
])
def test_a_map_off_the_sensor_is_refused(pixels: list, columns: tuple, message: str) -> None:
    """A pixel or column outside the sensor is refused, naming it."""
    with pytest.raises(ValueError, match=message):
        BadPixelMap.build(1024, pixels, columns)


def _faint_pair_scene(rng: np.random.Generator):
    """A faint Didymos (400-850 DN) 40 px across with Dimorphos, no defects, no plume."""
    scene = random_scene(rng, didymos_diameter_px=40.0, faint=True, plume=False, n_hot=0, n_cosmic=0,
                         phase_deg=40.0, pointing_error_px=0.0)
    return scene.__class__(**{**scene.__dict__, "defects": Defects(), "stars": ()})


@pytest.mark.parametrize(("kind", "seed"), [("hot", 1), ("hot", 2), ("cosmic", 3), ("cosmic", 4)])
def test_a_defect_on_a_faint_body_is_taken_out_before_binning(kind: str, seed: int) -> None:
    """A saturated hot pixel or a 6 px cosmic ray on a faint Didymos (same noise): the filter replaces it, so the
    body's region keeps its area within 2 px and its centroid within 0.2 px of the frame without the defect."""
    rng = np.random.default_rng([44, seed])
    scene = _faint_pair_scene(rng)
    prediction = prediction_for(scene, rng, 3.0)
    clean = process_frame(render(scene, np.random.default_rng(seed)).pixels, CFG, prediction=prediction)
    hit = with_defect(scene, rng, kind, 0)
    frame = render(hit, np.random.default_rng(seed)).pixels
    det = process_frame(frame, CFG, prediction=prediction)
    assert det.outliers >= 1
    assert clean.didymos is not None and det.didymos is not None
    assert abs(det.didymos.area_px - clean.didymos.area_px) <= 2
    assert math.dist(det.didymos.region_centroid_col_row, clean.didymos.region_centroid_col_row) <= 0.2
    unfiltered = process_frame(frame, ImagingConfig(outlier_filter=False), prediction=prediction)
    assert unfiltered.didymos is not None and unfiltered.didymos.peak_dn8 > det.didymos.peak_dn8


@pytest.mark.parametrize("seed", range(4))
def test_a_lit_surface_loses_no_pixel_to_the_filter(seed: int) -> None:
    """Bodies seen through the optics (PSF sigma 0.6-1.2 px), no defect and no star: the filter replaces nothing
    brighter than the noise around the bodies' limbs."""
    rng = np.random.default_rng([45, seed])
    scene = random_scene(rng, didymos_diameter_px=float(rng.uniform(20.0, 300.0)), n_hot=0, n_cosmic=0, plume=False)
    scene = scene.__class__(**{**scene.__dict__, "defects": Defects(), "stars": ()})
    frame = render(scene, rng).pixels
    out = filtered(frame, CFG, 12)
    lit = frame.reshape(-1)[out.outliers].astype(np.int64) - out.background_dn
    assert np.all(lit <= 2 * CFG.outlier_k_sigma * out.noise_sigma_dn)


def test_a_dead_column_across_a_body_is_filled_from_its_neighbours() -> None:
    """A dead column through Didymos: with the uploaded map the body's region is what it is without the column."""
    rng = np.random.default_rng(46)
    scene = random_scene(rng, didymos_diameter_px=120.0, plume=False, n_hot=0, n_cosmic=0, pointing_error_px=0.0)
    column = int(round(scene.bodies[0].col))
    clean_scene = scene.__class__(**{**scene.__dict__, "defects": Defects(), "stars": ()})
    dead_scene = scene.__class__(**{**scene.__dict__, "defects": Defects(dead_columns=(column,)), "stars": ()})
    clean = process_frame(render(clean_scene, np.random.default_rng(1)).pixels, CFG)
    frame = render(dead_scene, np.random.default_rng(1)).pixels
    fixed = process_frame(frame, CFG, bad_pixels=BadPixelMap.build(1024, [], (column,)))
    assert clean.didymos is not None and fixed.didymos is not None
    assert abs(fixed.didymos.area_px - clean.didymos.area_px) <= 0.01 * clean.didymos.area_px
    assert math.dist(fixed.didymos.region_centroid_col_row, clean.didymos.region_centroid_col_row) <= 0.3
    assert fixed.bad_pixels == 1024


def test_the_map_must_fit_the_frame() -> None:
    """A map for another sensor size is refused with the frame."""
    frame = np.zeros((2048, 2048), dtype=np.uint16)
    with pytest.raises(ValueError, match="1024 px sensor"):
        process_frame(frame, CFG, camera=CameraKnowledge(resolution_px=2048),
                      bad_pixels=BadPixelMap.build(1024, [(1, 1)]))
