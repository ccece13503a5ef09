"""An independent generator of camera frames of a binary asteroid, for the imaging tests and bench.

Written for the tests, sharing nothing with ``universe.camera``: its own bodies (triaxial ellipsoids of random
orientation, ray-cast orthographically at 3x3 sub-pixels), its own shading laws (Lambert, Lommel-Seeliger,
lunar-Lambert, Minnaert), its own plume (a fan of dust from Dimorphos falling off as a power of the distance), stars,
a Gaussian point-spread function, bias, Poisson shot noise, Gaussian read noise, and its own detector defects:
single hot pixels (up to saturation), cosmic-ray streaks (a straight track drawn with a one-pixel Bresenham-like
walk, no optics), dead pixels and a dead column. A scene is a physical geometry: Didymos and Dimorphos at a range,
Dimorphos on its orbit radius about Didymos in a random direction, the Sun at a phase angle and an azimuth in the
image, the camera pointed near Dimorphos (pointing error) so bodies may leave the frame.

``render(scene, rng)`` returns the frame and its truth; ``random_scene(rng, ...)`` draws a scene of the classes the
bench covers. Image axes: x = columns, y = rows, z = the boresight (the camera looks along +z; a surface facing the
camera has a normal with z < 0). Full-resolution pixel centres are at integer coordinates.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.ndimage import gaussian_filter
from scipy.spatial.transform import Rotation

FOCAL_1024_PX = 512.0 / math.tan(math.radians(1.45))  # a 2.9 deg field of view over 1024 px
DIDYMOS_RADIUS_M = 390.0
DIMORPHOS_RADIUS_M = 82.0
ORBIT_RADIUS_M = 1190.0
LAWS = ("lambert", "lommel-seeliger", "lunar-lambert", "minnaert")


@dataclass(frozen=True)
class Ellipsoid:
    """A triaxial body: centre (col, row) px and depth (m, along the boresight, for occlusion), semi-axes px,
    orientation (rotation body -> camera), surface brightness (DN at normal incidence and emission, zero phase)."""

    col: float
    row: float
    depth_m: float
    semi_axes_px: tuple[float, float, float]
    rotation: tuple[float, float, float, float]  # scalar-last quaternion body -> camera
    radiance_dn: float
    law: str = "lunar-lambert"
    law_parameter: float = 0.5  # lunar-Lambert weight L, or Minnaert exponent k

    @property
    def mean_radius_px(self) -> float:
        """Radius of the sphere of the same volume, px."""
        a, b, c = self.semi_axes_px
        return float((a * b * c) ** (1.0 / 3.0))


@dataclass(frozen=True)
class Plume:
    """A fan of ejecta from a body: axis angle in the image (deg from +columns), half-angle, length (px), brightness
    at one body radius from the source (DN), fall-off exponent (brightness ~ (r / r0)^-exponent) and where it starts,
    in body radii from the source."""

    axis_deg: float
    half_angle_deg: float
    length_px: float
    brightness_dn: float
    exponent: float = 1.0
    inner_radii: float = 0.5  # the dust starts this many source radii out (the slowest ejecta's reach)


@dataclass(frozen=True)
class Defects:
    """Detector defects drawn into a frame: hot pixels (col, row, DN), cosmic-ray streaks (col0, row0, col1, row1,
    DN per pixel), dead pixels (col, row), dead columns."""

    hot: tuple[tuple[int, int, int], ...] = ()
    cosmic_rays: tuple[tuple[float, float, float, float, float], ...] = ()
    dead: tuple[tuple[int, int], ...] = ()
    dead_columns: tuple[int, ...] = ()


@dataclass(frozen=True)
class Scene:
    """Everything a frame shows: bodies (Didymos first, then Dimorphos), the Sun, a plume, stars, the detector."""

    bodies: tuple[Ellipsoid, ...]
    range_m: float  # camera to Dimorphos, m
    phase_deg: float
    sun_azimuth_deg: float  # direction of the Sun's side in the image, deg from +columns towards +rows
    plume: Plume | None = None
    stars: tuple[tuple[float, float, float], ...] = ()  # (col, row, peak DN)
    psf_sigma_px: float = 0.8
    bias_dn: float = 64.0
    read_noise_dn: float = 3.0
    gain_e_per_dn: float = 4.0
    defects: Defects = field(default_factory=Defects)
    size_px: int = 1024
    bit_depth: int = 12

    @property
    def sun_camera(self) -> np.ndarray:
        """Unit vector to the Sun in camera axes: the phase angle from the direction to the camera (-z)."""
        g, a = math.radians(self.phase_deg), math.radians(self.sun_azimuth_deg)
        return np.array([math.sin(g) * math.cos(a), math.sin(g) * math.sin(a), -math.cos(g)])


@dataclass(frozen=True)
class BodyTruth:
    """What is true of one body in a frame: centre (full resolution and binned 512 px), apparent radius (binned px),
    lit pixels in the frame and hidden by the other body, and whether it touches the frame's edge."""

    centre_col_row: tuple[float, float]
    centre_512: tuple[float, float]
    radius_512_px: float
    lit_px: int  # full-resolution pixels showing its lit surface in the frame
    hidden_px: int  # full-resolution pixels of its lit surface behind the other body
    off_frame_px: int  # full-resolution pixels of its lit surface outside the frame
    touches_edge: bool

    @property
    def diameter_512_px(self) -> float:
        """Apparent diameter, binned px."""
        return 2.0 * self.radius_512_px

    @property
    def visible_fraction(self) -> float:
        """Fraction of the lit surface seen in the frame, neither hidden nor off the frame."""
        total = self.lit_px + self.hidden_px + self.off_frame_px
        return self.lit_px / total if total else 0.0


@dataclass(frozen=True)
class Frame:
    """A rendered frame and its truth."""

    pixels: np.ndarray  # (size, size) uint16
    scene: Scene
    truth: tuple[BodyTruth, ...]  # one per body, in scene order
    body_map: np.ndarray  # (size, size) int8: index of the body seen at each pixel (-1: none)


def _shade(law: str, parameter: float, mu0: np.ndarray, mu: np.ndarray) -> np.ndarray:
    """Reflectance of a surface element per law (1 at normal incidence and emission)."""
    mu0 = np.clip(mu0, 0.0, None)
    mu = np.clip(mu, 1e-6, None)
    if law == "lambert":
        return mu0
    if law == "lommel-seeliger":
        return 2.0 * mu0 / (mu0 + mu)
    if law == "lunar-lambert":
        return parameter * 2.0 * mu0 / (mu0 + mu) + (1.0 - parameter) * mu0
    if law == "minnaert":
        return mu0**parameter * mu ** (parameter - 1.0)
    raise ValueError(f"unknown shading law {law!r}")


def _cast(body: Ellipsoid, sun: np.ndarray, size: int, sub: int = 3
          ) -> tuple[np.ndarray, np.ndarray, tuple[int, int, int, int]] | None:
    """(radiance (h, w), coverage (h, w) of sub-pixel hits, box (r0, r1, c0, c1)) of a body, or None if it misses
    the frame; sub x sub rays per pixel, orthographic along +z."""
    a, b, c = body.semi_axes_px
    ext = max(a, b, c) + 1.0
    r0, r1 = max(int(math.floor(body.row - ext)), 0), min(int(math.ceil(body.row + ext)) + 1, size)
    c0, c1 = max(int(math.floor(body.col - ext)), 0), min(int(math.ceil(body.col + ext)) + 1, size)
    if r0 >= r1 or c0 >= c1:
        return None
    rot = Rotation.from_quat(body.rotation).as_matrix()
    q = rot @ np.diag([1.0 / a**2, 1.0 / b**2, 1.0 / c**2]) @ rot.T  # quadric of the ellipsoid, camera axes
    offs = (np.arange(sub) + 0.5) / sub - 0.5
    ys = (np.arange(r0, r1)[:, None] + offs[None, :]).reshape(-1) - body.row
    xs = (np.arange(c0, c1)[:, None] + offs[None, :]).reshape(-1) - body.col
    x, y = np.meshgrid(xs, ys)
    # points (x, y, t): q_zz t^2 + 2 (q_xz x + q_yz y) t + (q_xx x^2 + 2 q_xy x y + q_yy y^2 - 1) = 0
    qa = q[2, 2]
    qb = q[0, 2] * x + q[1, 2] * y
    qc = q[0, 0] * x * x + 2.0 * q[0, 1] * x * y + q[1, 1] * y * y - 1.0
    disc = qb * qb - qa * qc
    hit = disc >= 0.0
    t = (-qb - np.sqrt(np.where(hit, disc, 0.0))) / qa  # the near side: smaller t, facing the camera at -z
    p = np.stack([x, y, t], axis=-1)
    normal = p @ q  # gradient of the quadric (q symmetric)
    normal /= np.linalg.norm(normal, axis=-1, keepdims=True) + 1e-300
    mu0 = normal @ sun
    mu = -normal[..., 2]
    refl = np.where(hit, _shade(body.law, body.law_parameter, mu0, mu), 0.0) * body.radiance_dn
    h, w = r1 - r0, c1 - c0
    radiance = refl.reshape(h, sub, w, sub).mean(axis=(1, 3))
    coverage = hit.reshape(h, sub, w, sub).mean(axis=(1, 3))
    return radiance, coverage, (r0, r1, c0, c1)


def _streak(c0: float, r0: float, c1: float, r1: float, size: int) -> tuple[np.ndarray, np.ndarray]:
    """Pixels (rows, cols) of a one-pixel-wide straight track: one pixel per step along the major axis."""
    n = int(max(abs(c1 - c0), abs(r1 - r0))) + 1
    s = np.linspace(0.0, 1.0, n)
    cols = np.rint(c0 + s * (c1 - c0)).astype(np.int64)
    rows = np.rint(r0 + s * (r1 - r0)).astype(np.int64)
    on = (cols >= 0) & (cols < size) & (rows >= 0) & (rows < size)
    return rows[on], cols[on]


def render(scene: Scene, rng: np.random.Generator) -> Frame:
    """Render a scene: bodies near to far (nearer hides farther), plume, PSF, stars, noise, then the defects."""
    size = scene.size_px
    signal = np.zeros((size, size))
    owner = np.full((size, size), -1, dtype=np.int8)
    sun = scene.sun_camera
    lit_masks: list[tuple[np.ndarray, tuple[int, int, int, int]] | None] = [None] * len(scene.bodies)
    # far to near: a nearer body covers what is behind it, sub-pixel coverage blending the edge
    for i in sorted(range(len(scene.bodies)), key=lambda k: -scene.bodies[k].depth_m):
        body = scene.bodies[i]
        cast = _cast(body, sun, size)
        if cast is None:
            continue
        radiance, coverage, (r0, r1, c0, c1) = cast
        lit_masks[i] = (radiance > 0.02 * body.radiance_dn, (r0, r1, c0, c1))
        sig = signal[r0:r1, c0:c1]
        sig *= 1.0 - coverage
        sig += radiance
        win = owner[r0:r1, c0:c1]
        win[coverage > 0.5] = i
    if scene.plume is not None and len(scene.bodies) > 1:
        signal += _plume(scene.plume, scene.bodies[1], size) * (owner != 0)  # Didymos in front hides the dust
    blurred = gaussian_filter(signal, scene.psf_sigma_px, mode="constant")
    if scene.stars:
        cols = np.arange(size, dtype=np.float64)
        for sc, sr, peak in scene.stars:
            r_lo, r_hi = max(int(sr) - 6, 0), min(int(sr) + 7, size)
            c_lo, c_hi = max(int(sc) - 6, 0), min(int(sc) + 7, size)
            pr = cols[r_lo:r_hi, None] - sr
            pc = cols[None, c_lo:c_hi] - sc
            blurred[r_lo:r_hi, c_lo:c_hi] += peak * np.exp(-(pr * pr + pc * pc) / (2.0 * scene.psf_sigma_px ** 2))
    g = scene.gain_e_per_dn
    electrons = rng.poisson(np.clip(blurred, 0.0, None) * g)
    dn = electrons / g + scene.bias_dn + rng.normal(0.0, scene.read_noise_dn, signal.shape)
    vmax = (1 << scene.bit_depth) - 1
    d = scene.defects
    for c0, r0, c1, r1, level in d.cosmic_rays:
        rows, cols = _streak(c0, r0, c1, r1, size)
        dn[rows, cols] += level
    for c, r, level in d.hot:
        dn[r, c] = level
    frame = np.clip(np.rint(dn), 0, vmax).astype(np.uint16)
    for c, r in d.dead:
        frame[r, c] = int(round(scene.bias_dn))
    for c in d.dead_columns:
        frame[:, c] = int(round(scene.bias_dn))
    truth = []
    for i, body in enumerate(scene.bodies):
        cast = lit_masks[i]
        lit = hidden = 0
        touches = False
        if cast is not None:
            mask, (r0, r1, c0, c1) = cast
            seen_by = owner[r0:r1, c0:c1]
            lit = int(np.count_nonzero(mask & ((seen_by == i) | (seen_by < 0))))
            hidden = int(np.count_nonzero(mask & (seen_by >= 0) & (seen_by != i)))
            touches = bool(mask[0].any() and r0 == 0 or mask[-1].any() and r1 == size
                           or mask[:, 0].any() and c0 == 0 or mask[:, -1].any() and c1 == size)
        full = _lit_area_unclipped(body, sun)
        truth.append(BodyTruth(centre_col_row=(body.col, body.row),
                               centre_512=((body.col - 0.5) / 2.0, (body.row - 0.5) / 2.0),
                               radius_512_px=body.mean_radius_px / 2.0, lit_px=lit, hidden_px=hidden,
                               off_frame_px=max(full - lit - hidden, 0), touches_edge=touches))
    return Frame(pixels=frame, scene=scene, truth=tuple(truth), body_map=owner)


def noiseless_binned(scene: Scene, layer: int | str) -> np.ndarray:
    """One noise-free layer of a frame above the bias, blurred by the PSF and binned to 512 x 512 by the block mean:
    body ``layer`` (an index) alone, or the plume ('plume'); DN. For the bench's signal-to-noise and classes."""
    size = scene.size_px
    signal = np.zeros((size, size))
    if layer == "plume":
        if scene.plume is not None and len(scene.bodies) > 1:
            signal = _plume(scene.plume, scene.bodies[1], size)
    else:
        cast = _cast(scene.bodies[int(layer)], scene.sun_camera, size)
        if cast is not None:
            radiance, _, (r0, r1, c0, c1) = cast
            signal[r0:r1, c0:c1] = radiance
    f = size // 512
    return gaussian_filter(signal, scene.psf_sigma_px, mode="constant").reshape(512, f, 512, f).mean(axis=(1, 3))


def _lit_area_unclipped(body: Ellipsoid, sun: np.ndarray) -> int:
    """Lit pixels of the body rendered alone on a frame large enough to hold it (for the off-frame count)."""
    a = max(body.semi_axes_px)
    side = int(2 * a + 6)
    centred = replace(body, col=side // 2 + (body.col % 1.0), row=side // 2 + (body.row % 1.0))
    cast = _cast(centred, sun, side)
    if cast is None:
        return 0
    return int(np.count_nonzero(cast[0] > 0.02 * body.radiance_dn))


def _plume(plume: Plume, source: Ellipsoid, size: int) -> np.ndarray:
    """The fan's brightness on the frame: inside the cone, beyond the source's radius, up to its length."""
    r_src = source.mean_radius_px
    r0, r1 = max(int(source.row - plume.length_px), 0), min(int(source.row + plume.length_px) + 1, size)
    c0, c1 = max(int(source.col - plume.length_px), 0), min(int(source.col + plume.length_px) + 1, size)
    out = np.zeros((size, size))
    if r0 >= r1 or c0 >= c1:
        return out
    dy = np.arange(r0, r1, dtype=np.float64)[:, None] - source.row
    dx = np.arange(c0, c1, dtype=np.float64)[None, :] - source.col
    dist = np.hypot(dx, dy)
    off_axis = np.abs(np.angle(np.exp(1j * (np.arctan2(dy, dx) - math.radians(plume.axis_deg)))))
    half = math.radians(plume.half_angle_deg)
    inside = (off_axis < half) & (dist > plume.inner_radii * r_src) & (dist < plume.length_px)
    level = plume.brightness_dn * (np.maximum(dist, r_src) / max(r_src, 0.5)) ** -plume.exponent
    out[r0:r1, c0:c1] = np.where(inside, level * np.cos(0.5 * math.pi * off_axis / half), 0.0)
    return out


def _random_rotation(rng: np.random.Generator) -> tuple[float, float, float, float]:
    q = Rotation.random(random_state=rng).as_quat()
    return (float(q[0]), float(q[1]), float(q[2]), float(q[3]))


def _axes(rng: np.random.Generator, radius_px: float, max_ratio: float) -> tuple[float, float, float]:
    """Semi-axes a >= b >= c with the volume of a sphere of ``radius_px``, a / c at most ``max_ratio``."""
    b_a = rng.uniform(1.0 / max_ratio ** 0.5, 1.0)
    c_a = rng.uniform(1.0 / max_ratio, b_a)
    a = radius_px / (b_a * c_a) ** (1.0 / 3.0)
    return (a, a * b_a, a * c_a)


def random_scene(rng: np.random.Generator, *, didymos_diameter_px: float | None = None,
                 phase_deg: float | None = None, plume: bool | None = None, n_hot: int | None = None,
                 n_cosmic: int | None = None, pointing_error_px: float | None = None,
                 faint: bool | None = None, size_px: int = 1024) -> Scene:
    """A scene of the bench's classes: Didymos 1 to 400 px across (log-uniform; full resolution), Dimorphos on its
    1.19 km orbit in a random direction, phase 20 to 120 deg, one of four shading laws per body, triaxial shapes
    (axis ratios up to 1.5), a plume in 40 % of scenes, 0 to 30 stars, bias, shot and read noise, the PSF, hot pixels
    (up to saturation), cosmic-ray streaks (2 to 12 px), a few dead pixels and sometimes a dead column; the camera
    points at Dimorphos with an error up to 200 px, so bodies may leave the frame. Keyword arguments fix a class."""
    d_did = didymos_diameter_px if didymos_diameter_px is not None else float(np.exp(rng.uniform(0.0, math.log(400))))
    scale = size_px / 1024.0
    focal = FOCAL_1024_PX * scale
    range_m = focal * 2.0 * DIDYMOS_RADIUS_M / d_did
    px_per_m = focal / range_m
    g = phase_deg if phase_deg is not None else float(rng.uniform(20.0, 120.0))
    az = float(rng.uniform(0.0, 360.0))
    err = pointing_error_px if pointing_error_px is not None else float(rng.choice([0.0, 30.0, 120.0, 200.0]))
    centre = (size_px - 1) / 2.0
    theta = rng.uniform(0.0, 2.0 * math.pi)
    dim_col = centre + err * rng.uniform(0.0, 1.0) * math.cos(theta)
    dim_row = centre + err * rng.uniform(0.0, 1.0) * math.sin(theta)
    orbit = rng.standard_normal(3)
    orbit *= ORBIT_RADIUS_M * rng.uniform(0.98, 1.02) / np.linalg.norm(orbit)
    did_col, did_row = dim_col - orbit[0] * px_per_m, dim_row - orbit[1] * px_per_m
    is_faint = faint if faint is not None else bool(rng.random() < 0.3)
    radiance = float(rng.uniform(300.0, 850.0) if is_faint else rng.uniform(900.0, 3500.0))
    laws = [str(rng.choice(LAWS)) for _ in range(2)]
    params = [float(rng.uniform(0.6, 0.95)) if law == "minnaert" else float(rng.uniform(0.3, 0.9)) for law in laws]
    did_r = 0.5 * d_did * rng.uniform(0.97, 1.03)
    dim_r = did_r * DIMORPHOS_RADIUS_M / DIDYMOS_RADIUS_M * rng.uniform(0.95, 1.05)
    bodies = (
        Ellipsoid(did_col, did_row, range_m - orbit[2], _axes(rng, did_r, 1.3), _random_rotation(rng),
                  radiance, laws[0], params[0]),
        Ellipsoid(dim_col, dim_row, range_m, _axes(rng, dim_r, 1.5), _random_rotation(rng),
                  radiance * rng.uniform(0.9, 1.1), laws[1], params[1]),
    )
    has_plume = plume if plume is not None else bool(rng.random() < 0.4)
    fan = None
    if has_plume:
        fan = Plume(axis_deg=float(rng.uniform(0.0, 360.0)), half_angle_deg=float(rng.uniform(20.0, 70.0)),
                    length_px=float(max(dim_r, 1.0) * rng.uniform(5.0, 40.0)),
                    brightness_dn=float(radiance * rng.uniform(0.1, 0.7)), exponent=float(rng.uniform(0.5, 1.5)))
    stars = tuple((float(rng.uniform(0, size_px)), float(rng.uniform(0, size_px)), float(rng.uniform(100.0, 3000.0)))
                  for _ in range(int(rng.integers(0, 31))))
    n_h = n_hot if n_hot is not None else int(rng.integers(0, 51))
    hot = tuple((int(rng.integers(0, size_px)), int(rng.integers(0, size_px)),
                 int(rng.choice([4095, int(rng.integers(1000, 4096))]))) for _ in range(n_h))
    n_cr = n_cosmic if n_cosmic is not None else int(rng.integers(0, 6))
    crs = tuple(_cosmic_ray(rng, size_px) for _ in range(n_cr))
    dead = tuple((int(rng.integers(0, size_px)), int(rng.integers(0, size_px))) for _ in range(int(rng.integers(0, 21))))
    dead_cols = (int(rng.integers(0, size_px)),) if rng.random() < 0.2 else ()
    return Scene(bodies=bodies, range_m=float(range_m), phase_deg=g, sun_azimuth_deg=az, plume=fan, stars=stars,
                 psf_sigma_px=float(rng.uniform(0.6, 1.2)), bias_dn=float(rng.uniform(40.0, 200.0)),
                 read_noise_dn=float(rng.uniform(2.0, 8.0)), gain_e_per_dn=float(rng.uniform(2.0, 6.0)),
                 defects=Defects(hot=hot, cosmic_rays=crs, dead=dead, dead_columns=dead_cols), size_px=size_px)


def _cosmic_ray(rng: np.random.Generator, size: int, near: tuple[float, float] | None = None, length: float | None = None,
                level: float | None = None) -> tuple[float, float, float, float, float]:
    """A streak 2 to 12 px long at a random angle, 300 DN to saturation per pixel, anywhere or starting ``near``."""
    c0, r0 = near if near is not None else (rng.uniform(0, size), rng.uniform(0, size))
    n = length if length is not None else rng.uniform(2.0, 12.0)
    a = rng.uniform(0.0, math.pi)
    lvl = level if level is not None else rng.uniform(300.0, 4095.0)
    return (float(c0), float(r0), float(c0 + n * math.cos(a)), float(r0 + n * math.sin(a)), float(lvl))


def with_defect(scene: Scene, rng: np.random.Generator, kind: str, target: int | None = None) -> Scene:
    """The scene with one more defect: a saturated hot pixel (``kind`` 'hot') or a 6 px cosmic ray ('cosmic') placed
    on body ``target`` (a lit pixel of it, when visible), beside it, or anywhere (None)."""
    size = scene.size_px
    if target is not None and target < len(scene.bodies):
        b = scene.bodies[target]
        rad = b.mean_radius_px
        ang = rng.uniform(0.0, 2.0 * math.pi)
        dist = rng.uniform(0.0, 1.6) * rad + rng.uniform(0.0, 2.0)
        c, r = b.col + dist * math.cos(ang), b.row + dist * math.sin(ang)
    else:
        c, r = rng.uniform(0, size), rng.uniform(0, size)
    c = float(min(max(c, 0.0), size - 1.0))
    r = float(min(max(r, 0.0), size - 1.0))
    d = scene.defects
    if kind == "hot":
        d = replace(d, hot=d.hot + ((int(round(c)), int(round(r)), 4095),))
    elif kind == "cosmic":
        d = replace(d, cosmic_rays=d.cosmic_rays + (_cosmic_ray(rng, size, (c, r), 6.0),))
    else:
        raise ValueError(f"unknown defect kind {kind!r}")
    return replace(scene, defects=d)
