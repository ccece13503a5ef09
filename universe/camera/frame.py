"""The frame: the scene's electrons (plume, bodies, stars through the optics) read out by the detector."""

from __future__ import annotations

import cv2
import numpy as np

from universe.camera import display, plume_depth, raycast, readout
from universe.camera.bodies import add_bodies
from universe.camera.detector import read_out
from universe.camera.pinhole import camera_to_inertial_matrix, focal_length_px, principal_point_px, quat_matrix
from universe.camera.plume import plume_signal
from universe.camera.scene import Scene
from universe.camera.scratch import work_buffer
from universe.camera.stars import add_stars
from universe.config import CameraConfig, PlumeConfig


def warm_up() -> None:
    """Compile the camera's kernels (``universe.camera.raycast``, ``readout``, ``plume_depth``) now, or load them from
    their cache: seconds the first time after an install, which a node pays before its first frame is due."""
    raycast.warm_up()
    readout.warm_up()
    plume_depth.warm_up()
    display.warm_up()


def render_frame(
    scene: Scene, cfg: CameraConfig, plume: PlumeConfig, rng: np.random.Generator,
    cosmic_rng: np.random.Generator | None = None,
) -> np.ndarray:
    """Render one frame: (H, W) uint16 DN within [0, 2^bit_depth - 1]; the noise comes from ``rng``, the cosmic rays
    (when their flux is not zero) from ``cosmic_rng`` (default: ``rng``, after the noise)."""
    size = cfg.resolution_px
    max_dn = (1 << cfg.bit_depth) - 1
    if scene.saturated:
        return np.full((size, size), max_dn, dtype=np.uint16)
    signal, boxes, star_flat = _scene_electrons(scene, cfg, plume)
    return read_out(signal, boxes, star_flat, cfg, scene.exposure_s, rng, cosmic_rng)


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
    signal = work_buffer("signal", (size, size))
    boxes: list[tuple[int, int, int, int]] = []
    if scene.blank:
        signal.fill(0.0)
        return signal, boxes, np.empty(0, dtype=np.int64)
    f = focal_length_px(cfg)
    cx, cy = principal_point_px(cfg)
    c2i = camera_to_inertial_matrix(scene, cfg)
    # the plume first: when it covers the frame it initialises the signal, else the signal starts at zero
    pl = plume_signal(scene, cfg, plume, c2i, f, cx, cy, frame=signal)
    if pl is None or pl[1] is not None:
        signal.fill(0.0)
    if pl is not None:
        (pr0, pr1, pc0, pc1), fine = pl
        if fine is not None:
            window = signal[pr0:pr1, pc0:pc1]
            cv2.add(window, fine, dst=window)
        boxes.append((pr0, pr1, pc0, pc1))
    omega_c = c2i.T @ (quat_matrix(scene.q_body_to_inertial) @ scene.body_rate_rad_s)
    occluders = add_bodies(scene, cfg, c2i, omega_c, f, cx, cy, signal, boxes)
    star_flat = add_stars(scene, cfg, c2i, omega_c, f, cx, cy, signal, occluders)
    return signal, boxes, star_flat
