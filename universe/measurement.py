"""Centroid-level fidelity: what the on-board imaging chain would report of a frame, modelled from the truth.

Rendering a frame and running the imaging chain on it is most of a run's cost; a Monte Carlo campaign that studies
the closed loop rather than the imaging can replace both by this measurement model (``universe.fidelity:
centroid``). The universe owns the truth, so it makes the measurement; the flight software takes it where it would
take its imaging chain's output. The model and its parameters are described in ``CentroidModelConfig``; they are
fitted on image-level runs by ``flyby mc-fit``.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from contracts.messages import CentroidMeasurement
from universe.camera import Scene, camera_to_inertial_matrix, focal_length_px, principal_point_px
from universe.camera.pinhole import camera_to_inertial
from universe.camera.scene import unit3, unit_quat
from universe.config import CameraConfig, CentroidModelConfig

if TYPE_CHECKING:
    from universe.simulator import Universe

DRAWS_PER_FRAME = 4  # uniforms (Didymos dropout, Dimorphos seen, misidentification, episode length), 4 normals


def interp(x: float, xp: tuple[float, ...], fp: tuple[float, ...]) -> float:
    """``np.interp(x, xp, fp)`` of one value and an increasing table, the same bits: NumPy's algorithm (its search, its
    slope and its retries on NaN, in this order) in Python floats, without its conversions of the table to arrays
    (several microseconds a call inside a run)."""
    if len(xp) == 1:  # NumPy's own case: left, right and the single value are all fp[0]
        return float(fp[0])
    if x != x:
        return x
    j = bisect.bisect_right(xp, x) - 1  # xp[j] <= x < xp[j + 1]
    if j < 0:
        return float(fp[0])
    if j >= len(xp) - 1 or xp[j] == x:
        return float(fp[j])
    slope = (fp[j + 1] - fp[j]) / (xp[j + 1] - xp[j])
    y = slope * (x - xp[j]) + fp[j]
    if y != y:  # NaN in one direction: NumPy tries the other
        y = slope * (x - xp[j + 1]) + fp[j + 1]
        if y != y and fp[j] == fp[j + 1]:
            y = fp[j]
    return float(y)


def bias_fraction(model: CentroidModelConfig, phase_deg: float) -> float:
    """The centroid shift towards the Sun's side at a phase angle, fraction of the apparent radius."""
    return interp(phase_deg, model.phase_deg, model.bias_radius_fraction)


def dimorphos_dropout(model: CentroidModelConfig, phase_deg: float) -> float:
    """The probability that a visible Dimorphos apart from Didymos is not reported, at a phase angle."""
    return interp(phase_deg, model.phase_deg, model.dimorphos_dropout)


def merge_probability(model: CentroidModelConfig, gap_px: float) -> float:
    """The probability that Dimorphos is not told from Didymos with this gap between their discs (full-res px)."""
    return interp(gap_px, model.merge_gap_px, model.merge_probability)


# One body's view in Python floats: (col, row) of its centre (NaN behind the camera), apparent radius (px), phase
# angle (deg), the unit image direction (col, row) towards the Sun's side
_View = tuple[float, float, float, float, float, float]


def _view(c2i: list[list[float]], centre: list[float], camera_at: list[float], sun: list[float], radius_m: float,
          f: float, cx: float, cy: float) -> _View:
    """``body_view`` of a body at ``centre`` (inertial, m) seen from ``camera_at`` through ``c2i``'s rows, in floats."""
    # in Python floats, once a frame: NumPy's calls on 3-vectors cost more than their arithmetic. The same bits as
    # its forms: element-wise operations, and its 3-element dot and vector-matrix products sum in this order
    (c00, c01, c02), (c10, c11, c12), (c20, c21, c22) = c2i
    r0, r1, r2 = centre[0] - camera_at[0], centre[1] - camera_at[1], centre[2] - camera_at[2]
    range_m = math.sqrt(r0 * r0 + r1 * r1 + r2 * r2)
    l0, l1, l2 = r0 / range_m, r1 / range_m, r2 / range_m
    cos_sun = sun[0] * l0 + sun[1] * l1 + sun[2] * l2
    phase_deg = math.degrees(math.acos(min(max(-cos_sun, -1.0), 1.0)))
    a0, a1, a2 = sun[0] - cos_sun * l0, sun[1] - cos_sun * l1, sun[2] - cos_sun * l2  # the Sun across the line
    across_col, across_row = a0 * c00 + a1 * c10 + a2 * c20, a0 * c01 + a1 * c11 + a2 * c21  # camera axes
    norm = float(np.hypot(across_col, across_row))  # libm's hypot, as NumPy's (math.hypot rounds its own way)
    sun_col, sun_row = (across_col / norm, across_row / norm) if norm > 1e-12 else (0.0, 0.0)
    v0, v1, v2 = r0 * c00 + r1 * c10 + r2 * c20, r0 * c01 + r1 * c11 + r2 * c21, r0 * c02 + r1 * c12 + r2 * c22
    col, row = (cx + f * v0 / v2, cy + f * v1 / v2) if v2 > 0 else (math.nan, math.nan)  # project_camera's
    return col, row, f * radius_m / range_m, phase_deg, sun_col, sun_row


def _as_arrays(view: _View) -> tuple[np.ndarray, float, float, np.ndarray]:
    """A ``_View`` in ``body_view``'s form."""
    col, row, radius_px, phase_deg, sun_col, sun_row = view
    return np.array([col, row]), radius_px, phase_deg, np.array([sun_col, sun_row])


def body_view(scene: Scene, camera: CameraConfig, index: int,
              c2i: np.ndarray | None = None) -> tuple[np.ndarray, float, float, np.ndarray]:
    """Of body ``index`` in the frame: true pinhole (col, row) of its centre (NaN behind the camera), apparent
    radius (full-resolution px), phase angle (deg) and the unit image direction (col, row) towards the Sun's side.
    ``c2i``: the scene's ``camera_to_inertial_matrix``, if the caller has it already."""
    body = scene.bodies[index]
    c2i = camera_to_inertial_matrix(scene, camera) if c2i is None else c2i
    cx, cy = principal_point_px(camera)
    return _as_arrays(_view(c2i.tolist(), body.centre_inertial_m.tolist(), scene.camera_position_m.tolist(),
                            scene.sun_direction.tolist(), body.radius_m, focal_length_px(camera), cx, cy))


def body_views(scene: Scene, camera: CameraConfig) -> list[tuple[np.ndarray, float, float, np.ndarray]]:
    """``body_view`` of Didymos and Dimorphos, the camera's matrix computed once."""
    c2i = camera_to_inertial_matrix(scene, camera)
    return [body_view(scene, camera, i, c2i) for i in (0, 1)]


@dataclass
class MeasurementState:
    """What the model carries from frame to frame: the frames left in a misidentification episode."""

    misidentified_left: int = 0


def episode_frames(mean_frames: float, u: float) -> int:
    """A geometric episode length (1, 2, ... frames) of the given mean, from a uniform draw in [0, 1)."""
    if mean_frames <= 1.0:
        return 1
    return max(1, math.ceil(math.log1p(-u) / math.log1p(-1.0 / mean_frames)))


def centroid_measurement(scene: Scene, camera: CameraConfig, model: CentroidModelConfig,
                         rng: np.random.Generator, state: MeasurementState | None = None,
                         views: list[tuple[np.ndarray, float, float, np.ndarray]] | None = None
                         ) -> CentroidMeasurement:
    """The imaging chain's report of the frame of ``scene`` (bodies: Didymos, then Dimorphos); ``state`` carries a
    misidentification episode into the next frames (None: a frame on its own); ``views``: the scene's
    ``body_views``, if the caller has them already.

    Every frame takes the same number of draws, whatever it shows, so one frame's outcome never shifts the next's.
    """
    if views is None and not (scene.blank or scene.saturated):
        views = body_views(scene, camera)
    floats = [] if views is None else [
        (*col_row.tolist(), radius_px, phase_deg, *towards_sun.tolist())
        for col_row, radius_px, phase_deg, towards_sun in views]
    return _measurement(scene.blank or scene.saturated, floats, camera, model, rng, state)


def _measurement(dark: bool, views: list[_View], camera: CameraConfig, model: CentroidModelConfig,
                 rng: np.random.Generator, state: MeasurementState | None) -> CentroidMeasurement:
    """``centroid_measurement`` of a frame whose Didymos and Dimorphos are seen as ``views`` (``dark``: a blank or
    saturated frame, in which nothing stands out and ``views`` are not read)."""
    state = state if state is not None else MeasurementState()
    u = rng.random(DRAWS_PER_FRAME).tolist()
    z = rng.standard_normal(DRAWS_PER_FRAME).tolist()
    if dark:
        return CentroidMeasurement(dimorphos_col_row=None, dimorphos_area_px=0.0, didymos_col_row=None,
                                   didymos_area_px=0.0)
    n = camera.resolution_px
    seen: list[tuple[tuple[float, float], float] | None] = []
    for i, (col, row, radius_px, phase_deg, sun_col, sun_row) in enumerate(views):
        if not (-0.5 <= col <= n - 0.5 and -0.5 <= row <= n - 0.5):  # off the frame, or not finite (NaN compares false)
            seen.append(None)
            continue
        sigma = model.noise_px + model.noise_radius_fraction * radius_px
        # NumPy's element-wise col_row + bias * radius * towards_sun + sigma * z, in floats: the same operations
        shift = bias_fraction(model, phase_deg) * radius_px
        pos = (col + shift * sun_col + sigma * z[2 * i], row + shift * sun_row + sigma * z[2 * i + 1])
        area = math.pi * radius_px ** 2 * (1.0 + math.cos(math.radians(phase_deg))) / 2.0  # the lit part
        seen.append((pos, area))
    didymos, dimorphos = seen
    if didymos is not None and u[0] < model.didymos_dropout:
        didymos = None
    if dimorphos is not None:
        (did_col, did_row, did_r, _, _, _), (dim_col, dim_row, dim_r, dim_phase, _, _) = views
        finite = math.isfinite(did_col) and math.isfinite(did_row)
        gap = float(np.hypot(dim_col - did_col, dim_row - did_row)) - did_r - dim_r if finite else math.inf
        seen_p = (1.0 - merge_probability(model, gap)) * (1.0 - dimorphos_dropout(model, dim_phase))
        if u[1] >= seen_p:
            dimorphos = None
        elif didymos is not None and (state.misidentified_left > 0 or u[2] < model.misidentification):
            if state.misidentified_left == 0:  # an episode starts
                state.misidentified_left = episode_frames(model.misidentification_frames, u[3])
            state.misidentified_left -= 1
            dimorphos = didymos
    return CentroidMeasurement(
        dimorphos_col_row=None if dimorphos is None else dimorphos[0],
        dimorphos_area_px=0.0 if dimorphos is None else dimorphos[1],
        didymos_col_row=None if didymos is None else didymos[0],
        didymos_area_px=0.0 if didymos is None else didymos[1])


def measure_at(u: Universe, exposure_s: float) -> tuple[CentroidMeasurement, tuple[float, float], tuple[float, float]]:
    """The measurement of the frame the camera takes now, with the true pinhole (col, row) of the centres of
    Dimorphos and Didymos (as ``render_at`` gives them with the pixels).

    What ``scene_at`` would give of the centres, the camera and the Sun, without the rest of the scene (the bodies'
    spin and shapes, the motion, the plume: the measurement sees none of them), the same values to the bit.
    """
    g, t, camera = u.geometry, u.t_s, u.cfg.camera
    orbit = g.orbit_unit(t)  # Didymos and Dimorphos lie on it, as didymos_position_m and dimorphos_position_m
    centres = ((-g.didymos_arm_m * orbit).tolist(), (g.dimorphos_arm_m * orbit).tolist())
    radii = (u.cfg.bodies.didymos_diameter_m / 2.0, u.cfg.bodies.dimorphos_diameter_m / 2.0)
    q = unit_quat("Scene.q_body_to_inertial", u.state.q)  # as the scene normalises (and checks) it
    c2i = camera_to_inertial(q, camera).tolist()
    camera_at, sun = g.spacecraft_position_m(t).tolist(), unit3("Scene.sun_direction", g.sun_direction()).tolist()
    f = focal_length_px(camera)
    cx, cy = principal_point_px(camera)
    views = [_view(c2i, centres[i], camera_at, sun, radii[i], f, cx, cy) for i in (0, 1)]
    dark = bool(u.faults.active("frame_blank", t)) or bool(u.faults.active("frame_saturated", t))
    m = _measurement(dark, views, camera, u.cfg.centroid_model, u.rng["camera"], u.measurement)
    (did_col, did_row, *_), (dim_col, dim_row, *_) = views
    return m, (dim_col, dim_row), (did_col, did_row)
