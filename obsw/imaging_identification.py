"""Step 4 of the imaging chain, feature extraction and identification: which blobs are Didymos and Dimorphos.

Every blob (8-connected region of the binarised image) gets its area, binary (region) centroid, bounding box,
elongation and 8-bit brightness. A body candidate has at least ``min_body_area_px`` pixels (a hot pixel or a
cosmic-ray hit that escaped the filter is one pixel) and at most ``max_body_elongation`` (a plume ray or a smeared
star is longer). Identification uses area, shape and continuity, never a blob's peak pixel alone:

- **Expected sizes.** With a trajectory on board, the frame's prediction (``imaging_geometry.FramePrediction``)
  gives each body's expected area, pi r^2 times the lit fraction (1 + cos g) / 2 of its disc at phase angle g (the
  lit surface itself: the blur only adds faint pixels around it), and its largest region, the same with the radius
  k r + blur + 1 (k the largest radius factor: shape and range uncertainty; blur ``blur_margin_px``; one pixel of
  digitisation).
- **Didymos** is the candidate holding the most light in Didymos's expected area (``aperture_dn8``: its brightest
  pixels of that number above the threshold), among those within the orbit's reach of Dimorphos's predicted place;
  when Didymos must be resolved (its smallest radius at least twice ``point_source_sigma_max_px``), not a point
  source (``light_spread_px2``: a star brighter than a small Didymos) nor a blend of them (a close double star,
  ``_blend_of_point_sources``), none when every candidate is one (Didymos unseen: probability 0), and, when the
  candidate chosen holds Dimorphos's predicted place with more than both bodies' expected areas, another extended
  candidate off the place within the orbit's reach of the place and of that candidate, of Didymos's size and with at
  least half its light (``_beside_ejecta``: ejecta leave Dimorphos, so a fan of them brighter than a crescent at
  high phase holds the place, and Didymos is within the orbit's radius of the Dimorphos the fan holds); when Didymos
  may be partly out of the image, an extended candidate at the border with fewer pixels than its expected area,
  brighter over as many pixels as it shows (``_cut_by_the_edge``: beyond the border its pixels are unseen, not
  dark). When it need not be, shape cannot tell it from a star: with Dimorphos's place known, the candidate of most
  light times the Gaussian likelihood of its distance from the place beyond the orbit's radius
  (``_point_likelihood``), extended candidates first when Didymos may be resolved (a star never is, nor a close
  pair of them); without a prediction, the largest. When the blob so chosen is a point source, that choice comes
  with its probability (``Identification.didymos_probability``): its odds against being a star (the place's density
  over that of the frame's stars, its other point sources, ``_StarField``) over the sum of the point sources' odds
  and of the odds that Didymos is none of them, undetected or merged (``unresolved_body_detected_prior``): the
  imaging chain does not report a Didymos under ``didymos_min_report_probability``, as likely a star. With a pair
  seen in earlier frames, it is the candidate that has a companion where the pair's relative offset predicts
  Dimorphos, among those holding at least half the light of the best (near C/A, hundreds of noise clumps at the edge
  of a fan of dust always hold some pair at that offset), and a Dimorphos-sized blob (no larger than Dimorphos can
  be) that continues Dimorphos while that offset puts Didymos off the image is Dimorphos alone (near C/A). With
  none such (Dimorphos merged with its fan, no candidate of its own), it is an extended candidate where that offset
  puts Didymos from Dimorphos's place, when the place is known to less than the orbit's radius (``_anchored``). When
  Didymos may be off the image (the orbit's reach from Dimorphos's place crosses the edge) and the candidate chosen
  is where the trajectory puts Dimorphos with a lit surface (``surface_pixels``: the dust around it is fainter) under
  the geometric mean of the two bodies' expected areas, it is Dimorphos, cut to its surface, and Didymos is not seen;
  another candidate there, whole in the image, with a brighter surface is Dimorphos instead
  (``_brightest_surface_at``: a plume seen past a crescent's dark limb is a region of its own).
- **Ejecta merged with a body.** A blob larger than both bodies together can be holds the ejecta plume: it is
  trimmed to its brightest pixels of the expected area of both bodies, the 8-connected parts of which take its
  place, those within Didymos's reach of Dimorphos's place only (``_near_place``: a star in the plume's region
  beyond it holds its brightest pixels; none there, the blob stays whole); a blob with room for both is split the
  same way when a part of it is Dimorphos (no larger than Dimorphos can be, or larger, holding ejecta, at the
  trajectory's place when that place is closer than the orbit's radius). When the part chosen breaks a remembered
  pair, the blob's deblended objects take the parts' place if one of them continues it (``_paired_object``: a
  fan's root brighter than Didymos's surface holds all of the brightest pixels; Didymos has a peak of its own).
  The blob taken for Dimorphos, when larger than Dimorphos can be or than the disc of its predicted radius widened
  by the point-spread function's reach (``psf_reach_px``: a small body's light stays within it, ejecta do not), is
  trimmed to its brightest pixels of
  Dimorphos's expected area, and of their parts the brightest by mean among those of at least a quarter of that
  area (``trimmed``): the ejecta leave Dimorphos and fade away from it, and a star in the dust holds a few pixels.
  With its place known, a smaller part competes too where the lit part's centroid is expected (within the place's
  uncertainty, the centroid noise and the phase correction's error, ``_lit_agrees``), when it is no point source: at
  high phase the plume's core beside a thin crescent holds most of the brightest pixels. When no part lies there, at
  phases where the limb is not fitted (``limb_fit_max_phase_deg``), the brightest half of the pixels is cut again,
  and so on, until a part does (``_lit_part_above``): a core as bright as the crescent merges with it at the
  expected area's level and parts from it at a higher one.
  When no candidate is Dimorphos and the trajectory puts it well within the orbit's radius (its uncertainty
  radius under half the orbit's), the part of Didymos's region within that radius of the place (``Regions.within``),
  trimmed the same way, is Dimorphos when it is off Didymos's disc: ejecta brighter than its surface merged them.
  When still none is and Didymos was cut out of a larger region, or its own region, resolved, has room for both
  bodies, that region is deblended (``Regions.deblended``, SExtractor's multi-threshold deblending: at
  ``deblend_levels`` levels from the threshold to the peak, the parts that split from one another, each holding at
  least ``deblend_min_flux_fraction`` of the region's light), and its objects no smaller than Dimorphos can be nor
  larger (a larger one, both bodies resolved, by its brightest pixels of Dimorphos's expected area: a small
  Dimorphos parts with its plume's root around it), off Didymos's disc (for a larger one, other than the object
  holding most of Didymos, the disc of Didymos without it: Dimorphos merged with Didymos pulls its centroid over)
  and where its lit part is expected, are candidates among the others (``_deblended_dimorphos``): Dimorphos joined
  to Didymos by the plume or the blur below every level the cuts tried keeps its own peak. An object's own peak is no
  cut beside the body: its limb is not sought (``Identification.dimorphos_deblended``); the brightest part of a larger
  one is such a cut, and its limb is sought as for any other. When Didymos's region, whole or cut, held it, Didymos
  is that region without the object Dimorphos came from (``Without``): continuity measures the next frame's pair
  from it.
  A Didymos's region (of a disc whose blurred limb is under a quarter of it) with room for both bodies, most of whose pixels are
  fainter than halfway from the threshold to its surface's typical level (``_surface``), is cut to its pixels above
  that level, the largest part being Didymos and the others candidates: a lit surface is mostly that bright, a fan
  of dust mostly not. A Didymos's region still larger than both bodies' expected areas is cut to its pixels whose
  raw signal is at least ``dust_cut_fraction`` of its surface's (``_without_dust``), the cut kept only when it moves
  the centroid across the Sun's direction or away from the Sun: a lit body's own faint pixels (terminator, blurred
  limb) lie symmetrically about the Sun's direction, so cutting them moves it toward the Sun only; dust does not.
  The largest part is Didymos, and the others no larger than Dimorphos can be are candidates for it: Dimorphos
  merged with Didymos by the dust keeps a surface of the same albedo above the cut's level.
  No threshold is tuned on a flyby: the areas come from the known sizes and the range.
- **Dimorphos** is searched within the largest apparent radius of its orbit (plus both bodies' radii) of Didymos,
  and, when the trajectory's uncertainty allows, within that uncertainty of where the trajectory puts it (without
  a prediction: within ``dimorphos_max_separation_didymos_diameters`` of Didymos). A candidate there must be
  bright like a body (the light of its best-lit quarter of Dimorphos's expected area at least
  ``dimorphos_min_peak_fraction`` of Didymos's, times what the blur leaves of its narrower crescent's peak,
  ``_peak_kept_by_blur``; without a prediction, its peak) and not a piece of Didymos's thin
  crescent (beside its box and wholly on its disc). With its place known, only those whose centroid, as it would be
  reported (cut to its surface), agrees with it (``_lit_agrees``) when any does: a star smeared beside a crescent
  merged with the plume, or the plume's core cut out of a fan beside a crescent, lies within the body's radius of the
  place, off its lit part's expected centroid. The one continuing the last pair's relative offset wins; else the one
  holding the most light in Dimorphos's expected area, never a point source when Dimorphos must be resolved, and
  then no region larger than Dimorphos can be (dust, a fan's root brighter than a crescent) while an extended one
  of its size is a candidate; when it need not be, with its place known, the likeliest as for Didymos, at the
  place itself, among the point sources within the orbit's largest apparent radius of Didymos's phase-corrected
  centre (``_orbit_bound``: the gate's room for Didymos's whole radius is for regions it shares with ejecta),
  reported when the probability of both, Didymos's times its own given Didymos (the place's Gaussian within the
  gate), is at least ``dimorphos_min_report_probability`` (without a prediction: the largest up to
  ``dimorphos_max_area_fraction`` of Didymos).
- **Phase correction** (beyond the paper): each body's centroid is its region centroid moved from the lit part of
  its disc to its centre (``imaging_geometry.phase_offset_px``), with the predicted radius (without a trajectory,
  the radius of a disc whose lit part has the region's area).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import NamedTuple

import numpy as np
from scipy.special import chndtr

from obsw import imaging_kernels as kernels
from obsw.config import ImagingConfig
from obsw.imaging_geometry import LIT_CENTROID_FACTOR, FramePrediction, phase_offset_px
from obsw.imaging_labelling import Components, connected_components


class Without(NamedTuple):
    """A cut: the region without one of the parts of its brightest ``n_pixels`` (``Regions.parts``), the part
    holding the pixel (``col``, ``row``)."""

    n_pixels: int
    col: int
    row: int


class Blob(NamedTuple):  # a named tuple: near C/A a frame describes hundreds, at a third of a frozen dataclass's cost
    """One 8-connected region of the binarised 512x512 image (or the brightest part of one, ``trimmed_from``);
    immutable (a changed copy: ``blob._replace``)."""

    label: int  # 1-based, raster order of the region's first pixel (OpenCV numbering); trimmed parts follow
    area_px: int
    centroid_col_row: tuple[float, float]  # the body's centre: the region centroid, phase-corrected for a body
    bbox_col_row_w_h: tuple[int, int, int, int]  # left column, top row, width, height, px
    mean_dn8: float  # mean 8-bit brightness of the region's pixels
    peak_dn8: int
    elongation: float  # major/minor axis ratio from the second central moments (1 for a disc)
    threshold_dn8: int  # the region is the 8-connected set of pixels above this 8-bit value
    region_centroid_col_row: tuple[float, float]  # binary centroid of the region's pixels, px at binned scale
    trimmed_from: int = 0  # label of the region this was cut from (``cuts``; 0: a region of the binarised image)
    touches_edge: bool = False  # the region reaches the image's border (a body there may be cut)
    # the cuts that made it from its region, in order: a pixel count (its brightest pixels: ``Regions.parts``), a
    # disc (col, row, radius px: its pixels within it, ``Regions.within``) or a part taken out (``Without``)
    cuts: tuple[int | tuple[float, float, float] | Without, ...] = ()

    @property
    def diameter_px(self) -> int:
        """Largest side of the bounding box: the apparent diameter of a body, even a crescent."""
        return max(self.bbox_col_row_w_h[2], self.bbox_col_row_w_h[3])


@dataclass(frozen=True, slots=True)
class Regions:
    """The labelled foreground of a frame: its components and each foreground pixel's 8-bit value; the pixels of the
    parts cut out of blobs are kept by label."""

    components: Components
    values8: np.ndarray  # 8-bit value of each foreground pixel, in components.pixel_index order
    width: int
    threshold_dn8: int
    part_pixels: dict[int, np.ndarray] = field(default_factory=dict)  # label of a part -> its foreground positions
    # "regions": the 8-bit histograms of the regions described (``blobs``)
    histograms: dict[str, np.ndarray] = field(default_factory=dict)
    rows: list[int] = field(default_factory=list)  # each region's row in histograms["regions"] (-1: not described)
    light: dict[int, list[float]] = field(default_factory=dict)  # n -> aperture_dn8 of n px of each row
    linear8: np.ndarray | None = None  # the raw value each 8-bit code stands for (``light_spread_px2``)
    # a blob -> whether it is a blend of point sources (``_blend_of_point_sources``: a deblending, asked of one
    # Didymos candidate by each of a frame's two or three choices)
    blends: dict[Blob, bool] = field(default_factory=dict)
    spreads: dict[Blob, float] = field(default_factory=dict)  # a blob -> ``light_spread_px2``, asked ~30 times a frame
    # the foreground's positions grouped by region (each in raster order) and where each region starts, made at the
    # first ``pixels_of`` (one pass, instead of a pass over the whole foreground for each blob asked about)
    by_region: list[np.ndarray] = field(default_factory=list)

    def blobs(self, first_label: int = 1, offset_col_row: tuple[int, int] = (0, 0), trimmed_from: int = 0,
              image_size: int | None = None, cuts: tuple[int | tuple[float, float, float] | Without, ...] = (),
              min_area_px: int = 1) -> list[Blob]:
        """The Blob records of the components of at least ``min_area_px`` pixels (coordinates shifted by
        ``offset_col_row``); labels number every component."""
        c = self.components
        k = c.area_px.size
        if k == 0:
            return []
        keep = np.flatnonzero(c.area_px >= min_area_px)
        row = np.full(k, -1, dtype=np.int64)
        if first_label == 1:  # the histograms of the regions described (``aperture_dn8``)
            row[keep] = np.arange(keep.size)
        sums, peak, counts = kernels.region_values(c.pixel_component, self.values8, k, row,
                                                   keep.size if first_label == 1 else 0)
        mean = sums / c.area_px
        if first_label == 1:
            self.histograms["regions"] = counts
            self.rows[:] = row.tolist()
            self.light.clear()
        dx, dy = offset_col_row
        last = (image_size if image_size is not None else self.width) - 1
        out = []
        for i, area, cc, cr, x, y, w, h, m, p, e in zip(
                keep.tolist(), c.area_px[keep].tolist(), c.centroid_col[keep].tolist(), c.centroid_row[keep].tolist(),
                c.left[keep].tolist(), c.top[keep].tolist(), c.width[keep].tolist(), c.height[keep].tolist(),
                mean[keep].tolist(), peak[keep].tolist(), c.elongation[keep].tolist(), strict=True):
            x, y = x + dx, y + dy
            centroid = (cc + dx, cr + dy)
            # positional, in the fields' order (a keyword call costs half as much again)
            out.append(Blob(first_label + i, area, centroid, (x, y, w, h), m, p, e, self.threshold_dn8, centroid,
                            trimmed_from, x <= 0 or y <= 0 or x + w - 1 >= last or y + h - 1 >= last, cuts))
        return out

    def pixels_of(self, blob: Blob) -> np.ndarray:
        """Positions (in ``components.pixel_index`` order) of a blob's pixels."""
        part = self.part_pixels.get(blob.label)
        if part is not None:
            return part
        if not self.by_region:
            starts = np.zeros(self.components.area_px.size + 1, dtype=np.int64)
            np.cumsum(self.components.area_px, out=starts[1:])
            order = kernels.grouped_positions(self.components.pixel_component, starts)
            order.setflags(write=False)
            self.by_region.extend((order, starts))
        order, starts = self.by_region
        i = blob.label - 1
        if not 0 <= i < starts.size - 1:
            return order[:0]
        return order[starts[i]:starts[i + 1]]

    def parts(self, blob: Blob, n_pixels: int, first_label: int) -> list[Blob]:
        """The brightest part of a blob: its pixels at or above the level that leaves at least ``n_pixels`` of
        them (the n-th largest value), split into 8-connected parts, in raster order; [blob] if it is not larger."""
        n = max(int(n_pixels), 1)
        sel, level = self.brightest(blob, n)
        if level is None:
            return [blob]
        return self._cut(blob, sel, level - 1, first_label, n)

    def brightest(self, blob: Blob, n_pixels: int) -> tuple[np.ndarray, int | None]:
        """Positions of a blob's pixels at or above the level of its ``n_pixels``-th brightest (ties kept), and that
        level; all its pixels and None when it has no more than ``n_pixels``."""
        sel = self.pixels_of(blob)
        vals = self.values8[sel]
        if vals.size <= n_pixels:
            return sel, None
        level = int(np.partition(vals, vals.size - n_pixels)[vals.size - n_pixels])
        return sel[vals >= level], level

    def within(self, blob: Blob, centre_col_row: tuple[float, float], radius_px: float, first_label: int
               ) -> list[Blob]:
        """The part of a blob within ``radius_px`` of a point, split into 8-connected parts, in raster order; []
        when none of its pixels is there."""
        sel = self.pixels_of(blob)
        rows, cols = np.divmod(self.components.pixel_index[sel], self.width)
        inside = np.hypot(cols - centre_col_row[0], rows - centre_col_row[1]) <= radius_px
        if not inside.any():
            return []
        disc = (float(centre_col_row[0]), float(centre_col_row[1]), float(radius_px))
        return self._cut(blob, sel[inside], self.threshold_dn8, first_label, disc)

    def deblended(self, blob: Blob, levels: int, min_flux_fraction: float, first_label: int) -> list[Blob]:
        """The objects a blob's light holds (SExtractor's multi-threshold deblending, Bertin & Arnouts 1996): its
        pixels at each of ``levels`` 8-bit levels evenly spaced from the threshold to its peak, split into 8-connected
        parts; where two or more parts of one branch each hold at least ``min_flux_fraction`` of the blob's light
        (linear, above the threshold), each is a branch of its own. The branches that part no further, each at the
        lowest level where it stands alone (its widest outline), in raster order of their first pixel; the blob
        alone when nothing parts."""
        assert self.linear8 is not None
        sel = self.pixels_of(blob)
        vals = self.values8[sel]
        light = self.linear8[vals] - self.linear8[self.threshold_dn8]
        total = float(light.sum())
        peak = int(vals.max())
        if total <= 0.0 or peak <= self.threshold_dn8 + 1:
            return [blob]
        owner = np.full(sel.size, -1, dtype=np.int64)  # the branch holding each pixel (-1: the blob's trunk)
        branches: list[tuple[np.ndarray, int, int]] = []  # each branch's positions in ``sel``, level, pixels there
        parted: set[int] = set()  # branches that split into branches of their own
        # the blob's values on its bounding box (-1 off it) and each box pixel's index in ``sel``, made once: every
        # level is labelled on this box (raster order, and with it the parts' numbering and pixel order, is that of
        # any box holding them)
        flat, _, _, h, w = self._box(sel)
        box = np.full(h * w, -1, dtype=np.int16)
        box[flat] = vals
        box = box.reshape(h, w)
        if kernels.single_peak(box):  # no level can part it (a bright point source's image, the common case)
            return [blob]
        index_in_sel = np.full(h * w, -1, dtype=np.int64)
        index_in_sel[flat] = np.arange(sel.size)
        for level in np.unique(np.linspace(self.threshold_dn8 + 1, peak, levels).round().astype(np.int64)).tolist():
            sub = connected_components(box >= level)
            if sub.area_px.size < 2:
                continue
            members = index_in_sel[sub.pixel_index]  # each part's pixels as indices into ``sel``
            flux = np.bincount(sub.pixel_component, weights=light[members], minlength=sub.area_px.size)
            by_parent: dict[int, list[np.ndarray]] = {}
            for j in np.flatnonzero(flux >= min_flux_fraction * total).tolist():
                mine = members[sub.pixel_component == j]
                by_parent.setdefault(int(owner[mine[0]]), []).append(mine)  # a part lies in one branch below
            for parent, children in by_parent.items():
                if len(children) < 2:
                    continue
                parted.add(parent)
                for mine in children:
                    owner[mine] = len(branches)
                    branches.append((mine, level, int(members.size)))
        leaves = [b for i, b in enumerate(branches) if i not in parted]
        if not leaves:
            return [blob]
        out: list[Blob] = []
        for mine, level, n in sorted(leaves, key=lambda b: int(self.components.pixel_index[sel[b[0]]].min())):
            # recorded as ``parts`` would cut it: the brightest n pixels are those at or above its level
            first_label = self.free_label(first_label)
            out.extend(self._cut(blob, sel[mine], level - 1, first_label, n))
        return out

    def free_label(self, at_least: int) -> int:
        """The first label from ``at_least`` on past every part cut so far: a cut labelled from it takes no kept
        part's label (and with it the part's pixels)."""
        return max(at_least, max(self.part_pixels, default=0) + 1)

    def _connected(self, sel: np.ndarray, tags: np.ndarray) -> tuple[Components, np.ndarray, int, int, int]:
        """The 8-connected parts of the pixels ``sel`` (positions in ``components.pixel_index`` order), labelled on
        their bounding box: (the parts, each of their pixels' tag from ``tags``, aligned with ``sel``, the box's left
        column, top row and width)."""
        flat, left, top, h, w = self._box(sel)
        crop = np.zeros(h * w, dtype=bool)
        crop[flat] = True
        tagged = np.full(h * w, -1, dtype=np.int64)
        tagged[flat] = tags
        sub = connected_components(crop.reshape(h, w))
        return sub, tagged[sub.pixel_index], left, top, w

    def _box(self, sel: np.ndarray) -> tuple[np.ndarray, int, int, int, int]:
        """The bounding box of the pixels ``sel`` (positions in ``components.pixel_index`` order): each pixel's flat
        index in the box, the box's left column, top row, height and width."""
        rows, cols = np.divmod(self.components.pixel_index[sel], self.width)
        left, top = int(cols.min()), int(rows.min())
        h, w = int(rows.max()) - top + 1, int(cols.max()) - left + 1
        return (rows - top) * w + (cols - left), left, top, h, w

    def _cut(self, blob: Blob, sel: np.ndarray, threshold_dn8: int, first_label: int,
             cut: int | tuple[float, float, float] | Without) -> list[Blob]:
        """The 8-connected parts of the pixels ``sel`` (positions in ``components.pixel_index`` order) of a blob,
        labelled from ``first_label``, their pixels kept by label."""
        sub, flat_pos, left, top, w = self._connected(sel, sel)
        part = Regions(sub, self.values8[flat_pos], w, threshold_dn8)
        out = part.blobs(first_label, (left, top), blob.trimmed_from or blob.label, image_size=self.width,
                         cuts=blob.cuts + (cut,))
        for j, b in enumerate(out):
            self.part_pixels[b.label] = flat_pos[sub.pixel_component == j]
        return out


def _weighted_pixels(regions: Regions, blob: Blob) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A blob's pixels' light above the threshold (raw values, the 8-bit codes taken back through the compression
    table), rows and columns."""
    assert regions.linear8 is not None
    sel = regions.pixels_of(blob)
    rows, cols = np.divmod(regions.components.pixel_index[sel], regions.width)
    return regions.linear8[regions.values8[sel]] - regions.linear8[regions.threshold_dn8], rows, cols


def _light_centroid(w: np.ndarray, rows: np.ndarray, cols: np.ndarray) -> tuple[float, float, float]:
    """Pixels' total light ``w`` and its centroid: (total, column, row), the centroid nan when the total is not
    positive."""
    total = float(w.sum())
    if total <= 0.0:
        return total, math.nan, math.nan
    return total, float(w @ cols) / total, float(w @ rows) / total


def light_spread_px2(regions: Regions, blob: Blob) -> float:
    """The spread of a blob's light: the variance, mean of both axes, px^2, of its pixels' positions weighted by
    their light above the threshold (raw values, the 8-bit codes taken back through the compression table). A point
    source spreads it as the point-spread function does; a resolved disc of radius r adds r^2 / 4."""
    known = regions.spreads.get(blob)  # within a frame a blob's fields (label, cuts, area, box, values) are its pixels
    if known is not None:
        return known
    w, rows, cols = _weighted_pixels(regions, blob)
    total, mc, mr = _light_centroid(w, rows, cols)
    spread = 0.0
    if total > 0.0:
        spread = 0.5 * (float(w @ ((cols - mc) ** 2)) + float(w @ ((rows - mr) ** 2))) / total
    regions.spreads[blob] = spread
    return spread


def _must_be_resolved(radius_min_px: float, regions: Regions | None, cfg: ImagingConfig) -> bool:
    """Whether a body of at least ``radius_min_px`` is resolved, its spread at least twice a point source's: a disc's
    r^2 / 4 at least ``point_source_sigma_max_px`` squared (and the spread can be measured)."""
    return regions is not None and regions.linear8 is not None \
        and radius_min_px ** 2 / 4.0 >= cfg.point_source_sigma_max_px ** 2


def _didymos_resolved(exp: Expected, regions: Regions | None, cfg: ImagingConfig) -> bool:
    """Whether Didymos must be resolved at the smallest apparent size the prediction allows (``_must_be_resolved``)."""
    return _must_be_resolved(exp.didymos_radius / exp.radius_factor_max, regions, cfg)


def _dimorphos_resolved(exp: Expected, regions: Regions | None, cfg: ImagingConfig) -> bool:
    """Whether Dimorphos must be resolved at the smallest apparent size the prediction allows."""
    return _must_be_resolved(exp.dimorphos_radius / exp.radius_factor_max, regions, cfg)


def _dimorphos_resolved_diameter_px(exp: Expected, regions: Regions | None, cfg: ImagingConfig) -> float | None:
    """Dimorphos's largest apparent diameter when it must be resolved (``_dimorphos_resolved``), None when not."""
    return 2.0 * exp.dimorphos_radius * exp.radius_factor_max if _dimorphos_resolved(exp, regions, cfg) else None


def psf_reach_px(cfg: ImagingConfig) -> float:
    """How far from a point source its light stays above the threshold at most, px: a Gaussian of sigma s
    (``point_source_sigma_max_px``) with a peak of at most 2^16 times the threshold's level stays above it within
    s sqrt(2 ln 2^16) = 4.7 s of its centre."""
    return 4.7 * cfg.point_source_sigma_max_px


def _point_source(regions: Regions, blob: Blob, cfg: ImagingConfig) -> bool:
    """Whether a blob's light spreads no more than a point source's (``light_spread_px2``): a star. A blob wider than
    a point source's image can be (twice ``psf_reach_px``) is not one, without measuring it."""
    if blob.diameter_px > 2.0 * psf_reach_px(cfg) + 2.0:
        return False
    return light_spread_px2(regions, blob) <= cfg.point_source_sigma_max_px ** 2


def _blend_of_point_sources(regions: Regions, blob: Blob, cfg: ImagingConfig) -> bool:
    """Whether a blob no larger than two point sources' images side by side (in extent, and in area: each within
    ``psf_reach_px`` of its centre) is two or more of them blended (a close
    double star, or an unresolved Didymos with Dimorphos beside it, which shape cannot tell from one): its light
    deblends (``Regions.deblended``) into objects and, with each of its pixels given to the object whose centroid is
    nearest, the light's spread about each group's own centroid (``light_spread_px2``'s, within the groups) is no
    more than a point source's. A resolved disc split by its noise keeps the spread of its halves' widths (a disc of
    radius r, halved: r^2 / 6 and the blur's), a pair of stars that of the blur alone."""
    reach = psf_reach_px(cfg)
    if blob.diameter_px > 4.0 * reach + 2.0 or blob.area_px > 2.0 * math.pi * reach ** 2 \
            or regions.linear8 is None:
        return False
    known = regions.blends.get(blob)  # within a frame a blob's fields (label, cuts, area, box, values) are its pixels
    if known is None:
        known = regions.blends[blob] = _deblends_into_point_sources(regions, blob, cfg)
    return known


def _deblends_into_point_sources(regions: Regions, blob: Blob, cfg: ImagingConfig) -> bool:
    """``_blend_of_point_sources``'s deblending test, for a blob small enough to be a blend."""
    kept = set(regions.part_pixels)
    try:
        objects = regions.deblended(blob, cfg.deblend_levels, cfg.deblend_min_flux_fraction,
                                    regions.free_label(int(regions.components.area_px.size) + 1))
        if len(objects) < 2:
            return False
        w, rows, cols = _weighted_pixels(regions, blob)
        centres = []
        for o in objects:
            total, mc, mr = _light_centroid(*_weighted_pixels(regions, o))
            if total <= 0.0:
                return False
            centres.append((mc, mr))
        c = np.array(centres)
        group = np.argmin((cols[:, None] - c[None, :, 0]) ** 2 + (rows[:, None] - c[None, :, 1]) ** 2, axis=1)
        within = 0.0
        for g in range(len(objects)):
            m = group == g
            wg = w[m]
            total, mc, mr = _light_centroid(wg, rows[m], cols[m])
            if total <= 0.0:
                continue
            within += float(wg @ ((cols[m] - mc) ** 2 + (rows[m] - mr) ** 2))
        total = float(w.sum())
        return total > 0.0 and 0.5 * within / total <= cfg.point_source_sigma_max_px ** 2
    finally:
        for label in set(regions.part_pixels) - kept:  # a test, not a cut: the parts it made are not kept
            del regions.part_pixels[label]


def _star_like(regions: Regions, blob: Blob, cfg: ImagingConfig) -> bool:
    """Whether a blob is a point source or a blend of them (``_point_source``, ``_blend_of_point_sources``): a star
    or a close pair of stars, never a resolved body."""
    return _point_source(regions, blob, cfg) or _blend_of_point_sources(regions, blob, cfg)


def surface_pixels(regions: Regions, blob: Blob, n_pixels: int) -> int:
    """How many of a blob's pixels are at least halfway from the threshold to its surface's typical level, the
    median of its brightest ``n_pixels``: a lit surface is mostly that bright (its terminator and blurred limb are a
    thin fringe), a fan of dust around it fainter."""
    vals = regions.values8[regions.pixels_of(blob)]
    return int(kernels.surface_count(vals, min(max(1, int(n_pixels)), vals.size), regions.threshold_dn8))


def trimmed(regions: Regions, blob: Blob, n_pixels: int, first_label: int, place: _Place | None = None,
            cfg: ImagingConfig | None = None, resolved_diameter_px: float | None = None) -> Blob:
    """The body of ``n_pixels`` expected pixels in a blob that holds more: of the 8-connected parts of its brightest
    ``n_pixels``, or of its surface when that is fewer (``surface_pixels``, the level set by its best-lit quarter of
    ``n_pixels``: a body smaller than expected still sets it; dust fainter than half the surface, brighter near the
    body, does not pull the cut along it), the brightest by mean. A lit surface is brighter than the dust around it,
    though a dense fan may hold more pixels. Only parts of at least a quarter of ``n_pixels`` compete when there are
    any (a star or a speck of noise in the dust is brighter than the surface but holds a few pixels), and with the
    body's predicted ``place``, only those there when any is (ties: the larger, then raster order); with it, a smaller
    part competes too when its centroid is where the lit part's is expected (``_lit_agrees``), it can be a body
    (``min_body_area_px``) and is not a point source (at high phase the plume's core beside a thin crescent can hold
    most of its brightest pixels), and when none is, at phases where the limb is not fitted, the brightest such part
    of a higher level (``_lit_part_above``). When none is there (the brightest pixels are a star or the plume's core
    elsewhere in the region, and set the surface's level), the body is the region's part within the place's radius,
    trimmed the same way. The rules by where the lit part is expected need ``cfg`` (the body's smallest area, the
    point-spread function, the limb fit's phases); without it they are not applied. When the body must be resolved
    (``_must_be_resolved`` at its smallest predicted size; ``resolved_diameter_px`` its largest diameter), a point
    source among the competing parts farther than twice that diameter from every competing part that is not one
    does not compete: a star in the dust holding a quarter of a small body's expected area is brighter by mean than
    the body's own part, while a compact part near another may be the body's own, cut apart from the rest of it
    (within one diameter) or from the dust beside it (the extended part being dust, within another)."""
    surface = surface_pixels(regions, blob, max(1, round(n_pixels / 4)))
    parts = regions.parts(blob, min(surface, n_pixels), first_label)
    if place is not None:
        there = [p for p in parts if _distance(p.region_centroid_col_row, place.col_row) <= place.radius_px]
        if not there:
            # a body is at its place: a brighter star in the dust elsewhere sets a level its surface cannot reach
            inside = regions.within(blob, place.col_row, place.radius_px, regions.free_label(first_label))
            if inside:
                # the parts' pixels all lie in the place's disc, so do their brightest parts' centroids: one level
                return trimmed(regions, max(inside, key=lambda b: (b.area_px, -b.label)), n_pixels,
                               regions.free_label(first_label), place, cfg, resolved_diameter_px)
        parts = there or parts
    lit = [] if place is None or cfg is None else _lit_parts(regions, parts, place, cfg)
    if place is not None and cfg is not None and not lit \
            and (not cfg.limb_fit or place.phase_deg > cfg.limb_fit_max_phase_deg):
        # the plume's core as bright as the crescent merges with it at this level: at a higher one they part (where
        # the limb is fitted, its circle judges a cut off the body: a broad disc's best-lit part may lie anywhere)
        deeper = _lit_part_above(regions, blob, min(surface, n_pixels) // 2, regions.free_label(first_label), place,
                                 cfg)
        if deeper is not None:
            return deeper
    # a part smaller than a quarter competes when it lies where the crescent's centroid is expected and is not a
    # point source: at high phase the plume's core beside a thin crescent can hold more of the brightest pixels than
    # the thin crescent itself
    chosen_by_place = {id(p) for p in lit}
    parts = [p for p in parts if 4 * p.area_px >= n_pixels or id(p) in chosen_by_place] or parts
    if resolved_diameter_px is not None and cfg is not None and len(parts) > 1:
        extended = [p for p in parts if not _point_source(regions, p, cfg)]
        parts = [p for p in parts if any(p is e or _distance(p.region_centroid_col_row, e.region_centroid_col_row)
                                         <= 2.0 * resolved_diameter_px for e in extended)] or parts
    return max(parts, key=lambda b: (b.mean_dn8, b.area_px, -b.label))


def _lit_parts(regions: Regions, parts: list[Blob], place: _Place, cfg: ImagingConfig) -> list[Blob]:
    """The parts that may be Dimorphos's lit surface by where they are: their centroid where the lit part's is
    expected (``_lit_agrees``), at least a body's area and not a point source (a star in the dust)."""
    return [p for p in parts if p.area_px >= cfg.min_body_area_px and _lit_agrees(p, place)
            and not _point_source(regions, p, cfg)]


def _lit_part_above(regions: Regions, blob: Blob, n_pixels: int, first_label: int, place: _Place,
                    cfg: ImagingConfig) -> Blob | None:
    """The brightest by mean of the ``_lit_parts`` of a blob's brightest ``n_pixels``, or of half as many, and so on
    down to a body's area; None when none is. Where the plume's core is as bright as a crescent beside it, the two
    make one part at the expected area's level and part at a higher one: the crescent's best-lit pixels lie nearer
    its limb than its centroid, by less than the core lies off it."""
    n = n_pixels
    while n >= cfg.min_body_area_px:
        lit = _lit_parts(regions, regions.parts(blob, n, first_label), place, cfg)
        if lit:
            return max(lit, key=lambda b: (b.mean_dn8, b.area_px, -b.label))
        first_label = regions.free_label(first_label)
        n //= 2
    return None


@dataclass(frozen=True, slots=True)
class Expected:
    """The areas and radii a prediction gives the two bodies in this frame, binned px."""

    didymos_area: float
    dimorphos_area: float
    didymos_area_max: float
    dimorphos_area_max: float
    didymos_radius_max: float
    dimorphos_radius_max: float
    orbit_radius_max: float
    didymos_radius: float = 0.0  # predicted apparent radii
    dimorphos_radius: float = 0.0
    radius_factor_max: float = 1.0  # apparent radii are at most this many times the predicted ones (and at least
    # the predicted ones over it)
    lit_shift_per_radius: tuple[float, float] = (0.0, 0.0)  # (col, row) lit centroid - centre, in apparent radii
    lit_fraction: float = 1.0  # (1 + cos g) / 2: the lit part of a disc at phase angle g


def _largest_size(radius_px: float, k: float, lit: float, cfg: ImagingConfig) -> tuple[float, float]:
    """A body's largest apparent radius and region area, binned px: radius k r + blur, area pi (k r + blur + 1)^2 times
    the lit fraction (one pixel of digitisation)."""
    r_max = k * radius_px + cfg.blur_margin_px
    return r_max, math.pi * (r_max + 1.0) ** 2 * lit


def expected(prediction: FramePrediction | None, cfg: ImagingConfig) -> Expected | None:
    """The expected and largest areas of both bodies from a prediction with sizes; None without."""
    if prediction is None or prediction.didymos_radius_px is None or prediction.dimorphos_radius_px is None \
            or prediction.orbit_radius_max_px is None:
        return None
    sx, sy, sz = prediction.sun_camera
    cos_g = -sz  # the body near the boresight
    d = math.hypot(sx, sy)
    lit = 0.5 * (1.0 + cos_g)  # (1 + cos g) / 2
    k = prediction.radius_factor_max
    r_did, r_dim = prediction.didymos_radius_px, prediction.dimorphos_radius_px
    a_min = float(cfg.min_body_area_px)
    did_radius_max, did_area_max = _largest_size(r_did, k, lit, cfg)
    dim_radius_max, dim_area_max = _largest_size(r_dim, k, lit, cfg)
    return Expected(
        didymos_area=max(math.pi * r_did ** 2 * lit, a_min),
        dimorphos_area=max(math.pi * r_dim ** 2 * lit, a_min),
        didymos_area_max=did_area_max,
        dimorphos_area_max=dim_area_max,
        didymos_radius_max=did_radius_max,
        dimorphos_radius_max=dim_radius_max,
        orbit_radius_max=prediction.orbit_radius_max_px,
        didymos_radius=r_did,
        dimorphos_radius=r_dim,
        radius_factor_max=k,
        lit_fraction=lit,
        # the phase offset near the boresight (across the 2.9 deg field the phase angle changes by 1.5 deg at most)
        lit_shift_per_radius=(LIT_CENTROID_FACTOR * (1.0 - cos_g) * sx / d, LIT_CENTROID_FACTOR * (1.0 - cos_g) * sy / d)
        if d > 1e-12 else (0.0, 0.0),
    )


def _distance(a: tuple[float, float], b: tuple[float, float]) -> float:
    """Return the Euclidean distance between two (col, row) points."""
    return math.hypot(a[0] - b[0], a[1] - b[1])


def box_distance(blob: Blob, point: tuple[float, float]) -> float:
    """Distance from a point to a blob's bounding box (0 inside)."""
    x, y, w, h = blob.bbox_col_row_w_h
    dx = max(x - point[0], 0.0, point[0] - (x + w - 1))
    dy = max(y - point[1], 0.0, point[1] - (y + h - 1))
    return math.hypot(dx, dy)


def _relative(blob: Blob, origin: Blob) -> tuple[float, float]:
    """Return the region centroid of ``blob`` relative to that of ``origin``."""
    a, o = blob.region_centroid_col_row, origin.region_centroid_col_row
    return (a[0] - o[0], a[1] - o[1])


def _relative_jump_px(didymos: Blob, cfg: ImagingConfig, exp: Expected | None = None) -> float:
    """Return the largest change between frames of the Dimorphos offset from this Didymos, px: a fraction of its
    diameter, which is no larger than Didymos can be with a prediction (a fan of dust taken for Didymos would
    otherwise open the gate to anything)."""
    d = didymos.diameter_px if exp is None else min(didymos.diameter_px, 2.0 * exp.didymos_radius_max)
    return cfg.dimorphos_max_relative_jump_didymos_diameters * d + cfg.centroid_noise_px


def _continues_dimorphos_alone(blob: Blob, prev_did: Blob, prev_dim: Blob, cfg: ImagingConfig) -> bool:
    """Return whether ``blob`` is Dimorphos seen without Didymos: Dimorphos-like area, Didymos's centre off-image."""
    area_vs_dim = abs(math.log(blob.area_px / prev_dim.area_px))
    area_vs_did = abs(math.log(blob.area_px / prev_did.area_px))
    rel = _relative(prev_dim, prev_did)
    col = blob.region_centroid_col_row[0] - rel[0]
    row = blob.region_centroid_col_row[1] - rel[1]
    last = cfg.binned_size_px - 1
    return area_vs_dim < area_vs_did and not (0.0 <= col <= last and 0.0 <= row <= last)


def _continues_pair(dimorphos: Blob, didymos: Blob, prev_did: Blob | None, prev_dim: Blob | None,
                    cfg: ImagingConfig, exp: Expected | None) -> bool:
    """Whether a Dimorphos candidate sits where the last pair's relative offset puts it from this Didymos."""
    if prev_did is None or prev_dim is None:
        return False
    return _distance(_relative(dimorphos, didymos), _relative(prev_dim, prev_did)) \
        <= _relative_jump_px(didymos, cfg, exp)


def _box_gap_px(a: Blob, b: Blob) -> int:
    """Return the number of pixels between two bounding boxes along the axis that separates them most (0: touching
    or overlapping)."""
    ax, ay, aw, ah = a.bbox_col_row_w_h
    bx, by, bw, bh = b.bbox_col_row_w_h
    return max(bx - (ax + aw), ax - (bx + bw), by - (ay + ah), ay - (by + bh), 0)


def _piece_of_crescent(blob: Blob, didymos: Blob, exp: Expected | None, cfg: ImagingConfig) -> bool:
    """Return whether ``blob`` may be a piece of Didymos's thin crescent broken off at the threshold: Didymos is
    elongated, the blob lies within a few pixels of its box and, with expected sizes, on Didymos's disc: its centroid
    within its largest radius of its centre (its region centroid moved back from the lit part by the phase offset),
    and its box within that radius and the point-spread function's reach."""
    if didymos.elongation < cfg.crescent_min_elongation or _box_gap_px(blob, didymos) > cfg.crescent_gap_px:
        return False
    if exp is None:
        return True
    centre = _didymos_centre(didymos, exp)
    if _distance(blob.region_centroid_col_row, centre) > exp.didymos_radius_max:
        return False
    # the whole piece, not its centroid alone, blurred no further than a point source's light: a region of Dimorphos
    # and its plume reaching Didymos's crescent can have its centroid on Didymos's largest disc (bench seed 65 frame
    # 236)
    x, y, w, h = blob.bbox_col_row_w_h
    farthest = math.hypot(max(abs(x - centre[0]), abs(x + w - 1 - centre[0])),
                          max(abs(y - centre[1]), abs(y + h - 1 - centre[1])))
    return farthest <= exp.didymos_radius_max + psf_reach_px(cfg)


def _didymos_centre(didymos: Blob, exp: Expected) -> tuple[float, float]:
    """Didymos's centre: its region centroid moved back from the lit part by the phase offset of its expected
    radius."""
    c, shift, r = didymos.region_centroid_col_row, exp.lit_shift_per_radius, exp.didymos_radius
    return (c[0] - shift[0] * r, c[1] - shift[1] * r)


def _largest(blobs: list[Blob]) -> Blob:
    """Return the blob of largest area, the brighter peak then the first in raster order breaking ties."""
    return max(blobs, key=lambda b: (b.area_px, b.peak_dn8, -b.label))


def _best_didymos(blobs: list[Blob], exp: Expected | None, regions: Regions | None, cfg: ImagingConfig,
                  place: _Place | None, stars: _StarField | None = None) -> tuple[Blob, float]:
    """The blob holding the most light in Didymos's expected area (``aperture_dn8``): Didymos's lit surface, not a
    fainter clump of ejecta of its size or a small star; and when Didymos must be resolved, not a point source
    however bright (a star: ``_point_source``); when it need not be, with Dimorphos's place known, the most likely
    (``_point_likelihood``), an extended one first when Didymos may be resolved; without sizes, the largest. With
    the probability that it is Didymos when it was chosen among point sources that way (``_likeliest``, against the
    frame's ``stars``), else 1; a lone point source near the place gets its probability against the stars too.
    ``stars`` is given exactly when Didymos need not be resolved and the place is known (``_choose_didymos``)."""
    if exp is None or regions is None:
        return _largest(blobs), 1.0
    n = round(exp.didymos_area)
    lights = apertures_dn8(regions, blobs, n)
    resolved = _didymos_resolved(exp, regions, cfg)
    if place is not None and stars is not None:
        may = _must_be_resolved(exp.didymos_radius * exp.radius_factor_max, regions, cfg)
        return _likeliest(blobs, lights, place, exp.orbit_radius_max, may, regions, cfg, stars, blends=True)
    def rank(i: int) -> tuple[float, int, int]:
        return lights[i], blobs[i].area_px, -blobs[i].label

    best = max(range(len(blobs)), key=rank)
    if resolved and _star_like(regions, blobs[best], cfg):
        # never a star however bright, nor a close pair of them (``_star_like``): the brightest candidate that is
        # neither; when every one is, Didymos is not among them (unseen: too faint, or off the image)
        brightest = best
        best = next((i for i in sorted(range(len(blobs)), key=rank, reverse=True)
                     if not _star_like(regions, blobs[i], cfg)), -1)
        if best < 0:
            return blobs[brightest], 0.0
    if resolved and place is not None:
        best = _beside_ejecta(blobs, lights, best, exp, place, regions, cfg)
    return blobs[best], 1.0


def _cut_by_the_edge(blobs: list[Blob], best: int, n_pixels: int, regions: Regions, cfg: ImagingConfig) -> int:
    """The index of Didymos when it may be partly out of the image: an extended candidate at the image's border with
    fewer pixels than Didymos's expected area ``n_pixels``, brighter than ``best`` over as many pixels as it has; else
    ``best``. Beyond the border a body's pixels are unseen, not dark, so its light in the expected area undercounts
    it; over an equal count the lit surface is brighter than dust (a fan of ejecta holding as much light in the
    expected area as a crescent cut by the border), and a body seen whole has brighter pixels than a smaller one of
    like albedo."""
    b = blobs[best]
    better = []
    for i, c in enumerate(blobs):
        if i == best or not c.touches_edge or c.area_px >= n_pixels or _point_source(regions, c, cfg):
            continue
        own, theirs = apertures_dn8(regions, [c, b], c.area_px)
        if own > theirs:
            better.append((own, c.area_px, -c.label, i))
    return max(better)[3] if better else best


def _placed(blobs: list[Blob], exp: Expected | None, regions: Regions | None, cfg: ImagingConfig,
            place: _Place | None) -> bool:
    """Whether ``_best_didymos`` chooses among ``blobs`` by their distance from Dimorphos's place (``_likeliest``)
    and there is a choice: Didymos need not be resolved, the place is known, and more than one blob."""
    return place is not None and exp is not None and regions is not None and len(blobs) > 1 \
        and not _didymos_resolved(exp, regions, cfg)


def _beside_ejecta(blobs: list[Blob], lights: list[float], best: int, exp: Expected, place: _Place,
                   regions: Regions, cfg: ImagingConfig) -> int:
    """The index of Didymos when the ``best`` candidate holds Dimorphos's place with more than both bodies' expected
    areas (Dimorphos with the ejecta it sheds, Didymos beside it or not): another extended candidate off the place
    (its centroid: a large Didymos's box may reach within the place's radius, held-out 124/23), within the orbit's
    reach of the place and of ``best``, of Didymos's size (within its largest region, at least
    its expected area at the farthest range) and with at least half the light; else ``best``. Ejecta leave
    Dimorphos, so a fan of them brighter than a crescent holds the place; a second body-sized region within the
    orbit's reach is Didymos. The reach is from ``best`` too: the Dimorphos it would hold lies within its box, give
    or take Dimorphos's radius and the blur, and Didymos's limb within the orbit's radius and Didymos's of that
    Dimorphos; when the place is known to less than the orbit's radius, the reach from the place says little more,
    but a place known to tens of px would let a region far beyond the orbit (a pair of stars) pass for Didymos."""
    b = blobs[best]
    both = exp.didymos_area + exp.dimorphos_area
    if b.area_px <= both or box_distance(b, place.col_row) > place.radius_px:
        return best
    reach = _didymos_reach(place, exp)
    gap = exp.orbit_radius_max + exp.didymos_radius_max + exp.dimorphos_radius_max + psf_reach_px(cfg)
    smallest = exp.didymos_area / exp.radius_factor_max ** 2
    beside = [i for i, c in enumerate(blobs)
              if i != best and smallest <= c.area_px <= exp.didymos_area_max and lights[i] >= 0.5 * lights[best]
              and place.radius_px < _distance(c.region_centroid_col_row, place.col_row)
              and box_distance(c, place.col_row) <= reach and _box_gap_px(b, c) <= gap
              and not _point_source(regions, c, cfg)]
    return max(beside, key=lambda i: (lights[i], blobs[i].area_px, -blobs[i].label)) if beside else best


def _point_likelihood(blob: Blob, light: float, place: _Place, reach_px: float) -> float:
    """Log of how likely a blob is an unresolved body rather than a star, up to a constant: its light times the
    Gaussian likelihood of its distance from Dimorphos's place beyond ``reach_px`` (the body's largest distance from
    Dimorphos: the orbit's radius for Didymos, none for Dimorphos; the place's error one ``_Place.sigma_px``). Shape
    cannot tell a point-like body from a star, and stars are scattered over the image whatever the place; weighing
    the light by itself follows from star counts falling as the square of the flux (the sky's Euclidean count falls
    as its 2.5th power), the body's flux being unknown."""
    beyond = max(0.0, _distance(blob.region_centroid_col_row, place.col_row) - reach_px)
    log_light = math.log(max(light, 1e-9))
    if place.sigma_px <= 0.0:  # a place known exactly (no uncertainty, no jitter allowed): only there
        return log_light if beyond == 0.0 else -math.inf
    return log_light - 0.5 * (beyond / place.sigma_px) ** 2


@dataclass(frozen=True, slots=True)
class _StarField:
    """The frame's point sources taken as a sample of its stars (at most one of them is Didymos): how many per
    square px, the faintest one's light and the most a point source can hold (8-bit DN above the threshold, in the
    body's expected area). Stars, unlike the body, are anywhere in the image."""

    density_px2: float
    faintest_dn8: float
    brightest_dn8: float


def _star_field(cands: list[Blob], n_pixels: int, regions: Regions, cfg: ImagingConfig) -> _StarField:
    """The ``_StarField`` of a frame's candidates, lights in a body's expected area of ``n_pixels``: the point sources
    among them, all but one (the body, if it is one of them) stars, and at least one star in the frame (a sky without
    one is not told apart from a few)."""
    points = [c for c in cands if _point_source(regions, c, cfg)]
    lights = [x for x in apertures_dn8(regions, points, n_pixels) if x > 0.0] if points else []
    brightest = max(255.0 - regions.threshold_dn8, 1.0)
    faintest = min(min(lights), brightest) if lights else 1.0
    return _StarField(max(len(points) - 1, 1) / float(cfg.binned_size_px) ** 2, faintest, brightest)


def _spread_area_px2(sigma_px: float, reach_px: float) -> float:
    """The integral over the image plane of ``_point_likelihood``'s place term, exp(-(d - reach)^2 / (2 sigma^2))
    beyond the reach and 1 within it: pi R^2 + 2 pi (R sigma sqrt(pi / 2) + sigma^2), px^2 (2 pi sigma^2 for a
    Gaussian about a point)."""
    return math.pi * reach_px ** 2 + 2.0 * math.pi * (reach_px * sigma_px * math.sqrt(0.5 * math.pi) + sigma_px ** 2)


def _gaussian_share_in_disc(place: _Place, centre: tuple[float, float], radius_px: float) -> float:
    """The share of the place's 2-D Gaussian (one ``_Place.sigma_px``) within ``radius_px`` of ``centre``: where the
    body may be once another body's position bounds it. The squared distance from the Gaussian's mean over sigma^2 is
    a noncentral chi-square of 2 degrees of freedom, noncentrality (d / sigma)^2 for a disc d from the mean."""
    d = _distance(centre, place.col_row)
    return float(chndtr((radius_px / place.sigma_px) ** 2, 2.0, (d / place.sigma_px) ** 2))


def _star_log_odds(place: _Place, stars: _StarField, prior: float, spread_px2: float) -> float:
    """Log of the weight of "the body is none of the point sources" in ``_point_likelihood``'s units: the odds
    against the body being among them, (1 - prior) / prior, over the constant that makes a ``_point_likelihood`` the
    log-odds of a point source being the body rather than a star. That odds is the density of the body's position
    (the place term over ``spread_px2``, its integral where the body may be) over the stars' density, times the
    light's over a star's: for stars counted as the square of the flux above the faintest F0, density F0 / F^2, and a
    body's light equally likely on a log scale up to the brightest F1, density 1 / (F ln(F1 / F0)), the ratio is
    F / (F0 ln(F1 / F0))."""
    if prior >= 1.0:
        return -math.inf
    log_range = math.log(max(stars.brightest_dn8 / stars.faintest_dn8, math.e))
    constant = -math.log(spread_px2) - math.log(stars.density_px2) - math.log(stars.faintest_dn8 * log_range)
    return math.log((1.0 - prior) / prior) - constant


def _likeliest(blobs: list[Blob], lights: list[float], place: _Place, reach_px: float, may_be_resolved: bool,
               regions: Regions, cfg: ImagingConfig, stars: _StarField | None = None,
               bound: tuple[tuple[float, float], float] | None = None, blends: bool = False) -> tuple[Blob, float]:
    """The blob of highest ``_point_likelihood`` (ties: more light, larger, first), extended blobs first when the
    body may be resolved: a star is a point source. With the probability that it is the body: for a point source,
    its likelihood over the sum of the point sources' and, given the frame's ``stars``, of the body being none of
    them (``_star_log_odds``, ``cfg.unresolved_body_detected_prior``; without them, exactly one being the body);
    1 for an extended blob taken first (its shape told it from the stars). ``bound``: a centre and radius the body
    is within (Dimorphos within its orbit's reach of Didymos), the place's Gaussian taken within it only. With
    ``blends`` (Didymos), a blend of point sources (``_blend_of_point_sources``) is not taken first: a close double
    star is one too (Dimorphos, near its place in the gate, is not tested: each test deblends, about a millisecond)."""
    first = [may_be_resolved and not _point_source(regions, b, cfg) for b in blobs]
    scores = [_point_likelihood(b, light, place, reach_px) for b, light in zip(blobs, lights, strict=True)]

    def rank(i: int) -> tuple[bool, float, float, int, int]:
        return first[i], scores[i], lights[i], blobs[i].area_px, -blobs[i].label

    best = max(range(len(blobs)), key=rank)
    while blends and first[best] and _blend_of_point_sources(regions, blobs[best], cfg):  # where it decides: it costs
        first[best] = False
        best = max(range(len(blobs)), key=rank)
    if first[best]:
        return blobs[best], 1.0
    top = scores[best]
    if top == -math.inf:  # a place known exactly and none of them there: none can be the body
        return blobs[best], 0.0
    others = [s for s, f in zip(scores, first, strict=True) if not f]
    if stars is not None and place.sigma_px > 0.0:
        spread = _spread_area_px2(place.sigma_px, reach_px)
        if bound is not None:
            spread *= max(_gaussian_share_in_disc(place, *bound), 1e-300)
        others.append(_star_log_odds(place, stars, cfg.unresolved_body_detected_prior, spread))
    top = max(top, max(others))
    return blobs[best], math.exp(scores[best] - top) / math.fsum(math.exp(s - top) for s in others)


def reference_pair(previous: object | None, cfg: ImagingConfig) -> tuple[Blob | None, Blob | None]:
    """Return the (didymos, dimorphos) that continuity refers to: the previous frame's pair, or the last pair seen
    when the frames since saw no Dimorphos, while Didymos is at most ``cfg.pair_memory_max_didymos_px`` across (far
    enough for the offset to change slowly), for ``cfg.pair_memory_frames`` frames at that size and longer in
    proportion for a smaller one; else (None, None).
    ``previous`` is the previous frame's ``Detections``."""
    if previous is None:
        return None, None
    did, dim = previous.didymos, previous.dimorphos  # type: ignore[attr-defined]
    if did is not None and dim is not None:
        return did, dim
    pair, age = previous.pair, previous.pair_age_frames  # type: ignore[attr-defined]
    if dim is not None and pair is not None and age == 0:
        return pair  # Didymos identified with Dimorphos, not reported (``Identification.didymos_probability``)
    if dim is None and pair is not None and pair[0].diameter_px <= cfg.pair_memory_max_didymos_px \
            and age * max(pair[0].diameter_px, 1) < cfg.pair_memory_frames * cfg.pair_memory_max_didymos_px:
        # the offset changes at a rate inversely proportional to the range, so proportional to Didymos's size: a
        # Didymos half as large is remembered twice as long (held-out run 165 of worst-late-near: a 9 px Didymos, its
        # pair forgotten after 20 frames, and the root of Dimorphos's fan, brighter, taken for it)
        return pair
    return None, None


def _with_companion(likely: list[Blob], cands: list[Blob], predicted: tuple[float, float], cfg: ImagingConfig,
                    exp: Expected | None) -> list[Blob]:
    """The ``likely`` candidates having another candidate within ``_relative_jump_px`` of the ``predicted`` relative
    offset (``_continues_pair``'s rule). Near C/A hundreds of noise clumps make all pairs too many for Python: numpy
    screens them all with a small margin, and the few it keeps are decided by the scalar rule itself."""
    if not likely or len(cands) < 2:
        return []
    at = np.array([b.region_centroid_col_row for b in cands])
    origin = np.array([c.region_centroid_col_row for c in likely])
    jump = np.array([_relative_jump_px(c, cfg, exp) for c in likely])
    dx = (at[None, :, 0] - origin[:, None, 0]) - predicted[0]
    dy = (at[None, :, 1] - origin[:, None, 1]) - predicted[1]
    near = dx * dx + dy * dy <= (jump[:, None] * (1.0 + 1e-9) + 1e-9) ** 2  # never tighter than the rule
    found: set[int] = set()
    for i, j in zip(*(x.tolist() for x in np.nonzero(near)), strict=True):
        c = likely[i]
        if i not in found and cands[j] is not c and _distance(_relative(cands[j], c), predicted) <= jump[i]:
            found.add(i)
    return [c for i, c in enumerate(likely) if i in found]


def _choose_didymos(likely: list[Blob], cands: list[Blob], exp: Expected | None, prev_did: Blob | None,
                    prev_dim: Blob | None, cfg: ImagingConfig, regions: Regions | None, place: _Place | None,
                    anchor: _Place | None = None) -> tuple[Blob, float]:
    """Didymos among the ``likely`` candidates (see the module docstring), with the probability that it is
    (``_best_didymos``); ``cands`` are all candidates, the frame's stars among them. With a remembered pair, one
    with a companion where its offset puts Dimorphos first, else one where it puts Didymos from Dimorphos's place
    ``anchor`` (``_anchored``; ``place`` is for the choice among point sources, not given for a region's parts)."""
    stars = None
    if place is not None and exp is not None and regions is not None \
            and not _didymos_resolved(exp, regions, cfg):
        stars = _star_field(cands, round(exp.didymos_area), regions, cfg)
    didymos, probability = _best_didymos(likely, exp, regions, cfg, place, stars)
    if prev_did is not None and prev_dim is not None:
        # prefer a Didymos with a companion where the previous relative offset puts Dimorphos
        paired = _with_companion(likely, cands, _relative(prev_dim, prev_did), cfg, exp)
        if exp is not None and regions is not None:
            # comparable light, or a surface nearly as bright (its mean above the threshold at least three
            # quarters of the best's): a clump of noise at a fan's edge is near the threshold and holds little
            # light; a Didymos split from dust as bright as its surface may keep a small part of its light
            n = round(exp.didymos_area)
            least = 0.5 * aperture_dn8(regions, didymos, n)
            surface = 0.75 * (didymos.mean_dn8 - regions.threshold_dn8)
            paired = [c for c, light in zip(paired, apertures_dn8(regions, paired, n), strict=True)
                      if light >= least or c.mean_dn8 - regions.threshold_dn8 >= surface]
        if paired:
            didymos, probability = _best_didymos(paired, exp, regions, cfg, place, stars)
        else:
            anchored = _anchored(likely, exp, prev_did, prev_dim, cfg, regions, anchor)
            if anchored:
                didymos, probability = _best_didymos(anchored, exp, regions, cfg, place, stars)
    return didymos, probability


def _anchored(likely: list[Blob], exp: Expected | None, prev_did: Blob, prev_dim: Blob, cfg: ImagingConfig,
              regions: Regions | None, place: _Place | None) -> list[Blob]:
    """The ``likely`` candidates where the last pair's offset puts Didymos from Dimorphos's ``place`` (its lit part's
    expected centroid, as a region centroid is), within ``_relative_jump_px`` and the place's error: extended, no
    larger than Didymos can be, while Didymos is resolved and the pair's offset changes slowly (Didymos at most
    ``cfg.pair_memory_max_didymos_px`` across, as for ``reference_pair``), and nearer there than to the place, when
    the place is known to less than the orbit's radius (it then tells Dimorphos from Didymos, as in ``identify``).
    Continuity without a companion: a Dimorphos merged with its fan is no candidate of its own, but the trajectory
    knows where it is (held-out run 626 of worst-late-near: at 1000 km the fan's root, brighter than Didymos, taken
    for it)."""
    if place is None or exp is None or regions is None or prev_did.diameter_px > cfg.pair_memory_max_didymos_px \
            or place.radius_px >= exp.orbit_radius_max or not _didymos_resolved(exp, regions, cfg):
        return []
    rel = _relative(prev_dim, prev_did)
    at = (place.lit_col_row[0] - rel[0], place.lit_col_row[1] - rel[1])
    error = place.sigma_px * cfg.prediction_sigma
    # nearer Didymos's expected centroid than Dimorphos's: the place's error moves both, so a fan's root beside
    # Dimorphos may lie within it from Didymos's too
    # the point-source test last: it reads the blob's pixels, the others are a few comparisons
    return [c for c in likely if c.area_px <= exp.didymos_area_max
            and _distance(c.region_centroid_col_row, at) <= _relative_jump_px(c, cfg, exp) + error
            and _distance(c.region_centroid_col_row, at) < _distance(c.region_centroid_col_row, place.lit_col_row)
            and not _point_source(regions, c, cfg)]


def _continued(didymos: Blob, cands: list[Blob], exp: Expected | None, prev_did: Blob, prev_dim: Blob,
               cfg: ImagingConfig, regions: Regions | None, place: _Place | None) -> bool:
    """Whether a Didymos continues the last pair: a candidate where its offset puts Dimorphos (``_with_companion``),
    or Didymos where it puts it from Dimorphos's place (``_anchored``)."""
    return bool(_with_companion([didymos], cands, _relative(prev_dim, prev_did), cfg, exp)
                or _anchored([didymos], exp, prev_did, prev_dim, cfg, regions, place))


@dataclass(frozen=True, slots=True)
class _Place:
    """Where the trajectory puts Dimorphos: the point, the radius around it Dimorphos's region centroid is in, and
    the place's one-sigma error; where its lit part's centroid is expected (the phase offset of its predicted radius
    from the point), and the radius around the point its phase-corrected centroid is in (``_lit_agrees``)."""

    col_row: tuple[float, float]
    radius_px: float
    sigma_px: float
    lit_col_row: tuple[float, float]
    report_radius_px: float
    phase_deg: float = 0.0  # the phase angle near the boresight


def _place(prediction: FramePrediction | None, exp: Expected | None, cfg: ImagingConfig) -> _Place | None:
    """Dimorphos's predicted place, when the prediction gives one with a finite uncertainty."""
    if exp is None or prediction is None or prediction.dimorphos_col_row is None \
            or prediction.dimorphos_uncertainty_px is None or not math.isfinite(prediction.dimorphos_uncertainty_px):
        return None
    c, r = prediction.dimorphos_col_row
    shift_col, shift_row = (s * exp.dimorphos_radius for s in exp.lit_shift_per_radius)
    # the phase correction takes the predicted radius: a body k times larger (or smaller) has its lit centroid
    # (k - 1) times the offset further (or nearer)
    correction_error = math.hypot(shift_col, shift_row) * (exp.radius_factor_max - 1.0)
    # the uncertainty spans prediction_sigma sigmas; never tighter than a centroid's own jitter
    return _Place((c, r),
                  prediction.dimorphos_uncertainty_px + exp.dimorphos_radius_max + cfg.centroid_noise_px,
                  max(prediction.dimorphos_uncertainty_px, cfg.centroid_noise_px) / cfg.prediction_sigma,
                  (c + shift_col, r + shift_row),
                  prediction.dimorphos_uncertainty_px + cfg.centroid_noise_px + correction_error,
                  math.degrees(math.acos(min(1.0, max(-1.0, 2.0 * exp.lit_fraction - 1.0)))))


def _lit_agrees(blob: Blob, place: _Place) -> bool:
    """Whether a blob's region centroid, taken as Dimorphos's lit part, lies where the prediction puts that: within
    the place's uncertainty, the centroid's jitter and the phase correction's error for the body's size
    (``_Place.report_radius_px``) of the lit part's expected centroid, where its line of sight would be accepted. A
    cut of the plume's core beside a crescent, or a star smeared beside it, can lie within the body's radius of the
    place, as the crescent's centroid does, and still not agree."""
    return _distance(blob.region_centroid_col_row, place.lit_col_row) <= place.report_radius_px


def _may_hold_lit_part(blob: Blob, place: _Place) -> bool:
    """Whether a blob's box reaches within ``_Place.report_radius_px`` of the lit part's expected centroid: a region
    holding Dimorphos's lit part holds that part's centroid, which lies there. Its own centroid may not, when dust
    beside the body pulls it (``_lit_agrees`` is the stricter rule, for choosing among parts)."""
    return box_distance(blob, place.lit_col_row) <= place.report_radius_px


def _didymos_reach(place: _Place, exp: Expected) -> float:
    """How far from Dimorphos's place Didymos's region can reach, px: the place's radius, the orbit's largest
    apparent radius and Didymos's largest radius."""
    return place.radius_px + exp.orbit_radius_max + exp.didymos_radius_max


def _near_place(blobs: list[Blob], place: _Place | None, exp: Expected) -> list[Blob]:
    """The blobs whose box lies within ``_didymos_reach`` of Dimorphos's place (all of them without a place): those
    that can be Didymos, or part of it."""
    if place is None:
        return blobs
    reach = _didymos_reach(place, exp)
    return [b for b in blobs if box_distance(b, place.col_row) <= reach]


def _didymos_may_be_out(place: _Place, exp: Expected, n: int) -> bool:
    """Whether Didymos's centre may lie outside the n x n image, Dimorphos being at its predicted place."""
    reach = place.radius_px + exp.orbit_radius_max
    c, r = place.col_row
    return min(c, r, n - 1 - c, n - 1 - r) < reach


def _dimorphos_gate(didymos: Blob, exp: Expected | None, cfg: ImagingConfig) -> float:
    """Largest distance of Dimorphos's region centroid from Didymos's, px."""
    if exp is None:
        return cfg.dimorphos_max_separation_didymos_diameters * didymos.diameter_px + cfg.centroid_noise_px
    return exp.orbit_radius_max + exp.didymos_radius_max + exp.dimorphos_radius_max + cfg.centroid_noise_px


def _orbit_bound(didymos: Blob, exp: Expected, cfg: ImagingConfig) -> tuple[tuple[float, float], float]:
    """Where a point-like Dimorphos's region centroid can be: within the orbit's largest apparent radius of Didymos's
    centre (``_didymos_centre``), widened by that centre's error (a body up to ``radius_factor_max`` times its
    predicted radius has its lit centroid that much further), Dimorphos's largest radius and the centroid noise. The
    gate (``_dimorphos_gate``) adds Didymos's whole radius about its region centroid, for regions Didymos shares
    with ejecta or cut from them; a point source is no such region (held-out 120/224: a star 20 px from a 7 px
    Didymos, 18 px from its centre, the orbit 12 px, reported)."""
    return (_didymos_centre(didymos, exp), exp.orbit_radius_max + (exp.radius_factor_max - 1.0) * exp.didymos_radius
            + exp.dimorphos_radius_max + cfg.centroid_noise_px)


def _near(blob: Blob, point: tuple[float, float], limit: float, oversized: bool) -> bool:
    """Whether a blob is within ``limit`` of a point: its centroid, or its box for a blob holding ejecta (Dimorphos,
    their source, is at one end of it)."""
    return (box_distance(blob, point) if oversized else _distance(blob.region_centroid_col_row, point)) <= limit


def aperture_dn8(regions: Regions, blob: Blob, n_pixels: int) -> float:
    """The light a body of ``n_pixels`` would hold: the mean, over ``n_pixels``, of a blob's brightest pixels above
    the frame's threshold (a blob with fewer pixels counts the rest as dark), 8-bit DN. A single pixel cannot set it,
    a small star holds little of it, a faint clump of ejecta less than a lit surface."""
    return apertures_dn8(regions, [blob], n_pixels)[0]


def apertures_dn8(regions: Regions, blobs: list[Blob], n_pixels: int) -> list[float]:
    """``aperture_dn8`` of each blob, at once: near C/A a frame holds a hundred candidates or more, and a call each
    cost more than the statistic. A described region's comes from the regions' histograms, every region's at once
    (many candidates share each expected area); a part cut out of one, from its own pixels."""
    n = max(1, int(n_pixels))
    rows = regions.rows
    last = len(rows)
    light = regions.light.get(n)
    out = []
    for b in blobs:
        row = rows[b.label - 1] if not b.trimmed_from and 0 < b.label <= last else -1
        if row < 0:
            counts = np.bincount(regions.values8[regions.pixels_of(b)], minlength=256)[None, :]
            out.append(float(kernels.top_light(counts, n, regions.threshold_dn8)[0]))
            continue
        if light is None:
            light = regions.light[n] = kernels.top_light(regions.histograms["regions"], n,
                                                         regions.threshold_dn8).tolist()
        out.append(light[row])
    return out


def _crescent_peak(radius_px: float, lit: float, cfg: ImagingConfig) -> float:
    """The peak of a uniformly lit crescent of width 2 r lit (``Expected.lit_fraction``: the lit part of a disc of
    radius r, across its middle) seen through the point-spread function (its largest sigma,
    ``point_source_sigma_max_px``) and the pixel (a box, variance 1/12): erf(w / (2 sqrt(2) s)) of the surface's
    brightness, linear."""
    width = 2.0 * radius_px * lit
    sigma = math.sqrt(cfg.point_source_sigma_max_px ** 2 + 1.0 / 12.0)
    return math.erf(width / (2.0 * math.sqrt(2.0) * sigma)) if width > 0.0 else 0.0


def _peak_kept_by_blur(exp: Expected, cfg: ImagingConfig) -> float:
    """How much of Didymos's brightest light Dimorphos's, of the same albedo, can keep through the blur alone, in
    8-bit DN (the square-root compression): the square root of the ratio of their crescents' peaks
    (``_crescent_peak``, each body at its smallest predicted radius), at most 1. At high phase a few-pixel Dimorphos's
    crescent is a pixel or two wide, and the blur spreads its light where Didymos's is not."""
    k = exp.radius_factor_max
    did = _crescent_peak(exp.didymos_radius / k, exp.lit_fraction, cfg)
    dim = _crescent_peak(exp.dimorphos_radius / k, exp.lit_fraction, cfg)
    return min(math.sqrt(dim / did), 1.0) if did > 0.0 else 1.0


def _choose_dimorphos(cands: list[Blob], didymos: Blob, exp: Expected | None, place: _Place | None,
                      prev_did: Blob | None, prev_dim: Blob | None, cfg: ImagingConfig,
                      regions: Regions | None, didymos_probability: float = 1.0) -> Blob | None:
    """Dimorphos among the candidates, Didymos chosen with ``didymos_probability`` (see the module docstring); None if
    not seen. An unresolved Dimorphos chosen among point sources by its place, within the orbit's reach of Didymos, is
    reported when the probability of both, Didymos's times its own given Didymos, is at least
    ``dimorphos_min_report_probability``: a point source beside a star taken for Didymos is as likely a star."""
    gate = _dimorphos_gate(didymos, exp, cfg)
    origin = didymos.region_centroid_col_row

    def oversized(b: Blob) -> bool:
        return exp is not None and b.area_px > exp.dimorphos_area_max

    if exp is not None and regions is not None:
        # the brightest quarter of Dimorphos's expected area on both: the part of each disc lit nearest normal
        # incidence, whatever the phase and the shading law (a whole disc's mean is far lower at high phase)
        best_lit = max(1, round(exp.dimorphos_area / 4))
        # the blur takes more off the peak of Dimorphos's narrow crescent than off Didymos's wide one
        least = cfg.dimorphos_min_peak_fraction * _peak_kept_by_blur(exp, cfg) \
            * aperture_dn8(regions, didymos, best_lit)
        bright = [light >= least for light in apertures_dn8(regions, cands, best_lit)]
    else:
        least = cfg.dimorphos_min_peak_fraction * didymos.peak_dn8
        bright = [b.peak_dn8 >= least for b in cands]

    in_gate = [
        b for b, lit in zip(cands, bright, strict=True)
        if b is not didymos
        and lit
        and _near(b, origin, gate, oversized(b))
        and (place is None or _near(b, place.col_row, place.radius_px, oversized(b)))
        and not _piece_of_crescent(b, didymos, exp, cfg)
    ]
    if not in_gate:
        return None
    if place is not None and exp is not None and regions is not None and len(in_gate) > 1:
        # those whose centroid agrees with the place when any does, each taken as it would be reported (cut to its
        # surface, ``_dimorphos_surface``): a star smeared beside a crescent merged with the plume, or the plume's
        # core cut out of a fan beside a crescent, lies within the body's radius of the place, off the lit part's
        # expected centroid
        label = regions.free_label(int(regions.components.area_px.size) + 1)
        agree = []
        for b in in_gate:
            if _lit_agrees(_dimorphos_surface(regions, b, exp, label, place, cfg), place):
                agree.append(b)
            label = regions.free_label(label)
        in_gate = agree or in_gate
    if prev_did is not None and prev_dim is not None:
        predicted = _relative(prev_dim, prev_did)
        jump = _relative_jump_px(didymos, cfg, exp)
        continuing = [b for b in in_gate if _distance(_relative(b, didymos), predicted) <= jump]
        if continuing:
            # a continuing Dimorphos may outgrow the area limits: the ejecta grow around it
            return min(continuing, key=lambda b: _distance(_relative(b, didymos), predicted))
    if exp is None or regions is None:
        sized = [b for b in in_gate if b.area_px <= cfg.dimorphos_max_area_fraction * didymos.area_px]
        return _largest(sized) if sized else None
    # the most light in Dimorphos's expected area: the body, not a fainter clump of ejecta or a small star; and
    # when it must be resolved, never a point source (a star, however bright: Dimorphos hidden or merged with Didymos)
    n = round(exp.dimorphos_area)
    lights = apertures_dn8(regions, in_gate, n)
    if _dimorphos_resolved(exp, regions, cfg):
        ranked = sorted(range(len(in_gate)), reverse=True,
                        key=lambda i: (lights[i], in_gate[i].area_px, -in_gate[i].label))
        extended = (b for b in (in_gate[i] for i in ranked) if not _point_source(regions, b, cfg))
        best = next(extended, None)
        if best is not None and oversized(best):
            # a region larger than Dimorphos can be holds ejecta: beside an extended region of Dimorphos's size in
            # the gate (and, with a place, where the lit part is expected), it is the dust, its root brighter than
            # the crescent beside it (held-out frame 107/212: the fan's root reported 15.9 px off)
            return next((b for b in extended if not oversized(b)), best)
        return best
    if place is not None:
        # shape cannot tell it from a star: as for an unresolved Didymos, at the place itself, within the gate; a
        # point source only within the orbit's reach of Didymos's centre (``_orbit_bound``). The place's Gaussian is
        # taken within the gate still: Dimorphos's region, merged with ejecta, may lie anywhere in it (taken within
        # the orbit's reach instead, 4 stars of 44 bench seeds passed 0.95)
        may = _must_be_resolved(exp.dimorphos_radius * exp.radius_factor_max, regions, cfg)
        centre, reach = _orbit_bound(didymos, exp, cfg)
        kept = [i for i, b in enumerate(in_gate)
                if _distance(b.region_centroid_col_row, centre) <= reach or not _point_source(regions, b, cfg)]
        if not kept:
            return None
        chosen, probability = _likeliest([in_gate[i] for i in kept], [lights[i] for i in kept], place, 0.0, may,
                                         regions, cfg, _star_field(cands, n, regions, cfg), (origin, gate))
        return chosen if didymos_probability * probability >= cfg.dimorphos_min_report_probability else None
    return in_gate[max(range(len(in_gate)), key=lambda i: (lights[i], in_gate[i].area_px, -in_gate[i].label))]


def _split(regions: Regions, didymos: Blob, cands: list[Blob], likely: list[Blob], exp: Expected,
           prev_did: Blob | None, prev_dim: Blob | None, cfg: ImagingConfig, next_label: int, placed: bool,
           place: _Place | None) -> tuple[list[Blob], list[Blob], Blob, int]:
    """Replace Didymos's blob by the parts of its brightest pixels of both bodies' expected area and choose Didymos
    again: (candidates, Didymos candidates, Didymos, next free label); among its parts only when the region was
    ``placed`` (chosen among point-like candidates by its distance from Dimorphos's place: a star elsewhere, brighter
    than its parts, was less likely), or when the choice falls on a point source elsewhere while Didymos must be
    resolved and the region was not one (the region was taken over it for its shape). Only parts within Didymos's
    reach of Dimorphos's ``place`` (``_near_place``, as for every candidate) are Didymos candidates; with none there,
    the region stays whole (held-out 112/289: a star in the plume's region, 18 px from a 0.5 px Didymos's place,
    the region's brightest pixels)."""
    parts = [p for p in regions.parts(didymos, round(exp.didymos_area + exp.dimorphos_area), next_label)
             if p.area_px >= cfg.min_body_area_px and p.elongation <= cfg.max_body_elongation]
    parts = _near_place(parts, place, exp)
    if not parts or parts == [didymos]:
        return cands, likely, didymos, next_label
    cands = [c for c in cands if c is not didymos] + parts
    likely = [c for c in likely if c is not didymos] + parts
    # past every label the cut gave (the parts too small or long to be bodies too): a later cut never reuses one;
    # the place chose the region among stars, not between its parts (Didymos, Dimorphos and ejecta, all there)
    chosen = _choose_didymos(parts if placed else likely, cands, exp, prev_did, prev_dim, cfg, regions, None,
                             place)[0]
    if chosen not in parts and _didymos_resolved(exp, regions, cfg) and _point_source(regions, chosen, cfg) \
            and not _point_source(regions, didymos, cfg):
        # a point source the region was taken over for its shape (Didymos must be resolved) stays passed over when
        # the region's parts are point-like: a thin crescent's lit part, cut from the dust around it
        chosen = _choose_didymos(parts, cands, exp, prev_did, prev_dim, cfg, regions, None, place)[0]
    next_label = regions.free_label(next_label)
    if prev_did is not None and prev_dim is not None and prev_did.diameter_px <= cfg.pair_memory_max_didymos_px \
            and not _continued(chosen, cands, exp, prev_did, prev_dim, cfg, regions, place):
        # only where the pair's offset changes slowly (``reference_pair``): near C/A it sweeps across frames
        found = _paired_object(regions, didymos, cands, parts, exp, prev_did, prev_dim, cfg, next_label, place)
        if found is not None:
            objects, chosen = found
            cands = [c for c in cands if c not in parts] + objects
            likely = [c for c in likely if c not in parts] + objects
            next_label = regions.free_label(next_label)
    return cands, likely, chosen, next_label


def _paired_object(regions: Regions, region: Blob, cands: list[Blob], parts: list[Blob], exp: Expected,
                   prev_did: Blob, prev_dim: Blob, cfg: ImagingConfig, next_label: int, place: _Place | None
                   ) -> tuple[list[Blob], Blob] | None:
    """The region's objects (``Regions.deblended``, in place of its brightest ``parts``) and Didymos among them, when
    one of them continues the last pair (``_continued``) and the brightest parts' choice did not; else None, the
    objects' pixels forgotten. A plume's root brighter than Didymos's surface holds every pixel of the brightest cut,
    Didymos none (held-out run 626 of worst-late-near: a 9 px Didymos beside Dimorphos's fan from 1080 km on), while
    Didymos, a body with a peak of its own, parts from the fan at some level of the region's light."""
    every = regions.deblended(region, cfg.deblend_levels, cfg.deblend_min_flux_fraction, next_label)
    objects = _near_place([o for o in every if o.area_px >= cfg.min_body_area_px
                           and o.elongation <= cfg.max_body_elongation], place, exp)
    if len(objects) > 1:
        others = [c for c in cands if c not in parts] + objects
        chosen = _choose_didymos(objects, others, exp, prev_did, prev_dim, cfg, regions, None, place)[0]
        if _continued(chosen, others, exp, prev_did, prev_dim, cfg, regions, place):
            return objects, chosen
    _forget(regions, [o for o in every if o is not region])
    return None


def _surface(regions: Regions, blob: Blob, exp: Expected, cfg: ImagingConfig, first_label: int) -> list[Blob]:
    """The candidate parts (``Regions.parts``) of a blob's surface (``surface_pixels`` with Didymos's expected
    area) when it is under half of the blob: a fan of dust merged with a lit surface is mostly fainter; [] when
    not."""
    m = surface_pixels(regions, blob, round(exp.didymos_area))
    if 2 * m >= blob.area_px:
        return []
    return [p for p in regions.parts(blob, m, first_label)
            if p.area_px >= cfg.min_body_area_px and p.elongation <= cfg.max_body_elongation]


def _without_dust(regions: Regions, blob: Blob, exp: Expected, cfg: ImagingConfig, first_label: int) -> list[Blob]:
    """The parts (``Regions.parts``) of a Didymos region cut to its pixels whose raw signal above the
    threshold is at least ``dust_cut_fraction`` of its surface's typical signal (the median of its brightest
    Didymos's expected area), when the cut moves the region's centroid as removing dust does: across the Sun's
    direction in the image, or away from the Sun, by more than ``dust_shift_tolerance_radii`` of Didymos's predicted
    radius plus a pixel. A lit body's own faint pixels, its terminator and its blurred limb, lie symmetrically about
    the Sun's direction through it, so cutting them moves its centroid toward the Sun only, and the cut is not
    kept (the phase correction expects the whole lit region). The largest part first; [] when the cut is not kept or
    removes nothing."""
    assert regions.linear8 is not None
    sel = regions.pixels_of(blob)
    vals = regions.values8[sel]
    n = min(max(1, round(exp.didymos_area)), vals.size)
    typical = float(np.median(np.partition(vals, vals.size - n)[vals.size - n:]))
    linear = regions.linear8
    floor = float(linear[regions.threshold_dn8])
    surface = float(np.interp(typical, np.arange(linear.size), linear))
    level = int(np.searchsorted(linear, floor + cfg.dust_cut_fraction * (surface - floor)))  # first code at or above
    kept = int(np.count_nonzero(vals >= level))
    if kept == 0 or kept == vals.size:
        return []
    every = regions.parts(blob, kept, first_label)
    parts = sorted((p for p in every if p.area_px >= cfg.min_body_area_px and p.elongation <= cfg.max_body_elongation),
                   key=lambda b: (-b.area_px, b.label))
    if not parts:
        return _forget(regions, every)
    body = parts[0]
    dc = body.region_centroid_col_row[0] - blob.region_centroid_col_row[0]
    dr = body.region_centroid_col_row[1] - blob.region_centroid_col_row[1]
    sc, sr = exp.lit_shift_per_radius
    norm = math.hypot(sc, sr)
    if norm > 0.0:
        along, across = (dc * sc + dr * sr) / norm, abs(dc * sr - dr * sc) / norm
    else:  # at zero phase the lit disc is whole: any move is dust's
        along, across = 0.0, math.hypot(dc, dr)
    tolerance = cfg.dust_shift_tolerance_radii * exp.didymos_radius + 1.0
    return parts if across > tolerance or along < -tolerance else _forget(regions, every)


def _forget(regions: Regions, parts: list[Blob]) -> list[Blob]:
    """[] once the pixels of parts not kept are forgotten: the labels of later cuts, and so their order, are those
    of a frame where the parts were never cut."""
    for p in parts:
        regions.part_pixels.pop(p.label, None)
    return []


def _sized_by_didymos(exp: Expected, didymos: Blob, cfg: ImagingConfig) -> Expected:
    """``exp`` with Dimorphos's largest radius and area bounded by Didymos's measured size as well: both bodies are
    at the same range (the orbit is 2 % of it at 55 km), so Dimorphos's apparent radius is at most
    ``dimorphos_radius_margin_of_didymos`` times Didymos's measured one scaled by their diameters' ratio. Before
    the trajectory is recognised the range is known to a factor of several and so, from the prediction alone, is
    Dimorphos's size: a fan of dust holding Dimorphos passed for it. Only a whole, well-resolved Didymos region (not
    cut, not at the image's edge, a measured radius of at least ``didymos_sizing_min_radius_px``) measures it; its
    radius is that of a disc whose lit fraction has the region's area (larger with dust or blur: looser, not
    tighter)."""
    lit = exp.lit_fraction
    if didymos.trimmed_from or didymos.cuts or didymos.touches_edge or exp.didymos_radius <= 0.0 or lit <= 0.0:
        return exp
    measured = math.sqrt(didymos.area_px / (math.pi * lit))
    if measured < cfg.didymos_sizing_min_radius_px:
        return exp
    k = cfg.dimorphos_radius_margin_of_didymos * measured / exp.didymos_radius
    if k >= exp.radius_factor_max:
        return exp
    r_max, area_max = _largest_size(exp.dimorphos_radius, k, lit, cfg)
    return replace(exp, dimorphos_radius_max=min(exp.dimorphos_radius_max, r_max),
                   dimorphos_area_max=min(exp.dimorphos_area_max, area_max))


class Identification(NamedTuple):
    """Which blobs are the bodies (None: not seen), and the probability that the Didymos taken is Didymos: below 1
    when it is a point source chosen among point sources by its light and place (``_likeliest``)."""

    didymos: Blob | None
    dimorphos: Blob | None
    didymos_probability: float = 1.0
    dimorphos_deblended: bool = False  # Dimorphos is a peak of Didymos's region deblended (``Regions.deblended``)


def identify_bodies(blobs: tuple[Blob, ...] | list[Blob], cfg: ImagingConfig, previous: object | None = None,
                    prediction: FramePrediction | None = None, regions: Regions | None = None
                    ) -> tuple[Blob | None, Blob | None]:
    """Return (didymos, dimorphos) among the blobs, either None when not seen (``identify`` without the
    probability)."""
    found = identify(blobs, cfg, previous, prediction, regions)
    return found.didymos, found.dimorphos


def identify(blobs: tuple[Blob, ...] | list[Blob], cfg: ImagingConfig, previous: object | None = None,
             prediction: FramePrediction | None = None, regions: Regions | None = None) -> Identification:
    """Identify Didymos and Dimorphos among the blobs (see the module docstring).

    ``previous`` is the previous frame's ``Detections`` (continuity); ``regions`` the frame's labelled foreground,
    needed to trim blobs that hold ejecta (without it, blobs are taken whole). Centroids are not phase-corrected
    here (``phase_corrected``).
    """
    cands = [b for b in blobs if b.area_px >= cfg.min_body_area_px and b.elongation <= cfg.max_body_elongation]
    if not cands:
        return Identification(None, None)
    exp = expected(prediction, cfg)
    place = _place(prediction, exp, cfg)
    prev_did, prev_dim = reference_pair(previous, cfg)
    next_label = 1 + max(max(b.label for b in blobs),
                         0 if regions is None else int(regions.components.area_px.size))
    biggest = max(cands, key=lambda b: (b.area_px, -b.label))
    if prev_did is not None and prev_dim is not None and previous.dimorphos is prev_dim \
            and (exp is None or biggest.area_px <= exp.dimorphos_area_max) \
            and _continues_dimorphos_alone(biggest, prev_did, prev_dim, cfg):  # type: ignore[attr-defined]
        return Identification(None, biggest)
    likely = cands
    if place is not None and exp is not None:
        # Didymos is within the orbit's radius of Dimorphos, wherever the trajectory puts it
        likely = _near_place(cands, place, exp)
        if not likely:
            return Identification(None, None)
    didymos, probability = _choose_didymos(likely, cands, exp, prev_did, prev_dim, cfg, regions, place, place)
    taken = didymos
    placed = _placed(likely, exp, regions, cfg, place)
    may_be_out = place is not None and exp is not None and _didymos_may_be_out(place, exp, cfg.binned_size_px)
    # the smallest Didymos the prediction allows is resolved: Expected's Didymos sizes stay as predicted below
    resolved = exp is not None and _didymos_resolved(exp, regions, cfg)
    # the surface is counted last: it sorts the blob's pixels, the other tests are a few comparisons
    if may_be_out and place is not None and exp is not None \
            and _near(didymos, place.col_row, place.radius_px, didymos.area_px > exp.dimorphos_area_max) \
            and _surface_area(regions, didymos, exp) < math.sqrt(exp.didymos_area * exp.dimorphos_area):
        # no blob with a lit surface of Didymos's size: a Dimorphos-sized surface (with the ejecta it holds) where
        # Dimorphos is expected, Didymos out of the image
        return Identification(None, _brightest_surface_at(regions, didymos, cands, exp, next_label, place,
                                                          cfg))
    if may_be_out and exp is not None and regions is not None and resolved:
        # Didymos may be cut by the border and was not taken to be out of the image: a part of it there, brighter
        didymos = likely[_cut_by_the_edge(likely, likely.index(didymos), round(exp.didymos_area), regions, cfg)]
    if exp is not None and regions is not None and didymos.area_px > exp.didymos_area_max + exp.dimorphos_area_max:
        # larger than both bodies can be: ejecta merged with it; its brightest part of both bodies' size replaces it
        cands, likely, didymos, next_label = _split(regions, didymos, cands, likely, exp, prev_did, prev_dim, cfg,
                                                   next_label, placed, place)
    elif exp is not None and regions is not None and didymos.area_px > exp.didymos_area + exp.dimorphos_area:
        # room for both bodies: Dimorphos may be merged with Didymos, bridged by ejecta or the blur; a part of
        # Didymos's brightest pixels no larger than Dimorphos can be, and not a piece of a crescent, is Dimorphos;
        # so is a larger one (holding ejecta, trimmed below) where the trajectory puts Dimorphos, when it puts it
        # closer than the orbit's radius (the place then tells Dimorphos from Didymos), or where the last pair's
        # offset puts it from the part taken for Didymos
        split = _split(regions, didymos, cands, likely, exp, prev_did, prev_dim, cfg, next_label, placed, place)
        found = _choose_dimorphos(split[0], split[2], exp, place, prev_did, prev_dim, cfg, regions, probability)
        if found is not None and found.trimmed_from == (didymos.trimmed_from or didymos.label) \
                and (found.area_px <= exp.dimorphos_area_max
                     or place is not None and place.radius_px < exp.orbit_radius_max
                     or _continues_pair(found, split[2], prev_did, prev_dim, cfg, exp)):
            cands, likely, didymos, next_label = split
    if exp is not None and regions is not None and didymos.area_px > exp.didymos_area + exp.dimorphos_area \
            and exp.didymos_radius / exp.radius_factor_max > 8.0 * psf_reach_px(cfg):
        # larger than Didymos alone and mostly fainter than its surface; for a disc whose blurred limb (within
        # psf_reach_px of its edge) is under a quarter of it: a smaller one, or a close pair blurred together, is
        # mostly fringe
        cut = _surface(regions, didymos, exp, cfg, next_label)
        if cut:
            cands = [c for c in cands if c is not didymos] + cut
            didymos = max(cut, key=lambda b: (b.area_px, -b.label))
            next_label = regions.free_label(next_label)
    if exp is not None and regions is not None and didymos.area_px > exp.didymos_area + exp.dimorphos_area \
            and resolved:
        # still larger than Didymos alone: a fan of dust fainter than its surface may be merged with it
        cut = _without_dust(regions, didymos, exp, cfg, regions.free_label(next_label))
        if cut:
            # the other parts are brighter than the cut's level: clumps of dust, or Dimorphos merged with Didymos by
            # the dust (its surface, of Didymos's albedo, stays above the level); those no larger than Dimorphos can be
            # stay candidates for it, the others are dust
            cands = [c for c in cands if c is not didymos] + cut[:1] + [
                p for p in cut[1:] if p.area_px <= exp.dimorphos_area_max]
            didymos = cut[0]
            next_label = regions.free_label(next_label)
    if exp is not None:
        exp = _sized_by_didymos(exp, didymos, cfg)
    dimorphos = _choose_dimorphos(cands, didymos, exp, place, prev_did, prev_dim, cfg, regions, probability)
    deblended = False
    if dimorphos is None and place is not None and exp is not None and regions is not None \
            and 2.0 * place.radius_px < exp.orbit_radius_max:
        # Dimorphos merged with Didymos's region by ejecta brighter than its surface: the trajectory bounds where
        # it is (well within the orbit), so the part of that region there, cut to its brightest pixels of
        # Dimorphos's size and off Didymos's disc, is Dimorphos. When that cut lies on Didymos's disc, the part
        # within the place's disc stopped at Didymos's limb: beside it Didymos's lit limb is brighter than a small
        # Dimorphos blurred
        root = next((b for b in blobs if b.label == (didymos.trimmed_from or didymos.label)), didymos)
        centre = _didymos_centre(didymos, exp)
        off_didymos = min(place.radius_px, _distance(place.col_row, centre) - exp.didymos_radius)
        for reach in dict.fromkeys((place.radius_px, off_didymos)):
            pieces = [p for p in regions.within(root, place.col_row, reach, next_label)
                      if p.area_px >= cfg.min_body_area_px] if reach > 0.0 else []
            next_label = regions.free_label(next_label)
            if not pieces:
                continue
            piece = trimmed(regions, max(pieces, key=lambda b: (b.area_px, -b.label)), round(exp.dimorphos_area),
                            next_label, place, cfg, _dimorphos_resolved_diameter_px(exp, regions, cfg))
            next_label = regions.free_label(next_label)
            if _distance(piece.region_centroid_col_row, centre) > exp.didymos_radius:
                dimorphos = _choose_dimorphos([piece], didymos, exp, place, None, None, cfg, regions, probability)
                break
    if dimorphos is None and place is not None and exp is not None and regions is not None \
            and regions.linear8 is not None \
            and (didymos.trimmed_from or resolved):
        # Dimorphos merged with Didymos's region by the plume or the blur, below every level the cuts above tried:
        # a region cut for Didymos, or one left whole when Didymos is resolved (an unresolved one's blur and noise
        # can part into peaks of their own), whatever its area: a Didymos smaller than predicted (its apparent size
        # is known to radius_factor_max) leaves no room for Dimorphos in the predicted areas, yet holds it
        root = next((b for b in blobs if b.label == (didymos.trimmed_from or didymos.label)), didymos)
        dimorphos, source, next_label = _deblended_dimorphos(root, didymos, cands, exp, place, cfg, regions,
                                                             probability, next_label)
        # an object's own peak is no cut beside the body; the brightest part of a larger one is, as any cut
        deblended = dimorphos is not None and dimorphos is source
        if source is not None:
            # Didymos's region held Dimorphos: Didymos is that region without the object Dimorphos is or was cut
            # from, its centroid no longer pulled by Dimorphos or the dust around it (continuity measures from it)
            didymos, next_label = _without(regions, didymos if didymos.trimmed_from else root, source, exp, cfg,
                                           place, next_label)
    if dimorphos is not None and exp is not None:
        surface = _dimorphos_surface(regions, dimorphos, exp, next_label, place, cfg)
        far = surface is not dimorphos and _cut_beyond_gate(surface, didymos, exp, cfg)
        dimorphos, deblended = (None, False) if far else (surface, deblended)
    if dimorphos is not None and place is not None and not _may_hold_lit_part(dimorphos, place):
        # no pixel of it lies where Dimorphos's lit part can be: the only candidate, dust cut to its brightest part
        # where Dimorphos is hidden (behind Didymos's night side), is no Dimorphos
        dimorphos, deblended = None, False
    # the probability is the choice's, for the region chosen and the parts cut out of it (another region taken
    # after a cut was taken by its light among them all)
    same = (didymos.trimmed_from or didymos.label) == (taken.trimmed_from or taken.label)
    return Identification(didymos, dimorphos, probability if same else 1.0, deblended)


def _deblended_dimorphos(root: Blob, didymos: Blob, cands: list[Blob], exp: Expected, place: _Place,
                         cfg: ImagingConfig, regions: Regions, didymos_probability: float, next_label: int
                         ) -> tuple[Blob | None, Blob | None, int]:
    """Dimorphos among the objects of ``root``, the region Didymos was cut out of or Didymos's own
    (``Regions.deblended``), the object it is or was cut from, and the next free label: its own peak parts from
    Didymos's at some level. Candidates are the objects no smaller than Dimorphos can be (its expected area over
    the largest radius factor squared: the part of a Dimorphos in front of Didymos's limb brighter than the limb
    parts from it too, its centroid off the body's) nor larger (a larger one, both bodies resolved, its brightest
    pixels of Dimorphos's expected area), off Didymos's disc and, cut to their surface, where the lit part is
    expected (``_lit_agrees``: a piece of Didymos's limb or of the plume parts from the rest too); chosen among
    the frame's other candidates, so that a point-like one is weighed against all the frame's stars."""
    centre = _didymos_centre(didymos, exp)
    smallest = max(float(cfg.min_body_area_px), exp.dimorphos_area / exp.radius_factor_max ** 2)
    next_label = regions.free_label(next_label)
    # an object parts at its widest outline: a small Dimorphos at the root of its plume parts with the root around
    # it, so an object larger than Dimorphos can be is taken by its brightest pixels of its expected area when both
    # bodies are resolved at their predicted sizes (an unresolved Didymos's blur and noise part into objects of their
    # own, and an unresolved Dimorphos's expected area is any bright clump's peak)
    cut_larger = _didymos_resolved(exp, regions, cfg) and _must_be_resolved(exp.dimorphos_radius, regions, cfg)
    objects: list[tuple[Blob, Blob]] = []  # each candidate and the object it is or was cut from
    deblended = regions.deblended(root, cfg.deblend_levels, cfg.deblend_min_flux_fraction, next_label)
    # only a larger object is told from Didymos's own by it: not sought when there is none
    own = _didymos_object(regions, deblended, didymos, max(1, round(exp.didymos_area))) \
        if cut_larger and any(o.area_px > exp.dimorphos_area_max for o in deblended) else None
    for o in deblended:
        larger = cut_larger and o.area_px > exp.dimorphos_area_max
        # a larger object other than Didymos's own is judged by its brightest part: the limb or dust it holds beside
        # Dimorphos can put its centroid on a disc centred by a Didymos that Dimorphos pulled towards itself
        if (o is own) if larger else _distance(o.region_centroid_col_row, centre) <= exp.didymos_radius:
            continue
        next_label = regions.free_label(next_label)
        # Didymos's disc as it would be without the object: a Dimorphos merged with it pulls its centroid over
        disc = _centre_without(regions, didymos, o, exp) if larger else centre
        for p in regions.parts(o, round(exp.dimorphos_area), next_label) if larger else [o]:
            if smallest <= p.area_px <= exp.dimorphos_area_max \
                    and _distance(p.region_centroid_col_row, disc) > exp.didymos_radius:
                objects.append((p, o))
    next_label = regions.free_label(next_label)
    agree = []
    for o, source in objects:
        if _lit_agrees(_dimorphos_surface(regions, o, exp, next_label, place, cfg), place):
            agree.append((o, source))
        next_label = regions.free_label(next_label)
    if not agree:
        return None, None, next_label
    chosen = _choose_dimorphos(cands + [o for o, _ in agree], didymos, exp, place, None, None, cfg, regions,
                               didymos_probability)
    # the others were just found wanting without the objects: only an object is taken here
    source = next((src for o, src in agree if o is chosen), None)
    return (None, None, next_label) if source is None else (chosen, source, next_label)


def _centre_without(regions: Regions, didymos: Blob, o: Blob, exp: Expected) -> tuple[float, float]:
    """Didymos's centre (``_didymos_centre``) from its pixels outside the object ``o`` (all of them if none is)."""
    mine = regions.pixels_of(didymos)
    rest = np.setdiff1d(mine, regions.pixels_of(o), assume_unique=True)
    if rest.size == 0 or rest.size == mine.size:
        return _didymos_centre(didymos, exp)
    rows, cols = np.divmod(regions.components.pixel_index[rest], regions.width)
    return _didymos_centre(didymos._replace(region_centroid_col_row=(float(cols.mean()), float(rows.mean()))), exp)


def _didymos_object(regions: Regions, objects: list[Blob], didymos: Blob, n_pixels: int) -> Blob | None:
    """The deblended object holding the most of Didymos's surface, its brightest ``n_pixels`` (its expected area:
    the dust and a Dimorphos beside it are fainter or smaller); None if none holds any."""
    mine, _ = regions.brightest(didymos, n_pixels)
    marked = np.zeros(regions.components.pixel_index.size, dtype=np.bool_)
    marked[mine] = True
    shared = [int(np.count_nonzero(marked[regions.pixels_of(o)])) for o in objects]
    return objects[int(np.argmax(shared))] if shared and max(shared) > 0 else None


def _without(regions: Regions, region: Blob, part: Blob, exp: Expected, cfg: ImagingConfig, place: _Place,
             next_label: int) -> tuple[Blob, int]:
    """A region (Didymos's, whole or cut) without one of the deblended objects of the region it belongs to
    (``part``, recorded as the n brightest pixels that cut it): without the part of the region's own n brightest
    pixels sharing the most pixels with the object (the object itself when the region is whole), as Didymos
    (``_best_didymos`` among its 8-connected pieces), and the next free label; the region itself when the object
    does not overlap it or nothing is left."""
    n = int(part.cuts[-1])  # type: ignore[arg-type]
    theirs = regions.pixels_of(part)
    next_label = regions.free_label(next_label)
    held, anchor = None, None
    for p in regions.parts(region, n, next_label):
        common = np.intersect1d(regions.pixels_of(p), theirs, assume_unique=True)
        if common.size and (anchor is None or common.size > anchor.size):
            held, anchor = p, common
    if held is None or anchor is None:
        return region, regions.free_label(next_label)
    sel = np.setdiff1d(regions.pixels_of(region), regions.pixels_of(held), assume_unique=True)
    row, col = divmod(int(regions.components.pixel_index[anchor[0]]), regions.width)
    next_label = regions.free_label(next_label)
    pieces = regions._cut(region, sel, region.threshold_dn8, next_label, Without(n, col, row)) if sel.size else []
    next_label = regions.free_label(next_label)
    return (_best_didymos(pieces, exp, regions, cfg, place)[0] if pieces else region), next_label


def _surface_area(regions: Regions | None, blob: Blob, exp: Expected) -> int:
    """A blob's area without the fainter dust around a surface: its pixels at least halfway from the threshold to the
    typical level of its brightest Dimorphos's expected area (``surface_pixels``); its whole area without the
    regions."""
    if regions is None:
        return blob.area_px
    return min(blob.area_px, surface_pixels(regions, blob, round(exp.dimorphos_area)))


def _brightest_surface_at(regions: Regions | None, chosen: Blob, cands: list[Blob], exp: Expected, next_label: int,
                          place: _Place, cfg: ImagingConfig) -> Blob:
    """Dimorphos when Didymos is out of the image: the surface (``_dimorphos_surface``) of the ``chosen`` blob, or of
    another candidate at Dimorphos's place (centroid within its radius) of at least a quarter of Dimorphos's expected
    area and at most its largest, not at the image's edge, whichever is brightest by mean (ties: the chosen). A lit
    surface is brighter than the dust around it (``trimmed``'s rule), and a plume seen past a crescent's dark limb is
    a region of its own: the chosen blob, holding the most light, may be the plume. A region at the edge may be the
    limb of Didymos beyond it, as bright as any surface, and within a place known to tens of px. Dimorphos's centroid
    is within the place's radius: when the chosen blob's surface is not (a brighter piece of Didymos's limb at the
    edge, reaching towards the place), any such candidate is taken before it."""
    best = _dimorphos_surface(regions, chosen, exp, next_label, place, cfg)
    if regions is None:
        return best
    at_place = _distance(best.region_centroid_col_row, place.col_row) <= place.radius_px
    n = exp.dimorphos_area
    for c in cands:
        if c is chosen or c.touches_edge or 4 * c.area_px < n or c.area_px > exp.dimorphos_area_max \
                or _distance(c.region_centroid_col_row, place.col_row) > place.radius_px:
            continue
        next_label = regions.free_label(next_label)
        surface = _dimorphos_surface(regions, c, exp, next_label, place, cfg)
        if not at_place or surface.mean_dn8 > best.mean_dn8:
            best, at_place = surface, True
    return best


def _cut_beyond_gate(surface: Blob, didymos: Blob, exp: Expected, cfg: ImagingConfig) -> bool:
    """Whether a surface cut out of the region taken for Dimorphos lies beyond the gate (``_dimorphos_gate``): a
    region holding ejecta is taken by its box (Dimorphos, their source, at one end of it), and its brightest part may
    be the dust's, beyond the orbit's reach of Didymos (held-out 135/189: the plume's, 50 px from Didymos)."""
    return _distance(surface.region_centroid_col_row, didymos.region_centroid_col_row) > _dimorphos_gate(didymos, exp,
                                                                                                        cfg)


def _dimorphos_surface(regions: Regions | None, dimorphos: Blob, exp: Expected, next_label: int,
                       place: _Place | None, cfg: ImagingConfig) -> Blob:
    """The blob taken for Dimorphos, trimmed to its surface (``trimmed``) when it is larger than Dimorphos can be,
    cut out of a blob that held ejecta, a resolved disc (the point-spread function's reach, psf_reach_px, under
    half its radius) larger than expected, perhaps with dust brighter than the threshold around it, or larger than
    the disc of its predicted radius widened by that reach (a small body's light stays within it; ejecta do not)."""
    reach = psf_reach_px(cfg)
    if regions is not None and (
            dimorphos.area_px > exp.dimorphos_area_max
            or dimorphos.area_px > exp.dimorphos_area and (
                dimorphos.trimmed_from
                or exp.dimorphos_radius / exp.radius_factor_max >= 2.0 * reach
                or dimorphos.area_px > math.pi * (exp.dimorphos_radius + reach + 1.0) ** 2)):
        return trimmed(regions, dimorphos, round(exp.dimorphos_area), next_label, place, cfg,
                       _dimorphos_resolved_diameter_px(exp, regions, cfg))
    return dimorphos


def phase_corrected(blob: Blob | None, radius_px: float | None, prediction: FramePrediction | None,
                    cfg: ImagingConfig, fov_deg: float) -> Blob | None:
    """The blob with its centroid moved from the lit part to the body's centre (``phase_offset_px``) for the body's
    predicted apparent radius ``radius_px``; unchanged without one (no trajectory on board)."""
    if blob is None or prediction is None or radius_px is None or not cfg.phase_correction:
        return blob
    dc, dr = phase_offset_px(prediction.sun_camera, blob.region_centroid_col_row, radius_px, fov_deg,
                             cfg.binned_size_px)
    c = blob.region_centroid_col_row
    return blob._replace(centroid_col_row=(c[0] - dc, c[1] - dr))
