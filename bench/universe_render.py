"""Benchmark of the universe camera: median time to render a 1024x1024 frame on one core along the flyby.

Run: ``.venv/bin/python bench/universe_render.py [--frames 40] [--scenario PATH] [--resolution 1024] [--save DIR]``

Geometries of the scenario's flyby with perfect pointing (``universe.render.PerfectPointingCamera``), as in
``bench/universe.py``: far (Didymos ~10 px, before the impact), mid (~60 px, plume over half the frame), C/A
(~290 px, plume) and C/A - 20 s (~130 px). For each, the median of ``render_frame`` (the scene built once
outside the timing) and of its scene part alone (``scene_electrons``: bodies, plume, stars, optics); the detector
part (noise draws and digitisation) is the difference. Issue 3's target is 15 ms per frame; the reference is
drawing one frame of float32 standard normals with numpy (14.5 ms on the machine the target was set on), timed
alternately with the renders, so ``ratio <= 15 / 14.5`` meets the target whatever the load of the machine.
"""

from __future__ import annotations

import argparse
import math
import os
import sys

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # one core, as the budget is stated
# bench/universe.py would shadow the universe package: import from the repository root instead
_HERE = os.path.dirname(os.path.abspath(__file__))
sys.path[:] = [p for p in sys.path if os.path.abspath(p or ".") != _HERE]
sys.path.insert(0, os.path.dirname(_HERE))

import statistics  # noqa: E402
import time  # noqa: E402  (the benchmark, not the renderer, reads the clock)
from collections.abc import Callable  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from scenario.model import Scenario, load_scenario  # noqa: E402
from universe.camera import focal_length_px, frame_to_png8, render_frame, scene_electrons  # noqa: E402
from universe.render import PerfectPointingCamera  # noqa: E402
from universe.scene import scene_at  # noqa: E402
from scenario import compose

RENDER_TARGET_MS = 15.0  # issue 3: at most 15 ms per 1024x1024 frame on one core
ROOT = Path(_HERE).parent


def time_for_didymos_size_s(scenario: Scenario, size_px: float) -> float:
    """True time before C/A at which Didymos spans ``size_px`` pixels (C/A itself if it never gets that big)."""
    u = scenario.universe
    range_m = u.bodies.didymos_diameter_m * focal_length_px(u.camera) / size_px
    b = u.flyby.ca_distance_km * 1e3
    along = math.sqrt(max(range_m * range_m - b * b, 0.0))
    return u.flyby.ca_time_s - along / (u.flyby.speed_km_s * 1e3)


def median_ms(*fns: Callable[[], object], n: int) -> list[float]:
    """Median wall time of ``n`` calls of each of ``fns``, ms; the calls alternate, so a change in the machine's
    load weighs on all of them alike."""
    times: list[list[float]] = [[] for _ in fns]
    for _ in range(n):
        for fn, out in zip(fns, times):
            t0 = time.perf_counter()
            fn()
            out.append(time.perf_counter() - t0)
    return [statistics.median(t) * 1e3 for t in times]


def main() -> None:
    """Print the reference and, per geometry, the median render time, its scene and detector parts and the ratio."""
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenario", type=Path, default=ROOT / "configs" / "scenarios" / "nominal.yaml")
    ap.add_argument("--frames", type=int, default=40, help="timed renders per geometry")
    ap.add_argument("--resolution", type=int, default=None, choices=(1024, 2048), help="override the frame side")
    ap.add_argument("--save", default="", help="directory to write one PNG per geometry")
    args = ap.parse_args()
    cv2.setNumThreads(1)
    scenario = load_scenario(args.scenario)
    u = scenario.universe
    cfg = u.camera if args.resolution is None else u.camera.model_copy(update={"resolution_px": args.resolution})
    cam = PerfectPointingCamera(compose.universe(scenario))
    rng = np.random.default_rng(0)
    side = cfg.resolution_px
    (ref_ms,) = median_ms(lambda: rng.standard_normal((side, side), dtype=np.float32), n=args.frames)
    print(f"{side}x{side} frames, median of {args.frames}, one thread; reference numpy normal frame {ref_ms:.2f} ms")
    print(f"{'geometry':10s} {'t s':>7s} {'Didymos px':>10s} {'render ms':>10s} {'scene ms':>9s} {'detector ms':>11s} "
          f"{'ratio':>6s}")
    f = focal_length_px(cfg)
    for name, t in (
        ("far", time_for_didymos_size_s(scenario, 10.0)),
        ("mid", time_for_didymos_size_s(scenario, 60.0)),
        ("C/A - 20 s", u.flyby.ca_time_s - 20.0),
        ("C/A", u.flyby.ca_time_s),
    ):
        cam.frame_at(t)  # aims the universe at this geometry
        scene = scene_at(cam.universe, cfg.exposure_s)
        frame = render_frame(scene, cfg, u.plume, rng)  # warms the caches (shape tables, star cells, buffers)
        ref, render, part = median_ms(
            lambda: rng.standard_normal((side, side), dtype=np.float32),
            lambda: render_frame(scene, cfg, u.plume, rng),
            lambda: scene_electrons(scene, cfg, u.plume),
            n=args.frames,
        )
        g = cam.universe.geometry
        range_m = float(np.linalg.norm(g.didymos_position_m(t) - g.spacecraft_position_m(t)))
        size_px = u.bodies.didymos_diameter_m * f / range_m
        verdict = "within" if render / ref <= RENDER_TARGET_MS / 14.5 else "over"
        print(f"{name:10s} {t:+7.1f} {size_px:10.0f} {render:10.2f} {part:9.2f} {render - part:11.2f} "
              f"{render / ref:6.2f}  ({verdict} the target; reference {ref:.2f} ms alongside)")
        if args.save:
            from PIL import Image

            os.makedirs(args.save, exist_ok=True)
            out = os.path.join(args.save, name.replace("/", "").replace(" ", "") + ".png")
            Image.fromarray(frame_to_png8(frame, cfg.bit_depth)).save(out)


if __name__ == "__main__":
    main()
