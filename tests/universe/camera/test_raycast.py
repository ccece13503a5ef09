"""The compiled ray caster hits a body where a ray would, with the right depth and shading, at every grid step."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from universe.camera import Body, focal_length_px, principal_point_px
from universe.camera.bodies import BodyCaster, BodyView, body_box
from universe.camera.raycast import cast_body
from universe.config import CameraConfig
from universe.shapes import ShapeModel

CFG = CameraConfig(phase_slope_mag_deg=0.0)
F = focal_length_px(CFG)
CX, CY = principal_point_px(CFG)
SPREAD = {4: 1.7, 2: 3.0}  # bodies._SMOOTH_SPREAD_CELLS: the thresholds the camera uses


def caster_for(body: Body, centre_c: np.ndarray, sun_c: np.ndarray) -> tuple[BodyCaster, tuple[int, int, int, int]]:
    """The camera's per-frame tables of ``body`` seen at ``centre_c`` (camera frame, camera axes = inertial)."""
    r_max = body.radius_m * body.shape.max_radius()
    box = body_box(centre_c, r_max, F, CX, CY, CFG.resolution_px, 2)
    assert box is not None
    view = BodyView(0, body, centre_c, r_max, box, (0.0, 0.0))
    return BodyCaster(view, np.eye(3), sun_c, CFG, F, CX, CY), box


def cast(caster: BodyCaster, box: tuple[int, int, int, int], step: int, window: bool = True):
    """Depth (m, inf off the body; 0 where interpolated outside the window) and signal (e-/s) over ``box``."""
    r0, r1, c0, c1 = box
    depth = np.full((r1 - r0, c1 - c0), np.inf, dtype=np.float32)
    sig = np.zeros_like(depth)
    win = np.array((0, r1 - r0, 0, c1 - c0) if window else (0, 0, 0, 0), dtype=np.int64)
    cell_m = caster.dist / F
    cast_body(r0, c0, step, SPREAD[4] * 4 * cell_m, SPREAD[2] * 2 * cell_m, win, caster.table, caster.limb,
              caster.basis, caster.sun_v, caster.geometry, depth, sig)
    return depth, sig


def sphere_truth(box, centre_c: np.ndarray, radius: float, sun_c: np.ndarray, scale_e_s: float, w: float):
    """Closed form: ray/sphere front intersection distance and lunar-Lambert signal at every pixel of ``box``."""
    r0, r1, c0, c1 = box
    rows, cols = np.mgrid[r0:r1, c0:c1].astype(float)
    d = np.stack([(cols - CX) / F, (rows - CY) / F, np.ones_like(cols)], axis=-1)
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    b = d @ centre_c
    disc = b * b - centre_c @ centre_c + radius * radius
    hit = disc >= 0
    t_hit = b - np.sqrt(np.where(hit, disc, 0.0))
    n = (t_hit[..., None] * d - centre_c) / radius
    t = np.where(hit, t_hit, np.inf)
    mu0 = np.clip(n @ sun_c, 0.0, None)
    mu = np.clip(-np.sum(n * d, axis=-1), 0.0, None)
    law = w * 2 * mu0 / np.maximum(mu0 + mu, 1e-12) + (1 - w) * mu0
    return hit, t, np.where(hit, scale_e_s * law, 0.0)


@pytest.mark.parametrize("step", [1, 2, 4])
@pytest.mark.parametrize("offset_px", [(0.0, 0.0), (137.3, -88.6)])
def test_sphere_depth_and_shading_match_the_closed_form(step: int, offset_px: tuple[float, float]) -> None:
    """A sphere: hit pixels, depth and lunar-Lambert signal match the closed-form ray/sphere intersection."""
    radius, rng_m = 390.0, 30_000.0  # 314 px across: the 4 px quadtree is used by the camera
    centre = np.array([offset_px[0] / F * rng_m, offset_px[1] / F * rng_m, rng_m])
    sun = np.array([0.5, -0.2, -1.0]) / np.linalg.norm([0.5, -0.2, -1.0])
    caster, box = caster_for(Body(centre, radius, ShapeModel(irregularity=0.0)), centre, sun)
    depth, sig = cast(caster, box, step)
    hit, t, expected = sphere_truth(box, centre, radius, sun, caster.geometry[7], CFG.lommel_seeliger_weight)
    seen = np.isfinite(depth)
    assert np.count_nonzero(seen ^ hit) <= 2e-3 * hit.sum()  # at most grazing pixels on the rim differ
    both = seen & hit
    # cast pixels are within a tenth of a pixel's width; interpolated ones (bilinear across 2-4 px) within one
    assert np.max(np.abs(depth[both] - t[both])) < (0.1 if step == 1 else 1.0) * rng_m / F
    err = np.abs(sig[both] - expected[both]) / expected.max()
    assert np.median(err) < 1e-3 and np.percentile(err, 99) < 0.01


@pytest.mark.parametrize("seed", [1, 2, 3])
@pytest.mark.parametrize("diameter_px", [70.0, 320.0])
def test_quadtree_matches_casting_every_pixel_on_an_irregular_body(seed: int, diameter_px: float) -> None:
    """An irregular body: the 2 px and 4 px quadtrees hit the same pixels as casting every pixel, with the same light
    to within a few per cent of the peak per pixel and 0.5 % in total, and the same depth within a pixel's width but
    for a few grazing rays on the limb (where either may find a surface behind a bump: see
    ``universe.camera.raycast``)."""
    rng = np.random.default_rng(seed)
    radius = 390.0
    rng_m = 2 * radius * F / diameter_px
    centre = np.array([rng.uniform(-60, 60) / F * rng_m, rng.uniform(-60, 60) / F * rng_m, rng_m])
    sun = rng.normal(size=3)
    sun[2] = -abs(sun[2])  # phase under 90 deg: mostly lit
    sun /= np.linalg.norm(sun)
    shape = ShapeModel(irregularity=0.12, seed=seed)
    body = Body(centre, radius, shape, Rotation.random(random_state=seed).as_quat())
    caster, box = caster_for(body, centre, sun)
    ref_depth, ref_sig = cast(caster, box, 1)
    for step in (2, 4):
        depth, sig = cast(caster, box, step)
        hit, ref_hit = np.isfinite(depth), np.isfinite(ref_depth)
        assert np.count_nonzero(hit ^ ref_hit) <= 2e-3 * ref_hit.sum()
        err = np.abs(sig - ref_sig) / ref_sig.max()
        assert np.percentile(err[ref_hit], 99) < 0.04
        assert sig.sum() == pytest.approx(ref_sig.sum(), rel=5e-3)
        both = hit & ref_hit
        assert np.count_nonzero(np.abs(depth[both] - ref_depth[both]) > rng_m / F) <= 5e-3 * both.sum()


def test_interpolated_pixels_have_depth_only_inside_the_window() -> None:
    """Interpolated pixels get depth 0 outside the depth window (only whether they hit is kept), a depth inside."""
    radius, rng_m = 390.0, 30_000.0
    centre = np.array([0.0, 0.0, rng_m])
    sun = np.array([0.0, 0.0, -1.0])
    caster, box = caster_for(Body(centre, radius, ShapeModel(irregularity=0.0)), centre, sun)
    full, _ = cast(caster, box, 4, window=True)
    bare, _ = cast(caster, box, 4, window=False)
    assert np.array_equal(np.isfinite(full), np.isfinite(bare))
    assert np.all(full[np.isfinite(full)] > rng_m - 2 * radius)
    zero = bare == 0
    assert zero.sum() > 0.5 * np.isfinite(bare).sum()  # most of the disc is interpolated
    assert np.all(np.isin(bare[np.isfinite(bare) & ~zero], full))  # cast pixels keep their depth


def test_a_ray_outside_the_bounding_sphere_never_hits() -> None:
    """Rays passing the centre farther than the bounding radius miss, whatever the table says."""
    radius, rng_m = 390.0, 30_000.0
    centre = np.array([0.0, 0.0, rng_m])
    caster, box = caster_for(Body(centre, radius, ShapeModel(irregularity=0.2, seed=5)), centre, np.array([0, 0, -1.0]))
    depth, _ = cast(caster, box, 1)
    r0, r1, c0, c1 = box
    rows, cols = np.mgrid[r0:r1, c0:c1]
    off_axis_m = np.hypot(cols - CX, rows - CY) / F * rng_m
    assert not np.any(np.isfinite(depth) & (off_axis_m > caster.geometry[5] * 1.001))


def test_from_inside_the_bounding_sphere_rays_meet_the_closed_form_ellipsoid() -> None:
    """A camera inside an ellipsoid's bounding sphere, outside its surface, 77 m from it and looking at it 40 deg off
    its centre: every pixel hits, with the closed-form ray/ellipsoid depth (to 1 %: the shape tables' resolution) and
    lunar-Lambert signal, whether cast at every pixel or as the camera's quadtree."""
    radius = 390.0
    shape = ShapeModel(irregularity=0.0, axis_ratios=(0.8, 1.0, 1.25))
    semi = radius * np.array([0.8, 1.0, 1.25]) / np.prod([0.8, 1.0, 1.25]) ** (1 / 3)
    centre = 420.0 * np.array([np.sin(np.radians(40.0)), 0.0, np.cos(np.radians(40.0))])
    assert np.sum((centre / semi) ** 2) > 1.0 and np.linalg.norm(centre) < radius * shape.max_radius()
    sun = np.array([-0.6, -0.3, -1.0]) / np.linalg.norm([-0.6, -0.3, -1.0])
    caster, box = caster_for(Body(centre, radius, shape), centre, sun)
    r0, r1, c0, c1 = box
    rows, cols = np.mgrid[r0:r1, c0:c1].astype(float)
    d = np.stack([(cols - CX) / F, (rows - CY) / F, np.ones_like(cols)], axis=-1)
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    # closed form: x = t d on ((x - c) / semi)^2 = 1, the nearer root
    a = np.sum((d / semi) ** 2, -1)
    b = -2 * np.sum(d * centre / semi**2, -1)
    c = np.sum((centre / semi) ** 2) - 1
    t = (-b - np.sqrt(b * b - 4 * a * c)) / (2 * a)
    n = (t[..., None] * d - centre) / semi**2
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    mu0, mu = np.clip(n @ sun, 0, None), np.clip(-np.sum(n * d, -1), 0, None)
    w = CFG.lommel_seeliger_weight
    expected = caster.geometry[7] * (w * 2 * mu0 / np.maximum(mu0 + mu, 1e-12) + (1 - w) * mu0)
    assert 70.0 < t.min() and t.max() < 85.0
    for step in (1, 4):
        depth, sig = cast(caster, box, step)
        assert np.all(np.isfinite(depth))
        assert np.max(np.abs(depth - t) / t) < 0.01
        err = np.abs(sig - expected) / expected.max()
        assert np.median(err) < 1e-3 and np.percentile(err, 99) < 5e-3
