"""Benchmark of the universe camera: median time to render a frame on one core, at a few flyby geometries.

Run: ``.venv/bin/python bench/universe_render.py [--frames 50] [--resolution 1024] [--save DIR]``.
Geometries follow the default scenario (7 km/s, C/A 55 km, Sun 45 deg from the C/A direction):
far (Didymos ~10 px, before the impact), C/A without plume (Didymos ~290 px) and C/A with the 168 s plume.
"""

from __future__ import annotations

import argparse
import os
import sys

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # one core, as the budget is stated
# bench/universe.py would shadow the universe package: import from the repository root instead
_HERE = os.path.dirname(os.path.abspath(__file__))
sys.path[:] = [p for p in sys.path if os.path.abspath(p or ".") != _HERE]
sys.path.insert(0, os.path.dirname(_HERE))

import statistics  # noqa: E402
import time  # noqa: E402  (the benchmark, not the renderer, reads the clock)

import cv2  # noqa: E402
import numpy as np  # noqa: E402
from scipy.spatial.transform import Rotation  # noqa: E402

from universe.camera import Body, Scene, focal_length_px, frame_to_png8, render_frame  # noqa: E402
from universe.config import CameraConfig, PlumeConfig  # noqa: E402
from universe.shapes import ShapeModel  # noqa: E402


def look_at(camera: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Quaternion [x, y, z, w] (body -> inertial) pointing body +Z at ``target``, body +X in the inertial XY plane."""
    z = target - camera
    z = z / np.linalg.norm(z)
    x = np.cross([0.0, 0.0, 1.0], z)
    x = x / np.linalg.norm(x)
    return Rotation.from_matrix(np.stack([x, np.cross(z, x), z], axis=1)).as_quat()


def geometries() -> dict[str, Scene]:
    """Named scenes along the default flyby."""
    didymos = Body(np.zeros(3), 390.0, ShapeModel(seed=1, irregularity=0.06, axis_ratios=(1.03, 1.03, 0.94)))
    dimorphos = Body(np.array([0.0, 0.0, 1190.0]), 82.0, ShapeModel(seed=2, irregularity=0.1, axis_ratios=(1.2, 1.0, 0.8)))
    sun = np.array([-0.5, 0.5, 0.0]) / np.sqrt(0.5)
    out = {}
    for name, along_m, t_impact in (("far", -1.58e6, None), ("C/A", 0.0, None), ("C/A + plume", 0.0, 168.0)):
        cam = np.array([along_m, 55_000.0, 0.0])
        out[name] = Scene(
            camera_position_m=cam,
            q_body_to_inertial=look_at(cam, np.zeros(3)),
            body_rate_rad_s=np.array([0.0, np.deg2rad(0.2), 0.0]),
            exposure_s=0.01,
            bodies=(didymos, dimorphos),
            sun_direction=sun,
            time_since_impact_s=t_impact,
            star_seed=1,
            camera_velocity_m_s=np.array([7000.0, 0.0, 0.0]) * 0.02,  # residual of the tracked line of sight
            plume_body_index=1,
        )
    return out


def main() -> None:
    """Print the median render time per geometry."""
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--frames", type=int, default=50)
    ap.add_argument("--resolution", type=int, default=1024, choices=(1024, 2048))
    ap.add_argument("--save", default="", help="directory to write one PNG per geometry")
    args = ap.parse_args()
    cv2.setNumThreads(1)
    cfg = CameraConfig(resolution_px=args.resolution)
    plume = PlumeConfig()
    rng = np.random.default_rng(0)
    ifov = 1.0 / focal_length_px(cfg)
    print(f"{args.resolution}x{args.resolution}, {args.frames} frames per geometry, one thread")
    for name, scene in geometries().items():
        render_frame(scene, cfg, plume, rng)  # warm the caches (shape tables, star cells)
        times = []
        for _ in range(args.frames):
            t0 = time.perf_counter()
            frame = render_frame(scene, cfg, plume, rng)
            times.append(time.perf_counter() - t0)
        size_px = 780.0 / np.linalg.norm(scene.camera_position_m) / ifov
        print(f"{name:12s} Didymos {size_px:6.1f} px  median {statistics.median(times) * 1e3:6.1f} ms")
        if args.save:
            from PIL import Image

            os.makedirs(args.save, exist_ok=True)
            Image.fromarray(frame_to_png8(frame, cfg.bit_depth)).save(
                os.path.join(args.save, name.replace("/", "").replace(" + ", "_") + ".png")
            )


if __name__ == "__main__":
    main()
