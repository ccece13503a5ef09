"""Dimorphos's centre from its limb: the circle fit against discs drawn in the test (closed form: the disc's centre),
and the limb check on frames of the independent generator where Dimorphos passes in front of Didymos's limb with
the plume behind it, against the truth."""

from __future__ import annotations

import functools
import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from scipy.ndimage import gaussian_filter
from tests.obsw.frame_generator import Ellipsoid, Plume, Scene, random_scene, render
from tests.obsw.imaging_trials import PAPER_LIMIT_PX, ground_map, prediction_for, run_trial, scaled

from obsw.config import ImagingConfig
from obsw.imaging import Detections, FramePrediction, process_frame
from obsw.imaging_identification import Blob
from obsw.imaging_limb import _LIT_PASSES, _best_circle, limb_centre, limb_corrected, lit_limb_centre

CFG = ImagingConfig()
# the chain's cuts the limb check judges: without deblending, whose objects are peaks of their own and not checked
CUTS = CFG.model_copy(update={"deblend_min_flux_fraction": 0.999})


def _disc(size: int, col: float, row: float, radius: float, sub: int = 5) -> np.ndarray:
    """Fraction of each pixel inside the disc (pixel centres at integers), by sub x sub sampling."""
    o = (np.arange(sub) + 0.5) / sub - 0.5
    rows, cols = np.indices((size, size), dtype=np.float64)
    inside = np.zeros((size, size))
    for dy in o:
        for dx in o:
            inside += np.hypot(cols + dx - col, rows + dy - row) <= radius
    return inside / sub ** 2


@settings(max_examples=30, deadline=None)
@given(dc=st.floats(-0.5, 0.5), dr=st.floats(-0.5, 0.5), radius=st.floats(7.0, 20.0),
       back=st.floats(0.3, 1.6), side=st.floats(0.0, 2.0 * math.pi), place_err=st.floats(0.0, 8.0),
       place_dir=st.floats(0.0, 2.0 * math.pi), ramp=st.floats(0.0, 0.02), psf=st.floats(0.5, 1.0))
def test_the_circle_fit_finds_a_disc_in_front_of_another(dc: float, dr: float, radius: float, back: float,
                                                         side: float, place_err: float, place_dir: float,
                                                         ramp: float, psf: float) -> None:
    """A uniform disc in front of a larger one (brighter or fainter than it) over a brightness ramp (a plume's
    glow), blurred by the camera's point-spread function, is found within 1.5 px of its centre (the median step
    leans towards the stronger edges by about a pixel at worst), from a place up to 8 px off, by a circle of its
    radius."""
    size = 128
    c, r = 64.0 + dc, 64.0 + dr
    big_r = 4.0 * radius
    big_c, big_r_row = c + big_r * math.cos(side), r + big_r * math.sin(side)  # its limb through the small disc
    rows, cols = np.indices((size, size), dtype=np.float64)
    small = _disc(size, c, r, radius)
    image = gaussian_filter(1000.0 * ramp * cols + 1000.0 * back * _disc(size, big_c, big_r_row, big_r) * (1.0 - small)
                            + 1000.0 * small, psf)
    place = (c + place_err * math.cos(place_dir), r + place_err * math.sin(place_dir))
    fit = limb_centre(image, place, 9.0, radius / 1.5, radius * 1.5)
    assert fit is not None
    assert math.dist(fit.col_row, (c, r)) <= 1.5, (fit, (c, r))
    assert abs(fit.radius_px - radius) <= 1.0
    assert fit.score >= CFG.limb_fit_min_contrast * fit.window_median


def test_no_fit_outside_the_image_or_with_disordered_radii() -> None:
    """A search window off the image, or radii not positive and ordered, gives no circle rather than an error."""
    image = np.zeros((64, 64))
    assert limb_centre(image, (-100.0, 30.0), 5.0, 4.0, 6.0) is None
    assert limb_centre(image, (30.0, 30.0), 5.0, 6.0, 4.0) is None
    assert limb_centre(image, (30.0, 30.0), 5.0, 0.0, 4.0) is None
    assert limb_centre(image, (math.nan, 30.0), 5.0, 4.0, 6.0) is None
    assert limb_centre(np.full((64, 64), math.nan), (30.0, 30.0), 5.0, 4.0, 6.0) is None


def _scores_reference(gx: np.ndarray, gy: np.ndarray, cols: np.ndarray, rows: np.ndarray, radii: np.ndarray,
                      ang: np.ndarray, inward: bool) -> np.ndarray:
    """Every circle's score, written plainly: the median over its points of the bilinearly sampled radial step."""
    h, w = gx.shape
    out = np.zeros((cols.size, rows.size, radii.size))
    for i, c in enumerate(cols):
        for j, r in enumerate(rows):
            for k, rad in enumerate(radii):
                x, y = c + rad * np.cos(ang), r + rad * np.sin(ang)
                x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
                ok = (x0 >= 0) & (y0 >= 0) & (x0 + 1 < w) & (y0 + 1 < h)
                x0, y0 = np.where(ok, x0, 0), np.where(ok, y0, 0)
                fx, fy = x - x0, y - y0

                def at(g: np.ndarray) -> np.ndarray:
                    return ((1 - fx) * (1 - fy) * g[y0, x0] + fx * (1 - fy) * g[y0, x0 + 1]
                            + (1 - fx) * fy * g[y0 + 1, x0] + fx * fy * g[y0 + 1, x0 + 1])

                radial = at(gx) * np.cos(ang) + at(gy) * np.sin(ang)
                out[i, j, k] = np.median(np.where(ok, -radial if inward else np.abs(radial), 0.0))
    return out


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), levels=st.integers(0, 6), inward=st.booleans(),
       n_grid=st.integers(1, 7), n_radii=st.integers(1, 5), n_angles=st.sampled_from([5, 24, 48]))
def test_the_pruned_circle_search_is_the_argmax_of_every_circle_scored(seed: int, levels: int, inward: bool,
                                                                      n_grid: int, n_radii: int,
                                                                      n_angles: int) -> None:
    """The search that drops circles early picks the circle np.argmax picks over every circle's score, ties included."""
    rng = np.random.default_rng(seed)
    # few levels, many tied scores (none: a flat image, every circle tied at 0)
    image = rng.integers(0, levels + 1, size=(24, 24)).astype(np.float64)
    gy, gx = np.gradient(image)
    cols = 11.0 + np.arange(n_grid) - n_grid // 2 + rng.uniform(0.0, 1.0)
    rows = 11.0 + np.arange(n_grid) - n_grid // 2 + rng.uniform(0.0, 1.0)
    radii = 2.0 + np.arange(n_radii) * 1.5
    ang = np.linspace(0.0, 2.0 * np.pi, n_angles, endpoint=False)
    scores = _scores_reference(gx, gy, cols, rows, radii, ang, inward)
    want = np.unravel_index(int(np.argmax(scores)), scores.shape)
    i, j, k, score = _best_circle(gx, gy, cols, rows, radii, np.cos(ang), np.sin(ang), inward)
    assert (i, j, k) == tuple(int(v) for v in want)
    assert score == pytest.approx(float(scores[want]), abs=1e-12)


def _transit(rng: np.random.Generator, plume: bool, phase_deg: tuple[float, float] = (15.0, 40.0)) -> Scene:
    """Dimorphos (lit as brightly as Didymos) in front of Didymos's limb near C/A, 55-75 km away, at a phase within
    ``phase_deg``, the plume's fan from Dimorphos lying behind it over Didymos when asked."""
    focal = 1024.0 / (2.0 * math.tan(math.radians(1.45)))
    range_m = float(rng.uniform(55e3, 75e3))
    px_per_m = focal / range_m
    did_r, dim_r = 390.0 * px_per_m, 82.0 * px_per_m
    angle = rng.uniform(0.0, 2.0 * math.pi)
    # Dimorphos's centre within half its radius of Didymos's limb: the two overlap, Dimorphos in front
    d = did_r + rng.uniform(-0.5, 0.5) * dim_r
    dim_c, dim_r_row = 512.0 + rng.uniform(-20, 20), 512.0 + rng.uniform(-20, 20)
    did_c, did_row = dim_c - d * math.cos(angle), dim_r_row - d * math.sin(angle)
    radiance = float(rng.uniform(1500.0, 3000.0))
    bodies = (
        Ellipsoid(did_c, did_row, range_m + 1000.0, (did_r, did_r * 0.95, did_r * 0.9), (0.0, 0.0, 0.0, 1.0),
                  radiance, "lunar-lambert", 0.5),
        Ellipsoid(dim_c, dim_r_row, range_m, (dim_r * 1.1, dim_r, dim_r * 0.95),
                  tuple(float(v) for v in rng.normal(size=4) / 2.0), radiance * rng.uniform(0.9, 1.1),
                  "lunar-lambert", 0.5),
    )
    bodies = (bodies[0], replace(bodies[1], rotation=tuple(float(v) for v in np.asarray(bodies[1].rotation)
                                                             / np.linalg.norm(bodies[1].rotation))))
    fan = Plume(axis_deg=float(math.degrees(angle) + 180.0 + rng.uniform(-30, 30)), half_angle_deg=50.0,
                length_px=dim_r * 20.0, brightness_dn=radiance * rng.uniform(0.5, 0.9), exponent=0.7) \
        if plume else None
    return Scene(bodies=bodies, range_m=range_m, phase_deg=float(rng.uniform(*phase_deg)),
                 sun_azimuth_deg=float(rng.uniform(0.0, 360.0)), plume=fan)


@functools.cache  # the tests share the frames: rendering them is most of their time
def _transits(phase_deg: tuple[float, float] = (15.0, 40.0), seeds: int = 24, stream: int = 2027
              ) -> tuple[tuple[Scene, FramePrediction, np.ndarray, Detections], ...]:
    """Transit frames of the independent generator in which the chain cuts Dimorphos out of a shared region."""
    out = []
    for seed in range(seeds):
        rng = np.random.default_rng([stream, seed])
        scene = _transit(rng, plume=True, phase_deg=phase_deg)
        prediction = prediction_for(scene, rng, place_sigma_px=1.0)
        frame = render(scene, np.random.default_rng(seed))
        det = process_frame(frame.pixels, CUTS, bad_pixels=ground_map(scene), prediction=prediction)
        if det.dimorphos is not None and det.dimorphos.trimmed_from:
            out.append((scene, prediction, frame, det))
    return tuple(out)


def test_a_cut_off_its_body_is_moved_to_the_limb_and_one_on_it_is_kept() -> None:
    """On transit frames of the independent generator, a Dimorphos cut whose centroid lies 0.8-1.3 radii off the
    body's centre, towards Didymos (the cut holds Didymos's limb or the plume's core), is reported within 3 px of
    the centre; the chain's own cut, within half a radius of it, is reported unchanged."""
    cases = _transits()
    assert len(cases) >= 6
    for k, (scene, prediction, frame, det) in enumerate(cases):
        dim, truth = det.dimorphos, frame.truth[1].centre_512
        r = frame.truth[1].radius_512_px
        binned = ((frame.pixels.reshape(512, 2, 512, 2).astype(np.int64).sum(axis=(1, 3)) + 2) >> 2)
        kept, samples = limb_corrected(dim, binned, prediction, CFG, 2.9)
        assert samples > 0 and math.dist(dim.centroid_col_row, truth) <= 0.5 * r
        assert kept == dim
        did = frame.truth[0].centre_512
        towards = np.subtract(did, truth) / math.dist(did, truth)
        shift = (0.8 + 0.5 * k / len(cases)) * r * towards
        wrong = dim._replace(centroid_col_row=tuple(np.add(dim.centroid_col_row, shift)),
                        region_centroid_col_row=tuple(np.add(dim.region_centroid_col_row, shift)))
        moved, _ = limb_corrected(wrong, binned, prediction, CFG, 2.9)
        assert moved is not None and math.dist(moved.centroid_col_row, truth) <= 3.0, (k, moved, truth)


def test_a_cut_beyond_the_body_is_moved_to_the_limb_found_at_the_predicted_place() -> None:
    """On the same transit frames, a cut whose centroid lies beyond Dimorphos's largest radius from its centre (it kept
    the surface beside Dimorphos) is still reported within 3 px of the centre: the circle is taken because it lies
    where the prediction puts Dimorphos, within its uncertainty and the centroid noise."""
    cases = _transits()
    for k, (scene, prediction, frame, det) in enumerate(cases):
        dim, truth = det.dimorphos, frame.truth[1].centre_512
        r = frame.truth[1].radius_512_px
        binned = ((frame.pixels.reshape(512, 2, 512, 2).astype(np.int64).sum(axis=(1, 3)) + 2) >> 2)
        did = frame.truth[0].centre_512
        towards = np.subtract(did, truth) / math.dist(did, truth)
        r_max = prediction.dimorphos_radius_px * prediction.radius_factor_max + CFG.blur_margin_px
        shift = (r_max + (1.0 + k / len(cases)) * r) * towards
        wrong = dim._replace(centroid_col_row=tuple(np.add(truth, shift)),
                        region_centroid_col_row=tuple(np.add(truth, shift)))
        assert math.dist(wrong.region_centroid_col_row, truth) > r_max + 2.0  # beyond the body, the fit's circle too
        moved, _ = limb_corrected(wrong, binned, prediction, CFG, 2.9)
        assert moved is not None and math.dist(moved.centroid_col_row, truth) <= 3.0, (k, moved, truth)


def test_a_cut_off_the_place_is_moved_to_the_limb_found_on_it_however_near_the_two_are() -> None:
    """On the same transit frames, a cut whose centroid lies just beyond the place's allowance (its uncertainty and
    the centroid noise) on the far side of the body's centre, so within half a radius of the body's limb circle, is
    reported within 3 px of the centre: the circle is on the place, the cut is not (run 881 of the nominal campaign:
    a cut 7.5 px from a place known to 4 px, 11.1 px off the centre, was kept)."""
    cases = _transits()
    for k, (scene, prediction, frame, det) in enumerate(cases):
        dim, truth = det.dimorphos, frame.truth[1].centre_512
        binned = ((frame.pixels.reshape(512, 2, 512, 2).astype(np.int64).sum(axis=(1, 3)) + 2) >> 2)
        place = prediction.dimorphos_col_row
        away = np.subtract(truth, place)
        if np.hypot(*away) < 0.5:  # the place on the centre: away from it towards Didymos
            away = np.subtract(frame.truth[0].centre_512, truth)
        cut = tuple(np.add(place, (prediction.dimorphos_uncertainty_px + CFG.centroid_noise_px + 0.1)
                           * away / np.hypot(*away)))
        assert math.dist(cut, truth) < 0.5 * prediction.dimorphos_radius_px
        wrong = dim._replace(centroid_col_row=cut, region_centroid_col_row=cut)
        moved, _ = limb_corrected(wrong, binned, prediction, CFG, 2.9)
        assert moved is not None and math.dist(moved.centroid_col_row, truth) <= 3.0, (k, moved, truth)


def test_a_cut_off_its_body_is_moved_to_the_limb_up_to_70_deg_of_phase() -> None:
    """On transit frames of the independent generator at 60-70 deg of phase (the terminator anywhere, towards Didymos
    too: run 432 of the Monte Carlo campaigns, 63 deg), a cut one radius off Dimorphos's centre towards Didymos is
    reported within 4.5 px of the centre (the limb's circle, phase-corrected, within 4.2 px on 40 such frames); the
    chain's own cuts stay within 5 px."""
    cases = _transits(phase_deg=(60.0, 70.0), seeds=28, stream=2028)
    assert len(cases) >= 8
    for k, (scene, prediction, frame, det) in enumerate(cases):
        dim, truth = det.dimorphos, frame.truth[1].centre_512
        r = frame.truth[1].radius_512_px
        binned = ((frame.pixels.reshape(512, 2, 512, 2).astype(np.int64).sum(axis=(1, 3)) + 2) >> 2)
        assert math.dist(dim.centroid_col_row, truth) <= 5.0, (k, dim, truth)
        did = frame.truth[0].centre_512
        towards = np.subtract(did, truth) / math.dist(did, truth)
        wrong = dim._replace(centroid_col_row=tuple(np.add(truth, r * towards)),
                        region_centroid_col_row=tuple(np.add(truth, r * towards)))
        moved, samples = limb_corrected(wrong, binned, prediction, CFG, 2.9)
        assert samples > 0 and moved is not None and math.dist(moved.centroid_col_row, truth) <= 4.5, \
            (k, scene.phase_deg, moved, truth)


def test_at_70_to_90_deg_of_phase_the_limb_keeps_the_reports_on_the_body() -> None:
    """On transit frames of the independent generator at 70-90 deg of phase (a plume's fan behind Dimorphos over
    Didymos: run 22 of a worst-late-near campaign, Dimorphos in a plume as bright as its surface), the chain's own
    reports stay within 4 px of the centre (3.4 px measured; 5.4 when the circle's centre was moved back by the
    phase correction of a lit crescent's centroid, and with the limb fitted only up to 70 deg they reached 10 px on
    these frames and 11.4 on another 20), and a cut one radius off towards Didymos is moved within 3 px of the
    centre (2.3 measured, 7.1 with the phase correction) or, where the check does not run (the predicted place past
    90 deg) or the limb does not step clearly enough, left as it was; where the circle is off the place but nearer it
    than the cut (``limb_fit_circle_error_radii``), moved nearer the centre (5.7-7.9 px against 11-15 px: at this
    phase the dark limb does not step against the sky and the circle strays)."""
    cases = _transits(phase_deg=(70.0, 90.0), seeds=36, stream=2030)
    assert len(cases) >= 12
    for k, (scene, prediction, frame, det) in enumerate(cases):
        dim, truth = det.dimorphos, frame.truth[1].centre_512
        r = frame.truth[1].radius_512_px
        assert math.dist(dim.centroid_col_row, truth) <= 4.0, (k, scene.phase_deg, dim, truth)
        binned = ((frame.pixels.reshape(512, 2, 512, 2).astype(np.int64).sum(axis=(1, 3)) + 2) >> 2)
        did = frame.truth[0].centre_512
        towards = np.subtract(did, truth) / math.dist(did, truth)
        wrong = dim._replace(centroid_col_row=tuple(np.add(truth, r * towards)),
                             region_centroid_col_row=tuple(np.add(truth, r * towards)))
        moved, _ = limb_corrected(wrong, binned, prediction, CFG, 2.9)
        assert moved is not None
        off = math.dist(moved.centroid_col_row, truth)
        assert moved == wrong or off <= 3.0 or off < math.dist(wrong.centroid_col_row, truth) \
            and math.dist(moved.centroid_col_row, prediction.dimorphos_col_row) \
            < math.dist(wrong.centroid_col_row, prediction.dimorphos_col_row), (k, scene.phase_deg, moved, truth)


def test_without_a_prediction_or_a_cut_nothing_is_fitted() -> None:
    """A blob not cut out of a larger region, or a frame without a predicted place, is left as it is, unfitted."""
    scene, prediction, frame, det = _transits()[0]
    binned = ((frame.pixels.reshape(512, 2, 512, 2).astype(np.int64).sum(axis=(1, 3)) + 2) >> 2)
    whole = det.dimorphos._replace(trimmed_from=0)
    assert limb_corrected(whole, binned, prediction, CFG, 2.9) == (whole, 0)
    assert limb_corrected(det.dimorphos, binned, replace(prediction, dimorphos_col_row=None), CFG, 2.9) \
        == (det.dimorphos, 0)
    assert limb_corrected(det.dimorphos, binned, prediction, CFG.model_copy(update={"limb_fit": False}), 2.9) \
        == (det.dimorphos, 0)


def _lit_sphere(size: int, col: float, row: float, radius: float, sun: np.ndarray, sub: int = 4) -> np.ndarray:
    """A Lambert sphere seen from afar, lit from ``sun`` (unit, camera axes: x along columns, y along rows, z
    away from the camera): each pixel's mean of max(0, n . sun) over sub x sub samples, n the visible surface's
    normal."""
    o = (np.arange(sub) + 0.5) / sub - 0.5
    rows, cols = np.indices((size, size), dtype=np.float64)
    out = np.zeros((size, size))
    for dy in o:
        for dx in o:
            qx, qy = (cols + dx - col) / radius, (rows + dy - row) / radius
            q2 = qx * qx + qy * qy
            nz = -np.sqrt(np.clip(1.0 - q2, 0.0, None))  # the visible hemisphere faces the camera (-z)
            out += np.where(q2 <= 1.0, np.clip(qx * sun[0] + qy * sun[1] + nz * sun[2], 0.0, None), 0.0)
    return out / sub ** 2


def _sphere_and_wedge(radius: float, phase: float, sun_az: float, fan_turn: float
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, float]:
    """A Lambert sphere of ``radius`` px centred in a 128 px image at ``phase`` deg, the Sun ``sun_az`` rad round from
    +columns, and a 30 deg wedge from its limb turned ``fan_turn`` rad from the Sun: the Sun (camera axes), the
    sphere's shading, each pixel's distance from the centre, the wedge's pixels, the wedge's axis (rad)."""
    size, c, r = 128, 64.0, 64.0
    g = math.radians(phase)
    sun = np.array([math.sin(g) * math.cos(sun_az), math.sin(g) * math.sin(sun_az), -math.cos(g)])
    body = _lit_sphere(size, c, r, radius, sun)
    rows, cols = np.indices((size, size), dtype=np.float64)
    axis = sun_az + fan_turn
    dist = np.hypot(cols - c, rows - r)
    off_axis = np.abs((np.arctan2(rows - r, cols - c) - axis + math.pi) % (2.0 * math.pi) - math.pi)
    return sun, body, dist, (off_axis <= math.radians(15.0)) & (dist >= radius), axis


@settings(max_examples=25, deadline=None)
@given(radius=st.floats(1.5 * CFG.limb_fit_min_radius_px, 18.0), phase=st.floats(95.0, 130.0), sun_az=st.floats(0.0, 2.0 * math.pi),
       fan_turn=st.floats(math.radians(60.0), math.radians(300.0)), fan=st.floats(0.2, 0.7),
       psf=st.floats(0.5, 1.0))
@example(radius=10.0, phase=123.0, sun_az=0.0, fan_turn=1.375, fan=0.5, psf=1.0)  # 4.42 px: a pixel + 0.09
def test_the_lit_limb_of_a_crescent_beside_a_fan_of_ejecta_is_found(radius: float, phase: float, sun_az: float,
                                                                   fan_turn: float, fan: float, psf: float) -> None:
    """A Lambert sphere of 9-18 px radius (the fit runs only where the smallest radius searched, here R / 1.5, is at
    least limb_fit_min_radius_px: at 7 px a bright fan drew it 10 px off) at 95-130 deg of phase (a thin crescent) with a fan of ejecta rising from it (a 30 deg wedge,
    as bright as 0.2-0.7 of the surface's best-lit point at its root, fading as 1 / distance, turned 60-300 deg from
    the Sun), searched from the fan's brightest part: the lit limb's circle has its centre on the body, within the
    radii searched (R - R / 1.5) plus a pixel plus the half-diagonal of the search's finest grid cell (0.35 px) of its
    centre: the circle hugs the limb's middle, never the fan."""
    c, r = 64.0, 64.0
    sun, body, dist, wedge, axis = _sphere_and_wedge(radius, phase, sun_az, fan_turn)
    glow = np.where(wedge, fan * body.max() * radius / np.maximum(dist, radius), 0.0)
    image = gaussian_filter(1000.0 * (body + glow * (body == 0.0)), psf)
    root = (c + 1.5 * radius * math.cos(axis), r + 1.5 * radius * math.sin(axis))  # where a cut of the fan lies
    fit = lit_limb_centre(image, root, 2.0 * 1.5 * radius, radius / 1.5, radius * 1.5,
                          (math.cos(sun_az), math.sin(sun_az)))
    assert fit is not None
    cell = _LIT_PASSES[-1][1] / math.sqrt(2.0)  # a centre on the finest grid is this far from any point
    assert math.dist(fit.col_row, (c, r)) <= radius - radius / 1.5 + 1.0 + cell, (fit, (c, r))
    assert fit.score >= CFG.limb_fit_min_contrast * fit.window_median


@pytest.mark.parametrize(("seed", "k"), [(31, 214), (35, 270), (37, 243)])
def test_dimorphos_at_high_phase_is_not_the_root_of_its_fan(seed: int, k: int) -> None:
    """Dimorphos 22-29 px across at 101-118 deg of phase, a fan of ejecta rising from it, its place known to 90 px
    (too loosely for the whole limb's fit): it is reported within the paper's 15 px of its centre, where the cut of
    the fan's root beside the thin crescent lay 20-25 px off (bench frames; seeds 35 and 37 no change was tuned
    on before this one). The lit limb's circle moved that cut onto the body; since the crescent, a region of
    Dimorphos's size, is chosen before the fan (a region larger than Dimorphos can be), it is found without it too."""
    rng = np.random.default_rng([seed, k])
    scene = random_scene(rng)
    prediction = prediction_for(scene, rng, 3.0 if rng.random() < 0.5 else 30.0)
    frame = render(scene, np.random.default_rng(k))

    def error_px(cfg: ImagingConfig) -> float:
        det = process_frame(frame.pixels, cfg, bad_pixels=ground_map(scene), prediction=prediction)
        assert det.dimorphos is not None
        return math.dist(det.dimorphos.centroid_col_row, frame.truth[1].centre_512)

    assert error_px(CFG) <= PAPER_LIMIT_PX
    assert error_px(CFG.model_copy(update={"lit_limb_min_disagreement_radii": 1e9})) <= PAPER_LIMIT_PX


@pytest.mark.parametrize(("plume_brightness", "dimorphos_radiance"), [(1.0, 1.0), (0.6, 1.0), (1.5, 1.0),
                                                                      (1.0, 0.7), (1.0, 1.15)])
def test_the_lit_limb_s_circle_must_touch_the_cut_it_replaces(plume_brightness: float,
                                                              dimorphos_radiance: float) -> None:
    """Bench seed 64 frame 82 (a seed first run after the lit limb's fit was written), the plume or Dimorphos dimmer
    or brighter: Dimorphos 22 px across at 28 deg of phase, its place known to 90 px (too loosely for the whole
    limb's fit), its cut 1.5 px from its centre; the lit limb's best circle, searched about the cut, lies 35 px away
    on Didymos's limb, off the cut: the cut is kept (the circle replaced it, 29-41 px off)."""
    rng = np.random.default_rng([64, 82])
    scene = random_scene(rng)
    prediction = prediction_for(scene, rng, 3.0 if rng.random() < 0.5 else 30.0)
    scene = scaled(scene, plume_brightness, dimorphos_radiance)
    frame = render(scene, np.random.default_rng(82))
    det = process_frame(frame.pixels, CFG, bad_pixels=ground_map(scene), prediction=prediction)
    assert det.dimorphos is not None
    assert math.dist(det.dimorphos.centroid_col_row, frame.truth[1].centre_512) <= frame.truth[1].diameter_512_px / 4.0


@pytest.mark.parametrize(("seed", "k"), [(64, 82), (56, 139)])
def test_bench_frames_where_the_lit_limb_s_circle_lay_off_the_cut(seed: int, k: int) -> None:
    """Bench frames 64/82 and 56/139 (22 and 25 px Dimorphos at 28 and 83 deg of phase, its place known to 90 px, a
    cut within 2 px of its centre): the lit limb's best circle off the cut (on Didymos's limb, or on the plume) does
    not replace it (it did: 35.7 and 38.8 px off)."""
    rng = np.random.default_rng([seed, k])
    scene = random_scene(rng)
    prediction = prediction_for(scene, rng, 3.0 if rng.random() < 0.5 else 30.0)
    frame = render(scene, np.random.default_rng(k))
    det = process_frame(frame.pixels, CFG, bad_pixels=ground_map(scene), prediction=prediction)
    assert det.dimorphos is not None
    assert math.dist(det.dimorphos.centroid_col_row, frame.truth[1].centre_512) <= frame.truth[1].diameter_512_px / 4.0


def _dimorphos_over_didymos_s_limb(seed: int) -> Scene:
    """Dimorphos (28 px across at full resolution, +-15 %) in front of Didymos's lit limb, its disc 20-90 % over it,
    at 55-80 deg of phase, with a faint fan of ejecta: the pair just after Dimorphos's transit."""
    rng = np.random.default_rng([93, seed])
    sun = float(rng.uniform(-30.0, 30.0))
    did_c, did_r = 380.0 + rng.uniform(-40.0, 40.0), 536.0 + rng.uniform(-40.0, 40.0)
    big, small = 136.0 * rng.uniform(0.85, 1.15), 28.0 * rng.uniform(0.85, 1.15)
    a = math.radians(sun + rng.uniform(-60.0, 60.0))  # on Didymos's lit side
    d = big + small * rng.uniform(0.2, 0.9)
    q = (0.0, 0.0, 0.0, 1.0)
    return Scene(
        bodies=(Ellipsoid(did_c, did_r, 126.0e3, (big, 0.9 * big, 0.8 * big), q, 2400.0, law="lambert"),
                Ellipsoid(did_c + d * math.cos(a), did_r + d * math.sin(a), 125.0e3,
                          (small, 0.95 * small, 0.8 * small), q, 2400.0, law="lambert")),
        range_m=125.0e3, phase_deg=float(rng.uniform(55.0, 80.0)), sun_azimuth_deg=sun,
        plume=Plume(axis_deg=math.degrees(a) + rng.uniform(-40.0, 40.0), half_angle_deg=30.0, length_px=200.0,
                    brightness_dn=float(rng.uniform(100.0, 500.0)), exponent=0.5, inner_radii=1.5))


@pytest.mark.parametrize("seed", range(24))
def test_the_lit_limb_s_circle_is_not_didymos_s_own_limb(seed: int) -> None:
    """Dimorphos in front of Didymos's lit limb, its place known to 90 px (the lit limb's fit): every Dimorphos
    reported is itself, within the paper's 15 px of its centre; the lit limb's circle is never one centred inside
    Didymos (the circle of Didymos's limb beside the cut was taken on 2 of these 24 frames, 18 and 24 px off, and on
    4 of 48; in closed loop, star-tracker-outage at C/A+3 s, 26 px)."""
    scene = _dimorphos_over_didymos_s_limb(seed)
    t = run_trial(scene, seed, prediction_for(scene, np.random.default_rng([94, seed]), 30.0))
    if t.detections.dimorphos is not None:
        assert t.dimorphos.truth_index == 1
        assert t.dimorphos.error_px is not None and t.dimorphos.error_px <= PAPER_LIMIT_PX


def _crescent_beside_its_fan(radius: float, phase: float, sun_az: float, fan_turn: float, lit: float,
                             seed: int) -> tuple[np.ndarray, FramePrediction, Blob, tuple[float, float]]:
    """A 128 px binned image: a Lambert sphere of ``radius`` px at ``phase`` deg (its best-lit point ``lit`` times
    1000 DN) with a 30 deg wedge of ejecta rising from its limb, 400 DN at its root fading as 1 / distance, over a
    20 DN background with 3 DN of noise; the prediction (place 1 px off the centre, known to 3 px) and a cut of the
    fan's root as the chain would report it; and the body's centre."""
    c, r = 64.0, 64.0
    sun, body, dist, wedge, axis = _sphere_and_wedge(radius, phase, sun_az, fan_turn)
    glow = np.where(wedge, 400.0 * radius / np.maximum(dist, radius), 0.0)
    image = gaussian_filter(1000.0 * lit * body / max(float(body.max()), 1e-12) + glow * (body == 0.0), 0.8)
    image = 20.0 + image + np.random.default_rng(seed).normal(0.0, 3.0, image.shape)
    root = (c + 1.6 * radius * math.cos(axis), r + 1.6 * radius * math.sin(axis))
    prediction = FramePrediction(sun_camera=(float(sun[0]), float(sun[1]), float(sun[2])),
                                 dimorphos_radius_px=radius, radius_factor_max=1.2, dimorphos_col_row=(c + 1.0, r),
                                 dimorphos_uncertainty_px=3.0)
    box = (int(root[0]) - 4, int(root[1]) - 4, 9, 9)
    cut = Blob(label=2, area_px=50, centroid_col_row=root, bbox_col_row_w_h=box, mean_dn8=200.0, peak_dn8=255,
               elongation=1.2, threshold_dn8=60, region_centroid_col_row=root, trimmed_from=1)
    return image, prediction, cut, (c, r)


@settings(max_examples=20, deadline=None)
@given(radius=st.floats(10.0, 16.0), phase=st.floats(130.0, 165.0), sun_az=st.floats(0.0, 2.0 * math.pi),
       fan_turn=st.floats(math.radians(90.0), math.radians(270.0)), seed=st.integers(0, 2**16))
def test_the_root_of_the_ejecta_beside_an_unseen_crescent_is_not_reported(radius: float, phase: float, sun_az: float,
                                                                          fan_turn: float, seed: int) -> None:
    """A sphere of 10-16 px radius at 130-165 deg of phase whose crescent is too faint to see (its best-lit point 1 %
    of the fan's root), its fan rising 90-270 deg from the Sun, a cut of the fan's root 1.6 radii from its centre: no
    lit limb steps about the predicted place, and the cut is not reported as Dimorphos (it was: bench/envelope.py's
    roll-180 row, 19-22 px off); the same cut beside the crescent lit 1000 DN is reported (the lit limb is there to be
    found). Below 10 px (the rule runs from 7.2 px here) 4 of 300 such frames kept the cut, 14.5-15.6 px off: the fit
    about the place, confined to its uncertainty, found a 4.5-times step at the fan's root."""
    image, prediction, cut, _ = _crescent_beside_its_fan(radius, phase, sun_az, fan_turn, 0.004, seed)
    refused, samples = limb_corrected(cut, image, prediction, CFG, 2.9)
    assert refused is None and samples > 0
    kept, _ = limb_corrected(cut, image, prediction, CFG.model_copy(update={"unlit_cut_refused": False}), 2.9)
    assert kept is not None  # the rule, not another one, refuses it
    image, prediction, cut, _ = _crescent_beside_its_fan(radius, phase, sun_az, fan_turn, 1.0, seed)
    seen, _ = limb_corrected(cut, image, prediction, CFG, 2.9)
    assert seen is not None


@settings(max_examples=20, deadline=None)
@given(radius=st.floats(11.0, 16.0), phase=st.floats(35.0, 85.0), sun_az=st.floats(0.0, 2.0 * math.pi),
       fan_turn=st.floats(math.radians(90.0), math.radians(270.0)), seed=st.integers(0, 2**16))
def test_the_root_of_the_ejecta_beside_an_eclipsed_body_is_not_reported(radius: float, phase: float, sun_az: float,
                                                                         fan_turn: float, seed: int) -> None:
    """Below 90 deg of phase, where the whole limb is fitted: a sphere of 11-16 px radius in Didymos's shadow (its best-lit point 1 % of
    its fan's root), a cut of the fan's root 1.6 radii out: neither its limb nor a lit limb steps about the place, and
    the cut is not reported (worst-late-near's envelope, roll 0 phase 270: Dimorphos eclipsed at C/A beside the
    plume's edge, reported 18.6 px off); the same cut beside the sphere lit is reported. Measured edge: at 10 px radius
    and 30-35 deg, the fan 90 deg from the Sun, the lit limb's circle about the place, at its search square's corner,
    stepped 4.1 times on the fan's root and the cut was kept (0 of 1,500 random frames of 10-16 px)."""
    image, prediction, cut, _ = _crescent_beside_its_fan(radius, phase, sun_az, fan_turn, 0.004, seed)
    refused, samples = limb_corrected(cut, image, prediction, CFG, 2.9)
    assert refused is None and samples > 0
    kept, _ = limb_corrected(cut, image, prediction, CFG.model_copy(update={"unlit_cut_refused": False}), 2.9)
    assert kept is not None
    image, prediction, cut, _ = _crescent_beside_its_fan(radius, phase, sun_az, fan_turn, 1.0, seed)
    seen, _ = limb_corrected(cut, image, prediction, CFG, 2.9)
    assert seen is not None
