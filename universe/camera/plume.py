"""The DART ejecta plume: an optically thin-to-thick dust cone from the plume body after the impact
(``PlumeConfig``), line-of-sight integrated on a coarse grid (it is diffuse) and resampled. It is added on top of
the bodies (its part behind a body is not hidden).
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from universe.camera import plume_depth
from universe.camera.bodies import body_box, phase_factor
from universe.camera.scene import Scene, unit3
from universe.camera.scratch import work_buffer
from universe.config import CameraConfig, PlumeConfig


_PLUME_GRID = 64  # coarse nodes per side: the plume is diffuse
_PLUME_STEPS = 16  # line-of-sight samples, uniform in the angle seen from the source (exact for the 1/r^2 law)
_HALF_FRACTIONS = (np.arange(_PLUME_STEPS // 2) + 0.5) / (_PLUME_STEPS // 2)  # samples on one side, of phi_max


def plume_cross_section_m2(plume: PlumeConfig, t_s: float) -> float:
    """Total ejecta cross-section at ``t_s`` after the impact: A (1 - exp(-t/rise)) exp(-t/fade), m^2."""
    if t_s <= 0:
        return 0.0
    return plume.cross_section_m2 * (1.0 - math.exp(-t_s / plume.rise_time_s)) * math.exp(-t_s / plume.fade_time_s)


def plume_signal(
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
    outside = float(np.linalg.norm(centre_c)) > big_r
    if not outside:
        box = (0, size, 0, size)  # the camera is inside the plume
    else:
        b = body_box(centre_c, big_r, f, cx, cy, size, 0)
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
    axis_c = c2i.T @ unit3("PlumeConfig.axis_inertial", plume.axis_inertial)
    q_axis = q_c[0] * axis_c[0] + q_c[1] * axis_c[1] + q_c[2] * axis_c[2]
    d_axis = d[0] * axis_c[0] + d[1] * axis_c[1] + d[2] * axis_c[2]
    # the cone wall is not sharp (ejection directions scatter): a linear ramp over +-5 deg about the half-angle
    c_out = math.cos(math.radians(min(plume.half_angle_deg + 5.0, 90.0)))
    c_in = math.cos(math.radians(max(plume.half_angle_deg - 5.0, 0.0)))
    ramp = 1.0 / (c_in - c_out)

    def in_cone(cos_axis: np.ndarray) -> np.ndarray:
        return np.clip((cos_axis - c_out) * ramp, 0.0, 1.0)

    omega = 2.0 * math.pi * (1.0 - math.cos(math.radians(plume.half_angle_deg)))
    if outside:
        # samples symmetric about the closest point: x = q + ell d and q . d = 0, so |x|^2 = b^2 + ell^2 for +-ell
        # node by node, compiled (universe.camera.plume_depth); a ray whose closest point to the source is behind
        # the camera meets none of the cloud
        tau = plume_depth.depth_outside(b, b_eff, phi_max, q_axis, d_axis, t_c, _HALF_FRACTIONS, src.radius_m,
                                        c_out, ramp, area / (omega * big_r), _PLUME_STEPS)
    else:
        # from inside the cloud a line of sight runs from the camera (at ell = -t_c) out to the cloud's front
        phi_lo = np.arctan(-t_c / b_eff)
        frac = (np.arange(_PLUME_STEPS) + 0.5) / _PLUME_STEPS
        ell = b_eff[None] * np.tan(phi_lo[None] + frac[:, None, None] * (phi_max - phi_lo)[None])
        rr = np.sqrt(b[None] * b[None] + ell * ell)
        weight = in_cone((q_axis[None] + ell * d_axis[None]) / np.maximum(rr, 1e-9))
        inside_sum = (weight * (rr >= src.radius_m)).sum(axis=0)
        tau = area / (omega * big_r) * inside_sum * ((phi_max - phi_lo) / _PLUME_STEPS) / b_eff
    sun_c = c2i.T @ scene.sun_direction
    cos_alpha = float(sun_c @ (p / np.linalg.norm(p)))
    coarse = (cfg.body_signal_e_s * plume.reflectance_factor * phase_factor(cfg, cos_alpha)) * (-np.expm1(-tau))
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
                      dst=frame if whole else work_buffer("plume", (h, w)), interpolation=cv2.INTER_LINEAR)
    return (r0 + ra, r0 + rb, c0 + ca, c0 + cb), None if whole else fine[ra:rb, ca:cb]

