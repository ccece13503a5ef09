"""Compiled ray casting of one star-shaped body: the camera's inner loops, one ray at a time (Numba).

Theory of operation: a body is described, per frame, in its view frame (e3 from the body centre to the camera) by
a table of radius and view-frame normal over the stereographic coordinates of the direction from the centre
(``universe.camera.bodies._shape_table``) and by its limb: the largest perspective-projected radius per image
polar-angle bin (``universe.camera.bodies._limb_radius``). A ray through a pixel centre is tested against the limb
first (outside it the ray misses), then its front intersection with ``|x| = r(x / |x|)`` is found by safeguarded
Newton steps along the ray, bilinear look-ups in the table giving the radius and the normal, and the
lunar-Lambert law gives the signal there. Each ray stops as soon as it is on the surface, which array code could
not do without compacting its arrays every step. ``cast_body`` runs the quadtree over a body's box (see its
docstring), so that only the cells where the shading is not smooth are cast at every pixel.

A camera inside the bounding sphere (but outside the surface) has no silhouette to test against: each ray then
marches from the camera across the bounding sphere in ``NEAR_STEPS`` steps to its first point inside the surface
and refines the crossing from there. Outside the bounding sphere, a ray pointing away from the body centre misses.

Known limit: a ray grazing the limb through a bump can pass the bump's front surface between two Newton steps and
stop on the surface behind it: its depth is then too far (by up to the body's size) while its shading is that of a
grazing surface either way. In tests on irregular bodies this is under 0.2 % of the hit pixels, all on the limb.

Compiled on first use and cached next to this file (``cache=True``), so only the first process after an install
or an edit pays the compilation (a few seconds); ``warm_up`` lets a node pay it before its first frame is due.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

TABLE_S = 1.5  # stereographic half-extent of the shape tables: directions up to 112 deg from the camera direction
RAY_ITERATIONS = 6  # safeguarded Newton steps at most; rays on the surface stop earlier (most take 1 to 3)
NEAR_STEPS = 64  # steps across the bounding sphere searching for the surface from a camera inside that sphere
_FLOOR = 1e-3  # lower bound of the stereographic denominator and of n.x, relative to |x|


@njit(cache=True, nogil=True)
def _pseudo_angle(x: float, y: float) -> float:
    """A cheap increasing function of atan2(y, x) in [0, 4): 0 along +x, 1 along +y, 2 along -x, 3 along -y."""
    t = x / (abs(x) + abs(y) + 1e-30)
    return 1.0 - t + (2.0 + 2.0 * t if y < 0.0 else 0.0)


@njit(cache=True, nogil=True, inline="always")
def _lookup(table: np.ndarray, u: float, v: float) -> tuple[float, float, float, float]:
    """Bilinear look-up of the (n, n, 4) table at column ``u``, row ``v`` (clamped to the table, as a replicated
    border would)."""
    n = table.shape[0]
    u = min(max(u, 0.0), n - 1.0)
    v = min(max(v, 0.0), n - 1.0)
    j = min(int(u), n - 2)
    i = min(int(v), n - 2)
    fu = u - j
    fv = v - i
    w00 = (1.0 - fu) * (1.0 - fv)
    w01 = fu * (1.0 - fv)
    w10 = (1.0 - fu) * fv
    w11 = fu * fv
    # scalar indexing only: a row view of the table would be a new array, reference counted at every look-up
    return (
        w00 * table[i, j, 0] + w01 * table[i, j + 1, 0] + w10 * table[i + 1, j, 0] + w11 * table[i + 1, j + 1, 0],
        w00 * table[i, j, 1] + w01 * table[i, j + 1, 1] + w10 * table[i + 1, j, 1] + w11 * table[i + 1, j + 1, 1],
        w00 * table[i, j, 2] + w01 * table[i, j + 1, 2] + w10 * table[i + 1, j, 2] + w11 * table[i + 1, j + 1, 2],
        w00 * table[i, j, 3] + w01 * table[i, j + 1, 3] + w10 * table[i + 1, j, 3] + w11 * table[i + 1, j + 1, 3],
    )


@njit(cache=True, nogil=True, inline="always")
def _gap(table: np.ndarray, x1: float, x2: float, x3: float, bb: float, h: float, tiny: float, scale: float,
         off: float) -> float:
    """``|x| - r(x / |x|)`` (m) at the ray point x = q - h d (``bb`` = |q|^2): positive outside the surface."""
    qn = math.sqrt(bb + h * h) + tiny
    inv_den = scale / max(qn + x3, _FLOOR * qn)
    return qn - _lookup(table, x1 * inv_den + off, x2 * inv_den + off)[0]


@njit(cache=True, nogil=True)
def _cast_batch(
    rows: np.ndarray, cols: np.ndarray, guesses: np.ndarray, n: int, table: np.ndarray, limb: np.ndarray, ray: tuple,
    hits: np.ndarray, depths: np.ndarray, signals: np.ndarray,
) -> None:
    """Cast the first ``n`` rays through the pixel centres (``rows``, ``cols``): whether each hits, its depth (m along
    the ray from the camera) and signal (e-/s). A ``guesses`` entry (m, NaN for none) starts that ray's Newton steps
    ``warm_shift`` in front of it. ``ray`` holds the per-body constants (see ``cast_body``).

    The rays of a whole quadtree level are cast here in one loop: a function taking arrays, called per ray, would
    pay reference counting on every call.
    """
    dist, inv_f, cx, cy, r_min, r_max, radius, signal_scale, wls, warm_shift, near = ray[:11]
    b00, b01, b02, b10, b11, b12, b20, b21, b22, sun1, sun2, sun3 = ray[11:]
    n_side = table.shape[0]
    scale = (n_side - 1) / (2.0 * TABLE_S)
    off = TABLE_S * scale
    tiny = 1e-9 * dist
    tol = 1e-4 * radius
    bins = limb.shape[0] - 1
    inside_bound = near > 0.5
    for k in range(n):
        row, col, guess = rows[k], cols[k], guesses[k]
        # divisions and square roots are most of the cost: each one below is needed, and none is repeated
        dx = (col - cx) * inv_f
        dy = (row - cy) * inv_f
        inv = 1.0 / math.sqrt(dx * dx + dy * dy + 1.0)
        d1 = (b00 * dx + b01 * dy + b02) * inv
        d2 = (b10 * dx + b11 * dy + b12) * inv
        sin2 = d1 * d1 + d2 * d2
        bb = dist * dist * sin2  # squared distance of the ray from the centre
        if bb >= r_max * r_max:
            hits[k] = False
            continue
        away = b20 * dx + b21 * dy + b22 >= 0.0  # the ray points away from the centre (its e3 component is >= 0)
        if inside_bound:
            # the camera is inside the bounding sphere (not inside the surface): no silhouette; march from the camera
            # along the ray to the first point inside the surface, then refine between it and the previous step
            d3 = (b20 * dx + b21 * dy + b22) * inv
            q1, q2, q3 = -dist * d3 * d1, -dist * d3 * d2, dist * sin2
            chord = math.sqrt(r_max * r_max - bb)
            top = min(chord, -dist * d3)  # h of the camera: only points in front of it (smaller h) are seen
            lo = -chord
            dh = (top - lo) / NEAR_STEPS
            hi = top
            found = False
            for s in range(1, NEAR_STEPS + 1):
                h = top - s * dh
                if _gap(table, q1 - h * d1, q2 - h * d2, q3 - h * d3, bb, h, tiny, scale, off) <= 0.0:
                    lo = h
                    found = True
                    break
                hi = h
            if not found:
                hits[k] = False
                continue
            h = hi
        else:
            if away:  # the camera, outside the bounding sphere, is then the ray's closest point to the body
                hits[k] = False
                continue
            # silhouette: inside the body's projected limb radius rho_limb at the ray's polar angle in the view plane,
            # where the ray crosses it at rho^2 = bb / cos^2
            pos = _pseudo_angle(d1, d2) * (bins / 4.0)
            j = min(int(pos), bins - 1)
            rho_limb = limb[j] + (limb[j + 1] - limb[j]) * (pos - j)
            cos2 = 1.0 - sin2
            if bb > rho_limb * rho_limb * cos2:
                hits[k] = False
                continue
            d3 = -math.sqrt(cos2)
            # the ray passes the centre at q = (-dist d3 d1, -dist d3 d2, dist sin2); h counts the distance from there
            # towards the camera
            q1, q2, q3 = -dist * d3 * d1, -dist * d3 * d2, dist * sin2
            hi = math.sqrt(r_max * r_max - bb)
            inner = bb < r_min * r_min
            # inside the smallest radius the front root lies between that sphere and the bounding one
            lo = math.sqrt(r_min * r_min - bb) if inner else -hi
            if not math.isnan(guess):
                h = min(max(-dist * d3 - guess + warm_shift, lo), hi)
            elif inner:
                # first guess: a sphere as wide as the limb in this direction
                h = min(max(math.sqrt(max(rho_limb * rho_limb - bb, 0.0)), lo), hi)
            else:
                # off the inner sphere the front root is reached monotonically from the camera side: start there
                h = hi
        m1 = m2 = m3 = 0.0
        for _ in range(RAY_ITERATIONS):
            x1, x2, x3 = q1 - h * d1, q2 - h * d2, q3 - h * d3
            qn = math.sqrt(bb + h * h) + tiny
            den = max(qn + x3, _FLOOR * qn)
            p = 1.0 / (qn * den)
            inv_den = scale * qn * p  # scale / den
            r, m1, m2, m3 = _lookup(table, x1 * inv_den + off, x2 * inv_den + off)
            g = qn - r
            if abs(g) <= tol:
                break
            inv_q = den * p  # 1 / qn
            # r(u) along the ray: its tangential gradient is r (u - n / (n.u)), and du/dh = -(d - (u.d) u) / |x|;
            # with q . d = 0, x . d = -h, and the normal's length cancels in (n.d) / (n.u): g's slope is num / mx
            mx = max(m1 * x1 + m2 * x2 + m3 * x3, _FLOOR * qn)
            num = max(h * inv_q * (1.0 - r * inv_q) * mx - r * (m1 * d1 + m2 * d2 + m3 * d3), 1e-6 * mx)
            if g > 0.0:
                hi = h
            else:
                lo = h
            step = h - g * mx / num
            if lo < step < hi:
                converged = abs(step - h) <= tol
                h = step
                if converged:
                    break  # the normal of a point within tol of the root: no need to look it up again
            else:
                h = 0.5 * (lo + hi)
        norm2 = m1 * m1 + m2 * m2 + m3 * m3
        if norm2 > 0.0:
            inv_n = 1.0 / math.sqrt(norm2)
            m1, m2, m3 = m1 * inv_n, m2 * inv_n, m3 * inv_n
        mu0 = max(m1 * sun1 + m2 * sun2 + m3 * sun3, 0.0)
        mu = max(-(m1 * d1 + m2 * d2 + m3 * d3), 0.0)
        law = wls * 2.0 * mu0 / max(mu0 + mu, 1e-12) + (1.0 - wls) * mu0
        hits[k] = True
        depths[k] = -dist * d3 - h
        signals[k] = signal_scale * law


@njit(cache=True, nogil=True, inline="always")
def _bilinear(v00: float, v01: float, v10: float, v11: float, fy: float, fx: float) -> float:
    """Bilinear interpolation in a cell from its corners (row, column) at fractions ``fy`` down and ``fx`` across."""
    return v00 + (v10 - v00) * fy + (v01 - v00) * fx + (v00 - v10 - v01 + v11) * (fx * fy)


@njit(cache=True, nogil=True, inline="always")
def _spread(d00: float, d01: float, d10: float, d11: float) -> float:
    """Largest minus smallest of four depths."""
    return max(max(d00, d01), max(d10, d11)) - min(min(d00, d01), min(d10, d11))


@njit(cache=True, nogil=True, inline="always")
def _record_cell(
    cells: np.ndarray, n: int, py0: int, px0: int, size: int, s00: float, s01: float, s10: float, s11: float,
    d00: float, d01: float, d10: float, d11: float,
) -> None:
    """Row ``n`` of the cells to interpolate: pixel origin and size, corner signals then depths (00, 01, 10, 11)."""
    cells[n, 0], cells[n, 1], cells[n, 2] = py0, px0, size
    cells[n, 3], cells[n, 4], cells[n, 5], cells[n, 6] = s00, s01, s10, s11
    cells[n, 7], cells[n, 8], cells[n, 9], cells[n, 10] = d00, d01, d10, d11


@njit(cache=True, nogil=True)
def cast_body(
    r0: int, c0: int, step: int, max_spread_4: float, max_spread_2: float, window: np.ndarray,
    table: np.ndarray, limb: np.ndarray, basis: np.ndarray, sun_v: np.ndarray, geometry: np.ndarray,
    depth: np.ndarray, sig: np.ndarray,
) -> None:
    """Ray-cast one body over its box, whose top-left pixel is (``r0``, ``c0``): fills ``depth`` (m, left as it is
    where the body is not hit: inf) and ``sig`` (e-/s, left 0 there), both (h, w) float32.

    ``step`` 1 casts every pixel. ``step`` 2 casts a node every 2 px; the cells whose four corners hit with a depth
    spread under ``max_spread_2`` (m) are interpolated, the other cells touching the body cast at every pixel.
    ``step`` 4 casts a node every 4 px; the cells whose corners all hit within ``max_spread_4`` and all on the same
    side of the terminator are interpolated, the other cells touching the body go to the 2 px grid (their new nodes
    starting from the coarse cell's interpolated depth when all its corners hit). Rays of rough cells start from
    the interpolated depth of their cell's corners when all four hit. Interpolated pixels get their depth inside
    ``window`` (r0, r1, c0, c1 in the box) and 0 elsewhere (only whether they hit is kept).

    ``basis`` (3, 3) holds the view axes in camera components as rows, ``sun_v`` the Sun direction in the view frame;
    ``geometry`` is (dist, 1 / f, cx, cy, r_min, r_max, radius, signal_scale, lommel_seeliger_weight, warm_shift,
    near): ``near`` 1 when the camera is inside the bounding sphere (``limb`` then unused), else 0.
    Each level's rays are collected, cast in one ``_cast_batch`` and scattered; interpolated cells are filled last.
    """
    h, w = depth.shape
    # the per-ray constants as a tuple of floats, passed by value
    ray = (
        geometry[0], geometry[1], geometry[2], geometry[3], geometry[4], geometry[5], geometry[6], geometry[7],
        geometry[8], geometry[9], geometry[10], basis[0, 0], basis[0, 1], basis[0, 2], basis[1, 0], basis[1, 1],
        basis[1, 2], basis[2, 0], basis[2, 1], basis[2, 2], sun_v[0], sun_v[1], sun_v[2],
    )
    hn2, wn2 = h // 2 + 3, w // 2 + 3  # the 2 px grid: node (i, j) on pixel (2 i, 2 j); extra nodes close the cells
    hn4, wn4 = h // 4 + 2, w // 4 + 2  # the 4 px grid
    cap = max(h * w, hn2 * wn2)
    b_row = np.empty(cap, dtype=np.int64)
    b_col = np.empty(cap, dtype=np.int64)
    b_guess = np.empty(cap)
    b_dst = np.empty(cap, dtype=np.int64)  # where each result goes: a flat node or pixel index
    b_hit = np.empty(cap, dtype=np.bool_)
    b_depth = np.empty(cap)
    b_sig = np.empty(cap)
    flat_depth = depth.reshape(-1)
    flat_sig = sig.reshape(-1)
    if step == 1:
        n = 0
        for py in range(h):
            for px in range(w):
                b_row[n], b_col[n], b_guess[n] = r0 + py, c0 + px, math.nan
                n += 1
        _cast_batch(b_row, b_col, b_guess, n, table, limb, ray, b_hit, b_depth, b_sig)
        for k in range(n):
            if b_hit[k]:
                flat_depth[k] = b_depth[k]
                flat_sig[k] = b_sig[k]
        return
    hit2 = np.zeros((hn2, wn2), dtype=np.bool_)
    nd2 = np.zeros((hn2, wn2))
    ns2 = np.zeros((hn2, wn2))
    rough2 = np.zeros((hn2, wn2), dtype=np.bool_)  # cells of the 2 px grid to classify
    cells = np.empty((hn2 * wn2, 11))  # cells to interpolate, filled at the end (``_record_cell``)
    n_fill = 0
    if step == 2:
        n = 0
        for i in range(hn2):
            for j in range(wn2):
                b_row[n], b_col[n], b_guess[n], b_dst[n] = r0 + 2 * i, c0 + 2 * j, math.nan, i * wn2 + j
                n += 1
        _cast_batch(b_row, b_col, b_guess, n, table, limb, ray, b_hit, b_depth, b_sig)
        for k in range(n):
            i, j = b_dst[k] // wn2, b_dst[k] % wn2
            hit2[i, j], nd2[i, j], ns2[i, j] = b_hit[k], b_depth[k], b_sig[k]
        rough2[:, :] = True
    else:
        hit4 = np.zeros((hn4, wn4), dtype=np.bool_)
        nd4 = np.zeros((hn4, wn4))
        ns4 = np.zeros((hn4, wn4))
        n = 0
        for i in range(hn4):
            for j in range(wn4):
                b_row[n], b_col[n], b_guess[n], b_dst[n] = r0 + 4 * i, c0 + 4 * j, math.nan, i * wn4 + j
                n += 1
        _cast_batch(b_row, b_col, b_guess, n, table, limb, ray, b_hit, b_depth, b_sig)
        done2 = np.zeros((hn2, wn2), dtype=np.bool_)
        for k in range(n):
            i, j = b_dst[k] // wn4, b_dst[k] % wn4
            hit4[i, j], nd4[i, j], ns4[i, j] = b_hit[k], b_depth[k], b_sig[k]
            hit2[2 * i, 2 * j], nd2[2 * i, 2 * j], ns2[2 * i, 2 * j] = b_hit[k], b_depth[k], b_sig[k]
            done2[2 * i, 2 * j] = True
        n = 0
        for i in range(hn4 - 1):
            if 4 * i >= h:
                break
            for j in range(wn4 - 1):
                if 4 * j >= w:
                    break
                count = int(hit4[i, j]) + int(hit4[i, j + 1]) + int(hit4[i + 1, j]) + int(hit4[i + 1, j + 1])
                if count == 0:
                    continue
                d00, d01, d10, d11 = nd4[i, j], nd4[i, j + 1], nd4[i + 1, j], nd4[i + 1, j + 1]
                if count == 4:
                    lit = (int(ns4[i, j] > 0) + int(ns4[i, j + 1] > 0) + int(ns4[i + 1, j] > 0)
                           + int(ns4[i + 1, j + 1] > 0))
                    # the shading has a kink at the terminator: refine across it
                    if _spread(d00, d01, d10, d11) < max_spread_4 and (lit == 0 or lit == 4):
                        _record_cell(cells, n_fill, 4 * i, 4 * j, 4, ns4[i, j], ns4[i, j + 1], ns4[i + 1, j],
                                     ns4[i + 1, j + 1], d00, d01, d10, d11)
                        n_fill += 1
                        continue
                # refine: the four 2 px cells inside, and the nodes of the 2 px grid around them not cast yet
                rough2[2 * i, 2 * j] = rough2[2 * i, 2 * j + 1] = True
                rough2[2 * i + 1, 2 * j] = rough2[2 * i + 1, 2 * j + 1] = True
                for a in range(3):
                    for b in range(3):
                        fi, fj = 2 * i + a, 2 * j + b
                        if done2[fi, fj]:
                            continue
                        done2[fi, fj] = True
                        b_row[n], b_col[n], b_dst[n] = r0 + 2 * fi, c0 + 2 * fj, fi * wn2 + fj
                        b_guess[n] = _bilinear(d00, d01, d10, d11, 0.5 * a, 0.5 * b) if count == 4 else math.nan
                        n += 1
        _cast_batch(b_row, b_col, b_guess, n, table, limb, ray, b_hit, b_depth, b_sig)
        for k in range(n):
            i, j = b_dst[k] // wn2, b_dst[k] % wn2
            hit2[i, j], nd2[i, j], ns2[i, j] = b_hit[k], b_depth[k], b_sig[k]
    # the 2 px cells: interpolated where smooth, else cast at every pixel (the corner pixel is a node)
    n = 0
    for i in range(hn2 - 1):
        if 2 * i >= h:
            break
        for j in range(wn2 - 1):
            if 2 * j >= w:
                break
            if not rough2[i, j]:
                continue
            count = int(hit2[i, j]) + int(hit2[i, j + 1]) + int(hit2[i + 1, j]) + int(hit2[i + 1, j + 1])
            if count == 0:
                continue
            d00, d01, d10, d11 = nd2[i, j], nd2[i, j + 1], nd2[i + 1, j], nd2[i + 1, j + 1]
            if count == 4 and _spread(d00, d01, d10, d11) < max_spread_2:
                _record_cell(cells, n_fill, 2 * i, 2 * j, 2, ns2[i, j], ns2[i, j + 1], ns2[i + 1, j],
                             ns2[i + 1, j + 1], d00, d01, d10, d11)
                n_fill += 1
                continue
            py0, px0 = 2 * i, 2 * j
            if hit2[i, j]:
                flat_depth[py0 * w + px0] = nd2[i, j]
                flat_sig[py0 * w + px0] = ns2[i, j]
            for py in range(py0, min(py0 + 2, h)):
                for px in range(px0, min(px0 + 2, w)):
                    if py == py0 and px == px0:
                        continue
                    b_row[n], b_col[n], b_dst[n] = r0 + py, c0 + px, py * w + px
                    b_guess[n] = (_bilinear(d00, d01, d10, d11, 0.5 * (py - py0), 0.5 * (px - px0)) if count == 4
                                  else math.nan)
                    n += 1
    _cast_batch(b_row, b_col, b_guess, n, table, limb, ray, b_hit, b_depth, b_sig)
    for k in range(n):
        if b_hit[k]:
            flat_depth[b_dst[k]] = b_depth[k]
            flat_sig[b_dst[k]] = b_sig[k]
    # interpolated cells: signal everywhere, depth inside the window only
    for c in range(n_fill):
        py0, px0, size = int(cells[c, 0]), int(cells[c, 1]), int(cells[c, 2])
        s00, s01, s10, s11 = cells[c, 3], cells[c, 4], cells[c, 5], cells[c, 6]
        d00, d01, d10, d11 = cells[c, 7], cells[c, 8], cells[c, 9], cells[c, 10]
        inv = 1.0 / size
        for py in range(py0, min(py0 + size, h)):
            fy = (py - py0) * inv
            in_rows = window[0] <= py < window[1]
            for px in range(px0, min(px0 + size, w)):
                fx = (px - px0) * inv
                sig[py, px] = _bilinear(s00, s01, s10, s11, fy, fx)
                if in_rows and window[2] <= px < window[3]:
                    depth[py, px] = _bilinear(d00, d01, d10, d11, fy, fx)
                else:
                    depth[py, px] = 0.0


def warm_up() -> None:
    """Compile (or load from the cache) the kernels now, casting a small sphere at every grid step."""
    table = np.zeros((4, 4, 4), dtype=np.float32)
    table[..., 0] = 1.0
    table[..., 3] = 1.0
    limb = np.ones(65, dtype=np.float32)
    geometry = np.array([100.0, 1e-3, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 0.5, 0.025, 0.0])
    for step in (1, 2, 4):
        depth = np.full((6, 6), np.inf, dtype=np.float32)
        sig = np.zeros((6, 6), dtype=np.float32)
        cast_body(0, 0, step, 1.0, 1.0, np.zeros(4, dtype=np.int64), table, limb, np.eye(3), np.array([0.0, 0.0, 1.0]),
                  geometry, depth, sig)
