"""Identification of Didymos and Dimorphos on frames of the independent generator, class by class of the failures
bench/imaging.py found (plume, phase, crescent, stars), each against the truth and the OpenCV region of the same
blob; and the light-spread measure of a blob against OpenCV's moments."""

from __future__ import annotations

import math
from dataclasses import replace

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import quad
from scipy.special import i0e
from tests.obsw.frame_generator import (
    FOCAL_1024_PX,
    ORBIT_RADIUS_M,
    Defects,
    Ellipsoid,
    Plume,
    Scene,
    random_scene,
    render,
    with_defect,
)
from tests.obsw.imaging_trials import (
    PAPER_LIMIT_PX,
    ground_map,
    Trial,
    identity,
    prediction_for,
    reference_blob,
    reference_for,
    run_trial,
    scaled,
    swallowed,
    visible,
)
from tests.obsw.opencv_reference import reference_pipeline

from obsw.config import ImagingConfig
from obsw.imaging import Detections, FramePrediction, process_frame
from obsw.imaging_filtering import linear_values
from obsw.imaging_identification import (
    Blob,
    Expected,
    Regions,
    _likeliest,
    _gaussian_share_in_disc,
    _Place,
    _point_likelihood,
    _StarField,
    _relative_jump_px,
    _split,
    expected,
    identify_bodies,
    light_spread_px2,
    reference_pair,
    trimmed,
)
from obsw.imaging_labelling import connected_components

CFG = ImagingConfig()
REPORT_ALL = CFG.model_copy(update={"didymos_min_report_probability": 0.0})  # every Didymos identified is reported


def _bench_scene(seed: int, k: int) -> tuple[Scene, FramePrediction]:
    """The scene and prediction of frame k of bench/imaging.py's independent frames at ``seed``."""
    rng = np.random.default_rng([seed, k])
    scene = random_scene(rng)
    return scene, prediction_for(scene, rng, 3.0 if rng.random() < 0.5 else 30.0)


def _bench_trial(seed: int, k: int, cfg: ImagingConfig = CFG) -> Trial:
    """Frame k of bench/imaging.py's independent frames at ``seed``: the same scene, prediction and noise."""
    scene, prediction = _bench_scene(seed, k)
    return run_trial(scene, k, prediction, cfg)


def _apart(scene, rng: np.random.Generator):  # noqa: ANN001, ANN202 (a frame_generator.Scene)
    """The scene with Didymos moved to 1.5 of its diameters from Dimorphos in the image (the orbit seen broadside),
    in a random direction: the two bodies well apart."""
    did, dim = scene.bodies
    a = rng.uniform(0.0, 2.0 * math.pi)
    d = 3.0 * did.mean_radius_px
    return replace(scene, bodies=(replace(did, col=dim.col - d * math.cos(a), row=dim.row - d * math.sin(a)), dim))


def _assert_found(t: Trial, index: int) -> None:
    """The body is reported as itself, on the OpenCV region of the same blob, within the paper's 15 px."""
    body = t.didymos if index == 0 else t.dimorphos
    assert body.truth_index == index
    assert body.opencv_px is not None and body.opencv_px <= 1e-9
    assert body.error_px is not None and body.error_px <= PAPER_LIMIT_PX


@pytest.mark.parametrize(("seed", "k"), [(1, 108), (1, 233), (1, 285), (1, 309), (99, 291)])
def test_dimorphos_in_the_plume_is_not_a_star_in_the_dust(seed: int, k: int) -> None:
    """Dimorphos merged with a plume holding stars brighter than its surface: the part cut out for it is the body,
    not a star of a few pixels in the dust (bench frames that reported a star)."""
    _assert_found(_bench_trial(seed, k), 1)


@pytest.mark.parametrize(("seed", "k"), [(36, 76), (37, 86)])
def test_a_small_dimorphos_joined_to_didymos_by_the_glow_is_cut_off_its_disc(seed: int, k: int) -> None:
    """Dimorphos 4-5 px across, a few px off Didymos's limb and joined to it by the plume's glow, its place known to
    9 px: the part of the region cut for it stops at Didymos's limb, and Dimorphos is found (bench frames of seeds
    36 and 37, unseen before, that reported none: within the place's disc Didymos's lit limb was the brightest)."""
    _assert_found(_bench_trial(seed, k), 1)


@pytest.mark.parametrize(("seed", "k"), [(41, 123), (41, 281), (41, 303)])
def test_dimorphos_merged_with_didymos_below_every_cut_is_deblended(seed: int, k: int) -> None:
    """Dimorphos 8-39 px across joined to Didymos by the plume, its pixels below every level the cuts tried: the
    region deblended, its own peak is found (bench frames of seed 41, unseen before, that reported none: the seed's
    Dimorphos at 97.4 %); with no part significant enough to deblend, it is not."""
    _assert_found(_bench_trial(seed, k), 1)
    assert _bench_trial(seed, k, CFG.model_copy(update={"deblend_min_flux_fraction": 0.999})).detections.dimorphos \
        is None


@pytest.mark.parametrize(("seed", "k"), [(59, 112), (43, 54), (1, 213), (2, 5), (31, 262), (53, 6)])
def test_dimorphos_in_a_whole_region_with_room_for_both_bodies_is_deblended(seed: int, k: int) -> None:
    """Dimorphos 3-21 px across in the region of a resolved Didymos left whole (not cut: no part of it taken for
    Dimorphos), the region holding more than both bodies' areas: deblended, its own peak is found (bench frame 59/112,
    a seed first run before the rule, and frames of earlier seeds it also found); with no part significant enough to
    deblend, it is not."""
    _assert_found(_bench_trial(seed, k), 1)
    assert _bench_trial(seed, k, CFG.model_copy(update={"deblend_min_flux_fraction": 0.999})).detections.dimorphos \
        is None


@pytest.mark.parametrize(("seed", "k"), [(109, 244), (9, 166), (105, 148), (13, 279), (23, 289)])
def test_dimorphos_in_a_whole_region_smaller_than_predicted_is_deblended(seed: int, k: int) -> None:
    """Dimorphos 6-19 px across in the region of a resolved Didymos left whole, the region smaller than both bodies'
    predicted areas (Didymos smaller than predicted): deblended, its own peak is found and Didymos stays found
    (held-out bench frame 109/244, a 19 px Dimorphos touching Didymos, reported none; and frames of earlier seeds
    the same rule finds); with no part significant enough to deblend, it is not."""
    t = _bench_trial(seed, k)
    _assert_found(t, 0)
    _assert_found(t, 1)
    assert _bench_trial(seed, k, CFG.model_copy(update={"deblend_min_flux_fraction": 0.999})).detections.dimorphos \
        is None


@pytest.mark.parametrize("seed", range(8))
def test_dimorphos_touching_a_didymos_smaller_than_predicted_is_found(seed: int) -> None:
    """A resolved Didymos 80-110 px across with Dimorphos's limb 1-3 px off its limb, both predicted a tenth larger
    than they are (the range off by 10 %): the two make one region smaller than the predicted areas of both, and
    Dimorphos is found in it, on itself and within the paper's limit; Didymos too."""
    rng = np.random.default_rng([109, seed])
    scene = random_scene(rng, didymos_diameter_px=float(rng.uniform(80.0, 110.0)), phase_deg=float(rng.uniform(
        20.0, 50.0)), plume=False, n_hot=0, n_cosmic=0, pointing_error_px=0.0)
    did, dim = scene.bodies
    a = rng.uniform(0.0, 2.0 * math.pi)
    gap = did.mean_radius_px + dim.mean_radius_px + rng.uniform(1.0, 3.0)
    dim = replace(dim, col=did.col + gap * math.cos(a), row=did.row + gap * math.sin(a), depth_m=did.depth_m - 1e3,
                  radiance_dn=did.radiance_dn)
    scene = replace(scene, bodies=(did, dim), stars=(), defects=Defects())
    pred = prediction_for(scene, rng, 3.0)
    pred = replace(pred, didymos_radius_px=1.1 * did.mean_radius_px / 2,
                   dimorphos_radius_px=1.1 * dim.mean_radius_px / 2)
    t = run_trial(scene, seed, pred)
    _assert_found(t, 0)
    _assert_found(t, 1)


@pytest.mark.parametrize(("plume_brightness", "dimorphos_radiance"), [(1.0, 1.0), (1.25, 1.0), (1.5, 1.0),
                                                                      (1.0, 0.85), (1.0, 1.2)])
def test_a_crescent_beside_a_brighter_fan_is_dimorphos_not_the_fan_s_root(plume_brightness: float,
                                                                        dimorphos_radiance: float) -> None:
    """Held-out bench frame 107/212, the plume or Dimorphos dimmer or brighter: a 15 px crescent, a region of its own,
    beside the root of a fan whose brightest pixels are brighter than the crescent's; the fan (a region larger than
    Dimorphos can be) held the most light in Dimorphos's expected area and its root was reported, 15.9 px off. A
    region of Dimorphos's size, resolved, where the lit part is expected, is Dimorphos before a larger one."""
    scene, prediction = _bench_scene(107, 212)
    _assert_found(run_trial(scaled(scene, plume_brightness, dimorphos_radiance), 212, prediction), 1)


@pytest.mark.parametrize(("plume_brightness", "dimorphos_radiance"), [(1.0, 1.0), (0.8, 1.0), (1.0, 0.8),
                                                                      (1.0, 1.25)])
def test_a_crescent_didymos_whose_box_reaches_the_place_is_didymos_beside_a_brighter_fan(
        plume_brightness: float, dimorphos_radiance: float) -> None:
    """Held-out bench frame 124/23, the plume or Dimorphos dimmer or brighter: a 32 px crescent Didymos at 120 deg
    beside Dimorphos and the fan it sheds, whose root outshines the crescent in Didymos's expected area. The fan holds
    Dimorphos's place with more than both bodies' areas, so a body-sized region beside it is Didymos; the crescent's
    box reaches within the place's radius though its centroid is 30 px off, and it was passed over (the fan's root
    reported, 33.4 px off). Didymos is found, within the paper's limit. (With the plume a quarter brighter the
    crescent is offered, but a later step takes the fan's root again: not handled.)"""
    scene, prediction = _bench_scene(124, 23)
    _assert_found(run_trial(scaled(scene, plume_brightness, dimorphos_radiance), 23, prediction), 0)


@pytest.mark.parametrize(("plume_brightness", "dimorphos_radiance"), [(1.0, 1.0), (0.8, 1.0), (1.25, 1.0),
                                                                      (1.0, 0.8), (1.0, 1.25)])
def test_the_brightest_part_of_a_fan_beyond_the_gate_is_no_dimorphos(plume_brightness: float,
                                                                     dimorphos_radiance: float) -> None:
    """Held-out bench frame 135/189, the plume or Dimorphos dimmer or brighter: a 3 px Dimorphos in its plume, its
    trajectory not yet recognised; the fan, a region larger than Dimorphos can be, was taken by its box within the
    gate, and its brightest part, 50 px from Didymos's centre (the orbit 26 px), reported. No Dimorphos is reported
    beyond the paper's limit of its centre, and none farther from Didymos than the orbit's reach allows."""
    scene, prediction = _bench_scene(135, 189)
    t = run_trial(scaled(scene, plume_brightness, dimorphos_radiance), 189, prediction)
    dim = t.detections.dimorphos
    assert dim is None or t.dimorphos.error_px <= PAPER_LIMIT_PX
    if dim is not None:
        did = t.frame.truth[0]
        reach = prediction.orbit_radius_max_px + 2.0 * (did.radius_512_px + t.frame.truth[1].radius_512_px)
        assert math.dist(dim.centroid_col_row, did.centre_512) <= reach


@pytest.mark.parametrize(("seed", "k"), [(4, 142), (7, 185), (10, 8), (13, 233), (107, 191)])
def test_a_resolved_dimorphos_of_its_size_is_chosen_before_a_larger_region(seed: int, k: int) -> None:
    """Bench frames where a region larger than Dimorphos can be (a fan, or dust with a star) held more light in
    Dimorphos's expected area than Dimorphos's own region beside it, and its brightest part was reported 6.7-13.8 px
    off: Dimorphos is its own region, within 1 px of its centre."""
    t = _bench_trial(seed, k)
    _assert_found(t, 1)
    assert t.dimorphos.error_px is not None and t.dimorphos.error_px <= 1.0


@pytest.mark.parametrize(("seed", "k"), [(59, 112), (43, 54), (1, 213), (2, 5), (31, 262), (53, 6)])
def test_didymos_s_region_that_held_dimorphos_is_reported_without_it(seed: int, k: int) -> None:
    """Dimorphos found by deblending Didymos's own region (the frames above): Didymos is that region without the
    object Dimorphos came from, so the two reports share no pixel (OpenCV's regions cut the same way) and both are
    found; reported whole, Didymos's centroid held Dimorphos and the dust around it (continuity measures from it)."""
    scene, prediction = _bench_scene(seed, k)
    t = run_trial(scene, k, prediction)
    _assert_found(t, 0)
    _assert_found(t, 1)
    ref = reference_for(scene, t.frame.pixels)
    didymos = reference_blob(t.detections, t.detections.didymos, ref)
    dimorphos = reference_blob(t.detections, t.detections.dimorphos, ref)
    assert didymos is not None and dimorphos is not None
    assert not (didymos[0] & dimorphos[0]).any()


@pytest.mark.parametrize(("dimorphos_radiance", "plume_brightness"), [(0.8, 1.0), (0.9, 1.0), (1.1, 1.0),
                                                                      (1.25, 1.0), (1.0, 0.85), (1.0, 1.15)])
def test_a_small_dimorphos_in_didymos_s_plume_is_deblended(dimorphos_radiance: float,
                                                          plume_brightness: float) -> None:
    """Bench seed 59 frame 112, Dimorphos or the plume dimmer or brighter: Dimorphos, 3.1 px, 12 px from a 15 px
    Didymos at 66 deg of phase, inside Didymos's region with the plume (249 px, more than both bodies' areas, too
    small to cut), is found (none was reported)."""
    scene, prediction = _bench_scene(59, 112)
    scene = scaled(scene, plume_brightness, dimorphos_radiance)
    _assert_found(run_trial(scene, 112, prediction), 1)


@pytest.mark.parametrize(("plume_brightness", "dimorphos_radiance"), [(1.0, 1.0), (1.25, 1.0), (0.8, 1.0),
                                                                      (1.0, 0.7), (1.0, 0.85), (1.0, 1.3)])
def test_a_small_dimorphos_at_its_plume_s_root_is_its_object_s_brightest_part(plume_brightness: float,
                                                                            dimorphos_radiance: float) -> None:
    """Bench seed 67 frame 209 (a seed first run after the deblending was written), the plume or Dimorphos dimmer or
    brighter: Dimorphos, 3 px at the root of its plume, 21 px from a 15 px Didymos, in one region with both; deblended,
    Dimorphos parts from Didymos with the plume's root around it, an object larger than Dimorphos can be, and none
    was reported. The object is taken by its brightest pixels of Dimorphos's expected area: Dimorphos is found."""
    scene, prediction = _bench_scene(67, 209)
    scene = scaled(scene, plume_brightness, dimorphos_radiance)
    _assert_found(run_trial(scene, 209, prediction), 1)


@pytest.mark.parametrize(("plume_brightness", "dimorphos_radiance"), [(1.0, 1.0), (1.25, 1.0), (0.8, 1.0),
                                                                      (1.0, 0.85), (1.0, 1.2)])
def test_dimorphos_at_the_horn_of_didymos_s_crescent_parts_from_it_and_leaves_it(plume_brightness: float,
                                                                                dimorphos_radiance: float) -> None:
    """Bench seed 74 frame 184 (a seed first run at the nineteenth session), the plume or Dimorphos dimmer or
    brighter: Dimorphos, 25 px, touches the horn of a 124 px crescent at the root of its plume, and the cut to both
    bodies' area holds both. Deblended, Dimorphos's object (larger than Dimorphos can be, with the horn and the
    plume's root) had its centroid, and its brightest part's, on a disc centred by the Didymos Dimorphos pulled
    over: none was reported and Didymos was 22 px off. Judged against Didymos without that object, Dimorphos is
    found, and Didymos, reported without it, is found within the paper's limit."""
    scene, prediction = _bench_scene(74, 184)
    scene = scaled(scene, plume_brightness, dimorphos_radiance)
    t = run_trial(scene, 184, prediction)
    _assert_found(t, 0)
    _assert_found(t, 1)


@pytest.mark.parametrize(("seed", "k"), [(43, 127), (2, 137), (45, 170), (45, 260)])
def test_an_unresolved_didymos_region_is_not_deblended_into_dimorphos(seed: int, k: int) -> None:
    """A Didymos 1.7-2.7 px across, under the size that must be resolved, its region larger than both bodies'
    expected areas by its blur: its region is not deblended, so no part of its own image is reported as Dimorphos
    (bench frames where deblending it did, Dimorphos sub-pixel beside it). Didymos is itself or not reported: with
    Dimorphos beside it the region may be a blend of point sources, weighed like a star (``_blend_of_point_sources``:
    43/127 and 2/137 so, at 0.64 and 0.15)."""
    t = _bench_trial(seed, k)
    assert t.didymos.truth_index in (0, None)
    assert t.dimorphos.truth_index != 0


@pytest.mark.parametrize(("plume_brightness", "dimorphos_radiance"), [(1.0, 1.0), (1.25, 1.0), (1.5, 1.0),
                                                                      (1.0, 0.7), (1.0, 0.85), (1.0, 1.3)])
def test_a_region_reaching_beyond_didymos_s_disc_is_no_piece_of_its_crescent(plume_brightness: float,
                                                                           dimorphos_radiance: float) -> None:
    """Bench seed 65 frame 236 (a seed first run after the chain was written), the plume or Dimorphos dimmer or
    brighter: Dimorphos, 37 px at 116 deg of phase, and its plume make one region (9,673 px, twice Didymos's) whose
    box comes within a few px of Didymos's crescent's and whose centroid lies within Didymos's largest radius of its
    centre; it was taken for a piece of the crescent broken off at the threshold and Dimorphos was not reported. A
    piece of the crescent lies on Didymos's disc whole, and this region reaches far beyond it: Dimorphos is found."""
    scene, prediction = _bench_scene(65, 236)
    scene = scaled(scene, plume_brightness, dimorphos_radiance)
    _assert_found(run_trial(scene, 236, prediction), 1)


@pytest.mark.parametrize(("seed", "k"), [(3, 226), (47, 33)])
def test_a_piece_of_an_unresolved_didymos_s_image_is_not_dimorphos(seed: int, k: int) -> None:
    """A 1-1.2 px Didymos, its blurred image elongated by the noise, a piece of it broken off at the threshold: the
    piece's box reaches beyond Didymos's largest disc by the blur alone and it stays a piece of Didymos, not reported
    as Dimorphos (bench frames where a box test without the point-spread function's reach reported it)."""
    t = _bench_trial(seed, k)
    assert t.dimorphos.truth_index != 0


def _peaks_image(separation: float, ratio: float, sigma: float, bridge: float) -> np.ndarray:
    """An 8-bit image (64 x 96) of two Gaussian peaks along row 32, the second ``ratio`` times the first's 200 and
    ``separation`` px to its right, over a faint bar between them (``bridge``, 8-bit) that joins them above 10."""
    rows, cols = np.indices((64, 96), dtype=np.float64)
    a, b = 24.0, 24.0 + separation
    img = 200.0 * np.exp(-((cols - a) ** 2 + (rows - 32.0) ** 2) / (2.0 * sigma**2))
    img += 200.0 * ratio * np.exp(-((cols - b) ** 2 + (rows - 32.0) ** 2) / (2.0 * sigma**2))
    img += np.where((abs(rows - 32.0) <= 1.0) & (cols >= a) & (cols <= b), bridge, 0.0)
    return np.clip(np.round(img), 0, 255).astype(np.uint8)


def _regions_of(image8: np.ndarray, thr: int) -> Regions:
    comps = connected_components(image8 > thr)
    return Regions(comps, image8.reshape(-1)[comps.pixel_index], image8.shape[1], thr,
                   linear8=linear_values(CFG, 12))


@settings(max_examples=60, deadline=None)
@given(separation=st.floats(14.0, 40.0), ratio=st.floats(0.3, 1.0), sigma=st.floats(1.5, 3.5),
       bridge=st.floats(12.0, 30.0))
def test_deblending_parts_two_peaks_at_opencvs_components(separation: float, ratio: float, sigma: float,
                                                          bridge: float) -> None:
    """Two Gaussian peaks joined by a faint bar are two objects, each holding its own peak; each object is the OpenCV
    component (8-connected) of the pixels at or above its level that holds it, holds at least the least share of the
    region's light, and no two share a pixel."""
    image8 = _peaks_image(separation, ratio, sigma, bridge)
    thr = 10
    regions = _regions_of(image8, thr)
    (blob,) = regions.blobs()
    objects = regions.deblended(blob, CFG.deblend_levels, CFG.deblend_min_flux_fraction, 2)
    assert len(objects) == 2
    linear = linear_values(CFG, 12)
    total = float((linear[image8[image8 > thr]] - linear[thr]).sum())
    seen = np.zeros(image8.size, dtype=bool)
    # each peak's brightest pixel (the bar may lift a faint peak's pixel beside its centre)
    peaks = [c0 + int(np.argmax(image8[32, c0:c0 + 5])) for c0 in (22, math.floor(24 + separation) - 2)]
    for obj, peak_col in zip(objects, peaks, strict=True):
        flat = regions.components.pixel_index[regions.pixels_of(obj)]
        assert not seen[flat].any()
        seen[flat] = True
        level = obj.threshold_dn8 + 1
        _, labels = cv2.connectedComponents((image8 >= level).astype(np.uint8), connectivity=8)
        component = labels.reshape(-1) == labels.reshape(-1)[flat[0]]
        assert np.array_equal(np.sort(flat), np.flatnonzero(component))
        assert component.reshape(image8.shape)[32, peak_col]
        assert float((linear[image8.reshape(-1)[flat]] - linear[thr]).sum()) >= CFG.deblend_min_flux_fraction * total


@settings(max_examples=30, deadline=None)
@given(sigma=st.floats(1.5, 6.0), peak=st.integers(40, 255))
def test_deblending_leaves_a_single_peak_whole(sigma: float, peak: int) -> None:
    """One Gaussian peak, noise-free, parts at no level: the region alone."""
    rows, cols = np.indices((48, 48), dtype=np.float64)
    image8 = np.round(peak * np.exp(-((cols - 24.0) ** 2 + (rows - 24.0) ** 2) / (2.0 * sigma**2))).astype(np.uint8)
    regions = _regions_of(image8, 10)
    (blob,) = regions.blobs()
    assert regions.deblended(blob, CFG.deblend_levels, CFG.deblend_min_flux_fraction, 2) == [blob]


@pytest.mark.parametrize("seed", range(3))
def test_a_star_in_a_dense_fan_does_not_take_dimorphos_place(seed: int) -> None:
    """A fan from Dimorphos half as bright as its surface with a 3000 DN star in it, three Dimorphos radii out:
    Dimorphos is found on itself, whether its place is known to 9 px or to 90."""
    rng = np.random.default_rng([61, seed])
    scene = random_scene(rng, didymos_diameter_px=150.0, plume=True, phase_deg=40.0, n_hot=0, n_cosmic=0,
                         pointing_error_px=0.0, faint=False)
    scene = _apart(scene, rng)
    dim = scene.bodies[1]
    axis = math.degrees(math.atan2(dim.row - scene.bodies[0].row, dim.col - scene.bodies[0].col))
    plume = replace(scene.plume, axis_deg=axis, half_angle_deg=40.0, length_px=30.0 * dim.mean_radius_px,
                    brightness_dn=0.5 * dim.radiance_dn, exponent=0.6)
    out = 3.0 * dim.mean_radius_px
    star = (dim.col + out * math.cos(math.radians(axis)), dim.row + out * math.sin(math.radians(axis)), 3000.0)
    scene = replace(scene, plume=plume, stars=(star,))
    for sigma in (3.0, 30.0):
        _assert_found(run_trial(scene, seed, prediction_for(scene, rng, sigma)), 1)


@pytest.mark.parametrize("star_radii", [8.0, 10.0])
@pytest.mark.parametrize("seed", range(6))
def test_a_star_in_the_fan_of_a_small_resolved_crescent_is_not_dimorphos(seed: int, star_radii: float) -> None:
    """A resolved crescent Dimorphos (98 deg phase, about 6 binned px across) at the root of a fan of dust half as
    bright as its surface, a 1400 DN star in the fan 8 or 10 of its radii out (beyond twice its largest diameter),
    its place known to 90 px: of the parts of the region cut to Dimorphos's expected area, the star's, brighter by mean
    and a quarter of that area, is not taken for a body that must be resolved (held-out bench frame 99/291 reported
    the star 38 px off)."""
    rng = np.random.default_rng([66, seed])
    scene = random_scene(rng, didymos_diameter_px=60.0, plume=True, phase_deg=98.0, n_hot=0, n_cosmic=0,
                         pointing_error_px=0.0, faint=False)
    scene = _apart(scene, rng)
    did, dim = scene.bodies
    axis = math.degrees(math.atan2(dim.row - did.row, dim.col - did.col))
    plume = replace(scene.plume, axis_deg=axis, half_angle_deg=25.0, length_px=30.0 * dim.mean_radius_px,
                    brightness_dn=0.5 * dim.radiance_dn, exponent=1.2)
    out = star_radii * dim.mean_radius_px
    star = (dim.col + out * math.cos(math.radians(axis)), dim.row + out * math.sin(math.radians(axis)), 1400.0)
    scene = replace(scene, plume=plume, stars=(star,))
    _assert_found(run_trial(scene, seed, prediction_for(scene, rng, 30.0)), 1)


@pytest.mark.parametrize(("seed", "k"), [(17, 213), (45, 187)])
def test_a_compact_piece_of_a_resolved_dimorphos_is_not_taken_for_a_star(seed: int, k: int) -> None:
    """A resolved Dimorphos (5 binned px) cut into two parts 4 px apart, the brighter compact enough to pass for a
    point source: within the body's largest diameter of the other part it is the same body's, and the brighter
    part is reported, within 1.5 px of the centre (bench frames that a rule dropping every point source moved
    3-4 px)."""
    t = _bench_trial(seed, k)
    _assert_found(t, 1)
    assert t.dimorphos.error_px is not None and t.dimorphos.error_px <= 1.5


@pytest.mark.parametrize(("seed", "k"), [(1, 99), (1, 134), (1, 196)])
def test_dimorphos_at_high_phase_passes_the_brightness_gate(seed: int, k: int) -> None:
    """Dimorphos at 87-99 deg phase, another shading law than Didymos's: its best-lit part is as bright as
    Didymos's, though its whole disc's mean is not (bench frames that lost it)."""
    _assert_found(_bench_trial(seed, k), 1)


@pytest.mark.parametrize("seed", range(3))
def test_dimorphos_under_another_shading_law_at_high_phase_is_found(seed: int) -> None:
    """Didymos Lommel-Seeliger (bright to the terminator), Dimorphos Lambert (dark towards it) at 105 deg phase, well
    apart: Dimorphos is found."""
    rng = np.random.default_rng([62, seed])
    scene = random_scene(rng, didymos_diameter_px=float(rng.uniform(80.0, 200.0)), plume=False, phase_deg=105.0,
                         n_hot=0, n_cosmic=0, pointing_error_px=0.0)
    did, dim = _apart(scene, rng).bodies
    scene = replace(scene, bodies=(replace(did, law="lommel-seeliger"), replace(dim, law="lambert")))
    _assert_found(run_trial(scene, seed, prediction_for(scene, rng, 3.0)), 1)


def test_dimorphos_beside_a_crescent_box_but_off_its_disc() -> None:
    """Dimorphos at 97 deg phase near the corner of a crescent Didymos's box (with ejecta), 110 px from its centre:
    not a piece of the crescent (bench frame that lost it)."""
    _assert_found(_bench_trial(1, 158), 1)


@pytest.mark.parametrize(("seed", "k"), [(1, 160), (1, 169), (2, 144), (2, 246)])
def test_a_small_didymos_is_not_a_brighter_star(seed: int, k: int) -> None:
    """Didymos 5-6 px across, faint, its place known to 90 px only, stars brighter than it near: Didymos is the
    extended blob, not a star (bench frames that reported a star)."""
    _assert_found(_bench_trial(seed, k), 0)


def test_a_thin_crescent_cut_from_its_dust_is_not_passed_over_for_a_star() -> None:
    """A 5 px Didymos at 120 deg phase in its plume, a brighter star 17 px off: the region of crescent and dust is
    taken over the star for its shape and cut to its brightest pixels, which are point-like; Didymos is then the
    crescent's part, not the star the region was taken over (held-out bench frame 108/68, which reported the
    star)."""
    _assert_found(_bench_trial(108, 68), 0)


@pytest.mark.parametrize("seed", range(4))
def test_a_bright_star_beside_a_small_faint_didymos(seed: int) -> None:
    """A faint Didymos 10-14 px across at full resolution (5-7 binned), a 3000 DN star 30 px from it, Didymos's
    place known to 90 px: Didymos is found on itself."""
    rng = np.random.default_rng([63, seed])
    scene = random_scene(rng, didymos_diameter_px=float(rng.uniform(10.0, 14.0)), faint=True, plume=False,
                         n_hot=0, n_cosmic=0, pointing_error_px=0.0)
    did = scene.bodies[0]
    a = rng.uniform(0.0, 2.0 * math.pi)
    scene = replace(scene, stars=((did.col + 60.0 * math.cos(a), did.row + 60.0 * math.sin(a), 3000.0),),
                    defects=Defects())
    _assert_found(run_trial(scene, seed, prediction_for(scene, rng, 30.0)), 0)


def test_a_merged_pair_is_reported_as_the_body_it_holds_most_of() -> None:
    """The bench's identity: a blob holding Didymos (4 px) and Dimorphos merged, its centroid nearer Dimorphos's
    centre, is Didymos, the body it holds more pixels of."""
    t = _bench_trial(1, 7)
    blob = t.detections.didymos
    region = reference_blob(t.detections, blob, reference_pipeline(t.frame.pixels))
    assert region is not None
    truth = t.frame.truth
    assert math.dist(blob.region_centroid_col_row, truth[1].centre_512) \
        < math.dist(blob.region_centroid_col_row, truth[0].centre_512)
    assert identity(blob, t.frame, region[0]) == 0


def test_a_cosmic_ray_does_not_swap_the_bodies_of_an_unresolved_pair() -> None:
    """Both bodies in one binned pixel (0.6 and 0.1 px across), a cosmic ray beside them: the blob reported is the
    same, and the bench's identity of it too (the larger body whose centre it holds, not a tie broken by noise)."""
    scene, prediction = _bench_scene(1, 166)
    before = run_trial(scene, 166, prediction)
    after = run_trial(with_defect(scene, np.random.default_rng([1, 166, 7]), "cosmic", 0), 166, prediction)
    assert before.detections.didymos is not None and after.detections.didymos is not None
    assert math.dist(before.detections.didymos.region_centroid_col_row,
                     after.detections.didymos.region_centroid_col_row) < 1.0
    assert before.didymos.truth_index == after.didymos.truth_index == 0


def test_a_transit_is_swallowed_and_a_pair_apart_is_not() -> None:
    """Dimorphos drawn in front of Didymos's lit disc is swallowed (bench frame 40 of seed 1); Dimorphos 110 px away
    is not (frame 99)."""
    assert swallowed(_bench_trial(1, 40).frame, 1)
    t = _bench_trial(1, 99)
    assert not swallowed(t.frame, 1) and not swallowed(t.frame, 0)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_light_spread_is_the_weighted_second_moment_of_opencv(seed: int) -> None:
    """The light spread of each blob of a random 8-bit image equals OpenCV's central moments (mu20 + mu02) / 2 m00
    of the blob's light above the threshold (the codes taken back to raw values)."""
    rng = np.random.default_rng(seed)
    image8 = rng.integers(0, 256, (40, 40)).astype(np.uint8)
    image8[rng.random((40, 40)) < 0.6] = 0
    thr = int(rng.integers(0, 120))
    mask = image8 > thr
    comps = connected_components(mask)
    linear = linear_values(CFG, 12)
    values = image8.reshape(-1)[comps.pixel_index]
    regions = Regions(comps, values, 40, thr, linear8=linear)
    _, labels = cv2.connectedComponents(mask.astype(np.uint8), connectivity=8)
    for blob in regions.blobs():
        # OpenCV's region holding the blob's first pixel (its numbering may differ when it labels in parallel)
        first = int(comps.pixel_index[regions.pixels_of(blob)[0]])
        weight = np.where(labels == labels.reshape(-1)[first], linear[image8] - linear[thr], 0.0).astype(np.float64)
        assert np.count_nonzero(labels == labels.reshape(-1)[first]) == blob.area_px
        m = cv2.moments(weight)
        expected = 0.5 * (m["mu20"] + m["mu02"]) / m["m00"]
        assert light_spread_px2(regions, blob) == pytest.approx(expected, rel=1e-9, abs=1e-9)


@pytest.mark.parametrize(("seed", "k", "index"), [(1, 74, 0), (1, 74, 1), (3, 224, 0)])
def test_ejecta_bridging_the_pair_are_split_off_both(seed: int, k: int, index: int) -> None:
    """A plume merging Dimorphos with Didymos into one blob, Dimorphos's place known closer than the orbit's radius:
    the blob is split, Dimorphos (with dust, trimmed) at its place, and Didymos's centre within 15 px (bench frames
    that lost Dimorphos and put Didymos 20-35 px off)."""
    _assert_found(_bench_trial(seed, k), index)


@pytest.mark.parametrize(("seed", "k"), [(3, 260), (4, 97), (4, 269)])
def test_dimorphos_merged_with_didymos_by_bright_ejecta_is_cut_out_at_its_place(seed: int, k: int) -> None:
    """Ejecta brighter than Dimorphos's surface merge it with Didymos into one region none of whose brightest parts
    is Dimorphos: the part of the region where the trajectory puts it (known well within the orbit) is cut out and
    trimmed, and found on Dimorphos, on the OpenCV region cut the same way (bench frames that lost Dimorphos)."""
    _assert_found(_bench_trial(seed, k), 1)


def _fan_scene(seed: int, dimorphos_angle_deg: float) -> Scene:
    """Didymos 260 px across (full resolution), Dimorphos 60 px beyond its limb at ``dimorphos_angle_deg`` from
    +columns, a wide fan of dust from Dimorphos (200 DN, slowly fading) over a quarter of the frame whose edge at the
    threshold breaks into dozens of noise clumps."""
    rng = np.random.default_rng(seed)
    did_r, dim_r, col, row = 130.0, 27.0, 680.0, 512.0
    a, d = math.radians(dimorphos_angle_deg), did_r + dim_r + 60.0
    q = (0.0, 0.0, 0.0, 1.0)
    stars = tuple((float(rng.uniform(0, 1024)), float(rng.uniform(0, 1024)), float(rng.uniform(200, 2000)))
                  for _ in range(20))
    return Scene(
        bodies=(Ellipsoid(col, row, 56e3, (did_r * 1.05, did_r, did_r * 0.95), q, 2400.0),
                Ellipsoid(col + d * math.cos(a), row + d * math.sin(a), 55e3, (dim_r * 1.1, dim_r, dim_r * 0.9), q,
                          2400.0)),
        range_m=55e3, phase_deg=55.0, sun_azimuth_deg=180.0,
        plume=Plume(axis_deg=-90.0, half_angle_deg=75.0, length_px=900.0, brightness_dn=200.0, exponent=0.3),
        stars=stars)


@pytest.mark.parametrize("seed", range(4))
def test_noise_in_the_dust_is_never_didymos_by_its_offset_from_another_clump(seed: int) -> None:
    """With a previous pair whose relative offset the true pair no longer holds (Dimorphos a quarter of its orbit
    on), Didymos is still found on its disc: continuity does not prefer a clump of noise at the fan's edge holding a
    small fraction of Didymos's light because another clump sits at that offset (a closed-loop run took Didymos as a
    5 px clump near C/A)."""
    rng = np.random.default_rng(100 + seed)
    earlier, scene = _fan_scene(seed, 90.0), _fan_scene(seed, 180.0)
    previous = process_frame(render(earlier, rng).pixels, CFG, None, bad_pixels=ground_map(earlier),
                             prediction=prediction_for(earlier, rng, 30.0))
    assert previous.didymos is not None and previous.dimorphos is not None
    frame = render(scene, rng)
    det = process_frame(frame.pixels, CFG, previous, bad_pixels=ground_map(scene),
                        prediction=prediction_for(scene, rng, 30.0))
    truth = frame.truth[0]
    assert det.didymos is not None
    assert math.dist(det.didymos.region_centroid_col_row, truth.centre_512) <= truth.radius_512_px


@pytest.mark.parametrize(("seed", "k"), [(3, 284), (4, 269)])
def test_didymos_merged_with_a_fainter_fan_is_its_surface(seed: int, k: int) -> None:
    """A fan of dust fainter than Didymos's surface merged with it into a region within Didymos's largest area: the
    centroid is that of its pixels at least halfway to the surface's level, within the paper's 15 px, on the OpenCV
    region cut the same way (bench frames that put Didymos 22 and 80 px off)."""
    _assert_found(_bench_trial(seed, k), 0)


def _dimorphos_in_a_fan(seed: int, dim_r: float, fan_dn: float, length_r: float) -> Scene:
    """Didymos 240 px across (full resolution, 2400 DN surface), Dimorphos of radius ``dim_r`` 60 px beyond its limb
    with a fan of dust from it (``fan_dn`` at Dimorphos, fading over ``length_r`` of its radii) pointing away from
    Didymos, seen at 30 deg phase with the Sun on Didymos's side: no star, no defect."""
    rng = np.random.default_rng([63, seed])
    did_r, col, row = 120.0, 420.0, 512.0
    a = rng.uniform(-0.5, 0.5)
    d = did_r + dim_r + 60.0
    q = (0.0, 0.0, 0.0, 1.0)
    return Scene(
        bodies=(Ellipsoid(col, row, 56e3, (did_r * 1.05, did_r, did_r * 0.95), q, 2400.0),
                Ellipsoid(col + d * math.cos(a), row + d * math.sin(a), 55e3, (dim_r * 1.1, dim_r, dim_r * 0.9), q,
                          2400.0)),
        range_m=55e3, phase_deg=30.0, sun_azimuth_deg=180.0,
        plume=Plume(axis_deg=math.degrees(a), half_angle_deg=35.0, length_px=length_r * dim_r, brightness_dn=fan_dn,
                    exponent=0.8))


@pytest.mark.parametrize("seed", range(3))
def test_a_fan_is_not_dimorphos_before_the_range_is_known(seed: int) -> None:
    """Before the trajectory is recognised the range is known to a factor of 8, and from the prediction alone so is
    Dimorphos's size: a faint fan holding a small Dimorphos fits it. Didymos's measured size bounds Dimorphos's (the
    same range), and Dimorphos is found on itself, within 3 px, its region pulled along the fan by more than 5 px
    (closed-loop campaign run 65: 28 px; the previous chain took the whole region, 28 px off)."""
    scene = _dimorphos_in_a_fan(seed, 8.0, 250.0, 12.0)
    rng = np.random.default_rng(seed)
    p = prediction_for(scene, rng, None)
    early = replace(p, radius_factor_max=8.0, orbit_radius_max_px=8.0 * p.orbit_radius_max_px)
    t = run_trial(scene, seed, early)
    _assert_found(t, 1)
    assert t.dimorphos.error_px <= 3.0
    region = next(b for b in t.detections.blobs if b.label == t.detections.dimorphos.trimmed_from)
    assert math.dist(region.region_centroid_col_row, t.frame.truth[1].centre_512) > 5.0


@pytest.mark.parametrize("seed", range(3))
def test_a_resolved_dimorphos_in_fainter_dust_is_its_surface(seed: int) -> None:
    """A resolved Dimorphos (26 px across, binned) in a fan fainter than half its surface, their region within
    Dimorphos's largest area: the centroid is that of its surface, within 3 px, the whole region's pulled more than
    5 px along the fan (closed-loop campaign run 50: 13 px near C/A; the previous chain took the whole region, 10.6 px
    off)."""
    scene = _dimorphos_in_a_fan(seed, 26.0, 300.0, 2.5)
    rng = np.random.default_rng(seed)
    t = run_trial(scene, seed, prediction_for(scene, rng, 1.0))
    _assert_found(t, 1)
    assert t.dimorphos.error_px <= 3.0
    region = next(b for b in t.detections.blobs if b.label == t.detections.dimorphos.trimmed_from)
    assert math.dist(region.region_centroid_col_row, t.frame.truth[1].centre_512) > 5.0


@pytest.mark.parametrize("seed", range(4))
def test_a_small_dimorphos_in_a_faint_fan_is_its_surface(seed: int) -> None:
    """Dimorphos 17 px across (binned radius 8.5, under twice the point-spread function's reach of its smallest
    predicted radius) in a fan of 400 DN: their region, within Dimorphos's largest area, is larger than the disc of
    its predicted radius widened by that reach, so it holds dust; the centroid is that of its surface, within 3 px,
    the whole region's more than 5 px along the fan (bench seed 15 frame 182: the whole region, 17.9 px off; the
    previous chain here: 9.6-9.9 px)."""
    scene = _dimorphos_in_a_fan(seed, 17.0, 400.0, 3.0)
    rng = np.random.default_rng([70, seed])
    t = run_trial(scene, seed, prediction_for(scene, rng, 3.0))
    _assert_found(t, 1)
    assert t.dimorphos.error_px <= 3.0
    region = next(b for b in t.detections.blobs if b.label == t.detections.dimorphos.trimmed_from)
    assert math.dist(region.region_centroid_col_row, t.frame.truth[1].centre_512) > 5.0


def test_bench_frame_with_a_small_dimorphos_in_its_plume() -> None:
    """Bench seed 15 frame 182 (a seed no change was tuned on): a 17 px Dimorphos at 30 deg of phase in its plume is
    reported within 3 px of its centre, not at its region's centroid along the fan."""
    t = _bench_trial(15, 182)
    _assert_found(t, 1)
    assert t.dimorphos.error_px <= 3.0


def _pair_in_a_bright_fan(seed: int, merged: bool) -> tuple[np.ndarray, tuple[float, float], tuple[float, float]]:
    """A binned 8-bit 512 x 512 image drawn by hand: Didymos a disc of radius 4 at level 150 +- 6, Dimorphos an
    unresolved point 10.5 px from it at the apex of a fan of dust pointing away from Didymos. Apart, the fan is
    fainter than Didymos but near the apex (half-angle 40 deg, 14 px long, 175 fading to 100); ``merged``, a frame
    later, it is brighter than Didymos over most of it (half-angle 30 deg, 10 px long, 185 fading to 140) and a band of
    dust reaches Didymos's limb. Background 20 +- 3. Returns (image, Didymos's centre, Dimorphos's centre)."""
    rng = np.random.default_rng([65, seed])
    img = np.clip(rng.normal(20.0, 3.0, (512, 512)), 0, 255)
    a = rng.uniform(0.0, 2.0 * math.pi)
    did = (266.0 + rng.uniform(-0.5, 0.5), 257.0 + rng.uniform(-0.5, 0.5))
    dim = (did[0] - 10.5 * math.cos(a), did[1] - 10.5 * math.sin(a))
    rows, cols = np.mgrid[0:512, 0:512]
    disc = np.hypot(cols - did[0], rows - did[1]) <= 4.0
    img[disc] = rng.normal(150.0, 6.0, int(disc.sum()))
    r = np.hypot(cols - dim[0], rows - dim[1])
    away = np.arctan2(rows - dim[1], cols - dim[0]) - math.atan2(dim[1] - did[1], dim[0] - did[0])
    off = np.abs((away + math.pi) % (2.0 * math.pi) - math.pi)
    fan = (r <= (10.0 if merged else 14.0)) & (off <= math.radians(30.0 if merged else 40.0))
    img[fan] = np.maximum(img[fan], (185.0 - 45.0 * r[fan] / 10.0) if merged else (175.0 - 75.0 * r[fan] / 14.0))
    if merged:  # a band of dust from the apex to Didymos's limb
        t = np.clip(((cols - dim[0]) * (did[0] - dim[0]) + (rows - dim[1]) * (did[1] - dim[1])) / 10.5 ** 2, 0.0, 1.0)
        near = np.hypot(cols - (dim[0] + t * (did[0] - dim[0])), rows - (dim[1] + t * (did[1] - dim[1]))) <= 1.5
        img[near & ~disc] = np.maximum(img[near & ~disc], 90.0)
    return img.astype(np.uint8), did, dim


def _identify_drawn(img: np.ndarray, previous: object | None, did_r: float) -> tuple:  # noqa: ANN001
    """identify_bodies on a drawn 8-bit image (threshold 35) with the early prediction: radii from a range known to a
    factor of 1.9, Dimorphos's place unknown."""
    thr = 35
    comps = connected_components(img > thr)
    regions = Regions(comps, img.reshape(-1)[comps.pixel_index], 512, thr, linear8=linear_values(CFG, 12))
    prediction = FramePrediction(sun_camera=(0.0, 0.0, -1.0), didymos_radius_px=did_r,
                                 dimorphos_radius_px=did_r * 164.0 / 780.0, radius_factor_max=1.9,
                                 orbit_radius_max_px=1.9 * 1190.0 / 390.0 * did_r)
    return identify_bodies(regions.blobs(min_area_px=CFG.min_body_area_px), CFG, previous, prediction, regions)


@pytest.mark.parametrize("seed", range(4))
def test_continuity_keeps_didymos_split_from_dust_brighter_than_its_surface(seed: int) -> None:
    """Didymos and a fan of dust from Dimorphos brighter than its surface, seen apart and then merged into one region:
    the split's brightest pixels fall mostly in the dust, Didymos keeps a part nearly as bright as the best but with
    little of its light, and continuity with the pair seen apart still finds Didymos on its disc, not the dust, and
    Dimorphos at the fan's apex (closed-loop campaign runs 4, 29, 54 and 76 swapped them, and run 4 lost the
    target)."""
    apart, did, dim = _pair_in_a_bright_fan(seed, False)
    d0, m0 = _identify_drawn(apart, None, 3.8)
    assert d0 is not None and m0 is not None
    assert math.dist(d0.region_centroid_col_row, did) <= 1.5 and math.dist(m0.region_centroid_col_row, dim) <= 4.0
    previous = Detections((d0, m0), d0, m0, None, None, None, None, 35, 20, 3.0, 512, pair=(d0, m0))
    merged, did, dim = _pair_in_a_bright_fan(seed, True)
    d1, m1 = _identify_drawn(merged, previous, 3.8)
    assert d1 is not None and m1 is not None
    assert math.dist(d1.region_centroid_col_row, did) <= 4.0 and math.dist(m1.region_centroid_col_row, dim) <= 4.0



@settings(max_examples=60, deadline=None)
@given(st.floats(2.0, 80.0), st.floats(1.0, 4.0), st.integers(1, 400))
def test_continuity_gate_is_never_wider_than_didymos_can_be(did_r: float, k: float, width: int) -> None:
    """Continuity's gate on the pair's offset is a fraction of the candidate Didymos's diameter, and with a
    prediction never of more than Didymos's largest diameter: a fan of dust 400 px across taken for Didymos would
    otherwise accept any piece within 200 px as Dimorphos continuing the pair (closed-loop campaign run 88: 15.8 px,
    Dimorphos reported on Didymos's limb)."""
    exp = expected(FramePrediction(sun_camera=(0.0, 0.0, -1.0), didymos_radius_px=did_r,
                                   dimorphos_radius_px=did_r * 164.0 / 780.0, radius_factor_max=k,
                                   orbit_radius_max_px=k * 1190.0 / 390.0 * did_r), CFG)
    assert exp is not None
    blob = Blob(label=1, area_px=width * width // 2, centroid_col_row=(256.0, 256.0),
                bbox_col_row_w_h=(256 - width // 2, 256 - width // 2, width, width), mean_dn8=100.0, peak_dn8=150,
                elongation=1.0, threshold_dn8=35, region_centroid_col_row=(256.0, 256.0))
    largest = CFG.dimorphos_max_relative_jump_didymos_diameters * 2.0 * exp.didymos_radius_max + CFG.centroid_noise_px
    assert _relative_jump_px(blob, CFG, exp) <= largest + 1e-9
    assert _relative_jump_px(blob, CFG, exp) == pytest.approx(min(_relative_jump_px(blob, CFG), largest))


def _didymos_off_the_edge(rng: np.random.Generator) -> Scene:
    """Near C/A, Didymos's centre beyond an edge of the image (a sliver of its limb inside), Dimorphos resolved in
    the image with a fan of dust from it, as bright as its surface at the source: its region holds more pixels
    than Dimorphos can, and more light than Didymos's sliver."""
    focal = 1024.0 / (2.0 * math.tan(math.radians(1.45)))
    range_m = float(rng.uniform(55e3, 70e3))
    px_per_m = focal / range_m
    did_r, dim_r = 390.0 * px_per_m, 82.0 * px_per_m
    edge = int(rng.integers(4))
    along = float(rng.uniform(300.0, 724.0))
    beyond = float(rng.uniform(0.75, 0.95)) * did_r  # Didymos's centre this far outside the edge
    did = {0: (along, -beyond), 1: (1023.0 + beyond, along), 2: (along, 1023.0 + beyond), 3: (-beyond, along)}[edge]
    inward = {0: (0.0, 1.0), 1: (-1.0, 0.0), 2: (0.0, -1.0), 3: (1.0, 0.0)}[edge]
    gap = float(rng.uniform(250.0, 420.0))  # centre to centre, px, within the orbit's 1.19 km
    dim = (did[0] + gap * inward[0] + rng.uniform(-60, 60) * inward[1],
           did[1] + gap * inward[1] + rng.uniform(-60, 60) * inward[0])
    radiance = float(rng.uniform(1500.0, 3000.0))
    bodies = (
        Ellipsoid(did[0], did[1], range_m + 1000.0, (did_r, did_r * 0.95, did_r * 0.9), (0.0, 0.0, 0.0, 1.0),
                  radiance, "lunar-lambert", 0.5),
        Ellipsoid(dim[0], dim[1], range_m, (dim_r * 1.1, dim_r, dim_r * 0.95), (0.0, 0.0, 0.0, 1.0),
                  radiance * rng.uniform(0.9, 1.1), "lunar-lambert", 0.5),
    )
    away = math.degrees(math.atan2(-inward[1], -inward[0])) + 180.0  # the fan points into the image
    fan = Plume(axis_deg=float(away + rng.uniform(-40, 40)), half_angle_deg=float(rng.uniform(15.0, 30.0)),
                length_px=dim_r * 12.0, brightness_dn=radiance * rng.uniform(0.3, 0.5), exponent=1.0)
    return Scene(bodies=bodies, range_m=range_m, phase_deg=float(rng.uniform(20.0, 50.0)),
                 sun_azimuth_deg=float(rng.uniform(0.0, 360.0)), plume=fan)


def test_dimorphos_with_its_dust_is_not_taken_for_didymos_off_the_edge() -> None:
    """When Didymos is mostly off the image and the trajectory's place allows it, a region whose lit surface is of
    Dimorphos's size (with a fan of dust around it larger than Dimorphos can be) is Dimorphos, reported within 4
    binned px of its centre, and never Didymos (the independent generator, against its truth)."""
    checked = 0
    for seed in range(12):
        rng = np.random.default_rng([2028, seed])
        scene = _didymos_off_the_edge(rng)
        prediction = prediction_for(scene, rng, place_sigma_px=30.0)
        frame = render(scene, np.random.default_rng(seed))
        det = process_frame(frame.pixels, CFG, bad_pixels=ground_map(scene), prediction=prediction)
        truth = frame.truth[1]
        c, r = truth.centre_512
        holding = [b.area_px for b in det.blobs if not b.trimmed_from and b.bbox_col_row_w_h[0] <= c
                   < b.bbox_col_row_w_h[0] + b.bbox_col_row_w_h[2] and b.bbox_col_row_w_h[1] <= r
                   < b.bbox_col_row_w_h[1] + b.bbox_col_row_w_h[3]]
        exp = expected(prediction, CFG)
        assert exp is not None
        if not holding or max(holding) <= exp.dimorphos_area_max:
            continue  # the dust fell below the threshold: not this case
        checked += 1
        assert det.dimorphos is not None, f"seed {seed}: Dimorphos not reported"
        assert math.dist(det.dimorphos.centroid_col_row, truth.centre_512) <= 4.0, (seed, det.dimorphos)
        assert det.didymos is None or math.dist(det.didymos.region_centroid_col_row, truth.centre_512) > 2 * \
            prediction.dimorphos_radius_px, (seed, det.didymos)
    assert checked >= 6


@pytest.mark.parametrize(("seed", "k"), [(1, 158), (2, 231), (4, 97), (4, 236), (5, 103)])
def test_didymos_merged_with_a_fan_across_it_is_cut_to_its_surface(seed: int, k: int) -> None:
    """A fan of dust merged with Didymos into a region that is mostly its surface: the cut to the pixels of at least
    half the surface's signal is kept, as it moves the centroid across the Sun's direction, and Didymos is reported
    within the paper's 15 px, on the OpenCV region cut the same way (bench frames that put it 18-26 px off)."""
    _assert_found(_bench_trial(seed, k), 0)


def test_a_resolved_didymos_with_a_plume_is_reported_within_the_paper_limit() -> None:
    """On 40 frames of a resolved Didymos (80-360 px across) with a plume, the camera on Dimorphos (the independent
    generator, a stream apart from the bench's), Didymos is reported as itself within the paper's 15 px of its true
    centre wherever the frame's edge does not cut it (the stream's frame 33: 15.5 px without the dust cut)."""
    for seed in range(40):
        rng = np.random.default_rng([2037, seed])
        scene = random_scene(rng, didymos_diameter_px=float(rng.uniform(80.0, 360.0)), plume=True,
                             pointing_error_px=0.0)
        t = run_trial(scene, seed, prediction_for(scene, rng, 30.0))
        assert t.didymos.truth_index == 0, seed
        if t.frame.truth[0].touches_edge:
            continue
        assert t.didymos.error_px is not None and t.didymos.error_px <= PAPER_LIMIT_PX, (seed, t.didymos)


def test_without_dust_a_resolved_didymos_is_never_cut_to_its_bright_part() -> None:
    """Without a plume, cutting a lit body's faint pixels moves its centroid toward the Sun only, so the dust cut is
    never kept: on 16 clean frames of resolved bodies (the independent generator, any shading law, 20-120 deg of
    phase) both reports equal those with the cut switched off."""
    off = CFG.model_copy(update={"dust_shift_tolerance_radii": 1e9})
    for seed in range(16):
        rng = np.random.default_rng([2036, seed])
        scene = random_scene(rng, didymos_diameter_px=float(rng.uniform(60.0, 400.0)), plume=False)
        prediction = prediction_for(scene, rng, 30.0)
        frame = render(scene, np.random.default_rng(seed))
        on_det = process_frame(frame.pixels, CFG, bad_pixels=ground_map(scene), prediction=prediction)
        off_det = process_frame(frame.pixels, off, bad_pixels=ground_map(scene), prediction=prediction)
        assert (on_det.didymos, on_det.dimorphos) == (off_det.didymos, off_det.dimorphos), seed


def test_a_split_hands_on_a_label_past_every_part_it_cut() -> None:
    """Cutting a region into parts, the split hands on a label past every part it labelled, those too small to be a
    body too, so a later cut never takes a kept part's label (and with it the part's pixels): a region whose brightest
    pixels are a lone pixel first in raster order, then two 6x6 blocks, joined by faint pixels."""
    image8 = np.zeros((40, 40), dtype=np.uint8)
    image8[2, 2:34] = 20  # the faint frame joining everything
    image8[2:17, 2] = 20
    image8[16, 2:34] = 20
    image8[2:17, 33] = 20
    image8[10:16, 5:11] = 150
    image8[10:16, 25:31] = 150
    image8[10:16, 3:5] = 20
    image8[10:16, 11:25] = 20
    image8[10:16, 31:33] = 20
    image8[2, 2] = 200
    comps = connected_components(image8 > 10)
    assert comps.area_px.size == 1
    regions = Regions(comps, image8.reshape(-1)[comps.pixel_index], 40, 10, linear8=linear_values(CFG, 12))
    (blob,) = regions.blobs()
    exp = Expected(didymos_area=60.0, dimorphos_area=13.0, didymos_area_max=80.0, dimorphos_area_max=20.0,
                   didymos_radius_max=6.0, dimorphos_radius_max=3.0, orbit_radius_max=30.0)
    _, _, _, next_label = _split(regions, blob, [blob], [blob], exp, None, None, CFG, 2, False, None)
    assert sorted(regions.part_pixels) == [2, 3, 4]
    assert next_label > max(regions.part_pixels)


def _crescent_touching_a_core() -> tuple[Regions, Blob, tuple[float, float]]:
    """An 8-bit image of one region: a crescent (values 90, the lit half of a ring about (20, 20), radii 4.5 to 6.5,
    on the +column side) whose upper horn touches a plume's core (values 85, 8 x 5 px above the body), in a faint
    fan (20); the region, its blob and the crescent's centroid."""
    rows, cols = np.mgrid[0:40, 0:40]
    d = np.hypot(cols - 20.0, rows - 20.0)
    crescent = (d >= 4.5) & (d <= 6.5) & (cols >= 20)
    image8 = np.zeros((40, 40), dtype=np.uint8)
    image8[2:30, 8:34] = 20
    image8[9:14, 16:24] = 85
    image8[crescent] = 90
    comps = connected_components(image8 > 10)
    assert comps.area_px.size == 1
    regions = Regions(comps, image8.reshape(-1)[comps.pixel_index], 40, 10, linear8=linear_values(CFG, 12))
    (blob,) = regions.blobs()
    return regions, blob, (float(cols[crescent].mean()), float(rows[crescent].mean()))


def test_a_higher_level_parts_a_crescent_from_a_core_as_bright_touching_it() -> None:
    """At high phase (beyond the limb fit's), where a plume's core as bright as the crescent touches it, the brightest
    pixels of the expected area make one part off the lit part's expected centroid: the part cut at a higher level,
    there, is the body (its centroid the crescent's); without the place, the part of the expected area."""
    regions, blob, lit = _crescent_touching_a_core()
    n = int(np.count_nonzero(regions.values8 == 90)) + 20  # the crescent and half the core
    whole = trimmed(regions, blob, n, 2)
    assert math.dist(whole.region_centroid_col_row, lit) > 3.0  # the core pulls it off
    place = _Place((20.0, 20.0), 15.0, 1.0, lit, 2.0, phase_deg=120.0)
    body = trimmed(regions, blob, n, regions.free_label(2), place, CFG)
    assert body.area_px == int(np.count_nonzero(regions.values8 == 90))
    assert math.dist(body.region_centroid_col_row, lit) < 1e-9
    # where the limb is fitted the circle judges the cut: no higher level
    low = _Place((20.0, 20.0), 15.0, 1.0, lit, 2.0, phase_deg=60.0)
    assert trimmed(regions, blob, n, regions.free_label(2), low, CFG).area_px == whole.area_px


@pytest.mark.parametrize("seed", range(6))
def test_an_unresolved_didymos_at_its_place_is_not_a_brighter_star_beyond_it(seed: int) -> None:
    """Didymos 2-4 px across at full resolution (a point source binned), Dimorphos's place known to 3 px (one
    sigma), a 3000 DN star within the search's reach but 4 sigma beyond the orbit's radius: Didymos is reported, not
    the brighter star (the place makes the star unlikely, whatever its light)."""
    rng = np.random.default_rng([64, seed])
    scene = random_scene(rng, didymos_diameter_px=float(rng.uniform(2.0, 4.0)), faint=True, plume=False, n_hot=0,
                         n_cosmic=0, pointing_error_px=0.0)
    prediction = prediction_for(scene, rng, 3.0)
    dim = scene.bodies[1]
    place = ((dim.col - 0.5) / 2.0, (dim.row - 0.5) / 2.0)  # full resolution to binned px
    prediction = replace(prediction, dimorphos_col_row=place, dimorphos_uncertainty_px=9.0)
    assert prediction.orbit_radius_max_px is not None
    a = rng.uniform(0.0, 2.0 * math.pi)
    d = prediction.orbit_radius_max_px + 4.0 * 3.0  # binned px from Dimorphos
    scene = replace(scene, stars=((dim.col + 2.0 * d * math.cos(a), dim.row + 2.0 * d * math.sin(a), 3000.0),),
                    defects=Defects())
    t = run_trial(scene, seed, prediction)
    assert t.didymos.truth_index == 0
    assert t.didymos.error_px is not None and t.didymos.error_px <= PAPER_LIMIT_PX


@pytest.mark.parametrize(("seed", "k"), [(1, 69), (1, 146), (1, 206), (1, 270), (1, 299)])
def test_an_unresolved_didymos_is_the_likeliest_candidate_not_the_brightest_star(seed: int, k: int) -> None:
    """Didymos 1.1-2.8 px across, stars as bright or brighter within the search's reach: Didymos is identified, on
    its light weighed by how far it is from the place and, when it may be resolved, first among extended blobs
    (bench frames that reported a star); it is reported unless a star was nearly as likely."""
    _assert_found(_bench_trial(seed, k, REPORT_ALL), 0)
    t = _bench_trial(seed, k)
    if t.detections.didymos is None:
        assert t.detections.didymos_probability < CFG.didymos_min_report_probability
    else:
        _assert_found(t, 0)


def test_an_unresolved_dimorphos_in_the_glow_is_not_a_star_as_bright_farther_from_its_place() -> None:
    """Dimorphos 3.8 px across in the plume's glow, its place known to 90 px, a star as bright in Dimorphos's
    expected area 88 px from the place (Dimorphos's region 34 px): Dimorphos is reported (bench seed 4, frame 294)."""
    _assert_found(_bench_trial(4, 294), 1)


def test_a_place_known_exactly_ranks_candidates_without_dividing_by_zero() -> None:
    """Dimorphos's place with no uncertainty and no centroid jitter allowed (both zero, as a config may say): a blob
    within the reach of the place scores its light, one beyond it can never be chosen (no division by the zero
    sigma)."""
    place = _Place((100.0, 100.0), 5.0, 0.0, (100.0, 100.0), 0.0)
    near = Blob(1, 4, (101.0, 100.0), (100, 99, 2, 2), 80.0, 90, 1.0, 50, region_centroid_col_row=(101.0, 100.0))
    far = near._replace(label=2, region_centroid_col_row=(120.0, 100.0))
    assert _point_likelihood(near, 30.0, place, 2.0) == math.log(30.0)
    assert _point_likelihood(far, 3000.0, place, 2.0) == -math.inf


# point sources about a place: (distance px, direction rad, light 8-bit DN) each
SPOTS = st.lists(st.tuples(st.floats(0.0, 120.0), st.floats(0.0, 2.0 * math.pi), st.floats(1.0, 250.0)),
                 min_size=1, max_size=8)


def _point_sources_about(spots: list[tuple[float, float, float]], sigma: float
                         ) -> tuple[_Place, list[Blob], list[float], Regions]:
    """A place at (256, 256) known to ``sigma``, a two-pixel blob at each spot, their lights, and empty regions."""
    place = _Place((256.0, 256.0), 50.0, sigma, (256.0, 256.0), 3.0 * sigma)
    blobs = [Blob(i + 1, 2, (256.0 + d * math.cos(a), 256.0 + d * math.sin(a)), (0, 0, 1, 2), 80.0, 90, 1.0, 50,
                  region_centroid_col_row=(256.0 + d * math.cos(a), 256.0 + d * math.sin(a)))
             for i, (d, a, _) in enumerate(spots)]
    lights = [light for _, _, light in spots]
    regions = Regions(connected_components(np.zeros((4, 4), dtype=bool)), np.zeros(0, np.uint8), 4, 35)
    return place, blobs, lights, regions


@settings(max_examples=80, deadline=None)
@given(SPOTS,
       st.floats(0.5, 40.0), st.floats(0.0, 30.0))
def test_the_likeliest_point_source_comes_with_its_share_of_the_likelihood(
        spots: list[tuple[float, float, float]], sigma: float, reach: float) -> None:
    """Among point sources, the blob chosen is the one of most light times the Gaussian of its distance beyond the
    reach, and its probability is that product over the sum of all of theirs (computed here without logarithms)."""
    place, blobs, lights, regions = _point_sources_about(spots, sigma)
    chosen, probability = _likeliest(blobs, lights, place, reach, False, regions, CFG)
    weights = np.array([light * math.exp(-0.5 * (max(0.0, math.dist(b.region_centroid_col_row, place.col_row) - reach)
                                                 / sigma) ** 2) for b, light in zip(blobs, lights, strict=True)])
    if weights.max() <= 1e-300:  # every candidate hundreds of sigmas off: the logarithms still rank them
        return
    assert weights[blobs.index(chosen)] >= weights.max() * (1.0 - 1e-9)
    assert probability == pytest.approx(weights.max() / weights.sum(), rel=1e-9)


@settings(max_examples=80, deadline=None)
@given(SPOTS,
       st.floats(0.5, 40.0), st.floats(0.0, 30.0), st.integers(1, 60), st.floats(0.5, 30.0), st.floats(0.05, 1.0))
def test_a_point_source_is_weighed_against_the_frame_s_stars_and_the_body_being_none_of_them(
        spots: list[tuple[float, float, float]], sigma: float, reach: float, n_stars: int, faintest: float,
        prior: float) -> None:
    """Given the frame's stars (a density and the faintest's light), a point source's probability of being the body
    is its odds against being a star (the density of the body's position, the place's Gaussian beyond the reach
    normalised over the plane, over the stars' density, times its light over the faintest's and the log of the
    light's range) over the sum of all of theirs and of the odds that the body is none of them, (1 - prior) / prior
    (computed here without logarithms); the choice is unchanged."""
    place, blobs, lights, regions = _point_sources_about(spots, sigma)
    stars = _StarField(n_stars / 512.0 ** 2, faintest, 220.0)
    cfg = CFG.model_copy(update={"unresolved_body_detected_prior": prior})
    chosen, probability = _likeliest(blobs, lights, place, reach, False, regions, cfg, stars)
    assert chosen is _likeliest(blobs, lights, place, reach, False, regions, CFG)[0]
    # the place term's integral over the plane, by quadrature: the density of the body's position is the term over it
    spread = quad(lambda r: 2.0 * math.pi * r * math.exp(-0.5 * (max(0.0, r - reach) / sigma) ** 2), 0.0, reach)[0] \
        + quad(lambda r: 2.0 * math.pi * r * math.exp(-0.5 * ((r - reach) / sigma) ** 2), reach, math.inf)[0]
    gaussian = [math.exp(-0.5 * (max(0.0, math.dist(b.region_centroid_col_row, place.col_row) - reach) / sigma) ** 2)
                / spread for b in blobs]
    odds = [g / stars.density_px2 * light / (faintest * math.log(max(220.0 / faintest, math.e)))
            for g, light in zip(gaussian, lights, strict=True)]
    if max(odds) <= 1e-250:  # every candidate hundreds of sigmas off: the logarithms still weigh them
        return
    expected_probability = odds[blobs.index(chosen)] / (sum(odds) + (1.0 - prior) / prior)
    assert probability == pytest.approx(expected_probability, rel=1e-9, abs=1e-300)


def test_the_probability_of_a_point_like_didymos_is_borne_out_by_how_often_it_is_right() -> None:
    """Generated frames of an unresolved Didymos (0.6-2 px across, no plume, 0-30 stars), its place known to 90 px:
    the probabilities given to the point sources taken for Didymos add up to how many of them are within 15 px of
    Didymos's centre, within three of their standard deviations (before: 68 against 34 on 100 frames)."""
    probabilities, right = [], []
    for k in range(60):
        rng = np.random.default_rng([71, k])
        scene = random_scene(rng, didymos_diameter_px=float(rng.uniform(0.6, 2.0)), plume=False)
        t = run_trial(scene, k, prediction_for(scene, rng, 30.0), REPORT_ALL)
        if t.detections.didymos is None:
            continue
        did = scene.bodies[0]
        probabilities.append(t.detections.didymos_probability)
        right.append(math.dist(t.detections.didymos.centroid_col_row, ((did.col - 0.5) / 2, (did.row - 0.5) / 2))
                     <= PAPER_LIMIT_PX)
    p, ok = np.array(probabilities), np.array(right)
    assert len(p) >= 30
    assert abs(p.sum() - ok.sum()) <= 3.0 * math.sqrt(float((p * (1.0 - p)).sum())) + 1.0, (p.sum(), ok.sum(), len(p))


@pytest.mark.parametrize(("seed", "k"), [(31, 5), (31, 38), (32, 161), (33, 222), (33, 295), (34, 226)])
def test_a_star_near_the_place_of_a_point_like_didymos_among_many_stars_is_not_reported(seed: int, k: int) -> None:
    """Didymos 0.6-1.5 px across in a sub-pixel pair, its place known to 90 px, several stars in the frame and one
    within the place's reach likelier than Didymos: no Didymos is reported (bench frames of unseen seeds that
    reported that star, 56-65 px off, with a probability of 0.93-0.97 against the other point sources alone)."""
    t = _bench_trial(seed, k)
    assert t.detections.didymos is None or t.didymos.error_px is not None and t.didymos.error_px <= PAPER_LIMIT_PX, \
        t.didymos
    assert _bench_trial(seed, k, REPORT_ALL).didymos.truth_index != 0


@settings(max_examples=40, deadline=None)
@given(st.floats(0.5, 40.0), st.floats(0.0, 150.0), st.floats(1.0, 120.0))
def test_the_share_of_the_place_s_gaussian_within_a_disc_is_its_integral_there(
        sigma: float, offset: float, radius: float) -> None:
    """The share of a 2-D Gaussian of sigma s within a disc of radius R whose centre is d from its mean is the
    Gaussian's integral over the disc: over each circle of radius r about the disc's centre, in closed form, the
    Rice density r / s^2 exp(-(r^2 + d^2) / (2 s^2)) I0(r d / s^2); over r, by quadrature."""
    place = _Place((256.0, 256.0), 1e9, sigma, (256.0, 256.0), 3.0 * sigma)
    share = _gaussian_share_in_disc(place, (256.0 + offset, 256.0), radius)

    def ring(r: float) -> float:  # i0e(x) = exp(-x) I0(x): the exponentials combined, no overflow
        return r / sigma ** 2 * math.exp(-0.5 * (r - offset) ** 2 / sigma ** 2) * float(i0e(r * offset / sigma ** 2))

    near, far = max(0.0, offset - 8.0 * sigma), min(radius, offset + 8.0 * sigma)  # where the Gaussian is not nil
    expected = quad(ring, near, far, limit=200)[0] if near < far else 0.0
    assert share == pytest.approx(expected, abs=1e-6, rel=1e-5)


@pytest.mark.parametrize(("seed", "k"), [(32, 62), (32, 64), (33, 229)])
def test_a_star_near_the_place_of_a_point_like_dimorphos_is_not_reported_when_dimorphos_is_as_likely(
        seed: int, k: int) -> None:
    """Dimorphos 0.2-2.4 px across, its place known to 90 px, a star in the orbit's reach of Didymos likelier by
    light and place, or beside a star taken for a point-like Didymos: no star is reported as Dimorphos (bench frames
    of unseen seeds that reported one 40-125 px off, without a probability for Dimorphos)."""
    t = _bench_trial(seed, k)
    assert t.detections.dimorphos is None or t.dimorphos.truth_index == 1, t.dimorphos


def _small_pair(seed: int, phase_deg: tuple[float, float]) -> tuple[np.random.Generator, Scene]:
    """A Didymos 5-9 px across (binned) and its Dimorphos, no plume, stars or defects: the pair of a point-like
    Dimorphos."""
    rng = np.random.default_rng([120, seed])
    scene = random_scene(rng, didymos_diameter_px=float(rng.uniform(10.0, 18.0)), phase_deg=float(rng.uniform(
        *phase_deg)), plume=False, n_hot=0, n_cosmic=0, pointing_error_px=0.0, faint=False)
    return rng, replace(scene, stars=(), defects=Defects())


@pytest.mark.parametrize("seed", range(8))
def test_a_star_beyond_the_orbit_s_reach_of_didymos_s_centre_is_not_a_point_like_dimorphos(seed: int) -> None:
    """Dimorphos hidden behind a 5-9 px Didymos, its place known to 90 px, and a star beside Didymos, beyond the
    orbit's largest apparent radius of Didymos's centre (widened by that centre's error, Dimorphos's largest radius
    and the centroid noise) but within the gate about Didymos's region centroid, across the Sun's direction: no
    Dimorphos is reported (held-out 120/224: such a star, 15.3 px from a 1.5 px Dimorphos merged with Didymos, was
    reported with a probability of 0.98)."""
    rng, scene = _small_pair(seed, (20.0, 60.0))
    did, dim = scene.bodies
    dim = replace(dim, col=did.col, row=did.row, depth_m=did.depth_m + 1e3)  # behind Didymos
    scene = replace(scene, bodies=(did, dim))
    pred = prediction_for(scene, rng, 30.0)
    exp = expected(pred, CFG)
    assert exp is not None
    bound = exp.orbit_radius_max + (exp.radius_factor_max - 1.0) * exp.didymos_radius + exp.dimorphos_radius_max \
        + CFG.centroid_noise_px
    gate = exp.orbit_radius_max + exp.didymos_radius_max + exp.dimorphos_radius_max + CFG.centroid_noise_px
    sc, sr = exp.lit_shift_per_radius
    across = math.atan2(sc, -sr) + math.pi * rng.integers(0, 2)  # perpendicular to the Sun's direction in the image
    d = 2.0 * (bound + rng.uniform(0.3, 0.7) * (gate - bound))  # full-resolution px
    star = (did.col + d * math.cos(across), did.row + d * math.sin(across), 3000.0)
    t = run_trial(replace(scene, stars=(star,)), seed, pred)
    assert identity(t.detections.dimorphos, t.frame) != -1  # not the star
    assert t.detections.dimorphos is None or t.dimorphos.truth_index == 1


@pytest.mark.parametrize(("seed", "k"), [(2, 144), (3, 112), (16, 170), (18, 183), (99, 112), (105, 141),
                                       (120, 224)])
def test_a_star_beyond_the_orbit_s_reach_of_didymos_s_centre_in_a_bench_frame_is_not_reported(seed: int,
                                                                                              k: int) -> None:
    """Bench frames (held-out seeds 99, 105 and 120 among them) where a star 15-25 px from a Dimorphos of 0.8-1.5 px,
    beyond the orbit's reach of Didymos's centre, was reported as Dimorphos with a probability of 0.96-0.99: no
    Dimorphos is reported there now, or one within the paper's limit."""
    t = _bench_trial(seed, k)
    assert t.detections.dimorphos is None or t.dimorphos.error_px <= PAPER_LIMIT_PX


def test_a_star_beyond_the_orbit_s_reach_is_no_dimorphos_at_any_report_threshold() -> None:
    """Bench frame 4/190: a star beyond the orbit's reach of Didymos's centre, taken for a 1 px Dimorphos with a
    probability of 0.90, is not even a candidate: no Dimorphos is reported at a threshold of 0.9."""
    assert _bench_trial(4, 190, AT_90_PERCENT).detections.dimorphos is None


@pytest.mark.parametrize("seed", range(8))
def test_a_point_like_dimorphos_at_the_orbit_s_largest_apparent_radius_is_found(seed: int) -> None:
    """A 1-2 px Dimorphos on an orbit seen broadside, as far from a 5-9 px Didymos as its orbit allows, phase 20-110
    deg, its place known to 9 or 90 px: it is found, within the paper's limit (the orbit's reach of Didymos's centre
    keeps the Dimorphos it bounds)."""
    rng, scene = _small_pair(seed, (20.0, 110.0))
    did, dim = scene.bodies
    a = rng.uniform(0.0, 2.0 * math.pi)
    sep = 1.02 * ORBIT_RADIUS_M * FOCAL_1024_PX / scene.range_m  # the generator's largest orbit radius, broadside
    dim = replace(dim, col=did.col + sep * math.cos(a), row=did.row + sep * math.sin(a), depth_m=did.depth_m,
                  radiance_dn=did.radiance_dn)
    scene = replace(scene, bodies=(did, dim))
    t = run_trial(scene, seed, prediction_for(scene, rng, 3.0 if seed % 2 else 30.0))
    assert t.frame.truth[1].diameter_512_px < 3.0
    assert t.dimorphos.truth_index == 1
    assert t.dimorphos.error_px is not None and t.dimorphos.error_px <= PAPER_LIMIT_PX


@pytest.mark.parametrize("seed", range(8))
def test_a_close_double_star_is_not_taken_for_a_small_didymos_by_its_shape(seed: int) -> None:
    """A Didymos 5-8 px across too faint to be seen, its place known to 90 px, the frame's stars, and a double star
    (two stars 2.5-3.5 px apart, one blob wider than a point source, or two) within the place's
    reach: the double star is not reported as Didymos (held-out 109/94 and 117/171: such a blend, 2.0 and 2.4 px
    apart, 33 and 120 px off, was taken for Didymos with certainty, its light spread like a small disc's). Closer
    pairs, whose light shows one peak, are not told from a small disc."""
    rng = np.random.default_rng([117, seed])
    scene = random_scene(rng, didymos_diameter_px=float(rng.uniform(10.0, 16.0)), plume=False, n_hot=0, n_cosmic=0,
                         pointing_error_px=0.0)
    did, dim = scene.bodies
    scene = replace(scene, bodies=(replace(did, radiance_dn=1.0), replace(dim, radiance_dn=1.0)))
    pred = prediction_for(scene, rng, 30.0)
    a, b = rng.uniform(0.0, 2.0 * math.pi, size=2)
    d = 2.0 * rng.uniform(15.0, 40.0)  # from Didymos, full-resolution px
    c0, r0 = did.col + d * math.cos(a), did.row + d * math.sin(a)
    gap = 2.0 * rng.uniform(2.5, 3.5)
    pair = ((c0, r0, float(rng.uniform(1500.0, 3000.0))),
            (c0 + gap * math.cos(b), r0 + gap * math.sin(b), float(rng.uniform(1500.0, 3000.0))))
    t = run_trial(replace(scene, stars=scene.stars + pair), seed, pred)
    assert not visible(t.frame, 0)
    reported = t.detections.didymos
    assert reported is None or min(math.dist(reported.region_centroid_col_row, (c / 2.0, r / 2.0))
                                   for c, r, _ in pair) > 3.0


@pytest.mark.parametrize(("seed", "k"), [(109, 94), (117, 171)])
def test_a_close_double_star_in_a_bench_frame_is_not_a_didymos_that_may_be_resolved(seed: int, k: int) -> None:
    """Held-out bench frames: a faint 3 px Didymos (unseen) and a double star 2.0-2.4 px apart 33 and 120 px away,
    taken for Didymos with certainty for its shape: Didymos is reported within the paper's limit, or not at all."""
    t = _bench_trial(seed, k)
    assert t.detections.didymos is None or t.didymos.error_px <= PAPER_LIMIT_PX


@pytest.mark.parametrize("seed", range(8))
def test_a_resolved_didymos_unseen_among_stars_is_not_reported(seed: int) -> None:
    """A Didymos 5-8 px across (it must be resolved) too faint to be seen, its place known to 90 px, the frame's
    stars (0-30) about: no star is reported as Didymos (every candidate is a point source)."""
    rng = np.random.default_rng([117, seed])
    scene = random_scene(rng, didymos_diameter_px=float(rng.uniform(10.0, 16.0)), plume=False, n_hot=0, n_cosmic=0,
                         pointing_error_px=0.0)
    did, dim = scene.bodies
    scene = replace(scene, bodies=(replace(did, radiance_dn=1.0), replace(dim, radiance_dn=1.0)))
    t = run_trial(scene, seed, prediction_for(scene, rng, 30.0))
    assert not visible(t.frame, 0)
    assert t.detections.didymos is None


@pytest.mark.parametrize("seed", range(8))
def test_a_small_resolved_didymos_is_taken_for_its_shape_not_for_a_blend(seed: int) -> None:
    """A Didymos 3-8 px across (binned), bright, any phase and shading law, its place known to 90 px: it is found,
    within the paper's limit, with certainty (its shape told it from the stars: a disc split by its noise is no
    blend of point sources)."""
    rng = np.random.default_rng([118, seed])
    scene = random_scene(rng, didymos_diameter_px=float(rng.uniform(6.0, 16.0)), phase_deg=float(rng.uniform(
        20.0, 90.0)), plume=False, n_hot=0, n_cosmic=0, pointing_error_px=0.0, faint=False)
    t = run_trial(scene, seed, prediction_for(scene, rng, 30.0))
    assert visible(t.frame, 0)
    _assert_found(t, 0)
    assert t.detections.didymos_probability == 1.0


AT_90_PERCENT = CFG.model_copy(update={"didymos_min_report_probability": 0.9, "dimorphos_min_report_probability": 0.9})


@pytest.mark.parametrize(("seed", "k", "index"), [(1, 54, 0), (1, 225, 0), (3, 148, 0), (5, 140, 1),
                                                  (33, 258, 1), (35, 211, 1), (38, 179, 1), (39, 14, 0)])
def test_a_point_source_less_than_95_percent_likely_to_be_the_body_is_not_reported(seed: int, k: int,
                                                                                   index: int) -> None:
    """A body under 3 px across (0.6-2.3 px), its place known to 90 px, and a star or a speck of noise taken for it
    with a probability of 0.90-0.95: the body is reported unseen or within the paper's 15 px of its centre (bench
    frames whose report at 0.9 lay 16-120 px off, seeds 35-39 among them, which no change was tuned on)."""
    scene, prediction = _bench_scene(seed, k)
    frame = render(scene, np.random.default_rng(k))
    bad = ground_map(scene)

    def error_px(cfg: ImagingConfig) -> float | None:
        det = process_frame(frame.pixels, cfg, bad_pixels=bad, prediction=prediction)
        body = (det.didymos, det.dimorphos)[index]
        return None if body is None else math.dist(body.centroid_col_row, frame.truth[index].centre_512)

    assert frame.truth[index].diameter_512_px < 3.0
    error = error_px(CFG)
    assert error is None or error <= PAPER_LIMIT_PX, error
    before = error_px(AT_90_PERCENT)
    assert before is not None and before > PAPER_LIMIT_PX  # the frame holds the case: at 0.9 the report is off


@pytest.mark.parametrize("seed", range(4))
def test_a_point_like_didymos_no_likelier_than_a_star_is_not_reported(seed: int) -> None:
    """Didymos 1 px across and faint (a point source binned), two 3000 DN stars the same distance from Dimorphos's
    place, within the search's reach: neither is much likelier than the other to be Didymos, so none is reported as
    Didymos (before: a star, tens of px off), a part of one cut out of it included."""
    rng = np.random.default_rng([65, seed])
    scene = random_scene(rng, didymos_diameter_px=1.0, faint=True, plume=False, n_hot=0, n_cosmic=0,
                         pointing_error_px=0.0)
    prediction = prediction_for(scene, rng, 30.0)
    assert prediction.dimorphos_col_row is not None and prediction.orbit_radius_max_px is not None
    col, row = (2.0 * c + 0.5 for c in prediction.dimorphos_col_row)  # binned to full-resolution px
    a = rng.uniform(0.0, math.pi)
    d = 2.0 * (prediction.orbit_radius_max_px + 20.0)  # full-resolution px: 20 binned px beyond the orbit
    stars = ((col + d * math.cos(a), row + d * math.sin(a), 3000.0), (col - d * math.cos(a), row - d * math.sin(a),
                                                                    3000.0))
    t = run_trial(replace(scene, stars=stars, defects=Defects()), seed, prediction)
    assert t.detections.didymos is None, t.didymos
    assert t.detections.didymos_probability < 0.75  # about even: noise and sampling make their lights differ


@pytest.mark.parametrize(("seed", "k"), [(23, 297), (26, 13), (26, 285)])
def test_a_point_source_taken_for_a_didymos_that_may_be_resolved_is_not_reported_when_a_star_is_as_likely(
        seed: int, k: int) -> None:
    """Didymos 1.7-2.2 px across, predicted large enough that it may be resolved, but seen as a point source, its place
    known to 90 px and stars as bright within reach: the point source chosen is reported only if likely enough, and
    none was (bench frames of unseen seeds that reported a star 57-66 px off)."""
    t = _bench_trial(seed, k)
    assert t.detections.didymos is None, t.didymos
    assert t.detections.didymos_probability < CFG.didymos_min_report_probability


def test_a_didymos_identified_but_not_reported_still_pairs_with_dimorphos() -> None:
    """A frame whose Didymos was too likely a star to report, Dimorphos seen: the next frame's continuity refers to
    the pair identified, as when both were reported."""
    did = Blob(1, 2, (250.0, 250.0), (249, 249, 2, 1), 80.0, 90, 1.0, 50, region_centroid_col_row=(250.0, 250.0))
    dim = did._replace(label=2, centroid_col_row=(260.0, 255.0), region_centroid_col_row=(260.0, 255.0))
    previous = Detections((did, dim), None, dim, None, None, None, None, 35, 20, 3.0, 512, pair=(did, dim),
                          didymos_probability=0.4)
    assert reference_pair(previous, CFG) == (did, dim)
    assert reference_pair(replace(previous, pair_age_frames=1, pair=None), CFG) == (None, None)


def _crescent_beside_a_bright_fan(seed: int) -> Scene:
    """Didymos 90 px across (full resolution) at 110-125 deg of phase, a thin crescent; Dimorphos 20 px across
    100-130 px from it with a wide fan of ejecta (brighter than the crescent's surface near its source) pointing
    away from Didymos, in a random direction; a few faint stars."""
    rng = np.random.default_rng([64, seed])
    a = rng.uniform(0.0, 2.0 * math.pi)
    d = rng.uniform(100.0, 130.0)
    dim_col, dim_row = 512.0 + rng.uniform(-20, 20), 512.0 + rng.uniform(-20, 20)
    q = (0.0, 0.0, 0.0, 1.0)
    stars = tuple((float(rng.uniform(0, 1024)), float(rng.uniform(0, 1024)), float(rng.uniform(100, 400)))
                  for _ in range(10))
    return Scene(
        bodies=(Ellipsoid(dim_col - d * math.cos(a), dim_row - d * math.sin(a), 193.9e3, (47.0, 42.0, 36.0), q,
                          2400.0, law="lambert"),
                Ellipsoid(dim_col, dim_row, 193.3e3, (10.0, 9.6, 7.7), q, 2400.0, law="lambert")),
        range_m=193.3e3, phase_deg=float(rng.uniform(110.0, 125.0)),
        # the Sun on Didymos's side, within 60 deg: its crescent faces the Sun, the fan points away
        sun_azimuth_deg=math.degrees(a) + 180.0 + float(rng.uniform(-60.0, 60.0)),
        plume=Plume(axis_deg=math.degrees(a) + float(rng.uniform(-30.0, 30.0)), half_angle_deg=65.0, length_px=60.0,
                    brightness_dn=1500.0, exponent=0.65),
        stars=stars)


def _crescent_under_a_plume_core(seed: int) -> Scene:
    """Dimorphos 27 px across (full resolution) at 105-115 deg of phase, a thin crescent, with a fan of dust across
    the Sun's line starting 1.5 radii out (the slowest ejecta's reach), its core about as bright as the crescent and
    wider; Didymos 180-200 px away on the far side from the Sun."""
    rng = np.random.default_rng([77, seed])
    sun = rng.uniform(0.0, 360.0)
    dim_col, dim_row = 512.0 + rng.uniform(-20, 20), 512.0 + rng.uniform(-20, 20)
    d = rng.uniform(170.0, 200.0)
    a = math.radians(sun + 180.0 + rng.uniform(-20, 20))
    q = (0.0, 0.0, 0.0, 1.0)
    return Scene(
        bodies=(Ellipsoid(dim_col + d * math.cos(a), dim_row + d * math.sin(a), 126.0e3, (62.0, 58.0, 50.0), q, 2400.0,
                          law="lambert"),
                Ellipsoid(dim_col, dim_row, 125.0e3, (13.5, 13.0, 10.5), q, 2400.0, law="lambert")),
        range_m=125.0e3, phase_deg=float(rng.uniform(105.0, 115.0)), sun_azimuth_deg=sun,
        plume=Plume(axis_deg=sun + float(rng.choice([-1, 1])) * rng.uniform(80.0, 100.0), half_angle_deg=30.0,
                    length_px=120.0, brightness_dn=1400.0, exponent=0.3, inner_radii=1.5))


@pytest.mark.parametrize("seed", range(10))
def test_a_plume_core_beside_a_thin_crescent_is_not_dimorphos_where_its_place_is_known(seed: int) -> None:
    """A plume's core beside a thin crescent at high phase, holding most of the brightest pixels of Dimorphos's
    expected area, lies within the body's radius of a place known to 3 px but off the crescent's expected centroid:
    the crescent is reported, the smaller part of those pixels or, where the two make one part, the part a higher
    level cuts there (the chain took the core on 8 of these 10 frames, as in runs 98 and 127 of the nominal
    campaign, 10-11 px off; 3 of them with the first rule alone)."""
    scene = _crescent_under_a_plume_core(seed)
    t = run_trial(scene, seed, prediction_for(scene, np.random.default_rng([78, seed]), 1.0))
    _assert_found(t, 1)
    assert t.dimorphos.error_px is not None and t.dimorphos.error_px <= 3.0


def _hidden_behind_the_night_side(seed: int) -> Scene:
    """Dimorphos wholly behind Didymos's night side (the C/A of a pass over Didymos's dark hemisphere), its fan of
    ejecta streaming out past Didymos's dark limb: 60-120 deg phase, dust 300-1500 DN."""
    rng = np.random.default_rng([91, seed])
    sun = float(rng.uniform(0.0, 360.0))
    did_col, did_row = 512.0 + rng.uniform(-100.0, 100.0), 512.0 + rng.uniform(-100.0, 100.0)
    night = math.radians(sun + 180.0 + rng.uniform(-40.0, 40.0))
    d = rng.uniform(20.0, 40.0)
    q = (0.0, 0.0, 0.0, 1.0)
    return Scene(
        bodies=(Ellipsoid(did_col, did_row, 124.0e3, (62.0, 58.0, 50.0), q, 2400.0, law="lambert"),
                Ellipsoid(did_col + d * math.cos(night), did_row + d * math.sin(night), 125.0e3, (13.5, 13.0, 10.5),
                          q, 2400.0, law="lambert")),
        range_m=125.0e3, phase_deg=float(rng.uniform(60.0, 120.0)), sun_azimuth_deg=sun,
        plume=Plume(axis_deg=math.degrees(night) + rng.uniform(-30.0, 30.0), half_angle_deg=30.0, length_px=150.0,
                    brightness_dn=float(rng.uniform(300.0, 1500.0)), exponent=0.3, inner_radii=1.5))


@pytest.mark.parametrize("seed", range(12))
def test_dimorphos_hidden_behind_the_night_side_is_not_reported_as_its_dust(seed: int) -> None:
    """Dimorphos wholly hidden behind Didymos's night side, its place known to 3 px: no Dimorphos is reported (the
    chain reported a cut of the dust beyond the dark limb, or a piece of Didymos, on 11 of these 12 frames; in closed
    loop, a pass with its C/A over the night side had 19-28 px reports). Didymos is not asserted: on 2 of the 12 the
    dust beyond the dark limb, brighter than the crescent, is taken for it, on the build before as well."""
    scene = _hidden_behind_the_night_side(seed)
    t = run_trial(scene, seed, prediction_for(scene, np.random.default_rng([92, seed]), 1.0))
    assert t.frame.truth[1].lit_px == 0 and t.frame.truth[1].hidden_px > 0
    assert t.detections.dimorphos is None


@pytest.mark.parametrize("seed", range(4))
def test_a_fan_brighter_than_the_crescent_at_dimorphos_place_is_not_didymos(seed: int) -> None:
    """Ejecta leave Dimorphos: a fan of them holding Dimorphos's place, brighter in Didymos's expected area than
    Didymos's crescent at high phase, is Dimorphos with its dust, and the crescent beside it, within the orbit's
    reach, is Didymos (the chain took the fan for Didymos, reported 40 px off, on bench seed 11 frame 81)."""
    scene = _crescent_beside_a_bright_fan(seed)
    rng = np.random.default_rng([65, seed])
    t = run_trial(scene, seed, prediction_for(scene, rng, 3.0))
    _assert_found(t, 0)
    _assert_found(t, 1)


def test_bench_frame_with_a_fan_brighter_than_the_crescent() -> None:
    """Bench seed 11 frame 81 (a seed the chain was not tuned on): Didymos's 42 px crescent at 118 deg of phase and
    Dimorphos's fan of ejecta, brighter; both bodies found."""
    t = _bench_trial(11, 81)
    _assert_found(t, 0)
    _assert_found(t, 1)


def _small_pair_in_a_plume_and_a_star(seed: int) -> Scene:
    """Didymos about 3 px across (binned) with a sub-pixel Dimorphos beside it and a short plume from Dimorphos
    merging them into one region larger than both bodies can be, and a star brighter than Didymos 50-70 px (binned)
    away."""
    rng = np.random.default_rng([68, seed])
    col, row = 512.0 + rng.uniform(-40, 40), 512.0 + rng.uniform(-40, 40)
    a = rng.uniform(0.0, 2.0 * math.pi)
    q = (0.0, 0.0, 0.0, 1.0)
    b = rng.uniform(0.0, 2.0 * math.pi)
    far = rng.uniform(100.0, 140.0)
    return Scene(
        bodies=(Ellipsoid(col, row, 2.8431e6, (3.1, 2.7, 2.6), q, 600.0, law="minnaert", law_parameter=0.75),
                Ellipsoid(col + 3.5 * math.cos(a), row + 3.5 * math.sin(a), 2.8442e6, (0.65, 0.56, 0.55), q, 650.0,
                          law="minnaert", law_parameter=0.6)),
        range_m=2.8442e6, phase_deg=41.0, sun_azimuth_deg=float(rng.uniform(0.0, 360.0)),
        plume=Plume(axis_deg=float(rng.uniform(0.0, 360.0)), half_angle_deg=55.0, length_px=27.0, brightness_dn=480.0,
                    exponent=0.65),
        stars=((col + far * math.cos(b), row + far * math.sin(b), 4000.0),))


@pytest.mark.parametrize("seed", range(4))
def test_an_unresolved_didymos_split_from_its_plume_is_not_a_star_elsewhere(seed: int) -> None:
    """An unresolved Didymos merged with the plume, chosen among point-like candidates by its distance from
    Dimorphos's place (known to 90 px), is split from the ejecta; Didymos is then one of the region's parts, not a
    brighter star beyond the orbit that the place had already ruled less likely (bench seed 14 frame 287: the star,
    60 px off)."""
    scene = _small_pair_in_a_plume_and_a_star(seed)
    rng = np.random.default_rng([69, seed])
    t = run_trial(scene, seed, prediction_for(scene, rng, 30.0))
    assert t.didymos.truth_index == 0
    assert t.didymos.error_px is not None and t.didymos.error_px <= PAPER_LIMIT_PX


def test_bench_frame_with_an_unresolved_didymos_in_its_plume() -> None:
    """Bench seed 14 frame 287 (a seed no change was tuned on): the 2.8 px Didymos in its plume is reported, not the
    brighter star 60 px away."""
    t = _bench_trial(14, 287)
    assert t.didymos.truth_index == 0
    assert t.didymos.error_px is not None and t.didymos.error_px <= PAPER_LIMIT_PX


def _crescent_before_a_plume(seed: int) -> Scene:
    """Dimorphos (about 80 px across, full resolution) at 100-105 deg of phase, the Sun towards +columns, its plume
    behind it pointing away from the Sun, as bright near its dark limb as a third of the crescent and filling Didymos's
    expected area; Didymos 500 px beyond it towards the Sun, its lit side off the image: the plume, seen past
    Dimorphos's dark limb, is a region of its own beside the crescent."""
    rng = np.random.default_rng([71, seed])
    col, row = 470.0 + rng.uniform(-20, 20), 512.0 + rng.uniform(-40, 40)
    q = (0.0, 0.0, 0.0, 1.0)
    return Scene(
        bodies=(Ellipsoid(col + 500.0, row + rng.uniform(-30, 30), 42.0e3, (200.0, 190.0, 180.0), q, 1600.0),
                Ellipsoid(col, row, 42.5e3, (42.0, 39.0, 37.0), q, 1500.0, law="minnaert", law_parameter=0.65)),
        range_m=42.5e3, phase_deg=float(rng.uniform(100.0, 105.0)), sun_azimuth_deg=float(rng.uniform(-20.0, 20.0)),
        plume=Plume(axis_deg=180.0 + float(rng.uniform(-20.0, 20.0)), half_angle_deg=48.0, length_px=1300.0,
                    brightness_dn=700.0, exponent=1.3))


@pytest.mark.parametrize("seed", range(4))
def test_with_didymos_out_a_crescent_beside_its_plume_is_dimorphos(seed: int) -> None:
    """With Didymos's lit side off the image, the blob holding the most light in Didymos's expected area is the plume
    behind Dimorphos, a region of its own past the crescent's dark limb; Dimorphos is the brightest surface at its
    place, the crescent, not the plume's brightest part beside it (bench seed 21 frame 5: the plume, 32.6 px off)."""
    scene = _crescent_before_a_plume(seed)
    rng = np.random.default_rng([72, seed])
    t = run_trial(scene, seed, prediction_for(scene, rng, 3.0))
    _assert_found(t, 1)


def test_bench_frame_with_a_crescent_beside_its_plume_and_didymos_out() -> None:
    """Bench seed 21 frame 5 (a seed no change was tuned on): Dimorphos's crescent at 102 deg of phase beside its
    plume, Didymos's lit side at the image's edge; Dimorphos reported within 3 px of its centre."""
    t = _bench_trial(21, 5)
    _assert_found(t, 1)
    assert t.dimorphos.error_px <= 3.0


@pytest.mark.parametrize("star_dn", [1500.0, 2000.0, 3000.0, 4000.0])
def test_a_star_brighter_than_a_small_dimorphos_in_its_plume_is_not_its_surface(star_dn: float) -> None:
    """Bench seed 31 frame 147 (a seed no change was tuned on), the star in the plume made 1,500-4,000 DN: a 6 px
    Dimorphos at 111 deg of phase merged with its plume, which holds a star ten Dimorphos radii out, the place known
    to 9 px. The star set the surface's level and was cut out as Dimorphos (before, on every brightness); the
    region's part at the place is cut instead, within 5 px of the centre."""
    scene, prediction = _bench_scene(31, 147)
    body = scene.bodies[1]
    near = [s for s in scene.stars if math.dist(s[:2], (body.col, body.row)) < 12.0 * body.mean_radius_px]
    assert len(near) == 1  # the frame's star in the plume
    stars = tuple((s[0], s[1], star_dn) if s is near[0] else s for s in scene.stars)
    t = run_trial(replace(scene, stars=stars), 147, prediction)
    _assert_found(t, 1)
    assert t.dimorphos.error_px <= 5.0


@pytest.mark.parametrize(("seed", "k", "noise"), [(3, 299, 299), (12, 304, 304), (28, 184, 184), (33, 290, 290),
                                                  (33, 290, 1), (33, 290, 2)])
def test_dimorphos_merged_with_didymos_by_the_dust_is_a_candidate_after_the_cut(seed: int, k: int, noise: int) -> None:
    """Bench frames where Dimorphos (4-22 px, in the plume, the place known to 90 px or within the orbit's reach)
    was merged with Didymos's region by the dust and lost with it when the region was cut to the pixels above the
    dust's level (Dimorphos unseen on all six before; seed 33 frame 290 with three noise draws): the parts of
    Dimorphos's size that the cut leaves beside Didymos are candidates, and Dimorphos is found on itself."""
    scene, prediction = _bench_scene(seed, k)
    t = run_trial(scene, noise, prediction)
    _assert_found(t, 1)
    assert t.dimorphos.error_px <= 10.0


@pytest.mark.parametrize(("seed", "k"), [(23, 107), (34, 235)])
def test_a_small_dimorphos_at_high_phase_passes_the_brightness_gate_after_the_blur(seed: int, k: int) -> None:
    """Bench frames (seeds no change was tuned on): a 5-6 px Dimorphos at 107-112 deg of phase, its crescent a pixel
    or two wide, its brightest pixels dimmed by the blur where Didymos's wide crescent's are not (under the gate by
    8 and 14 % before): found on itself."""
    _assert_found(_bench_trial(seed, k), 1)


@settings(max_examples=200, deadline=None)
@given(st.floats(0.05, 200.0), st.floats(0.0, 1.0), st.floats(0.05, 2.0))
def test_the_blur_keeps_a_crescents_peak_as_a_convolved_strip_does(radius_px: float, lit: float, sigma_px: float
                                                                      ) -> None:
    """The peak of a strip of width 2 r lit convolved with a Gaussian of the PSF's and the pixel's variance, summed
    numerically, equals the closed form the gate uses; it grows with the width and never passes the surface's."""
    from scipy.integrate import quad

    from obsw.imaging_identification import _crescent_peak
    cfg = CFG.model_copy(update={"point_source_sigma_max_px": sigma_px})
    width = 2.0 * radius_px * lit
    s = math.sqrt(sigma_px ** 2 + 1.0 / 12.0)
    area = quad(lambda x: math.exp(-0.5 * (x / s) ** 2), -width / 2.0, width / 2.0)[0]
    numeric = area / (s * math.sqrt(2.0 * math.pi))
    peak = _crescent_peak(radius_px, lit, cfg)
    assert peak == pytest.approx(numeric, abs=1e-6)
    assert 0.0 <= peak <= 1.0
    assert _crescent_peak(radius_px * 1.5, lit, cfg) >= peak


def _small_pair_and_two_stars_far_off(seed: int) -> tuple[Scene, FramePrediction]:
    """Didymos about 6 px across (binned) at 100-110 deg of phase with a 1 px Dimorphos 8 px from it, blurred into
    one region larger than both bodies; two stars 2.3 px apart (binned), one blob of a star pair's spread; the place
    known to 90 px (3 sigma) and put 15 px off Dimorphos, away from the stars, which lie 96-104 px from it: beyond
    the place's radius, within its reach, and 8-9 orbit radii from the bodies (bench seed 52 frame 242, where the
    stars were reported as Didymos, 121 px off)."""
    rng = np.random.default_rng([91, seed])
    col, row = 512.0 + rng.uniform(-40, 40), 512.0 + rng.uniform(-40, 40)
    a, b = rng.uniform(0.0, 2.0 * math.pi, 2)
    q = (0.0, 0.0, 0.0, 1.0)
    dim_col, dim_row = col + 16.0 * math.cos(a), row + 16.0 * math.sin(a)
    far = 2.0 * (rng.uniform(96.0, 104.0) - 15.0)
    s_col, s_row = dim_col + far * math.cos(b), dim_row + far * math.sin(b)
    scene = Scene(
        bodies=(Ellipsoid(col, row, 1.3984e6, (5.9, 5.7, 5.4), q, 1100.0, law="lunar-lambert", law_parameter=0.37),
                Ellipsoid(dim_col, dim_row, 1.3988e6, (1.4, 1.3, 1.0), q, 1150.0, law="minnaert", law_parameter=0.9)),
        range_m=1.3988e6, phase_deg=float(rng.uniform(100.0, 110.0)), sun_azimuth_deg=float(rng.uniform(0.0, 360.0)),
        stars=((s_col, s_row, 1200.0), (s_col + 4.7 * math.cos(b + 1.2), s_row + 4.7 * math.sin(b + 1.2), 500.0)),
        psf_sigma_px=1.04, bias_dn=144.0, read_noise_dn=5.5, gain_e_per_dn=3.0)
    prediction = prediction_for(scene, np.random.default_rng([92, seed]), None)
    place = ((dim_col - 0.5) / 2.0 - 15.0 * math.cos(b), (dim_row - 0.5) / 2.0 - 15.0 * math.sin(b))
    return scene, replace(prediction, dimorphos_col_row=place, dimorphos_uncertainty_px=90.0)


@pytest.mark.parametrize("seed", range(6))
def test_a_star_pair_beyond_the_orbit_s_reach_of_a_merged_pair_is_not_didymos(seed: int) -> None:
    """A region holding Dimorphos's place with more than both bodies' areas leaves Didymos to another extended
    region only within the orbit's reach of it: a star pair 100 px away, off a place known to 90 px, is not Didymos."""
    scene, prediction = _small_pair_and_two_stars_far_off(seed)
    t = run_trial(scene, seed, prediction)
    _assert_found(t, 0)


def test_bench_frame_with_a_star_pair_far_off_a_small_merged_pair() -> None:
    """Bench seed 52 frame 242 (a seed first run after the rule was written): Didymos, 5.7 px, is found."""
    _assert_found(_bench_trial(52, 242), 0)


@pytest.mark.parametrize(("brightness", "half_angle_deg"), [(1.0, 60.2), (1.5, 60.2), (2.0, 60.2), (1.0, 45.0),
                                                           (1.5, 75.0)])
def test_a_crescent_cut_by_the_border_is_didymos_not_a_fan_of_as_much_light(brightness: float,
                                                                          half_angle_deg: float) -> None:
    """Bench seed 56 frame 210 (first run after the chain was written), its fan brighter or wider: Didymos's crescent
    at 115 deg of phase, two thirds of it beyond the border, holds as much light in Didymos's expected area as
    Dimorphos's fan of ejecta, whose region is many times larger; over as many pixels as the crescent shows, its
    surface is the brighter: the fan is never reported as Didymos (it was, 299 px off), the crescent is, unless
    the fan's region has no lit surface of Didymos's size (Didymos then taken to be out of the image, the fan
    Dimorphos's dust: not reported, as it need not be with two thirds of it out)."""
    scene, prediction = _bench_scene(56, 210)
    assert scene.plume is not None
    scene = replace(scene, plume=replace(scene.plume, brightness_dn=scene.plume.brightness_dn * brightness,
                                         half_angle_deg=half_angle_deg))
    t = run_trial(scene, 210, prediction)
    assert t.frame.truth[0].touches_edge
    assert t.frame.truth[0].off_frame_px > t.frame.truth[0].lit_px / 2
    assert t.didymos.truth_index in (0, None)
    if t.didymos.truth_index == 0:
        assert t.didymos.opencv_px is not None and t.didymos.opencv_px <= 1e-9
    assert t.dimorphos.truth_index == 1


@pytest.mark.parametrize("dimorphos_radiance", [0.7, 0.85, 1.0, 1.15])
def test_with_didymos_out_a_piece_of_its_limb_off_the_place_is_not_dimorphos(dimorphos_radiance: float) -> None:
    """Bench seed 54 frame 90 (first run after the chain was written), Dimorphos dimmer or brighter: Didymos, 179 px
    at 38 deg of phase, its centre beyond the left edge, is taken to be out of the image (no lit surface of its size
    in one region); Dimorphos, 36 px, is the surface at its place known to 90 px, not a brighter piece of Didymos's
    limb at the edge reaching towards it, whose centroid lies beyond the place's radius (reported, 215 px off)."""
    scene, prediction = _bench_scene(54, 90)
    did, dim = scene.bodies
    scene = replace(scene, bodies=(did, replace(dim, radiance_dn=dim.radiance_dn * dimorphos_radiance)))
    _assert_found(run_trial(scene, 90, prediction), 1)


def _point_like_didymos_in_a_plume_with_a_star(seed: int) -> tuple[Scene, FramePrediction]:
    """A Didymos about 1 px across (full resolution) and a sub-pixel Dimorphos, Dimorphos's place known to 9 px, their
    plume, and a star brighter than the plume's core on its axis, 1.5-4 binned px beyond the farthest Didymos's region
    can reach from the place (the place's radius, the orbit's and Didymos's largest radii), the plume reaching
    nearly to it: one region, its brightest pixels the star's, its centroid near enough the place to be likely."""
    rng = np.random.default_rng([112, seed])
    col, row = 512.0 + rng.uniform(-40, 40), 512.0 + rng.uniform(-40, 40)
    q = (0.0, 0.0, 0.0, 1.0)
    axis = rng.uniform(0.0, 360.0)
    b = rng.uniform(0.0, 2.0 * math.pi)
    scene = Scene(
        bodies=(Ellipsoid(col, row, 1.47e7, (0.59, 0.55, 0.46), q, 2500.0),
                Ellipsoid(col + 1.8 * math.cos(b), row + 1.8 * math.sin(b), 1.47e7 + 500.0, (0.13, 0.12, 0.10), q,
                          2300.0)),
        range_m=1.47e7, phase_deg=float(rng.uniform(90.0, 110.0)), sun_azimuth_deg=float(rng.uniform(0.0, 360.0)))
    pred = prediction_for(scene, rng, 3.0)
    exp = expected(pred, CFG)
    assert exp is not None and pred.dimorphos_col_row is not None and pred.dimorphos_uncertainty_px is not None
    reach = pred.dimorphos_uncertainty_px + exp.dimorphos_radius_max + CFG.centroid_noise_px \
        + exp.orbit_radius_max + exp.didymos_radius_max  # binned px
    # the star on the plume's axis from Didymos, at t binned px, |Didymos + t u - place| = reach + margin
    u = (math.cos(math.radians(axis)), math.sin(math.radians(axis)))
    dx, dy = (col - 0.5) / 2.0 - pred.dimorphos_col_row[0], (row - 0.5) / 2.0 - pred.dimorphos_col_row[1]
    want = reach + rng.uniform(1.5, 4.0)
    half_b = dx * u[0] + dy * u[1]
    t = -half_b + math.sqrt(half_b ** 2 - (dx * dx + dy * dy - want * want))
    star = (col + 2.0 * t * u[0], row + 2.0 * t * u[1], float(rng.uniform(2500.0, 3500.0)))
    plume = Plume(axis_deg=float(axis), half_angle_deg=float(rng.uniform(45.0, 50.0)),
                  length_px=2.0 * t * float(rng.uniform(0.85, 1.0)), brightness_dn=1500.0, exponent=0.63)
    return replace(scene, plume=plume, stars=(star,)), pred


@pytest.mark.parametrize("seed", range(8))
def test_a_star_in_the_plume_s_region_beyond_didymos_s_reach_is_not_a_point_like_didymos(seed: int) -> None:
    """A point-like Didymos merged with its plume and a star on the plume's axis into one region, Dimorphos's place
    known to 9 px, the star beyond the farthest Didymos's region can reach from the place: the region's brightest
    pixels (the star's) are not Didymos; Didymos is reported within the paper's limit of its centre, or not at all
    (held-out 112/289: the star, 18 px from a 0.5 px Didymos, reported at 0.95)."""
    scene, pred = _point_like_didymos_in_a_plume_with_a_star(seed)
    t = run_trial(scene, seed, pred)
    assert identity(t.detections.didymos, t.frame) != -1  # not the star
    did = t.detections.didymos
    assert did is None or math.dist(did.centroid_col_row, t.frame.truth[0].centre_512) <= PAPER_LIMIT_PX


def test_bench_frame_with_a_star_in_the_plume_s_region_far_from_a_point_like_didymos() -> None:
    """Held-out 112/289: a star in the plume's region of a 0.5 px Didymos, 18 px off, is not reported as Didymos."""
    t = _bench_trial(112, 289)
    assert t.detections.didymos is None or t.didymos.error_px <= PAPER_LIMIT_PX
