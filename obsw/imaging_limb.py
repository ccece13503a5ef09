"""Dimorphos's centre from its limb, when it is cut out of a region it shares with Didymos or the plume (beyond the
paper).

Near C/A Dimorphos can pass in front of Didymos's limb with the plume's core behind it. Didymos's surface and the
plume's core are then as bright as Dimorphos, the binarised region holds all three, and whatever part of it the chain
cuts out by brightness (``imaging_identification.trimmed``) may hold Didymos's limb or the plume's core: in the Monte
Carlo runs such a cut's centroid lay 12-18 px from Dimorphos's centre, above the paper's 15 px limit. Its outline
still shows where it is: a body in front of everything draws a step of brightness all round its limb, whatever lies
behind it, brighter or darker.

``limb_centre`` finds the circle, centred about the predicted place and of a radius the prediction allows, along
which the image's brightness steps most: the median over the circle of the radial derivative's magnitude (the
median, so that the step must run round most of the circle: an arc of Didymos's limb or the edge of the plume does
not make one). A coarse pass on a 1 px grid, then a fine one on a quarter-pixel grid around the best circle
(``_PASSES``). The circle's centre is the body's centre, taken as it is: the check runs on cuts of a region the body
shares with Didymos or the plume, and a body in front of them steps against that brighter background on its dark
side too (moved back by the phase correction of a lit crescent's centroid, ``imaging_geometry.phase_offset_px``, it
lay up to 7.1 px off on the transit frames of the tests, 2.3 px without, and 6.8 px off in run 196 of the nominal
campaign). Against the dark sky a circle can sit inside the crescent, its dark half on the terminator: 5.3 px off in
the worst-early-far flyby at 86 deg of phase.

``limb_corrected`` takes the circle's centre only where the cut's centroid disagrees with it by more than half a
radius, or lies off the predicted place while the circle is on it: for a cut of the surface alone the centroid is the
better of the two (the circle sits up to a third of a radius off a body that is not a sphere), and it lies where the
place is. Where both lie off the place, the circle is taken when nearer it, off it by no more than the place's
allowance and its own error (``limb_fit_circle_error_radii``): held-out run 272 of worst-late-near, a cut of the jet's
root above the body 12.1 px off the place and 13.95 px off the centre, the circle 6.4 px off the place, 3.3 px off the
centre.

Where the whole limb is not fitted, beyond that phase or with a place known too loosely to search about it (the
prediction before the trajectory is recognised), ``lit_limb_centre`` fits the lit half of the limb alone: the circle
whose half towards the Sun steps down outward most (the median of minus the radial derivative). However thin a
crescent, its lit limb is a sharp step from the surface to what lies beyond, the terminator on its other side steps
the other way, and a fan of ejecta rising from the body fades smoothly: at 101-118 deg of phase, where a cut of the
fan's bright root beside the crescent lay 20-25 px off Dimorphos's centre (bench/imaging.py seeds 31, 35 and 37),
the circle's centre lies 4-7 px off. It is searched about the cut and taken only where it is more than
``lit_limb_min_disagreement_radii`` off it (a circle smaller than the body hugs the middle of its lit limb, sunward
of its centre) and the body's largest disc about it touches the cut (a circle off the cut hugs another limb: bench
seed 64 frame 82, Didymos's, 35 px from a cut 1.5 px off Dimorphos's centre).

Where the cut lies off the place, its limb (the whole limb below limb_fit_max_phase_deg, the lit limb beyond) is not
found on the place, and no lit limb steps about the place either, the cut is not Dimorphos and is refused
(``ImagingConfig.unlit_cut_refused``): beyond 130 deg of phase a crescent can be too thin to see, and the bright root
of the ejecta just beyond its dark disc is then the brightest cut near the place (bench/envelope.py's roll-180 row:
19-22 px off; configs/scenarios/night-side-pass.yaml); an eclipsed Dimorphos leaves the plume's edge beside it
(worst-late-near's envelope, roll 0 phase 270: 18.6 px off).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numba import njit

from obsw.config import ImagingConfig
from obsw.imaging_geometry import FramePrediction, focal_length_px, phase_angle_deg, phase_offset_px
from obsw.imaging_identification import Blob, box_distance, psf_reach_px


@dataclass(frozen=True, slots=True)
class LimbFit:
    """The circle along which the brightness steps most: centre (col, row) and radius, px of the image searched; its
    score (median radial step along it, image units per px) against the median step over the search window."""

    col_row: tuple[float, float]
    radius_px: float
    score: float
    window_median: float
    samples: int  # gradient samples taken, the fit's cost (obsw.timing)


# the search's passes: (half-width of the grid around the best circle so far, px, or None for the whole search;
# grid step, px; samples per circle): the fine pass covers the coarse one's step around its best circle
_PASSES: tuple[tuple[float | None, float, int], ...] = ((None, 1.0, 48), (1.0, 0.25, 48))
# the lit limb's: coarser first (its search spans the body's size about a cut, not a precise place), 24 samples on
# the half of the circle within _LIT_ARC_HALF_DEG of the Sun's direction (its ends, the horns, fade)
_LIT_PASSES: tuple[tuple[float | None, float, int], ...] = ((None, 2.0, 24), (2.0, 0.5, 24))
_LIT_ARC_HALF_DEG = 80.0


@njit(cache=True, nogil=True, inline="always")
def _sample(gx: np.ndarray, gy: np.ndarray, x: float, y: float, c: float, s: float, inward: bool) -> float:
    """|radial derivative| (bilinear samples of gx, gy) at (x, y) along the direction (c, s), or with ``inward`` the
    step down outward (minus the radial derivative); 0 (no step) outside the arrays."""
    h, w = gx.shape
    x0 = int(math.floor(x))
    y0 = int(math.floor(y))
    if x0 < 0 or y0 < 0 or x0 + 1 >= w or y0 + 1 >= h:
        return 0.0
    fx = x - x0
    fy = y - y0
    w00 = (1 - fx) * (1 - fy)
    w01 = fx * (1 - fy)
    w10 = (1 - fx) * fy
    w11 = fx * fy
    vx = w00 * gx[y0, x0] + w01 * gx[y0, x0 + 1] + w10 * gx[y0 + 1, x0] + w11 * gx[y0 + 1, x0 + 1]
    vy = w00 * gy[y0, x0] + w01 * gy[y0, x0 + 1] + w10 * gy[y0 + 1, x0] + w11 * gy[y0 + 1, x0 + 1]
    radial = vx * c + vy * s
    return -radial if inward else abs(radial)


@njit(cache=True, nogil=True)
def _best_circle(gx: np.ndarray, gy: np.ndarray, cols: np.ndarray, rows: np.ndarray, radii: np.ndarray,
                 cos_a: np.ndarray, sin_a: np.ndarray, inward: bool) -> tuple[int, int, int, float]:
    """Indices (i, j, k) of the circle centred at (cols[i], rows[j]) of radius radii[k] whose score, the median of
    ``_sample`` over its points at the angles (cos_a, sin_a), is the largest (the first in i, j, k order on a tie,
    as ``np.argmax`` of the scores), and that score.

    The same result as scoring every circle (the gradients finite), for less: the middle centre's circles are
    scored first, and a circle is dropped as soon as more than half its samples lie below the best score so far (its
    median cannot reach it: the upper middle sample is below, and the median is at most that).
    """
    n = cos_a.size
    buf = np.empty(n)
    prune_at = n // 2 + 1  # samples below the best that put the upper middle sample below it
    best, bi, bj, bk = -np.inf, -1, -1, -1
    seed_i, seed_j = cols.size // 2, rows.size // 2
    for p in range(-1, cols.size * rows.size):
        if p < 0:  # the seeding pass: the middle centre, every radius
            i, j = seed_i, seed_j
        else:
            i, j = p // rows.size, p % rows.size
            if i == seed_i and j == seed_j:
                continue
        for k in range(radii.size):
            below = 0
            for a in range(n):
                v = _sample(gx, gy, cols[i] + radii[k] * cos_a[a], rows[j] + radii[k] * sin_a[a], cos_a[a], sin_a[a],
                            inward)
                buf[a] = v
                if v < best:
                    below += 1
                    if below >= prune_at:
                        break
            if below >= prune_at:
                continue
            m = np.median(buf)
            if m > best or (m == best and (i, j, k) < (bi, bj, bk)):
                best, bi, bj, bk = m, i, j, k
    return bi, bj, bk, best


def _best(gx: np.ndarray, gy: np.ndarray, cols: np.ndarray, rows: np.ndarray, radii: np.ndarray, ang: np.ndarray,
          inward: bool) -> tuple[float, float, float, float]:
    """The best circle of the grid (centre col, row, radius) and its score, sampled at the angles ``ang``."""
    i, j, k, score = _best_circle(gx, gy, cols, rows, radii, np.cos(ang), np.sin(ang), inward)
    return float(cols[i]), float(rows[j]), float(radii[k]), float(score)


def warm_up() -> None:
    """Compile (or load from the cache) the circle scores now, for the image types the chain gives."""
    g = np.zeros((4, 4))
    one = np.zeros(1)
    _best_circle(g, g, one, one, one + 1.0, one + 1.0, one, False)


def limb_centre(image: np.ndarray, place_col_row: tuple[float, float], search_px: float, radius_min_px: float,
                radius_max_px: float) -> LimbFit | None:
    """The circle of radius in [radius_min_px, radius_max_px], centred in the square of half-width ``search_px``
    about ``place_col_row``, along which ``image`` (2-D, any numeric type) steps most (module docstring); None when
    the search window leaves the image or holds non-finite values, or the radii are not positive and ordered."""
    return _fit(image, place_col_row, search_px, radius_min_px, radius_max_px, _PASSES,
                lambda n: np.linspace(0.0, 2.0 * np.pi, n, endpoint=False), inward=False)


def lit_limb_centre(image: np.ndarray, near_col_row: tuple[float, float], search_px: float, radius_min_px: float,
                    radius_max_px: float, sun_col_row: tuple[float, float]) -> LimbFit | None:
    """The circle of radius in [radius_min_px, radius_max_px], centred in the square of half-width ``search_px``
    about ``near_col_row``, whose half towards the Sun's direction in the image ``sun_col_row`` (not nil) steps
    down outward most: the lit limb, a sharp step from the surface to what lies beyond, however thin the crescent
    (module docstring); None as for ``limb_centre``."""
    if not math.hypot(*sun_col_row) > 0.0:
        return None
    towards = math.atan2(sun_col_row[1], sun_col_row[0])
    return _fit(image, near_col_row, search_px, radius_min_px, radius_max_px, _LIT_PASSES,
                lambda n: towards + np.radians(np.linspace(-_LIT_ARC_HALF_DEG, _LIT_ARC_HALF_DEG, n)), inward=True)


def _fit(image: np.ndarray, centre_col_row: tuple[float, float], search_px: float, radius_min_px: float,
         radius_max_px: float, passes: tuple[tuple[float | None, float, int], ...], angles: Callable[[int], np.ndarray],
         inward: bool) -> LimbFit | None:
    """The best circle of the grid search ``passes`` (``_PASSES``) about ``centre_col_row``, sampled at
    ``angles(n)`` (``_best_circle``); None when the search window leaves the image or holds non-finite values, or the
    radii are not positive and ordered."""
    if not (0.0 < radius_min_px <= radius_max_px and search_px >= 0.0):
        return None
    if not all(math.isfinite(v) for v in (*centre_col_row, search_px, radius_min_px, radius_max_px)):
        return None
    h, w = image.shape
    reach = search_px + radius_max_px + 2.0
    left, top = int(math.floor(centre_col_row[0] - reach)), int(math.floor(centre_col_row[1] - reach))
    right, bottom = int(math.ceil(centre_col_row[0] + reach)) + 1, int(math.ceil(centre_col_row[1] + reach)) + 1
    left, top, right, bottom = max(left, 0), max(top, 0), min(right, w), min(bottom, h)
    if right - left < 3 or bottom - top < 3:
        return None
    crop = np.asarray(image[top:bottom, left:right], dtype=np.float64)
    if not np.isfinite(crop).all():  # a float image's NaN or infinity has no step to measure
        return None
    gy, gx = np.gradient(crop)
    c, r = centre_col_row[0] - left, centre_col_row[1] - top
    _, first_step, _ = passes[0]
    span = first_step * math.ceil(search_px / first_step)
    offsets = np.arange(-span, span + 1e-9, first_step)
    radii = np.arange(radius_min_px, radius_max_px + first_step - 1e-9, first_step)
    count = 0
    for half, step, n_samples in passes:
        if half is not None:  # a finer grid around the best circle so far
            offsets = np.arange(-half, half + 1e-9, step)
            radii = np.unique(np.clip(rad + offsets, radius_min_px, radius_max_px))
        c, r, rad, score = _best(gx, gy, c + offsets, r + offsets, np.minimum(radii, radius_max_px),
                                 angles(n_samples), inward)
        count += offsets.size ** 2 * radii.size * n_samples
    window = float(np.median(np.hypot(gx, gy)))
    return LimbFit(col_row=(c + left, r + top), radius_px=rad, score=score, window_median=window, samples=count)


def limb_corrected(blob: Blob | None, image: np.ndarray, prediction: FramePrediction | None, cfg: ImagingConfig,
                   fov_deg: float, didymos: Blob | None = None) -> tuple[Blob | None, int]:
    """Dimorphos's blob (its centroid already phase-corrected) with its centroid moved to the centre of its fitted
    limb (``limb_centre``) when the two disagree by more than
    ``limb_fit_max_disagreement_radii`` of its predicted radius: a cut that holds the body's surface alone lies
    nearer its centre than that, one that holds Didymos's limb or the plume's core does not. Fitted only when the
    blob was cut out of a larger region (``trimmed_from``), the prediction gives its place (within
    ``limb_fit_max_search_px`` with the margins) and size, it is resolved
    (``limb_fit_min_radius_px``), lit at a low enough phase (``limb_fit_max_phase_deg``), and the limb found steps
    clearly (``limb_fit_min_contrast``) and gives a centre within the prediction's uncertainty and the centroid noise
    of its place; the circle's centre also replaces a centroid nearer than that when the centroid is off the place by
    more than the same allowance, and a centroid off the place by more than a circle that is off it by no more than
    the allowance and ``limb_fit_circle_error_radii`` predicted radii (the circle's own error); beyond that phase or search, the lit limb's circle (``_lit_limb_corrected``); None
    for a cut off the place with no limb on it where no lit limb steps about the place either (``_unless_unlit``);
    the blob unchanged otherwise (``didymos``, the blob reported as Didymos, rules out a lit limb inside it). With it,
    the gradient samples the fit took (0 when not fitted), its cost on the FPGA (``obsw.timing``)."""
    if blob is None or not blob.trimmed_from or not cfg.limb_fit or prediction is None \
            or prediction.dimorphos_col_row is None or prediction.dimorphos_radius_px is None \
            or prediction.dimorphos_uncertainty_px is None or not math.isfinite(prediction.dimorphos_uncertainty_px):
        return blob, 0
    k = max(prediction.radius_factor_max, 1.0)
    r_min, r_max = prediction.dimorphos_radius_px / k, prediction.dimorphos_radius_px * k
    if r_min < cfg.limb_fit_min_radius_px:
        return blob, 0
    n = cfg.binned_size_px
    place = prediction.dimorphos_col_row
    allowed = prediction.dimorphos_uncertainty_px + cfg.centroid_noise_px
    search = allowed + focal_length_px(fov_deg, n) * math.tan(math.radians(cfg.limb_fit_pointing_margin_deg))
    if phase_angle_deg(prediction.sun_camera, place, fov_deg, n) > cfg.limb_fit_max_phase_deg \
            or search > cfg.limb_fit_max_search_px:
        return _lit_limb_corrected(blob, image, prediction, cfg, fov_deg, (r_min, r_max), allowed, didymos)
    fit = limb_centre(image, place, search, r_min, r_max)
    if fit is None:
        return blob, 0
    centre = fit.col_row  # the body's own: its outline steps all round (module docstring), no phase correction
    # it must be where the prediction puts Dimorphos: a circle near the cut but off the place is another body's limb
    # or the plume's edge (the nominal flyby at C/A+3 s: 12.6 px from a place known to 5.2 px, 13 px off)
    clear = fit.score >= cfg.limb_fit_min_contrast * fit.window_median
    off = math.dist(centre, place)
    if clear and allowed < off <= allowed + cfg.limb_fit_circle_error_radii * prediction.dimorphos_radius_px \
            and off < math.dist(blob.centroid_col_row, place):
        # the cut off the place too, and farther: the circle's own error (the body not a sphere) may put it beyond
        # the place's allowance, a cut of the plume's root beside the body lies a radius off
        return blob._replace(centroid_col_row=centre), fit.samples
    if not clear or off > allowed:
        # no limb at the place (an eclipsed Dimorphos beside the plume's edge: worst-late-near's envelope, roll 0
        # phase 270, 18.6 px off)
        sun = phase_offset_px(prediction.sun_camera, place, 1.0, fov_deg, n)
        return _unless_unlit(blob, image, prediction, cfg, (r_min, r_max), allowed, sun, fit.samples)
    # a cut off the place while the circle is on it holds more than the body, however near the two are (run 881 of
    # the nominal campaign: the cut 7.5 px from a place known to 4 px, 11.1 px off; the circle 2 px from it)
    near = cfg.limb_fit_max_disagreement_radii * prediction.dimorphos_radius_px
    if math.dist(centre, blob.centroid_col_row) <= near and math.dist(blob.centroid_col_row, place) <= allowed:
        return blob, fit.samples
    return blob._replace(centroid_col_row=centre), fit.samples


def _lit_limb_corrected(blob: Blob, image: np.ndarray, prediction: FramePrediction, cfg: ImagingConfig,
                        fov_deg: float, radii: tuple[float, float], allowed: float,
                        didymos: Blob | None = None) -> tuple[Blob | None, int]:
    """``limb_corrected`` where the whole limb is not fitted (a phase beyond ``limb_fit_max_phase_deg``, or a place
    too loose to search): the centre of the lit limb (``lit_limb_centre``) of a radius within ``radii``, searched
    within twice the largest about the cut, replaces the cut's centroid when it steps clearly, lies within
    ``allowed`` of the place, is more than ``lit_limb_min_disagreement_radii`` predicted radii off the cut, and
    touches the cut (the largest disc about its centre within the point-spread function's reach of the cut's box:
    the cut holds a part of the body or of a fan rising from its limb; a circle off it hugs another body's limb,
    bench seed 64 frame 82), and is not centred inside Didymos (within the disc of its region's area about its
    region's centroid: the lit limb of Didymos's own disc beside a Dimorphos cut in front of it touches the cut,
    star-tracker-outage at C/A+3 s, 26 px off); with the samples the fit took."""
    assert prediction.dimorphos_col_row is not None and prediction.dimorphos_radius_px is not None
    r_min, r_max = radii
    # only the direction of the lit centroid's offset counts: the Sun's in the image
    sun = phase_offset_px(prediction.sun_camera, blob.region_centroid_col_row, 1.0, fov_deg, cfg.binned_size_px)
    fit = lit_limb_centre(image, blob.region_centroid_col_row, 2.0 * r_max, r_min, r_max, sun)
    if fit is None:
        return blob, 0
    if fit.score < cfg.limb_fit_min_contrast * fit.window_median \
            or math.dist(fit.col_row, prediction.dimorphos_col_row) > allowed \
            or math.dist(fit.col_row, blob.centroid_col_row) <= cfg.lit_limb_min_disagreement_radii \
            * prediction.dimorphos_radius_px \
            or box_distance(blob, fit.col_row) > r_max + psf_reach_px(cfg) \
            or didymos is not None and math.dist(fit.col_row, didymos.region_centroid_col_row) \
            < math.sqrt(didymos.area_px / math.pi):
        return _unless_unlit(blob, image, prediction, cfg, radii, allowed, sun, fit.samples)
    return blob._replace(centroid_col_row=fit.col_row), fit.samples


def _unless_unlit(blob: Blob, image: np.ndarray, prediction: FramePrediction, cfg: ImagingConfig,
                  radii: tuple[float, float], allowed: float, sun: tuple[float, float],
                  samples: int) -> tuple[Blob | None, int]:
    """A cut whose limb was not found on the place: None (not Dimorphos) when it lies off the place (by more than
    ``allowed``) and no lit limb steps clearly about the place either (``ImagingConfig.unlit_cut_refused``): a
    crescent too thin to see beside the ejecta's bright root leaves the root as the brightest cut; the cut
    otherwise. With the samples the fits took (``samples``, those before, included)."""
    assert prediction.dimorphos_col_row is not None
    if not cfg.unlit_cut_refused or math.dist(blob.centroid_col_row, prediction.dimorphos_col_row) <= allowed:
        return blob, samples
    at_place = lit_limb_centre(image, prediction.dimorphos_col_row, allowed, radii[0], radii[1], sun)
    if at_place is None:
        return blob, samples
    samples += at_place.samples
    if at_place.score < cfg.limb_fit_min_contrast * at_place.window_median:
        return None, samples
    return blob, samples
