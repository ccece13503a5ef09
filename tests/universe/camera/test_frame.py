"""The frame: any attitude, rate and position gives a valid frame; the compiled kernels are cached next to their
source, so later processes do not recompile them."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.universe.camera.common import SPHERE, scene
from universe.camera import Body, Scene, raycast, readout, render_frame, scene_electrons, warm_up
from universe.config import CameraConfig, PlumeConfig
from universe.shapes import ShapeModel

ROOT = Path(__file__).resolve().parents[3]

_PROBE = """
import json
from universe.camera import raycast, readout, warm_up
warm_up()
stats = {d.__name__: d.stats for d in (raycast.cast_body, readout.digitise, readout.digitise_dark,
                                              readout.dark_frame)}
print(json.dumps({k: [s.cache_path, len(s.cache_hits), len(s.cache_misses)] for k, s in stats.items()}))
"""


def test_a_new_process_loads_the_kernels_from_the_cache_next_to_their_source() -> None:
    """After one warm-up, a fresh process's warm-up only hits the cache in universe/camera/__pycache__."""
    warm_up()  # writes the cache if this process compiled the kernels
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    out = subprocess.run([sys.executable, "-c", _PROBE], capture_output=True, text=True, env=env, cwd=ROOT,
                         timeout=120, check=True)
    stats = json.loads(out.stdout.strip().splitlines()[-1])
    here = Path(raycast.__file__).parent / "__pycache__"
    assert Path(readout.__file__).parent / "__pycache__" == here
    for name, (path, hits, misses) in stats.items():
        assert Path(path) == here, name
        assert hits > 0 and misses == 0, (name, hits, misses)


# ------------------------------------------------------------------------------------------------ any geometry

DIDYMOS = Body(np.zeros(3), 390.0, ShapeModel(seed=11, axis_ratios=(1.04, 1.0, 0.96)))
CFG = CameraConfig()
MAX_DN = 2**CFG.bit_depth - 1


def unit_quaternion(v: tuple[float, float, float, float]) -> np.ndarray:
    """A point of the unit ball (4-D) pushed onto the sphere: uniform over rotations when the point is uniform."""
    q = np.asarray(v)
    return q / np.linalg.norm(q)


in_ball4 = st.tuples(*[st.floats(-1.0, 1.0)] * 4).filter(lambda v: 0.01 < sum(c * c for c in v) <= 1.0)
in_ball3 = st.tuples(*[st.floats(-1.0, 1.0)] * 3).filter(lambda v: sum(c * c for c in v) <= 1.0)


def valid(frame: np.ndarray, cfg: CameraConfig = CFG) -> bool:
    """A frame as the camera sends it: its size, 16-bit words, values within the bit depth."""
    side = cfg.resolution_px
    return frame.shape == (side, side) and frame.dtype == np.uint16 and int(frame.max()) <= 2**cfg.bit_depth - 1


@settings(max_examples=40, deadline=None)
@given(
    q=in_ball4,
    rate=in_ball3,
    where=in_ball3.filter(lambda v: sum(c * c for c in v) > 1e-4),
    log_range=st.floats(-0.7, 6.5),
    velocity=in_ball3,
    exposure_s=st.floats(1e-4, 0.05),
    since_impact_s=st.one_of(st.none(), st.floats(-10.0, 600.0)),
    sun=in_ball3.filter(lambda v: sum(c * c for c in v) > 1e-4),
)
def test_every_attitude_rate_and_position_renders_a_valid_frame(
    q, rate, where, log_range, velocity, exposure_s, since_impact_s, sun
) -> None:
    """Any attitude (uniform over rotations), body rate up to 1 rad/s, camera from inside the bounding sphere to
    3000 km from the bodies, at up to 10 km/s: a frame of the right size and type within the bit depth."""
    r_max = DIDYMOS.radius_m * DIDYMOS.shape.max_radius()
    direction = np.asarray(where) / np.linalg.norm(where)
    camera = direction * r_max * 10.0**log_range
    moon = Body(np.array([1190.0, 0.0, 0.0]), 82.0, ShapeModel(seed=12, axis_ratios=(1.12, 1.0, 0.88)))
    s = Scene(
        camera_position_m=camera, q_body_to_inertial=unit_quaternion(q), body_rate_rad_s=np.asarray(rate),
        exposure_s=exposure_s, bodies=(DIDYMOS, moon), sun_direction=np.asarray(sun), star_seed=1,
        camera_velocity_m_s=1e4 * np.asarray(velocity), time_since_impact_s=since_impact_s,
        plume_body_index=1 if since_impact_s is not None else None,
    )
    assert valid(render_frame(s, CFG, PlumeConfig(), np.random.default_rng(0)))


@pytest.mark.parametrize("rate_rad_s, exposure_s", [(3.0, 0.1), (50.0, 2.0)])
def test_tumbling_far_beyond_any_wheel_renders_a_valid_frame(rate_rad_s: float, exposure_s: float) -> None:
    """Rates and exposures far beyond the spacecraft's (a turn of 0.3 and 100 rad in the exposure), near a body moving
    across the view at 7 km/s: still a valid frame."""
    s = scene((Body(np.array([0.0, 0.0, 2_000.0]), 390.0, ShapeModel(seed=2)),), star_seed=4,
              body_rate_rad_s=np.array([0.6, 0.8, 0.1]) * rate_rad_s, exposure_s=exposure_s,
              camera_velocity_m_s=np.array([7_000.0, 0.0, 0.0]))
    assert valid(render_frame(s, CFG, PlumeConfig(), np.random.default_rng(0)))


def test_a_body_beside_the_camera_changes_no_pixel() -> None:
    """The flyby's tumbling case: Didymos 55 km away, 89.95 deg off the boresight, its bounding sphere across the
    image plane, the camera turning and moving (the image motion there has no bound): the frame is the empty one."""
    kw = dict(star_seed=5, body_rate_rad_s=np.array([0.3, 0.1, 0.2]), camera_velocity_m_s=np.array([0, 7_000.0, 0]))
    beside = Body(np.array([55_648.5, 13.2, 45.65]), 390.0, ShapeModel(seed=5))
    a = render_frame(scene((beside,), **kw), CFG, PlumeConfig(), np.random.default_rng(3))
    b = render_frame(scene((), **kw), CFG, PlumeConfig(), np.random.default_rng(3))
    assert np.array_equal(a, b)


def test_a_body_behind_a_near_camera_looking_away_changes_no_pixel() -> None:
    """Just outside a body's bounding sphere (it spans 60 deg), looking 140 deg away from its centre: rays that pass
    close to the centre behind the camera do not hit it, so the frame is the empty one."""
    radius = 390.0
    dist = radius / math.sin(math.radians(60.0))
    away = math.radians(140.0)
    body = Body(dist * np.array([math.sin(away), 0.0, math.cos(away)]), radius, SPHERE)
    a = render_frame(scene((body,), star_seed=6), CFG, PlumeConfig(), np.random.default_rng(4))
    b = render_frame(scene((), star_seed=6), CFG, PlumeConfig(), np.random.default_rng(4))
    assert np.array_equal(a, b)


def test_from_inside_a_body_the_frame_is_the_dark_frame() -> None:
    """A camera inside a body's surface receives no light: the frame is the blank (dark) frame of the same noise,
    stars, the other body and its ejecta hidden."""
    inside = Body(np.array([30.0, -20.0, 150.0]), 390.0, ShapeModel(seed=7))
    other = Body(np.array([0.0, 0.0, 5_000.0]), 82.0, SPHERE)
    s = scene((inside, other), star_seed=2, plume_body_index=1, time_since_impact_s=60.0)
    assert scene_electrons(replace(s, bodies=(other,), plume_body_index=0), CFG, PlumeConfig()).max() > 1e3
    a = render_frame(s, CFG, PlumeConfig(), np.random.default_rng(5))
    b = render_frame(scene((), blank=True), CFG, PlumeConfig(), np.random.default_rng(5))
    assert np.array_equal(a, b)


def test_a_plume_behind_the_camera_changes_no_pixel() -> None:
    """From outside the ejecta cloud, with its source 140 deg off the boresight and its front across the image plane,
    no ray in the frame meets it: the frame is that without the plume."""
    away = math.radians(140.0)
    src = Body(8_000.0 * np.array([math.sin(away), 0.0, math.cos(away)]), 82.0, SPHERE)
    # the cone opens toward the rays' closest points to the source, behind the camera; its front (7 km at 140 s)
    # reaches in front of the camera
    plume = PlumeConfig(axis_inertial=(-1.0, 0.0, 0.0))
    kw = dict(star_seed=7, time_since_impact_s=140.0)
    a = render_frame(scene((src,), plume_body_index=0, **kw), CFG, plume, np.random.default_rng(6))
    b = render_frame(scene((src,), **kw), CFG, plume, np.random.default_rng(6))
    assert np.array_equal(a, b)


@pytest.mark.parametrize("sun", [(0.0, 0.0, 1.0), (0.0, 0.0, -1.0)])
def test_the_sun_along_the_boresight_renders_a_valid_frame(sun: tuple[float, float, float]) -> None:
    """The Sun behind the body (180 deg phase) or behind the camera (0 deg), the body on the boresight: a valid
    frame, the body dark against the sky or lit."""
    body = Body(np.array([0.0, 0.0, 55_000.0]), 390.0, ShapeModel(seed=8))
    frame = render_frame(scene((body,), sun=sun, star_seed=1), CFG, PlumeConfig(), np.random.default_rng(7))
    assert valid(frame)
    lit = frame[500:524, 500:524].mean() > CFG.dark_offset_dn + 100
    assert lit == (sun[2] < 0)
