"""The universe's narrow-angle camera: renders 12-bit frames from the true geometry and attitude.

Model, in the order the light goes through it, one module each:

- ``scene``: what one frame depends on (``Scene``, ``Body``, ``StarCatalogue``), at mid-exposure, checked on creation.
- ``pinhole``: pinhole projection, camera axes and the image motion of a point.
- ``plume``: the DART ejecta cone, line-of-sight integrated on a coarse grid.
- ``bodies``: irregular asteroids ray-cast (compiled kernel ``raycast``), shaded by the lunar-Lambert law,
  composited by depth, blurred by the smeared PSF.
- ``stars``: the seeded all-sky catalogue and explicit stars, hidden behind bodies.
- ``psf``: Gaussian PSF convolved with the line of the image motion during the exposure (the body rate for
  everything, plus the translation of each body's line of sight when ``camera_velocity_m_s`` is given).
- ``detector``: shot, dark and read noise, digitisation to the bit depth (compiled kernel ``readout``), with the
  sensor's fixed ``defects`` (hot, warm and dead pixels, dead columns, dark-current non-uniformity) and
  ``cosmic_rays``; ``dark_frame`` is a frame with the shutter closed.
- ``frame``: all of the above for one frame (``render_frame``, ``scene_electrons``); ``display``: the 8-bit stretch.

Any attitude, rate and position gives a valid frame: bodies are cast only over their boxes clipped to the frame
(from inside a bounding sphere, over the whole frame, each ray marching from the camera; from inside a surface the
frame is dark), a body's smear is its image motion where it shows in the frame, at most ``bodies._MAX_SMEAR_PX``
long, rendered on coarser pixels when the smeared kernel would reach beyond ``bodies._FINE_MARGIN_PX``, and stars
with long streaks are drawn as trails of point images along their true path.

Faults: ``saturated`` gives a frame at full scale; ``blank`` gives a dark frame (no light from the scene: bias, dark
current, read noise and hot pixels only).

Speed (target: one 1024x1024 frame in at most 15 ms on one core, measured by ``bench/universe_render.py``): the
per-ray and per-pixel loops are compiled with Numba (``raycast``, ``readout``, cached next to their source;
``warm_up`` compiles them or loads them from that cache), work buffers are reused per thread (``scratch``), star
sets are cached per boresight bin, the plume is integrated on 64x64 nodes.
"""

from universe.camera.cosmic_rays import CosmicRays, cosmic_rays, deposit, expected_hits
from universe.camera.defects import SensorDefects, hot_pixels, sensor_defects
from universe.camera.detector import NORMAL_QUANTILES, dark_frame, normal_codes
from universe.camera.display import display_png8, frame_to_png8
from universe.camera.frame import render_frame, scene_electrons, warm_up
from universe.camera.pinhole import (
    camera_to_inertial_matrix,
    focal_length_px,
    principal_point_px,
    project_camera,
    project_inertial,
    quat_matrix,
)
from universe.camera.plume import plume_cross_section_m2
from universe.camera.psf import psf_half_size_px, psf_kernel, smeared_psf
from universe.camera.scene import Body, RenderError, Scene, StarCatalogue
from universe.camera.stars import sky_stars

__all__ = [
    "NORMAL_QUANTILES", "Body", "CosmicRays", "RenderError", "Scene", "SensorDefects", "StarCatalogue",
    "camera_to_inertial_matrix", "cosmic_rays", "dark_frame", "deposit", "expected_hits", "focal_length_px",
    "display_png8", "frame_to_png8", "hot_pixels", "normal_codes", "plume_cross_section_m2", "principal_point_px",
    "project_camera", "project_inertial", "psf_half_size_px", "psf_kernel", "quat_matrix", "render_frame",
    "scene_electrons", "sensor_defects", "sky_stars", "smeared_psf", "warm_up",
]
