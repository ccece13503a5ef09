"""Frames the camera would see with perfect pointing: the pure part of ``flyby render``.

Perfect pointing puts the boresight (body +Z) exactly on the centre of Dimorphos with ``simulator.pointing_attitude``,
body +X as close as possible to minus the flyby velocity by default: that puts body +Y on the flyby-plane normal,
the roll the simulator's initial attitude and the on-board tracking loop hold, so these frames are oriented like the
frames of a run. The body rate is
the angular velocity of that attitude (the true line-of-sight rate plus any roll the reference forces), so the smear
in the frames is the one a perfect tracker would have. Everything else (bodies, plume, stars, noise, the camera
faults of the scenario's ``frame_blank``, ``frame_saturated`` and ``plume_brightening`` windows) is the universe's
own ``scene_at``/``render_at``; ``frame_lost`` is a transfer fault, so those frames are still rendered here.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from universe.camera import display_png8
from universe.dynamics import AttitudeState
from universe.geometry import FlybyGeometry
from universe.scene import render_at
from universe.simulator import Universe, pointing_attitude


class RenderRequestError(ValueError):
    """The times or sizes asked of ``flyby render`` are impossible; the message names the value at fault."""


@dataclass(frozen=True)
class PerfectPointing:
    """Attitude (body -> inertial, [x, y, z, w]) and body rate (rad/s, body axes) of perfect pointing at a time."""

    q: np.ndarray
    omega_body_rad_s: np.ndarray


@dataclass(frozen=True)
class RenderedFrame:
    """One frame at true time ``t_s`` (uint16 DN) with the true (col, row) of the Dimorphos and Didymos centres
    (None for a centre without a pixel: behind the camera)."""

    t_s: float
    pixels: np.ndarray
    dimorphos_px: tuple[float, float] | None
    didymos_px: tuple[float, float] | None


def pointing_rate_inertial_rad_s(
    los_inertial: np.ndarray, los_rate_inertial: np.ndarray, roll_ref_inertial: np.ndarray
) -> np.ndarray:
    """Angular velocity (inertial, rad/s) of ``pointing_attitude(los, roll_ref)`` when ``los`` turns at ``los_rate``.

    ``los_inertial`` is a unit vector and ``los_rate_inertial`` its time derivative (perpendicular to it); the roll
    reference is fixed. With the attitude's columns x, y, z: omega = (x cross x' + y cross y' + z cross z') / 2.
    """
    z = np.asarray(los_inertial, dtype=float)
    zd = np.asarray(los_rate_inertial, dtype=float)
    ref = np.asarray(roll_ref_inertial, dtype=float)
    u = ref - (ref @ z) * z
    ud = -(ref @ zd) * z - (ref @ z) * zd
    if np.linalg.norm(u) < 1e-9:  # the same fallback perpendicular as pointing_attitude
        c = np.array([0.0, 0.0, 1.0]) if abs(z[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
        u, ud = np.cross(z, c), np.cross(zd, c)
    n = float(np.linalg.norm(u))
    x = u / n
    xd = (ud - (ud @ x) * x) / n
    y = np.cross(z, x)
    yd = np.cross(zd, x) + np.cross(z, xd)
    return 0.5 * (np.cross(x, xd) + np.cross(y, yd) + np.cross(z, zd))


def perfect_pointing(
    geometry: FlybyGeometry, t_s: float, roll_ref_inertial: np.ndarray | None = None
) -> PerfectPointing:
    """The attitude with the boresight on Dimorphos at ``t_s`` and its rate; body +X leans to ``roll_ref_inertial``
    (default minus the flyby velocity direction)."""
    ref = -geometry.e_v if roll_ref_inertial is None else np.asarray(roll_ref_inertial, dtype=float)
    rel = geometry.dimorphos_position_m(t_s) - geometry.spacecraft_position_m(t_s)
    vel = geometry.dimorphos_velocity_m_s(t_s) - geometry.spacecraft_velocity_m_s(t_s)
    rng_m = float(np.linalg.norm(rel))
    los = rel / rng_m
    los_rate = (vel - (vel @ los) * los) / rng_m
    att = pointing_attitude(los, ref)
    omega_inertial = pointing_rate_inertial_rad_s(los, los_rate, ref)
    return PerfectPointing(q=att.as_quat(), omega_body_rad_s=att.inv().apply(omega_inertial))


def render_times_s(start_s: float, end_s: float, every_s: float) -> np.ndarray:
    """Times ``start_s, start_s + every_s, ...`` up to ``end_s`` inclusive (to a microsecond), s."""
    if not (math.isfinite(every_s) and every_s > 0):
        raise RenderRequestError(f"--every must be a positive number of seconds, got {every_s}")
    if not (math.isfinite(start_s) and math.isfinite(end_s)) or end_s < start_s:
        raise RenderRequestError(f"--from {start_s} s must not be after --to {end_s} s")
    n = int(math.floor((end_s - start_s) / every_s + 1e-6)) + 1
    return start_s + every_s * np.arange(n)


class PerfectPointingCamera:
    """The scenario's camera, bodies and faults, rendered from perfect pointing at any true time.

    Frames share the universe's seeded camera noise stream: the same scenario and times give the same frames.
    """

    def __init__(self, universe: Universe) -> None:
        self.universe = universe
        self.camera = universe.cfg.camera

    def frame_at(self, t_s: float, exposure_s: float | None = None) -> RenderedFrame:
        """Render the frame centred on Dimorphos at true time ``t_s`` (mid-exposure), s."""
        if not math.isfinite(t_s):
            raise RenderRequestError(f"render time must be finite, got {t_s}")
        u = self.universe
        p = perfect_pointing(u.geometry, t_s)
        u.t_s = float(t_s)  # scene_at reads the universe's time and state: set both to the perfect-pointing truth
        u.state = AttitudeState(q=p.q, omega_rad_s=p.omega_body_rad_s,
                                wheel_speed_rad_s=np.zeros(u.dynamics.n_wheels))
        pixels, dim, did = render_at(u, exposure_s if exposure_s is not None else self.camera.exposure_s)
        return RenderedFrame(t_s=float(t_s), pixels=pixels, dimorphos_px=dim, didymos_px=did)


def perfect_pointing_frames(universe: Universe, times_s: np.ndarray) -> Iterator[RenderedFrame]:
    """The frames at ``times_s`` (true time, s), in order, from one ``PerfectPointingCamera`` of a new universe."""
    camera = PerfectPointingCamera(universe)
    for t in times_s:
        yield camera.frame_at(float(t))


def display_frame(pixels: np.ndarray, bit_depth: int, size_px: int) -> np.ndarray:
    """8-bit display image (asinh stretch of ``frame_to_png8``) resampled to ``size_px`` square (area averaging)."""
    if size_px < 1:
        raise RenderRequestError(f"--size must be at least 1 px, got {size_px}")
    return display_png8(pixels, bit_depth, size_px)
