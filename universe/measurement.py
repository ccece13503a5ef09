"""Centroid-level fidelity: what the on-board imaging chain would report of a frame, modelled from the truth.

Rendering a frame and running the imaging chain on it is most of a run's cost; a Monte Carlo campaign that studies
the closed loop rather than the imaging can replace both by this measurement model (``universe.fidelity:
centroid``). The universe owns the truth, so it makes the measurement; the flight software takes it where it would
take its imaging chain's output. The model and its parameters are described in ``CentroidModelConfig``; they are
fitted on image-level runs by ``flyby mc-fit``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from contracts.messages import CentroidMeasurement
from universe.camera import Scene, camera_to_inertial_matrix, focal_length_px, principal_point_px
from universe.config import CameraConfig, CentroidModelConfig
from universe.scene import scene_at

if TYPE_CHECKING:
    from universe.simulator import Universe

DRAWS_PER_FRAME = 4  # uniforms (Didymos dropout, Dimorphos seen, misidentification, episode length), 4 normals


def bias_fraction(model: CentroidModelConfig, phase_deg: float) -> float:
    """The centroid shift towards the Sun's side at a phase angle, fraction of the apparent radius."""
    return float(np.interp(phase_deg, model.phase_deg, model.bias_radius_fraction))


def dimorphos_dropout(model: CentroidModelConfig, phase_deg: float) -> float:
    """The probability that a visible Dimorphos apart from Didymos is not reported, at a phase angle."""
    return float(np.interp(phase_deg, model.phase_deg, model.dimorphos_dropout))


def merge_probability(model: CentroidModelConfig, gap_px: float) -> float:
    """The probability that Dimorphos is not told from Didymos with this gap between their discs (full-res px)."""
    return float(np.interp(gap_px, model.merge_gap_px, model.merge_probability))


def body_view(scene: Scene, camera: CameraConfig, index: int,
              c2i: np.ndarray | None = None) -> tuple[np.ndarray, float, float, np.ndarray]:
    """Of body ``index`` in the frame: true pinhole (col, row) of its centre (NaN behind the camera), apparent
    radius (full-resolution px), phase angle (deg) and the unit image direction (col, row) towards the Sun's side.
    ``c2i``: the scene's ``camera_to_inertial_matrix``, if the caller has it already."""
    body = scene.bodies[index]
    c2i = camera_to_inertial_matrix(scene, camera) if c2i is None else c2i
    # in Python floats, once a frame: NumPy's calls on 3-vectors cost more than their arithmetic. The same bits as
    # its forms: element-wise operations, and its 3-element dot and vector-matrix products sum in this order
    (c00, c01, c02), (c10, c11, c12), (c20, c21, c22) = c2i.tolist()
    centre, camera_at, sun = (body.centre_inertial_m.tolist(), scene.camera_position_m.tolist(),
                              scene.sun_direction.tolist())
    r0, r1, r2 = centre[0] - camera_at[0], centre[1] - camera_at[1], centre[2] - camera_at[2]
    range_m = math.sqrt(r0 * r0 + r1 * r1 + r2 * r2)
    l0, l1, l2 = r0 / range_m, r1 / range_m, r2 / range_m
    cos_sun = sun[0] * l0 + sun[1] * l1 + sun[2] * l2
    phase_deg = math.degrees(math.acos(min(max(-cos_sun, -1.0), 1.0)))
    a0, a1, a2 = sun[0] - cos_sun * l0, sun[1] - cos_sun * l1, sun[2] - cos_sun * l2  # the Sun across the line
    across_col, across_row = a0 * c00 + a1 * c10 + a2 * c20, a0 * c01 + a1 * c11 + a2 * c21  # camera axes
    norm = float(np.hypot(across_col, across_row))  # libm's hypot, as NumPy's (math.hypot rounds its own way)
    towards_sun = np.array([across_col / norm, across_row / norm]) if norm > 1e-12 else np.zeros(2)
    v0, v1, v2 = r0 * c00 + r1 * c10 + r2 * c20, r0 * c01 + r1 * c11 + r2 * c21, r0 * c02 + r1 * c12 + r2 * c22
    f = focal_length_px(camera)
    cx, cy = principal_point_px(camera)
    col_row = np.array([cx + f * v0 / v2, cy + f * v1 / v2] if v2 > 0 else [math.nan, math.nan])  # project_camera's
    return col_row, f * body.radius_m / range_m, phase_deg, towards_sun


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
    state = state if state is not None else MeasurementState()
    u = rng.random(DRAWS_PER_FRAME)
    z = rng.standard_normal(DRAWS_PER_FRAME)
    if scene.blank or scene.saturated:  # nothing stands out of a blank or saturated frame
        return CentroidMeasurement(dimorphos_col_row=None, dimorphos_area_px=0.0, didymos_col_row=None,
                                   didymos_area_px=0.0)
    n = camera.resolution_px
    seen: list[tuple[tuple[float, float], float] | None] = []
    views = body_views(scene, camera) if views is None else views
    for i, (col_row, radius_px, phase_deg, towards_sun) in enumerate(views):
        col, row = col_row.tolist()
        if not (-0.5 <= col <= n - 0.5 and -0.5 <= row <= n - 0.5):  # off the frame, or not finite (NaN compares false)
            seen.append(None)
            continue
        sigma = model.noise_px + model.noise_radius_fraction * radius_px
        pos = col_row + bias_fraction(model, phase_deg) * radius_px * towards_sun + sigma * z[2 * i: 2 * i + 2]
        area = math.pi * radius_px ** 2 * (1.0 + math.cos(math.radians(phase_deg))) / 2.0  # the lit part
        seen.append(((float(pos[0]), float(pos[1])), area))
    didymos, dimorphos = seen
    if didymos is not None and u[0] < model.didymos_dropout:
        didymos = None
    if dimorphos is not None:
        (did_px, did_r, _, _), (dim_px, dim_r, dim_phase, _) = views
        gap = float(np.hypot(*(dim_px - did_px))) - did_r - dim_r if np.all(np.isfinite(did_px)) else math.inf
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
    Dimorphos and Didymos (as ``render_at`` gives them with the pixels)."""
    scene = scene_at(u, exposure_s, oriented=False)  # centres and sizes only: the bodies' spin is not seen
    views = body_views(scene, u.cfg.camera)
    m = centroid_measurement(scene, u.cfg.camera, u.cfg.centroid_model, u.rng["camera"], u.measurement, views)
    (did_px, _, _, _), (dim_px, _, _, _) = views
    return m, (float(dim_px[0]), float(dim_px[1])), (float(did_px[0]), float(did_px[1]))
