"""The bodies: star-shaped irregular surfaces ray-cast over the boxes of their projected bounding spheres,
composited by depth, shaded by the lunar-Lambert law and blurred by the smeared PSF.

Per frame and body, radius and normal are tabulated over the stereographic projection of the directions seen from
the camera; the silhouette is exact (up to sampling): the largest perspective-projected radius of the surface slice in
each image polar-angle bin. Rays inside it get their front intersection by safeguarded Newton steps on
``|x| - r(u)`` along the ray (bilinear look-ups in the table), in the compiled kernel ``universe.camera.raycast``.
Bodies wider than 48 px are cast as a quadtree: on a 4 px grid first (96 px and wider) or a 2 px grid; cells whose
corners all hit at similar depths (on the 4 px grid: facing the camera, emission cosine above ~0.5, and all on one
side of the terminator) are interpolated bilinearly (smooth shading), the other cells touching the body are cast on
the grid twice as fine, and the 2 px cells still not smooth (limb, grazing or occluding edges) at every pixel; rays
with cast neighbours start their Newton steps from the neighbours' depth. Bodies whose boxes overlap are composited
by depth (occultation); cast shadows are not modelled.

Photometry: lunar-Lambert law (McEwen 1991) ``L * 2 mu0 / (mu0 + mu) + (1 - L) * mu0``, a Lommel-Seeliger (single
scattering, right for dark regolith: uniform disc at zero phase, sharp terminator) plus a Lambert part weighted by
``lommel_seeliger_weight``, times a linear-magnitude phase darkening ``10^(-0.4 * slope * alpha)``. The whole of a
body (or of bodies overlapping on the frame) is smeared by the image motion of the first one's centre; the roll part
of the smear is not evaluated across an extended body.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np

from universe.camera.pinhole import cross3, image_velocity_px_s, quat_matrix, view_basis
from universe.camera.psf import blurred, psf_half_size_px
from universe.camera.raycast import TABLE_S as _TABLE_S
from universe.camera.raycast import cast_body
from universe.camera.scene import Body, Scene
from universe.config import CameraConfig


_TABLE_MAX = 96  # radius/normal table side at most: 1.9 deg per cell at the limb, finer than any bump
_TABLE_MIN = 24  # ... and at least (bodies a few pixels across)
_LIMB_ANGLES = np.deg2rad(np.linspace(50.0, 130.0, 25))  # polar angles from the camera direction searched for the limb


@lru_cache(maxsize=16)
def _stereo_directions(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """View-frame unit directions (n, n) of the stereographic table nodes (columns: s1, rows: s2)."""
    g = np.linspace(-_TABLE_S, _TABLE_S, n)
    s1, s2 = np.meshgrid(g, g)
    rho2 = s1 * s1 + s2 * s2
    out = tuple(
        a.astype(np.float32) for a in (2.0 * s1 / (1.0 + rho2), 2.0 * s2 / (1.0 + rho2), (1.0 - rho2) / (1.0 + rho2))
    )
    for a in out:
        a.setflags(write=False)
    return out


def _table_side(diameter_px: float) -> int:
    """Table side giving about one node per pixel across the visible hemisphere (which spans 2/3 of it)."""
    return int(min(_TABLE_MAX, max(_TABLE_MIN, 16 * math.ceil(1.5 * diameter_px / 16))))


def _limb_radius(table: np.ndarray, dist: float, perimeter_px: float) -> np.ndarray:
    """Projected limb radius (m, in the plane through the centre normal to the view) per pseudo-angle bin.

    Points seen at image polar angle psi lie in the half-plane through the camera-centre line at psi, so the limb
    there is the largest perspective-projected radius over that half-plane's slice of the surface: a sampled
    maximum over the angle from the camera direction, refined by a parabola through the best three samples.
    Bin j is at ``pseudo_angle = 4 j / M``; M (a power of two) gives 0.7 to 1.4 bins per pixel of perimeter.
    """
    m = int(min(4096, max(64, 2 ** round(math.log2(max(perimeter_px, 1.0))))))
    mx, my, st, ct = _limb_maps(m, table.shape[0])
    r = cv2.remap(np.ascontiguousarray(table[..., 0]), mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    distf = np.float32(dist)
    proj = distf * r * st / (distf - r * ct)  # (m, samples)
    k = np.clip(np.argmax(proj, axis=1), 1, len(st) - 2)
    rows = np.arange(m)
    y0, y1, y2 = proj[rows, k - 1], proj[rows, k], proj[rows, k + 1]
    den = y0 - 2 * y1 + y2
    u = np.where(den < 0, np.float32(0.5) * (y0 - y2) / np.where(den < 0, den, np.float32(-1.0)), np.float32(0.0))
    limb = y1 - np.float32(0.25) * (y0 - y2) * u
    return np.append(limb, limb[0])  # closed: bin M is bin 0


@lru_cache(maxsize=32)
def _limb_maps(m: int, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Table coordinates (m, samples) of the limb search in each of ``m`` pseudo-angle bins of an (n, n) table, and
    the sine and cosine (samples,) of the searched polar angles, float32."""
    t = 4.0 * np.arange(m) / m
    tx = np.where(t < 2.0, 1.0 - t, t - 3.0)
    ty = np.where(t < 2.0, 1.0 - np.abs(tx), np.abs(tx) - 1.0)
    norm = np.hypot(tx, ty)
    cos_psi, sin_psi = tx / norm, ty / norm
    th = _LIMB_ANGLES
    st, ct = np.sin(th), np.cos(th)
    s_len = st / (1.0 + ct)  # stereographic radius of each polar angle
    scale = (n - 1) / (2.0 * _TABLE_S)
    mx = ((cos_psi[:, None] * s_len[None, :] + _TABLE_S) * scale).astype(np.float32)
    my = ((sin_psi[:, None] * s_len[None, :] + _TABLE_S) * scale).astype(np.float32)
    out = (mx, my, st.astype(np.float32), ct.astype(np.float32))
    for arr in out:
        arr.setflags(write=False)
    return out


def _shape_table(body: Body, view_to_ast: np.ndarray, n: int) -> np.ndarray:
    """(n, n, 4) float32 table of radius (m) and view-frame normal over stereographic view coordinates."""
    v1, v2, v3 = _stereo_directions(n)
    m = view_to_ast.astype(np.float32)
    ast = body.shape.lookup(
        m[0, 0] * v1 + m[0, 1] * v2 + m[0, 2] * v3,
        m[1, 0] * v1 + m[1, 1] * v2 + m[1, 2] * v3,
        m[2, 0] * v1 + m[2, 1] * v2 + m[2, 2] * v3,
    )
    # one small matrix product: the radius scaled to metres, the body-frame normal turned into the view frame
    to_view = np.zeros((4, 4), dtype=np.float32)
    to_view[0, 0] = body.radius_m
    to_view[1:, 1:] = view_to_ast  # (n_ast row) @ view_to_ast = (view_to_ast^T n_ast)^T
    return ast @ to_view


def phase_factor(cfg: CameraConfig, cos_alpha: float) -> float:
    """Linear-magnitude phase darkening ``10^(-0.4 slope alpha)`` at the phase angle whose cosine is ``cos_alpha``."""
    alpha_deg = math.degrees(math.acos(max(-1.0, min(1.0, cos_alpha))))
    return 10.0 ** (-0.4 * cfg.phase_slope_mag_deg * alpha_deg)


@dataclass
class BodyView:
    """A body as seen in this frame: camera-frame geometry and its pixel box (r0, r1, c0, c1), end-exclusive."""

    index: int
    body: Body
    centre_c: np.ndarray
    r_max_m: float
    box: tuple[int, int, int, int]
    smear_px: tuple[float, float]


def body_box(
    centre_c: np.ndarray, r_max: float, f: float, cx: float, cy: float, size: int, margin: int
) -> tuple[int, int, int, int] | None:
    """Pixel box of the projected bounding sphere within the frame grown by ``margin``; None if out of view.

    From inside the bounding sphere the body may be seen in any direction: the box is the whole grown frame.
    """
    dist = float(np.linalg.norm(centre_c))
    lo, hi = -margin, size + margin
    if dist <= r_max:
        return lo, hi, lo, hi
    cx_m, cy_m, cz_m = float(centre_c[0]), float(centre_c[1]), float(centre_c[2])
    den = cz_m * cz_m - r_max * r_max
    if cz_m > 0 and den > 1e-6 * dist * dist:
        # whole sphere in front: the tangent planes x - u z = 0 (distance r_max from the centre (a, ., c)) give
        # u = (a c +- r sqrt(a^2 + c^2 - r^2)) / (c^2 - r^2), and likewise for rows
        ru = r_max * math.sqrt(cx_m * cx_m + den)
        rv = r_max * math.sqrt(cy_m * cy_m + den)
        u0, u1 = (cx_m * cz_m - ru) / den, (cx_m * cz_m + ru) / den
        v0, v1 = (cy_m * cz_m - rv) / den, (cy_m * cz_m + rv) / den
        box = (
            max(lo, int(math.floor(cy + f * v0)) - 2),
            min(hi, int(math.ceil(cy + f * v1)) + 3),
            max(lo, int(math.floor(cx + f * u0)) - 2),
            min(hi, int(math.ceil(cx + f * u1)) + 3),
        )
        return None if box[0] >= box[1] or box[2] >= box[3] else box
    c = centre_c / dist
    beta = math.asin(r_max / dist)
    e1, e2 = view_basis(c)
    th = np.linspace(0.0, 2.0 * np.pi, 64, endpoint=False)
    rim = c * math.cos(beta) + (np.cos(th)[:, None] * e1 + np.sin(th)[:, None] * e2) * math.sin(beta)
    if np.all(rim[:, 2] <= 0) and c[2] <= 0:
        return None
    if np.any(rim[:, 2] <= 1e-9):
        box = (lo, hi, lo, hi)
    else:
        col = cx + f * rim[:, 0] / rim[:, 2]
        row = cy + f * rim[:, 1] / rim[:, 2]
        box = (
            max(lo, int(math.floor(row.min())) - 2),
            min(hi, int(math.ceil(row.max())) + 3),
            max(lo, int(math.floor(col.min())) - 2),
            min(hi, int(math.ceil(col.max())) + 3),
        )
    if box[0] >= box[1] or box[2] >= box[3]:
        return None
    return box


class BodyCaster:
    """Ray caster of one body in one frame, in the view frame (e3 from the body centre to the camera).

    Holds the per-frame tables of the body (radius and normal over stereographic view coordinates, limb radius per
    polar-angle bin); the rays themselves are cast by the compiled kernel ``universe.camera.raycast.cast_body``.
    """

    def __init__(
        self, view: BodyView, c2i: np.ndarray, sun_c: np.ndarray, cfg: CameraConfig, f: float, cx: float, cy: float
    ) -> None:
        body = view.body
        p = -view.centre_c  # camera relative to the body centre, camera frame
        self.dist = dist = float(np.linalg.norm(p))
        e3 = p / dist
        e1, e2 = view_basis(e3)
        self.basis = np.stack([e1, e2, e3])
        self.diameter_px = 2.0 * f * view.r_max_m / dist
        n_side = _table_side(self.diameter_px)
        view_to_cam = np.stack([e1, e2, e3], axis=1)
        view_to_ast = quat_matrix(body.q_body_to_inertial).T @ c2i @ view_to_cam
        self.table = _shape_table(body, view_to_ast, n_side)
        # inside the bounding sphere there is no silhouette (the kernel marches each ray instead); inside the surface
        # itself the camera sees the body's inside: no light, and nothing beyond it
        self.near = dist <= view.r_max_m
        self.inside = self.near and surrounds_camera(body, view.centre_c, c2i)
        self.limb = _NO_LIMB if self.near else _limb_radius(self.table, dist, math.pi * self.diameter_px)
        self.sun_v = view_to_cam.T @ sun_c
        signal_scale = cfg.body_signal_e_s * body.reflectance_factor * phase_factor(cfg, float(sun_c @ e3))
        self.geometry = np.array([
            dist, 1.0 / f, cx, cy, body.radius_m * body.shape.min_radius(), view.r_max_m, body.radius_m, signal_scale,
            cfg.lommel_seeliger_weight, 0.25 * dist / f,  # warm starts a quarter pixel in front of the guess
            1.0 if self.near else 0.0,
        ])


def surrounds_camera(body: Body, centre_c: np.ndarray, c2i: np.ndarray) -> bool:
    """Whether the camera is inside the body's surface (``centre_c``: the body centre in camera axes, m)."""
    dist = float(np.linalg.norm(centre_c))
    if dist > body.radius_m * body.shape.max_radius():
        return False
    if dist == 0.0:
        return True
    to_camera = quat_matrix(body.q_body_to_inertial).T @ (c2i @ (-centre_c / dist))
    return dist <= body.radius_m * float(body.shape.radius(to_camera[None, :])[0])


_NO_LIMB = np.ones(65, dtype=np.float32)  # the limb table of a body seen from inside its bounding sphere: unused
_NO_LIMB.setflags(write=False)


_SUBSAMPLE_MIN_PX = 48.0  # bodies at least this wide are cast on a 2 px grid inside, per pixel along edges
_COARSE_MIN_PX = 96.0  # ... and at least this wide on a 4 px grid first, refined to 2 px where it is not smooth
# Largest depth spread inside an interpolated cell, in cell widths, per node spacing (px). A spread over 3 widths
# means an occluding edge or a grazing surface (emission cosine below ~0.3) whose shading bends fast. Bilinear error
# grows as spacing^2 / cos^3(emission), so 4 px cells stop at cos 0.5 (1.7 widths) to keep the 2 px cells' worst case.
_SMOOTH_SPREAD_CELLS = {2: 3.0, 4: 1.7}


def grid_step_px(diameter_px: float) -> int:
    """Node spacing (px) of the first ray-casting pass for a body ``diameter_px`` wide: 1, 2 or 4."""
    if diameter_px < _SUBSAMPLE_MIN_PX:
        return 1
    return 2 if diameter_px < _COARSE_MIN_PX else 4


def _cast_view(
    view: BodyView,
    c2i: np.ndarray,
    sun_c: np.ndarray,
    cfg: CameraConfig,
    f: float,
    cx: float,
    cy: float,
    depth_window: tuple[int, int, int, int] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Ray-cast one body over its box: depth (m, inf where the body is not hit) and signal (e-/s), both (h, w).

    Small bodies are cast at every pixel. Wider ones are cast at every ``grid_step_px`` pixel first, then refined
    as a quadtree: the cells whose four corners hit the body at similar depths (and, on the 4 px grid, all on the
    same side of the terminator) are interpolated bilinearly, the shading being smooth there; the other cells that
    touch the body are cast on the grid twice as fine, and those still not smooth on the 2 px grid (limb, occluding
    edges) at every pixel. Rays with cast neighbours start their intersection from the neighbours' depth.
    Interpolated pixels get their depth inside ``depth_window`` (r0, r1, c0, c1 within the box: where other bodies
    may be in front or behind) and 0 elsewhere (only whether they hit is kept); cast pixels always get theirs.
    """
    r0, r1, c0, c1 = view.box
    caster = BodyCaster(view, c2i, sun_c, cfg, f, cx, cy)
    if caster.inside:  # the body surrounds the camera: it hides everything, at zero depth, and shows no light
        return np.zeros((r1 - r0, c1 - c0), dtype=np.float32), np.zeros((r1 - r0, c1 - c0), dtype=np.float32)
    depth = np.full((r1 - r0, c1 - c0), np.inf, dtype=np.float32)
    sig = np.zeros((r1 - r0, c1 - c0), dtype=np.float32)
    window = np.array(depth_window if depth_window is not None else (0, 0, 0, 0), dtype=np.int64)
    cell_m = caster.dist / f  # one pixel's width at the body's distance
    cast_body(
        r0, c0, grid_step_px(caster.diameter_px), _SMOOTH_SPREAD_CELLS[4] * 4 * cell_m,
        _SMOOTH_SPREAD_CELLS[2] * 2 * cell_m, window, caster.table, caster.limb, caster.basis, caster.sun_v,
        caster.geometry, depth, sig,
    )
    return depth, sig


def _overlap(view: BodyView, members: list[BodyView]) -> tuple[int, int, int, int] | None:
    """Bounding box, relative to ``view``'s box, of where the other members' boxes overlap it (None: nowhere)."""
    r0, r1, c0, c1 = view.box
    parts = [
        (max(r0, b[0]) - r0, min(r1, b[1]) - r0, max(c0, b[2]) - c0, min(c1, b[3]) - c0)
        for b in (m.box for m in members if m is not view)
    ]
    parts = [p for p in parts if p[0] < p[1] and p[2] < p[3]]
    if not parts:
        return None
    return min(p[0] for p in parts), max(p[1] for p in parts), min(p[2] for p in parts), max(p[3] for p in parts)


@dataclass
class _Cluster:
    box: tuple[int, int, int, int]
    members: list[BodyView]


def _clusters(views: list[BodyView]) -> list[_Cluster]:
    """Group bodies whose cast boxes overlap (they must be composited by depth)."""
    out: list[_Cluster] = []
    for v in sorted(views, key=lambda v: -(v.box[1] - v.box[0]) * (v.box[3] - v.box[2])):
        merged = _Cluster(v.box, [v])
        changed = True
        while changed:
            changed = False
            for c in out:
                a, b = c.box, merged.box
                if a[0] < b[1] and b[0] < a[1] and a[2] < b[3] and b[2] < a[3]:
                    out.remove(c)
                    merged = _Cluster(
                        (min(a[0], b[0]), max(a[1], b[1]), min(a[2], b[2]), max(a[3], b[3])), c.members + merged.members
                    )
                    changed = True
                    break
        out.append(merged)
    return out


# Smear of the bodies. Up to a kernel half-size of _FINE_MARGIN_PX they are rendered on the frame's own pixels; a
# longer streak hides detail finer than its length over the kernel's reach anyway, so they are then rendered by the
# same pinhole at 1/scale of the resolution (scale a power of two up to _MAX_SCALE) and resampled onto the frame.
# Streaks are at most _MAX_SMEAR_PX long (the camera turning ~0.19 rad in one exposure at the default 2.9 deg field):
# that bounds the work of any exposure; a longer streak keeps its direction and its light.
_FINE_MARGIN_PX = 128
_MAX_SCALE = 16
_MAX_SMEAR_PX = 3840.0
_FAR_OFF_FRAMES = 1.5  # a centre projecting farther than this many frame widths from the frame centre is off view


def body_smear_px(
    centre_c: np.ndarray, r_max: float, vel_c: np.ndarray, omega_c: np.ndarray, f: float, cx: float, cy: float,
    size: int, exposure_s: float,
) -> np.ndarray | None:
    """Image motion (dcol, drow) of a body during the exposure, px, at most ``_MAX_SMEAR_PX`` long; None if the body
    is out of view.

    The motion is that of the body centre, or, when the centre projects far off the frame or lies behind the camera,
    that of the point at the body's range along the centre of its box on the frame: the image velocity of a point
    near the image plane grows without bound, while what shows in the frame moves at the rate of the frame's pixels.
    ``vel_c`` is the velocity of the bodies relative to the camera, ``omega_c`` the body rate, both in camera axes.
    """
    z = float(centre_c[2])
    far = _FAR_OFF_FRAMES * size
    if z > 0 and abs(f * float(centre_c[0]) / z) <= far and abs(f * float(centre_c[1]) / z) <= far:
        point = centre_c
    else:
        box = body_box(centre_c, r_max, f, cx, cy, size, 0)
        if box is None:
            return None
        ray = np.array([((box[2] + box[3] - 1) / 2.0 - cx) / f, ((box[0] + box[1] - 1) / 2.0 - cy) / f, 1.0])
        point = ray * (float(np.linalg.norm(centre_c)) / float(np.linalg.norm(ray)))
    smear = image_velocity_px_s(point, vel_c - cross3(omega_c, point), f) * exposure_s
    length = float(np.hypot(smear[0], smear[1]))
    if length > _MAX_SMEAR_PX:
        smear *= _MAX_SMEAR_PX / length
    return smear


def render_scale(sigma_px: float, smear_px: float) -> int:
    """Scale (1, 2, 4 ... _MAX_SCALE) of the pixels bodies are rendered on for a streak ``smear_px`` long: the
    smallest that keeps the smeared kernel's half-size within ``_FINE_MARGIN_PX`` of those pixels."""
    scale = 1
    while scale < _MAX_SCALE and psf_half_size_px(sigma_px / scale, smear_px / scale) > _FINE_MARGIN_PX:
        scale *= 2
    return scale


def add_bodies(
    scene: Scene, cfg: CameraConfig, c2i: np.ndarray, omega_c: np.ndarray, f: float, cx: float, cy: float,
    signal: np.ndarray, boxes: list[tuple[int, int, int, int]],
) -> list[tuple[tuple[int, int, int, int], np.ndarray]]:
    """Add the bodies' electrons in the exposure, blurred by the smeared PSF, to ``signal`` (H, W) and their boxes
    (r0, r1, c0, c1) to ``boxes``; return the occluders: per group of overlapping bodies, its box and hit mask.

    ``omega_c`` is the body rate in camera axes (rad/s); the camera moves at ``scene.camera_velocity_m_s``.
    """
    size = cfg.resolution_px
    vel_c = c2i.T @ (-scene.camera_velocity_m_s)
    seen = []
    for i, body in enumerate(scene.bodies):
        centre_c = c2i.T @ (body.centre_inertial_m - scene.camera_position_m)
        r_max = body.radius_m * body.shape.max_radius()
        smear = body_smear_px(centre_c, r_max, vel_c, omega_c, f, cx, cy, size, scene.exposure_s)
        if smear is not None:
            seen.append((i, body, centre_c, r_max, smear))
        if surrounds_camera(body, centre_c, c2i):  # no light reaches the camera: the plume is hidden too
            signal.fill(0.0)
    scale = render_scale(cfg.psf_sigma_px, max((float(np.hypot(*s[4])) for s in seen), default=0.0))
    if scale == 1:
        return _add_views(seen, scene, cfg, c2i, f, cx, cy, size, cfg.psf_sigma_px, signal, boxes)
    # the same pinhole at 1/scale resolution: focal length f / scale, principal point at the coarse frame's centre
    n = size // scale
    coarse = np.zeros((n, n), dtype=np.float32)
    coarse_boxes: list[tuple[int, int, int, int]] = []
    seen = [(i, body, centre_c, r_max, smear / scale) for i, body, centre_c, r_max, smear in seen]
    c = (n - 1) / 2.0
    occluders = _add_views(seen, scene, cfg, c2i, f / scale, c, c, n, cfg.psf_sigma_px / scale, coarse, coarse_boxes)
    if coarse_boxes:
        r0, r1 = min(b[0] for b in coarse_boxes) * scale, max(b[1] for b in coarse_boxes) * scale
        c0, c1 = min(b[2] for b in coarse_boxes) * scale, max(b[3] for b in coarse_boxes) * scale
        fine = cv2.resize(coarse, (size, size), interpolation=cv2.INTER_LINEAR)
        signal[r0:r1, c0:c1] += fine[r0:r1, c0:c1]
        boxes.append((r0, r1, c0, c1))
    return [((b[0] * scale, b[1] * scale, b[2] * scale, b[3] * scale),
             np.repeat(np.repeat(hit, scale, axis=0), scale, axis=1)) for b, hit in occluders]


def _add_views(
    seen: list[tuple[int, Body, np.ndarray, float, np.ndarray]], scene: Scene, cfg: CameraConfig, c2i: np.ndarray,
    f: float, cx: float, cy: float, size: int, sigma_px: float, signal: np.ndarray,
    boxes: list[tuple[int, int, int, int]],
) -> list[tuple[tuple[int, int, int, int], np.ndarray]]:
    """``add_bodies`` on a square pixel grid of ``size`` with focal length ``f`` and principal point (cx, cy), px,
    for the bodies in view (index, body, camera-frame centre, bounding radius, smear on that grid)."""
    texp = scene.exposure_s
    occluders: list[tuple[tuple[int, int, int, int], np.ndarray]] = []
    sun_c = c2i.T @ scene.sun_direction
    views: list[BodyView] = []
    for i, body, centre_c, r_max, smear in seen:
        margin = psf_half_size_px(sigma_px, float(np.hypot(*smear)))
        box = body_box(centre_c, r_max, f, cx, cy, size, margin)
        if box is not None:
            views.append(BodyView(i, body, centre_c, r_max, box, (float(smear[0]), float(smear[1]))))
    for cluster in _clusters(views):
        r0, r1, c0, c1 = cluster.box
        h, w = r1 - r0, c1 - c0
        depth: np.ndarray | None = None
        for v in cluster.members:
            vr0, vr1, vc0, vc1 = v.box
            dep, sig = _cast_view(v, c2i, sun_c, cfg, f, cx, cy, _overlap(v, cluster.members))
            if depth is None and v.box == cluster.box:
                depth, rad = dep, sig
                continue
            if depth is None:
                depth = np.full((h, w), np.inf, dtype=np.float32)
                rad = np.zeros((h, w), dtype=np.float32)
            win = (slice(vr0 - r0, vr1 - r0), slice(vc0 - c0, vc1 - c0))
            nearer = dep < depth[win]
            depth[win] = np.where(nearer, dep, depth[win])
            rad[win] = np.where(nearer, sig, rad[win])
        hit = np.isfinite(depth)
        if not hit.any():
            continue
        occluders.append((cluster.box, hit))
        m, cut = blurred(rad * np.float32(texp), sigma_px, cluster.members[0].smear_px)
        fr0, fr1 = max(0, r0 - m), min(size, r1 + m)
        fc0, fc1 = max(0, c0 - m), min(size, c1 + m)
        if fr0 < fr1 and fc0 < fc1:
            signal[fr0:fr1, fc0:fc1] += cut[fr0 - r0 + m : fr1 - r0 + m, fc0 - c0 + m : fc1 - c0 + m]
            boxes.append((fr0, fr1, fc0, fc1))
    return occluders
