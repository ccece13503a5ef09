"""The universe's narrow-angle camera: renders 12-bit frames from the true geometry and attitude.

Model, in the order the light goes through it:

- Pinhole camera: ``fov_deg`` across the full width, square pixels, principal point at the frame centre
  ``((W-1)/2, (H-1)/2)``, boresight ``CameraConfig.boresight_body`` (body +Z by default); image columns increase
  along camera +X (body +X by default), rows along camera +Y.
- Bodies: star-shaped irregular surfaces (``universe.shapes``) ray-cast inside the bounding box of each body's
  projected bounding sphere only, by the compiled kernel ``universe.raycast``. Per frame and body, radius and normal
  are tabulated over the stereographic projection of the directions seen from the camera; the silhouette is exact
  (up to sampling): the largest perspective-projected radius of the surface slice in each image polar-angle bin.
  Rays inside it get their front intersection by safeguarded Newton steps on ``|x| - r(u)`` along the ray
  (bilinear look-ups in the table). Bodies wider than 48 px are cast as a quadtree: on a 4 px grid first (96 px and
  wider) or a 2 px grid; cells whose corners all hit at similar depths (on the 4 px grid: facing the camera,
  emission cosine above ~0.5, and all on one side of the terminator) are interpolated bilinearly (smooth shading),
  the other cells touching the body are cast on the grid twice as fine, and the 2 px cells still not smooth (limb,
  grazing or occluding edges) at every pixel; rays with cast neighbours start their Newton steps from the
  neighbours' depth. Bodies whose boxes overlap are composited by depth (occultation); cast shadows are not
  modelled.
- Photometry: lunar-Lambert law (McEwen 1991) ``L * 2 mu0 / (mu0 + mu) + (1 - L) * mu0``, a Lommel-Seeliger
  (single scattering, right for dark regolith: uniform disc at zero phase, sharp terminator) plus a Lambert part
  weighted by ``lommel_seeliger_weight``, times a linear-magnitude phase darkening ``10^(-0.4 * slope * alpha)``.
- Plume: optically thin-to-thick dust cone from the plume body after the impact (``PlumeConfig``), line-of-sight
  integrated on a coarse grid (it is diffuse) and resampled; it is added on top of the bodies (its part behind a
  body is not hidden).
- Stars: a seeded all-sky catalogue (uniform directions, counts ``N(<m) = 4800 * 10^(0.46 (m - 6))`` over the sky,
  generated lazily per cell of a cube-sphere tiling) and/or an explicit ``StarCatalogue``; stars behind a body are
  hidden.
- Optics and motion: Gaussian PSF of ``psf_sigma_px`` (kernel cut at 3.5 sigma) convolved with a line of the image
  motion during the exposure (body rate for everything, plus the translation of each body's line of sight when
  ``camera_velocity_m_s`` is given); the scene geometry is that of mid-exposure. The roll component of the smear (rotation about the
  boresight) is evaluated at each star's and each body's position, not across an extended body.
- Detector: signal electrons plus dark current; noise is Gaussian with the Poisson variance (signal + dark) plus
  read noise, digitised with the gain and dark offset, rounded and clipped to the bit depth; hot pixels at fixed
  seeded positions. Standard normal deviates come from inverse-CDF sampling of independent 16-bit uniforms per
  pixel and per frame (the generator's raw 64-bit draws cut in four; 65536 normal quantiles, tails clipped at
  +-4.3 sigma): about 5x faster than ``Generator.standard_normal`` and distributed the same within that
  resolution. Pixels outside the boxes holding bodies and plume (and off stars and hot pixels) are digitised by
  a per-run table from code to DN, the same arithmetic as with signal; the boxes, or the whole frame when they
  cover most of it, by the compiled kernel ``universe.readout`` in one pass.
- Faults: ``saturated`` gives a frame at full scale; ``blank`` gives a dark frame (no light from the scene:
  bias, dark current, read noise and hot pixels only).

Speed (issue 3: one 1024x1024 frame in at most 15 ms on one core): the per-ray and per-pixel loops are compiled
with Numba (``universe.raycast``, ``universe.readout``; ``warm_up`` compiles them or loads them from their cache),
work buffers are reused per thread, star sets are cached per boresight bin, the plume is integrated on 64x64 nodes.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field
from functools import lru_cache

import cv2
import numpy as np
from scipy.spatial.transform import Rotation
from scipy.special import erf, ndtri

from universe.config import CameraConfig, PlumeConfig
from universe.raycast import TABLE_S as _TABLE_S
from universe import raycast, readout
from universe.raycast import cast_body
from universe.shapes import ShapeModel


class RenderError(ValueError):
    """A scene or camera parameter makes the frame impossible to render; the message names the field."""


def _vec3(name: str, v: object) -> np.ndarray:
    a = np.asarray(v, dtype=np.float64)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise RenderError(f"{name} must be a finite 3-vector, got {v!r}")
    return a


def _unit3(name: str, v: object) -> np.ndarray:
    a = _vec3(name, v)
    n = float(np.linalg.norm(a))
    if n < 1e-12:
        raise RenderError(f"{name} must be a non-zero vector, got {v!r}")
    return a / n


def _quat(name: str, q: object) -> np.ndarray:
    a = np.asarray(q, dtype=np.float64)
    if a.shape != (4,) or not np.all(np.isfinite(a)) or np.linalg.norm(a) < 1e-12:
        raise RenderError(f"{name} must be a non-zero finite quaternion [x, y, z, w], got {q!r}")
    return a / np.linalg.norm(a)


@dataclass(frozen=True, eq=False)
class Body:
    """One asteroid: centre (inertial, m), mean radius (m), shape, orientation (body -> inertial, [x, y, z, w])."""

    centre_inertial_m: np.ndarray
    radius_m: float
    shape: ShapeModel = ShapeModel()
    q_body_to_inertial: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 0.0, 1.0]))
    reflectance_factor: float = 1.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "centre_inertial_m", _vec3("Body.centre_inertial_m", self.centre_inertial_m))
        object.__setattr__(self, "q_body_to_inertial", _quat("Body.q_body_to_inertial", self.q_body_to_inertial))
        if not (math.isfinite(self.radius_m) and self.radius_m > 0):
            raise RenderError(f"Body.radius_m must be a positive number, got {self.radius_m!r}")
        if not (math.isfinite(self.reflectance_factor) and self.reflectance_factor >= 0):
            raise RenderError(f"Body.reflectance_factor must be >= 0, got {self.reflectance_factor!r}")


@dataclass(frozen=True, eq=False)
class StarCatalogue:
    """Explicit stars: unit directions (N, 3) in the inertial frame and visual magnitudes (N,)."""

    directions_inertial: np.ndarray
    magnitudes: np.ndarray

    def __post_init__(self) -> None:
        d = np.asarray(self.directions_inertial, dtype=np.float64).reshape(-1, 3)
        m = np.asarray(self.magnitudes, dtype=np.float64).reshape(-1)
        if len(d) != len(m):
            raise RenderError(f"StarCatalogue: {len(d)} directions but {len(m)} magnitudes")
        n = np.linalg.norm(d, axis=1)
        if np.any(n < 1e-12) or not np.all(np.isfinite(d)) or not np.all(np.isfinite(m)):
            raise RenderError("StarCatalogue.directions_inertial must be finite non-zero vectors, magnitudes finite")
        object.__setattr__(self, "directions_inertial", d / n[:, None])
        object.__setattr__(self, "magnitudes", m)


@dataclass(frozen=True, eq=False)
class Scene:
    """Everything one frame depends on, at mid-exposure; all vectors inertial unless named otherwise.

    ``camera_velocity_m_s`` is the camera's velocity relative to the bodies (smears them, not the stars);
    ``plume_body_index`` names the body the ejecta leave from (None: no plume); ``star_seed`` selects the seeded
    all-sky star field (None: none), ``star_catalogue`` adds explicit stars.
    """

    camera_position_m: np.ndarray
    q_body_to_inertial: np.ndarray
    body_rate_rad_s: np.ndarray
    exposure_s: float
    bodies: tuple[Body, ...]
    sun_direction: np.ndarray
    time_since_impact_s: float | None = None
    star_seed: int | None = None
    star_catalogue: StarCatalogue | None = None
    blank: bool = False
    saturated: bool = False
    camera_velocity_m_s: np.ndarray = field(default_factory=lambda: np.zeros(3))
    plume_body_index: int | None = None
    plume_brightness_factor: float = 1.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "camera_position_m", _vec3("Scene.camera_position_m", self.camera_position_m))
        object.__setattr__(self, "q_body_to_inertial", _quat("Scene.q_body_to_inertial", self.q_body_to_inertial))
        object.__setattr__(self, "body_rate_rad_s", _vec3("Scene.body_rate_rad_s", self.body_rate_rad_s))
        object.__setattr__(self, "sun_direction", _unit3("Scene.sun_direction", self.sun_direction))
        object.__setattr__(self, "camera_velocity_m_s", _vec3("Scene.camera_velocity_m_s", self.camera_velocity_m_s))
        object.__setattr__(self, "bodies", tuple(self.bodies))
        if not (math.isfinite(self.exposure_s) and self.exposure_s > 0):
            raise RenderError(f"Scene.exposure_s must be a positive number of seconds, got {self.exposure_s!r}")
        for i, b in enumerate(self.bodies):
            if not isinstance(b, Body):
                raise RenderError(f"Scene.bodies[{i}] must be a Body, got {type(b).__name__}")
        if self.plume_body_index is not None and not 0 <= self.plume_body_index < len(self.bodies):
            raise RenderError(
                f"Scene.plume_body_index {self.plume_body_index} is not an index of the {len(self.bodies)} bodies"
            )
        if not (math.isfinite(self.plume_brightness_factor) and self.plume_brightness_factor >= 0):
            raise RenderError(f"Scene.plume_brightness_factor must be >= 0, got {self.plume_brightness_factor!r}")
        if self.time_since_impact_s is not None and not math.isfinite(self.time_since_impact_s):
            raise RenderError(f"Scene.time_since_impact_s must be finite or None, got {self.time_since_impact_s!r}")


# ----------------------------------------------------------------------------------------------------------------
# Pinhole geometry


def focal_length_px(cfg: CameraConfig) -> float:
    """Focal length in pixels: ``fov_deg`` spans the full frame width."""
    return 0.5 * cfg.resolution_px / math.tan(math.radians(cfg.fov_deg) / 2.0)


def principal_point_px(cfg: CameraConfig) -> tuple[float, float]:
    """(col, row) of the principal point: the frame centre."""
    c = (cfg.resolution_px - 1) / 2.0
    return c, c


@lru_cache(maxsize=64)
def _camera_to_body(boresight: tuple[float, float, float]) -> np.ndarray:
    b = np.asarray(boresight, dtype=np.float64)
    b = b / np.linalg.norm(b)
    if np.allclose(b, [0.0, 0.0, 1.0]):
        return np.eye(3)
    if np.allclose(b, [0.0, 0.0, -1.0]):
        return Rotation.from_rotvec([np.pi, 0.0, 0.0]).as_matrix()
    # minimal rotation taking camera +Z onto the boresight
    axis = np.cross([0.0, 0.0, 1.0], b)
    angle = math.atan2(float(np.linalg.norm(axis)), float(b[2]))
    return Rotation.from_rotvec(axis / np.linalg.norm(axis) * angle).as_matrix()


def camera_to_inertial_matrix(scene: Scene, cfg: CameraConfig) -> np.ndarray:
    """3x3 matrix taking camera-frame vectors to the inertial frame."""
    return quat_matrix(scene.q_body_to_inertial) @ _camera_to_body(tuple(cfg.boresight_body))


def project_inertial(scene: Scene, cfg: CameraConfig, point_inertial: np.ndarray) -> tuple:
    """Pinhole (col, row) of inertial point(s) (3,) or (N, 3) in metres; NaN for points behind the camera."""
    p = np.asarray(point_inertial, dtype=np.float64)
    if p.shape[-1:] != (3,):
        raise RenderError(f"project_inertial: point_inertial must have shape (3,) or (N, 3), got {p.shape}")
    v = (p - scene.camera_position_m) @ camera_to_inertial_matrix(scene, cfg)  # rows: camera-frame vectors
    f = focal_length_px(cfg)
    cx, cy = principal_point_px(cfg)
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(v[..., 2] > 0, v[..., 2], np.nan)
        col = cx + f * v[..., 0] / z
        row = cy + f * v[..., 1] / z
    if p.ndim == 1:
        return float(col), float(row)
    return col, row


def _image_velocity_px_s(v_c: np.ndarray, dv_c: np.ndarray, f: float) -> np.ndarray:
    """Image-plane velocity (dcol/dt, drow/dt) of camera-frame vectors ``v_c`` moving at ``dv_c`` (..., 3)."""
    z = v_c[..., 2]
    return np.stack(
        [
            f * (dv_c[..., 0] * z - v_c[..., 0] * dv_c[..., 2]) / (z * z),
            f * (dv_c[..., 1] * z - v_c[..., 1] * dv_c[..., 2]) / (z * z),
        ],
        axis=-1,
    )


# ----------------------------------------------------------------------------------------------------------------
# Point-spread function with motion smear


_POINT_SMEAR_PX = 1e-3  # smear lengths up to this (px) use the plain Gaussian


def smeared_psf(dx: np.ndarray, dy: np.ndarray, sigma_px: float, lx: np.ndarray, ly: np.ndarray) -> np.ndarray:
    """Unit-integral Gaussian PSF (sigma) convolved with a centred line segment (lx, ly) px, at offsets (dx, dy).

    Closed form: Gaussian across the segment times a difference of error functions along it.
    ``lx, ly`` broadcast against ``dx, dy`` (one segment per star, for instance).
    """
    length = np.hypot(lx, ly)
    safe = np.maximum(length, 1e-9)
    ex, ey = lx / safe, ly / safe
    s = dx * ex + dy * ey
    p = -dx * ey + dy * ex
    two_s2 = 2.0 * sigma_px * sigma_px
    point = np.exp(-(dx * dx + dy * dy) / two_s2) / (np.pi * two_s2)
    k = 1.0 / (math.sqrt(2.0) * sigma_px)
    line = (
        np.exp(-p * p / two_s2)
        / (math.sqrt(2.0 * np.pi) * sigma_px)
        * 0.5
        * (erf((s + 0.5 * length) * k) - erf((s - 0.5 * length) * k))
        / safe
    )
    return np.where(length > _POINT_SMEAR_PX, line, point)


def psf_half_size_px(sigma_px: float, smear_px: float) -> int:
    """Half-size of a kernel holding the PSF and its smear: 3.5 sigma (99.8 % of the light) beyond half the smear."""
    return int(math.ceil(3.5 * sigma_px + 0.5 * smear_px))


def psf_kernel(sigma_px: float, smear_px: tuple[float, float]) -> np.ndarray:
    """Odd square float32 kernel of the smeared PSF, centred, summing to 1."""
    h = psf_half_size_px(sigma_px, math.hypot(*smear_px))
    o = np.arange(-h, h + 1, dtype=np.float64)
    k = smeared_psf(o[None, :], o[:, None], sigma_px, np.float64(smear_px[0]), np.float64(smear_px[1]))
    return (k / k.sum()).astype(np.float32)


# ----------------------------------------------------------------------------------------------------------------
# Bodies


_TABLE_MAX = 96  # radius/normal table side at most: 1.9 deg per cell at the limb, finer than any bump
_TABLE_MIN = 24  # ... and at least (bodies a few pixels across)
_LIMB_ANGLES = np.deg2rad(np.linspace(50.0, 130.0, 25))  # polar angles from the camera direction searched for the limb


def quat_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrix of a unit quaternion [x, y, z, w] (scipy's order), without Rotation's ~50 us of overhead."""
    x, y, z, w = float(q[0]), float(q[1]), float(q[2]), float(q[3])
    return np.array([
        [1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - z * w), 2.0 * (x * z + y * w)],
        [2.0 * (x * y + z * w), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - x * w)],
        [2.0 * (x * z - y * w), 2.0 * (y * z + x * w), 1.0 - 2.0 * (x * x + y * y)],
    ])


def _cross3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross product of two 3-vectors (np.cross costs ~50 us of argument handling)."""
    a0, a1, a2 = float(a[0]), float(a[1]), float(a[2])
    b0, b1, b2 = float(b[0]), float(b[1]), float(b[2])
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def _view_basis(e3: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    helper = np.array([1.0, 0.0, 0.0]) if abs(e3[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = _cross3(helper, e3)
    e1 /= math.sqrt(float(e1 @ e1))
    return e1, _cross3(e3, e1)


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


def _phase_factor(cfg: CameraConfig, cos_alpha: float) -> float:
    alpha_deg = math.degrees(math.acos(max(-1.0, min(1.0, cos_alpha))))
    return 10.0 ** (-0.4 * cfg.phase_slope_mag_deg * alpha_deg)


@dataclass
class _BodyView:
    """A body as seen in this frame: camera-frame geometry and its pixel box (r0, r1, c0, c1), end-exclusive."""

    index: int
    body: Body
    centre_c: np.ndarray
    r_max_m: float
    box: tuple[int, int, int, int]
    smear_px: tuple[float, float]


def _body_box(
    centre_c: np.ndarray, r_max: float, f: float, cx: float, cy: float, size: int, margin: int
) -> tuple[int, int, int, int] | None:
    """Pixel box of the projected bounding sphere within the frame grown by ``margin``; None if out of view."""
    dist = float(np.linalg.norm(centre_c))
    if dist <= r_max:
        raise RenderError(f"camera is inside a body's bounding sphere (range {dist:.1f} m <= {r_max:.1f} m)")
    lo, hi = -margin, size + margin
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
    e1, e2 = _view_basis(c)
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


class _BodyCaster:
    """Ray caster of one body in one frame, in the view frame (e3 from the body centre to the camera).

    Holds the per-frame tables of the body (radius and normal over stereographic view coordinates, limb radius per
    polar-angle bin); the rays themselves are cast by the compiled kernel ``universe.raycast.cast_rays``.
    """

    def __init__(
        self, view: _BodyView, c2i: np.ndarray, sun_c: np.ndarray, cfg: CameraConfig, f: float, cx: float, cy: float
    ) -> None:
        body = view.body
        p = -view.centre_c  # camera relative to the body centre, camera frame
        self.dist = dist = float(np.linalg.norm(p))
        e3 = p / dist
        e1, e2 = _view_basis(e3)
        self.basis = np.stack([e1, e2, e3])
        self.diameter_px = 2.0 * f * view.r_max_m / dist
        n_side = _table_side(self.diameter_px)
        view_to_cam = np.stack([e1, e2, e3], axis=1)
        view_to_ast = quat_matrix(body.q_body_to_inertial).T @ c2i @ view_to_cam
        self.table = _shape_table(body, view_to_ast, n_side)
        self.limb = _limb_radius(self.table, dist, math.pi * self.diameter_px)
        self.sun_v = view_to_cam.T @ sun_c
        signal_scale = cfg.body_signal_e_s * body.reflectance_factor * _phase_factor(cfg, float(sun_c @ e3))
        self.geometry = np.array([
            dist, 1.0 / f, cx, cy, body.radius_m * body.shape.min_radius(), view.r_max_m, body.radius_m, signal_scale,
            cfg.lommel_seeliger_weight, 0.25 * dist / f,  # warm starts a quarter pixel in front of the guess
        ])


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


def _cast_body(
    view: _BodyView,
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
    caster = _BodyCaster(view, c2i, sun_c, cfg, f, cx, cy)
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


def _overlap(view: _BodyView, members: list[_BodyView]) -> tuple[int, int, int, int] | None:
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
    members: list[_BodyView]


def _clusters(views: list[_BodyView]) -> list[_Cluster]:
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


# ----------------------------------------------------------------------------------------------------------------
# Stars

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
    e1, e2 = _view_basis(centre)
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


# ----------------------------------------------------------------------------------------------------------------
# Plume

_PLUME_GRID = 64  # coarse nodes per side: the plume is diffuse
_PLUME_STEPS = 16  # line-of-sight samples, uniform in the angle seen from the source (exact for the 1/r^2 law)


def plume_cross_section_m2(plume: PlumeConfig, t_s: float) -> float:
    """Total ejecta cross-section at ``t_s`` after the impact: A (1 - exp(-t/rise)) exp(-t/fade), m^2."""
    if t_s <= 0:
        return 0.0
    return plume.cross_section_m2 * (1.0 - math.exp(-t_s / plume.rise_time_s)) * math.exp(-t_s / plume.fade_time_s)


def _plume_signal(
    scene: Scene, cfg: CameraConfig, plume: PlumeConfig, c2i: np.ndarray, f: float, cx: float, cy: float,
    frame: np.ndarray | None = None,
) -> tuple[tuple[int, int, int, int], np.ndarray | None] | None:
    """Plume electrons per pixel in the exposure over its clipped pixel box (a view of a work buffer, valid until the
    next call), or None if there is none in view.

    When the plume's box is the whole frame and ``frame`` (H, W) is given, the plume is resampled straight into it
    (overwriting it: no zeroing and adding of a frame-sized buffer) and None is returned in place of the pixels."""
    t = scene.time_since_impact_s
    if not plume.enabled or t is None or t <= 0 or scene.plume_body_index is None:
        return None
    src = scene.bodies[scene.plume_body_index]
    big_r = plume.speed_m_s * t
    if big_r <= src.radius_m:
        return None  # still within the source body
    area = plume_cross_section_m2(plume, t) * scene.plume_brightness_factor
    if area <= 0:
        return None
    size = cfg.resolution_px
    centre_c = c2i.T @ (src.centre_inertial_m - scene.camera_position_m)
    if float(np.linalg.norm(centre_c)) <= big_r:
        box = (0, size, 0, size)  # the camera is inside the plume
    else:
        b = _body_box(centre_c, big_r, f, cx, cy, size, 0)
        if b is None:
            return None
        box = b
    r0, r1, c0, c1 = box
    h, w = r1 - r0, c1 - c0
    gh, gw = min(_PLUME_GRID, h), min(_PLUME_GRID, w)
    # node positions matching cv2.resize's pixel-centre convention
    cols = c0 + (np.arange(gw) + 0.5) * (w / gw) - 0.5
    rows = r0 + (np.arange(gh) + 0.5) * (h / gh) - 0.5
    dx, dy = np.meshgrid((cols - cx) / f, (rows - cy) / f)
    inv = 1.0 / np.sqrt(dx * dx + dy * dy + 1.0)
    d = (dx * inv, dy * inv, inv)
    p = -centre_c
    t_c = -(d[0] * p[0] + d[1] * p[1] + d[2] * p[2])
    q_c = (p[0] + t_c * d[0], p[1] + t_c * d[1], p[2] + t_c * d[2])  # closest point of each ray to the source
    b = np.sqrt(q_c[0] * q_c[0] + q_c[1] * q_c[1] + q_c[2] * q_c[2])
    b_eff = np.maximum(b, 0.5 * src.radius_m)
    phi_max = np.arctan(np.sqrt(np.maximum(big_r * big_r - b * b, 0.0)) / b_eff)
    axis_c = c2i.T @ _unit3("PlumeConfig.axis_inertial", plume.axis_inertial)
    q_axis = q_c[0] * axis_c[0] + q_c[1] * axis_c[1] + q_c[2] * axis_c[2]
    d_axis = d[0] * axis_c[0] + d[1] * axis_c[1] + d[2] * axis_c[2]
    # samples symmetric about the closest point: x = q + ell d and q . d = 0, so |x|^2 = b^2 + ell^2 for +-ell
    half = _PLUME_STEPS // 2
    frac = (np.arange(half) + 0.5) / half
    ell = b_eff[None] * _tan_multiples(phi_max, frac)  # (steps/2, gh, gw), ell >= 0
    rr = np.sqrt(b[None] * b[None] + ell * ell)
    inv_rr = 1.0 / np.maximum(rr, 1e-9)
    # the cone wall is not sharp (ejection directions scatter): a linear ramp over +-5 deg about the half-angle
    c_out = math.cos(math.radians(min(plume.half_angle_deg + 5.0, 90.0)))
    c_in = math.cos(math.radians(max(plume.half_angle_deg - 5.0, 0.0)))
    ramp = 1.0 / (c_in - c_out)
    along = ell * d_axis[None]
    edge_sum = np.clip(((q_axis[None] + along) * inv_rr - c_out) * ramp, 0.0, 1.0)
    edge_sum += np.clip(((q_axis[None] - along) * inv_rr - c_out) * ramp, 0.0, 1.0)
    inside_sum = (edge_sum * (rr >= src.radius_m)).sum(axis=0)
    omega = 2.0 * math.pi * (1.0 - math.cos(math.radians(plume.half_angle_deg)))
    dphi = 2.0 * phi_max / _PLUME_STEPS
    tau = area / (omega * big_r) * inside_sum * dphi / b_eff
    sun_c = c2i.T @ scene.sun_direction
    cos_alpha = float(sun_c @ (p / np.linalg.norm(p)))
    coarse = (cfg.body_signal_e_s * plume.reflectance_factor * _phase_factor(cfg, cos_alpha)) * (-np.expm1(-tau))
    # keep the part that can change a pixel: more than 1 % of the read noise (or of one electron) in the exposure
    on = coarse * scene.exposure_s > 0.01 * max(cfg.read_noise_e, 1.0)
    rows_on = np.flatnonzero(on.any(axis=1))
    cols_on = np.flatnonzero(on.any(axis=0))
    if rows_on.size == 0:
        return None
    # one node of margin: bilinear resampling spreads a node over its neighbours' cells
    ra = int(max(0, math.floor((rows_on[0] - 0.5) * h / gh)))
    rb = int(min(h, math.ceil((rows_on[-1] + 2.5) * h / gh)))
    ca = int(max(0, math.floor((cols_on[0] - 0.5) * w / gw)))
    cb = int(min(w, math.ceil((cols_on[-1] + 2.5) * w / gw)))
    whole = frame is not None and (h, w) == frame.shape
    fine = cv2.resize((coarse * scene.exposure_s).astype(np.float32), (w, h),
                      dst=frame if whole else _scratch("plume", (h, w)), interpolation=cv2.INTER_LINEAR)
    return (r0 + ra, r0 + rb, c0 + ca, c0 + cb), None if whole else fine[ra:rb, ca:cb]


def _tan_multiples(angle: np.ndarray, frac: np.ndarray) -> np.ndarray:
    """``tan(frac[j] * angle)`` (len(frac), *angle.shape) for equally spaced ``frac``, by rotating (cos, sin) from
    the first multiple in equal steps: four trigonometric calls per node instead of one per sample."""
    step = (frac[1] - frac[0]) * angle if len(frac) > 1 else np.zeros_like(angle)
    c0, s0 = np.cos(frac[0] * angle), np.sin(frac[0] * angle)
    cs, sn = np.cos(step), np.sin(step)
    out = np.empty((len(frac),) + angle.shape)
    c, s_ = c0, s0
    for j in range(len(frac)):
        out[j] = s_ / c
        c, s_ = c * cs - s_ * sn, s_ * cs + c * sn
    return out


# ----------------------------------------------------------------------------------------------------------------
# Detector


NORMAL_QUANTILES = ndtri((np.arange(65536, dtype=np.float64) + 0.5) / 65536.0).astype(np.float32)
_FULL_FRAME_FRACTION = 0.5  # signal boxes covering more of the frame than this are digitised as one full frame


def normal_codes(rng: np.random.Generator, shape: tuple[int, ...]) -> np.ndarray:
    """Independent uniform 16-bit codes; ``NORMAL_QUANTILES[codes]`` are standard normal deviates (inverse CDF).

    The codes are the raw 64-bit outputs of the generator's bit generator cut in four (its cheapest draw).
    """
    n = int(np.prod(shape))
    return rng.bit_generator.random_raw(-(-n // 4)).view(np.uint16)[:n].reshape(shape)


@lru_cache(maxsize=64)
def _dark_dn_table(cfg: CameraConfig, dark_e: float, max_dn: int) -> np.ndarray:
    """DN of a pixel without scene signal for each of the 65536 normal codes (the same arithmetic as with signal)."""
    table = _digitise(
        np.zeros((256, 256), np.float32), np.arange(65536, dtype=np.uint16).reshape(256, 256), cfg, dark_e, max_dn
    ).reshape(-1)
    table.setflags(write=False)
    return table


@lru_cache(maxsize=16)
def hot_pixels(seed: int, count: int, size: int, signal_e: float) -> tuple[np.ndarray, np.ndarray]:
    """Fixed hot pixels of a ``size`` x ``size`` sensor: flat indices and excess electrons per frame."""
    rng = np.random.default_rng(seed)
    idx = rng.choice(size * size, size=min(count, size * size), replace=False)
    level = signal_e * rng.uniform(0.2, 1.0, idx.size)
    idx.setflags(write=False)
    level.setflags(write=False)
    return idx, level


_SCRATCH = threading.local()  # per-thread float32 work buffers: fresh multi-MB arrays cost page faults every frame


def _scratch(name: str, shape: tuple[int, ...]) -> np.ndarray:
    """A reusable float32 work array of ``shape`` (contents undefined), private to this thread and ``name``."""
    n = int(np.prod(shape))
    buf = getattr(_SCRATCH, name, None)
    if buf is None or buf.size < n:
        buf = np.empty(max(n, 1), dtype=np.float32)
        setattr(_SCRATCH, name, buf)
    return buf[:n].reshape(shape)




def _digitise(
    signal_e: np.ndarray, codes: np.ndarray, cfg: CameraConfig, dark_e: float, max_dn: int
) -> np.ndarray:
    """DN (uint16, same shape) of pixels holding ``signal_e`` scene electrons (float32), with their own normal codes.

    ``offset + dark/g + (s + sqrt(s + dark + read^2) z) / g`` with s clamped at 0, rounded to nearest (ties to even)
    and clipped to [0, max_dn] (``universe.readout.digitise``; 1-D inputs are handled as one row).
    """
    shape = signal_e.shape
    s = signal_e.reshape(1, -1) if signal_e.ndim == 1 else signal_e
    c = codes.reshape(1, -1) if codes.ndim == 1 else codes
    out = np.empty(s.shape, dtype=np.uint16)
    inv_g = 1.0 / cfg.gain_e_per_dn
    readout.digitise(s, c, NORMAL_QUANTILES, float(dark_e + cfg.read_noise_e**2), inv_g,
                     cfg.dark_offset_dn + dark_e * inv_g, max_dn, out)
    return out.reshape(shape)


def _merged_boxes(boxes: list[tuple[int, int, int, int]]) -> list[tuple[int, int, int, int]]:
    """Bounding boxes of the groups of overlapping boxes (r0, r1, c0, c1): every pixel is digitised once."""
    out: list[tuple[int, int, int, int]] = []
    for b in boxes:
        merged = b
        changed = True
        while changed:
            changed = False
            for a in out:
                if a[0] < merged[1] and merged[0] < a[1] and a[2] < merged[3] and merged[2] < a[3]:
                    out.remove(a)
                    merged = (min(a[0], merged[0]), max(a[1], merged[1]), min(a[2], merged[2]), max(a[3], merged[3]))
                    changed = True
                    break
        out.append(merged)
    return out


# ----------------------------------------------------------------------------------------------------------------
# The frame


def warm_up() -> None:
    """Compile the camera's kernels (``universe.raycast``, ``universe.readout``) now, or load them from their cache:
    seconds the first time after an install, which a node pays before its first frame is due."""
    raycast.warm_up()
    readout.warm_up()


def render_frame(scene: Scene, cfg: CameraConfig, plume: PlumeConfig, rng: np.random.Generator) -> np.ndarray:
    """Render one frame: (H, W) uint16 DN within [0, 2^bit_depth - 1]; the noise comes from ``rng``."""
    size = cfg.resolution_px
    max_dn = (1 << cfg.bit_depth) - 1
    if scene.saturated:
        return np.full((size, size), max_dn, dtype=np.uint16)
    signal, boxes, star_flat = _scene_electrons(scene, cfg, plume)
    hot_idx, hot_e = hot_pixels(cfg.hot_pixel_seed, cfg.hot_pixel_count, size, cfg.hot_pixel_signal_e)
    flat_signal = signal.reshape(-1)
    flat_signal[hot_idx] += hot_e.astype(np.float32)

    dark_e = cfg.dark_current_e_s * scene.exposure_s
    codes = normal_codes(rng, (size, size))
    regions = _merged_boxes(boxes)
    if sum((r1 - r0) * (c1 - c0) for r0, r1, c0, c1 in regions) > _FULL_FRAME_FRACTION * size * size:
        return _digitise(signal, codes, cfg, dark_e, max_dn)  # mostly lit: one pass over the whole frame
    frame = np.empty((size, size), dtype=np.uint16)
    readout.dark_frame(codes, _dark_dn_table(cfg, dark_e, max_dn), frame)
    for r0, r1, c0, c1 in regions:
        frame[r0:r1, c0:c1] = _digitise(signal[r0:r1, c0:c1], codes[r0:r1, c0:c1], cfg, dark_e, max_dn)
    points = np.concatenate([star_flat, hot_idx])
    if points.size:
        frame.reshape(-1)[points] = _digitise(flat_signal[points], codes.reshape(-1)[points], cfg, dark_e, max_dn)
    return frame


def scene_electrons(scene: Scene, cfg: CameraConfig, plume: PlumeConfig) -> np.ndarray:
    """Expected scene electrons per pixel in the exposure, (H, W) float32: bodies, plume and stars through the
    optics and smear; without dark current, hot pixels or noise (zero for a blank or saturated frame)."""
    if scene.saturated:
        return np.zeros((cfg.resolution_px,) * 2, dtype=np.float32)
    return _scene_electrons(scene, cfg, plume)[0].copy()


def _scene_electrons(
    scene: Scene, cfg: CameraConfig, plume: PlumeConfig
) -> tuple[np.ndarray, list[tuple[int, int, int, int]], np.ndarray]:
    """Scene electrons (H, W) float32, the boxes (r0, r1, c0, c1) holding bodies and plume, the stars' flat pixels."""
    size = cfg.resolution_px
    signal = _scratch("signal", (size, size))
    boxes: list[tuple[int, int, int, int]] = []
    if scene.blank:
        signal.fill(0.0)
        return signal, boxes, np.empty(0, dtype=np.int64)
    f = focal_length_px(cfg)
    cx, cy = principal_point_px(cfg)
    c2i = camera_to_inertial_matrix(scene, cfg)
    # the plume first: when it covers the frame it initialises the signal, else the signal starts at zero
    pl = _plume_signal(scene, cfg, plume, c2i, f, cx, cy, frame=signal)
    if pl is None or pl[1] is not None:
        signal.fill(0.0)
    if pl is not None:
        (pr0, pr1, pc0, pc1), fine = pl
        if fine is not None:
            window = signal[pr0:pr1, pc0:pc1]
            cv2.add(window, fine, dst=window)
        boxes.append((pr0, pr1, pc0, pc1))
    texp = scene.exposure_s
    omega_c = c2i.T @ (quat_matrix(scene.q_body_to_inertial) @ scene.body_rate_rad_s)
    occluders: list[tuple[tuple[int, int, int, int], np.ndarray]] = []
    sun_c = c2i.T @ scene.sun_direction
    vel_c = c2i.T @ (-scene.camera_velocity_m_s)
    views: list[_BodyView] = []
    for i, body in enumerate(scene.bodies):
        centre_c = c2i.T @ (body.centre_inertial_m - scene.camera_position_m)
        dv = vel_c - _cross3(omega_c, centre_c)
        smear = _image_velocity_px_s(centre_c, dv, f) * texp if centre_c[2] > 0 else np.zeros(2)
        margin = psf_half_size_px(cfg.psf_sigma_px, float(np.hypot(*smear)))
        r_max = body.radius_m * body.shape.max_radius()
        box = _body_box(centre_c, r_max, f, cx, cy, size, margin)
        if box is not None:
            views.append(_BodyView(i, body, centre_c, r_max, box, (float(smear[0]), float(smear[1]))))
    for cluster in _clusters(views):
        r0, r1, c0, c1 = cluster.box
        h, w = r1 - r0, c1 - c0
        depth: np.ndarray | None = None
        for v in cluster.members:
            vr0, vr1, vc0, vc1 = v.box
            dep, sig = _cast_body(v, c2i, sun_c, cfg, f, cx, cy, _overlap(v, cluster.members))
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
        m, cut = _blurred(rad * np.float32(texp), cfg.psf_sigma_px, cluster.members[0].smear_px)
        fr0, fr1 = max(0, r0 - m), min(size, r1 + m)
        fc0, fc1 = max(0, c0 - m), min(size, c1 + m)
        if fr0 < fr1 and fc0 < fc1:
            signal[fr0:fr1, fc0:fc1] += cut[fr0 - r0 + m : fr1 - r0 + m, fc0 - c0 + m : fc1 - c0 + m]
            boxes.append((fr0, fr1, fc0, fc1))

    star_flat = _add_stars(scene, cfg, c2i, omega_c, f, cx, cy, signal, occluders)
    return signal, boxes, star_flat


def _blurred(image: np.ndarray, sigma_px: float, smear_px: tuple[float, float]) -> tuple[int, np.ndarray]:
    """``image`` convolved with the smeared PSF over itself grown by the kernel's half-size m: (m, result).

    Without smear, or with a smear along an image axis, the kernel is exactly separable (a Gaussian across the smear
    times the smeared Gaussian along it): two 1-D passes instead of one 2-D pass.
    """
    kernel = psf_kernel(sigma_px, smear_px)
    m = kernel.shape[0] // 2
    padded = cv2.copyMakeBorder(image, m, m, m, m, cv2.BORDER_CONSTANT, value=0.0)
    if min(abs(smear_px[0]), abs(smear_px[1])) <= _POINT_SMEAR_PX:
        # the kernel sums to 1, so it is the outer product of its row and column sums
        return m, cv2.sepFilter2D(padded, -1, kernel.sum(axis=0), kernel.sum(axis=1), borderType=cv2.BORDER_CONSTANT)
    return m, cv2.filter2D(padded, -1, kernel, borderType=cv2.BORDER_CONSTANT)


def _add_stars(
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
    smear = _image_velocity_px_s(v, dv, f) * scene.exposure_s
    # stamps cut at 3.5 sigma beyond half the smear along each image axis (a rectangle along a streak)
    hx = psf_half_size_px(cfg.psf_sigma_px, float(np.max(np.abs(smear[:, 0]), initial=0.0)))
    hy = psf_half_size_px(cfg.psf_sigma_px, float(np.max(np.abs(smear[:, 1]), initial=0.0)))
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


# ----------------------------------------------------------------------------------------------------------------
# Display


def frame_to_png8(frame: np.ndarray, bit_depth: int) -> np.ndarray:
    """8-bit display stretch of a frame: asinh between the median background and the brightest pixels."""
    if frame.ndim != 2:
        raise RenderError(f"frame_to_png8: frame must be 2-D, got shape {frame.shape}")
    if not 1 <= bit_depth <= 16:
        raise RenderError(f"frame_to_png8: bit_depth must be within [1, 16], got {bit_depth}")
    x = frame.astype(np.float32)
    lo = float(np.median(x[:: max(1, x.shape[0] // 256), :: max(1, x.shape[1] // 256)]))
    hi = max(float(np.percentile(x, 99.99)), lo + 1.0)
    soft = 20.0  # asinh knee: faint signal gets most of the 8-bit range
    y = np.arcsinh(np.clip((x - lo) / (hi - lo), 0.0, None) * soft) / math.asinh(soft)
    return np.clip(np.rint(y * 255.0), 0, 255).astype(np.uint8)
