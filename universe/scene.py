"""What the camera sees at the current true time: the universe state turned into a camera ``Scene``.

Didymos spins about the orbit normal (2.26 h, Pravec et al. 2006); Dimorphos is tidally locked, so it turns once
per orbit, keeping one face to Didymos. Both shapes are fixed per scenario (seeded from the scenario seed), so
every frame of a run shows the same asteroids.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from scipy.spatial.transform import Rotation

from universe.camera import Body, Scene, project_inertial, render_frame
from universe.shapes import ShapeModel

if TYPE_CHECKING:
    from universe.dynamics import AttitudeState
    from universe.simulator import Universe

DIDYMOS_ROTATION_PERIOD_S = 2.26 * 3600.0  # Pravec et al. 2006


def body_shapes(seed: int) -> tuple[ShapeModel, ShapeModel]:
    """The shapes of Didymos and Dimorphos for a scenario seed (made once per run: each caches its tables)."""
    return (ShapeModel(seed=2 * seed + 1, axis_ratios=(1.04, 1.0, 0.96)),
            ShapeModel(seed=2 * seed + 2, axis_ratios=(1.12, 1.0, 0.88)))


def scene_at(u: Universe, exposure_s: float, t_s: float | None = None, state: AttitudeState | None = None) -> Scene:
    """The camera scene at true time ``t_s`` in attitude state ``state`` (default: the universe's current ones). The
    centroid-level measurement (``measurement.measure_at``) computes what it reads of a scene without making one."""
    g = u.geometry
    t = u.t_s if t_s is None else t_s
    state = u.state if state is None else state
    bodies_cfg = u.cfg.bodies
    n = g.orbit_normal
    spin = Rotation.from_rotvec(n * (2.0 * math.pi * t / DIDYMOS_ROTATION_PERIOD_S)).as_quat()
    lock = Rotation.from_rotvec(n * float(g.mean_motion_rad_s * t)).as_quat()
    seed = u.seed
    didymos = Body(centre_inertial_m=g.didymos_position_m(t), radius_m=bodies_cfg.didymos_diameter_m / 2.0,
                   shape=u.shapes[0], q_body_to_inertial=spin)
    dimorphos = Body(centre_inertial_m=g.dimorphos_position_m(t), radius_m=bodies_cfg.dimorphos_diameter_m / 2.0,
                     shape=u.shapes[1], q_body_to_inertial=lock)
    since_impact = t - bodies_cfg.impact_time_s
    brightening = 1.0
    for f in u.faults.active("plume_brightening", t):
        brightening *= f.magnitude if f.magnitude is not None else 2.0
    return Scene(
        camera_position_m=g.spacecraft_position_m(t),
        q_body_to_inertial=state.q,
        body_rate_rad_s=state.omega_rad_s,
        exposure_s=exposure_s,
        bodies=(didymos, dimorphos),
        sun_direction=g.sun_direction(),
        time_since_impact_s=since_impact if since_impact >= 0 else None,
        star_seed=seed,
        blank=bool(u.faults.active("frame_blank", t)),
        saturated=bool(u.faults.active("frame_saturated", t)),
        camera_velocity_m_s=g.spacecraft_velocity_m_s(t) - g.dimorphos_velocity_m_s(t),
        plume_body_index=1 if u.cfg.plume.enabled and since_impact >= 0 else None,
        plume_brightness_factor=brightening,
    )


def render_at(
    u: Universe, exposure_s: float, t_s: float | None = None, state: AttitudeState | None = None
) -> tuple[np.ndarray, tuple[float, float] | None, tuple[float, float] | None]:
    """Render the frame the camera takes now (or at ``t_s`` in ``state``; uint16, values within the bit depth),
    with the true pinhole (col, row) of the centres of Dimorphos and Didymos in it (None when the centre has no
    pixel: behind the camera, or so near the image plane that its projection is not a finite number)."""
    scene = scene_at(u, exposure_s, t_s, state)
    pixels = render_frame(scene, u.cfg.camera, u.cfg.plume, u.rng["camera"], u.rng["cosmic_rays"])
    return pixels, _pixel(scene, u, 1), _pixel(scene, u, 0)


def _pixel(scene: Scene, u: Universe, body: int) -> tuple[float, float] | None:
    """Pinhole (col, row) of a body's centre, None if it has no finite one."""
    col, row = project_inertial(scene, u.cfg.camera, scene.bodies[body].centre_inertial_m)
    return (col, row) if math.isfinite(col) and math.isfinite(row) else None
