"""The stars: a seeded all-sky catalogue and explicit ones, drawn as smeared PSFs where no body hides them.

The seeded catalogue has uniform directions and counts ``N(<m) = 4800 * 10^(0.46 (m - 6))`` over the sky, generated
lazily per cell of a cube-sphere tiling, so the same seed gives the same sky whatever the pointing. Each star is
smeared by the image motion at its own position (the body rate, roll included).
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from universe.camera.pinhole import image_velocity_px_s, view_basis
from universe.camera.psf import psf_half_size_px, smeared_psf
from universe.camera.scene import Scene
from universe.config import CameraConfig

_SKY_CELLS_PER_FACE = 32
_STARS_BRIGHTER_THAN_6 = 4800.0  # whole-sky count of stars brighter than V = 6 (Allen's Astrophysical Quantities)
_STAR_COUNT_SLOPE = 0.46  # d log10 N / d m for V ~ 6-10 (Allen's Astrophysical Quantities)


def _cube_cell(v: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Face (0-5), i, j of the cube-sphere cell holding each unit vector (n, 3)."""
    ax = np.argmax(np.abs(v), axis=1)
    rows = np.arange(len(v))
    major = v[rows, ax]
    face = ax * 2 + (major < 0)
    a1 = (ax + 1) % 3
    a2 = (ax + 2) % 3
    u = v[rows, a1] / np.abs(major)
    w = v[rows, a2] / np.abs(major)
    k = _SKY_CELLS_PER_FACE
    i = np.clip(((u + 1.0) * 0.5 * k).astype(int), 0, k - 1)
    j = np.clip(((w + 1.0) * 0.5 * k).astype(int), 0, k - 1)
    return face, i, j


@lru_cache(maxsize=4096)
def _cell_stars(seed: int, face: int, i: int, j: int, limiting_mag: float) -> tuple[np.ndarray, np.ndarray]:
    """Seeded stars of one cube-sphere cell: inertial unit directions (n, 3) and magnitudes (n,)."""
    k = _SKY_CELLS_PER_FACE
    u0, u1 = -1.0 + 2.0 * i / k, -1.0 + 2.0 * (i + 1) / k
    w0, w1 = -1.0 + 2.0 * j / k, -1.0 + 2.0 * (j + 1) / k

    def corner(u: float, w: float) -> float:
        return math.atan(u * w / math.sqrt(1.0 + u * u + w * w))

    solid_angle = corner(u1, w1) - corner(u0, w1) - corner(u1, w0) + corner(u0, w0)
    per_sr = _STARS_BRIGHTER_THAN_6 * 10.0 ** (_STAR_COUNT_SLOPE * (limiting_mag - 6.0)) / (4.0 * math.pi)
    rng = np.random.default_rng([seed, face, i, j])
    n = int(rng.poisson(per_sr * solid_angle))
    # uniform in the face coordinates: the density varies by < 1 % across a cell
    u = rng.uniform(u0, u1, n)
    w = rng.uniform(w0, w1, n)
    ax = face // 2
    v = np.empty((n, 3))
    v[:, ax] = -1.0 if face % 2 else 1.0
    v[:, (ax + 1) % 3] = u
    v[:, (ax + 2) % 3] = w
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    mags = limiting_mag + np.log10(1.0 - rng.uniform(0.0, 1.0, n)) / _STAR_COUNT_SLOPE
    v.setflags(write=False)
    mags.setflags(write=False)
    return v, mags


_STAR_BIN_PER_RAD = 400.0  # boresight components are rounded to 1/400: star sets are cached per 0.14 deg bin


def sky_stars(seed: int, c2i: np.ndarray, cfg: CameraConfig) -> tuple[np.ndarray, np.ndarray]:
    """Seeded all-sky stars near the field of view: inertial unit directions (n, 3) and magnitudes (n,).

    The stars of every cube-sphere cell within the field's circumscribed cone plus one cell, around the boresight
    rounded to a bin (any roll), cached per bin: a superset of the stars in the field, the same on every call.
    """
    b = c2i[:, 2]
    key = (round(float(b[0]) * _STAR_BIN_PER_RAD), round(float(b[1]) * _STAR_BIN_PER_RAD),
           round(float(b[2]) * _STAR_BIN_PER_RAD))
    return _sky_stars_around(seed, key, float(cfg.fov_deg), float(cfg.star_limiting_mag))


@lru_cache(maxsize=512)
def _sky_stars_around(
    seed: int, key: tuple[int, int, int], fov_deg: float, limiting_mag: float
) -> tuple[np.ndarray, np.ndarray]:
    """Stars of the cells within the field's half-diagonal plus one cell (3.5 deg) and the bin's reach of a
    boresight bin ``key`` (components times _STAR_BIN_PER_RAD)."""
    centre = np.asarray(key, dtype=np.float64)
    centre /= np.linalg.norm(centre)
    reach = math.radians(fov_deg) / 2.0 * math.sqrt(2.0) + math.radians(3.5) + math.sqrt(3.0) / _STAR_BIN_PER_RAD
    e1, e2 = view_basis(centre)
    g = np.tan(np.linspace(-reach, reach, int(math.degrees(2 * reach) / 0.3) + 2))
    gx, gy = np.meshgrid(g, g)
    near = gx * gx + gy * gy <= math.tan(reach) ** 2 * 1.02
    probe = centre + gx[near][:, None] * e1 + gy[near][:, None] * e2
    probe /= np.linalg.norm(probe, axis=1, keepdims=True)
    cells = set(zip(*(a.tolist() for a in _cube_cell(probe))))
    dirs, mags = [], []
    for face, i, j in sorted(cells):
        d, m = _cell_stars(seed, face, i, j, limiting_mag)
        dirs.append(d)
        mags.append(m)
    out = (np.concatenate(dirs), np.concatenate(mags)) if dirs else (np.empty((0, 3)), np.empty(0))
    for arr in out:
        arr.setflags(write=False)
    return out

def add_stars(
    scene: Scene,
    cfg: CameraConfig,
    c2i: np.ndarray,
    omega_c: np.ndarray,
    f: float,
    cx: float,
    cy: float,
    signal: np.ndarray,
    occluders: list[tuple[tuple[int, int, int, int], np.ndarray]],
) -> np.ndarray:
    """Add the visible stars' smeared PSFs to ``signal``; return the flat indices touched."""
    dirs, mags = [], []
    if scene.star_seed is not None:
        d, m = sky_stars(scene.star_seed, c2i, cfg)
        dirs.append(d)
        mags.append(m)
    if scene.star_catalogue is not None:
        dirs.append(scene.star_catalogue.directions_inertial)
        mags.append(scene.star_catalogue.magnitudes)
    if not dirs:
        return np.empty(0, dtype=np.int64)
    v = np.concatenate(dirs) @ c2i  # camera frame
    mag = np.concatenate(mags)
    size = cfg.resolution_px
    front = v[:, 2] > 1e-6
    v, mag = v[front], mag[front]
    col = cx + f * v[:, 0] / v[:, 2]
    row = cy + f * v[:, 1] / v[:, 2]
    w0, w1, w2 = float(omega_c[0]), float(omega_c[1]), float(omega_c[2])
    # -omega x v per star, by components (np.cross costs more in argument handling than in arithmetic)
    dv = np.stack([w2 * v[:, 1] - w1 * v[:, 2], w0 * v[:, 2] - w2 * v[:, 0], w1 * v[:, 0] - w0 * v[:, 1]], axis=1)
    smear = image_velocity_px_s(v, dv, f) * scene.exposure_s
    reach = np.max(np.abs(smear), axis=0, initial=0.0)
    if not np.all(np.isfinite(reach)) or psf_half_size_px(cfg.psf_sigma_px, float(reach.max())) > _MAX_STAMP_HALF_PX:
        return _add_star_trails(v, mag, scene.exposure_s, cfg, omega_c, f, cx, cy, signal, occluders)
    # stamps cut at 3.5 sigma beyond half the smear along each image axis (a rectangle along a streak)
    hx = psf_half_size_px(cfg.psf_sigma_px, float(reach[0]))
    hy = psf_half_size_px(cfg.psf_sigma_px, float(reach[1]))
    keep = (col > -hx) & (col < size - 1 + hx) & (row > -hy) & (row < size - 1 + hy)
    ic = np.rint(col).astype(np.int64)
    ir = np.rint(row).astype(np.int64)
    for (r0, r1, c0, c1), hit in occluders:
        inside = keep & (ir >= r0) & (ir < r1) & (ic >= c0) & (ic < c1)
        where = np.flatnonzero(inside)
        keep[where[hit[ir[where] - r0, ic[where] - c0]]] = False
    if not keep.any():
        return np.empty(0, dtype=np.int64)
    col, row, ic, ir, mag, smear = col[keep], row[keep], ic[keep], ir[keep], mag[keep], smear[keep]
    ox = np.arange(-hx, hx + 1)
    oy = np.arange(-hy, hy + 1)
    pc = ic[:, None, None] + ox[None, None, :]
    pr = ir[:, None, None] + oy[None, :, None]
    sm = smear.astype(np.float32)
    stamp = smeared_psf(
        (pc - col[:, None, None]).astype(np.float32),
        (pr - row[:, None, None]).astype(np.float32),
        cfg.psf_sigma_px,
        sm[:, 0, None, None],
        sm[:, 1, None, None],
    )
    flux_e = (cfg.star_mag0_e_s * 10.0 ** (-0.4 * mag) * scene.exposure_s).astype(np.float32)
    stamp *= (flux_e / stamp.sum(axis=(1, 2)))[:, None, None]
    pr, pc = np.broadcast_arrays(pr, pc)
    ok = (pr >= 0) & (pr < size) & (pc >= 0) & (pc < size)
    flat = pr[ok] * size + pc[ok]
    np.add.at(signal.reshape(-1), flat, stamp[ok])
    return flat



# Streaks whose stamps would reach farther than this (px) from the star, or stars whose image-plane motion is not
# finite (near the image plane), are drawn as trails of point images along their true path instead of rectangles.
_MAX_STAMP_HALF_PX = 128
_TRAIL_SAMPLES_MAX = 1 << 20  # point images per frame at most (all stars): bounds the work of any rate and exposure
_TRAIL_CHUNK = 1 << 16  # point images stamped at a time


def _add_star_trails(
    v: np.ndarray, mag: np.ndarray, exposure_s: float, cfg: CameraConfig, omega_c: np.ndarray, f: float, cx: float,
    cy: float, signal: np.ndarray, occluders: list[tuple[tuple[int, int, int, int], np.ndarray]],
) -> np.ndarray:
    """Add stars (camera-frame unit directions ``v`` at mid-exposure) as the average of their point images over the
    exposure while the camera turns at ``omega_c``: K instants evenly spread over it, at most half a PSF sigma apart
    in the frame (a sum of Gaussians one sigma apart is already flat to 1e-8; half a sigma keeps the streak's ends
    within 0.5 % of the peak of the closed form), each with 1/K of the star's light and hidden where a body covers
    it. Return the flat indices touched. Used for long streaks: the cost grows with the length of the
    trails inside the frame, not with the square of the streak, and the path is exact (a rotation), not linearised.
    """
    size = cfg.resolution_px
    sigma = cfg.psf_sigma_px
    rate = float(np.linalg.norm(omega_c))
    turn = rate * exposure_s  # rad the camera turns in the exposure
    half_diag = math.atan(math.hypot(size, size) / (2.0 * f))
    # only stars within the field's half-diagonal plus the turn (and the PSF) of the boresight can enter the frame
    reach = half_diag + turn + 4.0 * sigma / f
    if reach < math.pi:
        near = v[:, 2] >= math.cos(reach)
        v, mag = v[near], mag[near]
    if len(v) == 0:
        return np.empty(0, dtype=np.int64)
    # the frame's pixels move at up to |omega| f (1 + tan^2) px/s: instants half a sigma apart there
    px_per_rad = f * (1.0 + math.tan(min(half_diag, 1.5)) ** 2)
    k = int(min(max(math.ceil(2.0 * turn * px_per_rad / sigma), 1), max(_TRAIL_SAMPLES_MAX // len(v), 1)))
    frac = (np.arange(k) + 0.5) / k - 0.5  # instants, fraction of the exposure from mid-exposure
    if rate > 0.0:
        axis = omega_c / rate
        # a fixed direction seen from a camera turning at omega: v(t) = R(-omega t) v (Rodrigues)
        phi = -turn * frac
        cos_p, sin_p = np.cos(phi)[None, :, None], np.sin(phi)[None, :, None]
        axv = np.cross(axis, v)[:, None, :]
        adv = (v @ axis)[:, None, None] * axis[None, None, :]
        pts = v[:, None, :] * cos_p + axv * sin_p + adv * (1.0 - cos_p)  # (stars, k, 3)
    else:
        pts = v[:, None, :]
    flux_e = np.repeat(cfg.star_mag0_e_s * 10.0 ** (-0.4 * mag) * exposure_s / k, pts.shape[1])
    pts = pts.reshape(-1, 3)
    h = psf_half_size_px(sigma, 0.0)
    front = pts[:, 2] > 1e-6
    z = np.where(front, pts[:, 2], 1.0)
    col = cx + f * pts[:, 0] / z
    row = cy + f * pts[:, 1] / z
    keep = front & (col > -h) & (col < size - 1 + h) & (row > -h) & (row < size - 1 + h)
    col, row, flux_e = col[keep], row[keep], flux_e[keep]
    ic = np.rint(col).astype(np.int64)
    ir = np.rint(row).astype(np.int64)
    seen = np.ones(len(col), dtype=bool)
    for (r0, r1, c0, c1), hit in occluders:
        where = np.flatnonzero((ir >= r0) & (ir < r1) & (ic >= c0) & (ic < c1))
        seen[where[hit[ir[where] - r0, ic[where] - c0]]] = False
    col, row, ic, ir, flux_e = col[seen], row[seen], ic[seen], ir[seen], flux_e[seen]
    o = np.arange(-h, h + 1)
    zero = np.float32(0.0)
    touched = np.zeros(size * size, dtype=bool)
    for s in range(0, len(col), _TRAIL_CHUNK):
        part = slice(s, s + _TRAIL_CHUNK)
        pc = ic[part, None, None] + o[None, None, :]
        pr = ir[part, None, None] + o[None, :, None]
        stamp = smeared_psf((pc - col[part, None, None]).astype(np.float32),
                            (pr - row[part, None, None]).astype(np.float32), sigma, zero, zero)
        stamp *= (flux_e[part] / stamp.sum(axis=(1, 2))).astype(np.float32)[:, None, None]
        pr, pc = np.broadcast_arrays(pr, pc)
        ok = (pr >= 0) & (pr < size) & (pc >= 0) & (pc < size)
        flat = pr[ok] * size + pc[ok]
        np.add.at(signal.reshape(-1), flat, stamp[ok])
        touched[flat] = True
    return np.flatnonzero(touched)
