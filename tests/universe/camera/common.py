"""Shared scene set-up of the camera tests: the default camera at the origin looking along inertial +Z."""

from __future__ import annotations

import math

import numpy as np

from universe.camera import Body, Scene
from universe.config import CameraConfig
from universe.shapes import ShapeModel

SPHERE = ShapeModel(irregularity=0.0)
IDENTITY = np.array([0.0, 0.0, 0.0, 1.0])
F_1024 = 512.0 / math.tan(math.radians(2.9) / 2.0)  # closed-form focal length of the default camera, px
C_1024 = 511.5
NO_DEFECTS = dict(dark_current_dsnu_e_s=0.0, warm_pixel_fraction=0.0, dead_pixel_count=0, dead_column_count=0,
                  cosmic_ray_flux_cm2_s=0.0)
"""The detector's defects off (CameraConfig keywords), for the tests of an ideal camera's optics and noise."""


def scene(bodies: tuple[Body, ...] = (), sun=(0.0, 0.0, -1.0), **kw) -> Scene:
    """Camera at the origin, body axes = inertial axes (boresight +Z), at rest."""
    base = dict(
        camera_position_m=np.zeros(3),
        q_body_to_inertial=IDENTITY,
        body_rate_rad_s=np.zeros(3),
        exposure_s=0.01,
        bodies=bodies,
        sun_direction=np.array(sun),
    )
    base.update(kw)
    return Scene(**base)


def lit_pixels(frame: np.ndarray, cfg: CameraConfig, level_dn: float) -> np.ndarray:
    """Mask of pixels above the dark level by more than ``level_dn``."""
    dark = cfg.dark_offset_dn + cfg.dark_current_e_s * 0.01 / cfg.gain_e_per_dn
    return frame.astype(float) - dark > level_dn
