"""Cosmic rays: charged particles crossing the sensor during the exposure, each leaving a straight streak of charge.

Hits are a Poisson process over the sensor's area (``resolution_px`` x ``pixel_pitch_um``, squared) and the exposure,
at ``cosmic_ray_flux_cm2_s``. Each hits a point uniform over the sensor, from a direction of an isotropic flux: the
number crossing a plane at zenith angle theta goes as cos(theta) sin(theta), so cos^2(theta) is uniform on (0, 1],
and the in-plane direction is uniform. Crossing the charge-collecting depth d, the particle draws a streak
d tan(theta) / pitch pixels long (at most the sensor's diagonal), frees ``cosmic_ray_charge_e_per_um`` electrons per
micrometre of its path in the silicon, and that charge spreads evenly along the streak; charge off the sensor is lost.
The length's law follows: P(L <= l) = 1 - 1 / (1 + (l pitch / d)^2).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from universe.config import CameraConfig

_STEP_PX = 0.25  # spacing of the charge samples along a streak, px


@dataclass(frozen=True, eq=False)
class CosmicRays:
    """The hits of one exposure: streak centre (col, row) px, in-plane direction (rad, [0, pi)), length px and
    charge electrons, one entry each."""

    col: np.ndarray
    row: np.ndarray
    angle_rad: np.ndarray
    length_px: np.ndarray
    charge_e: np.ndarray


def expected_hits(cfg: CameraConfig, exposure_s: float) -> float:
    """Mean number of particles crossing the sensor in ``exposure_s``: flux x area x time."""
    side_cm = cfg.resolution_px * cfg.pixel_pitch_um * 1e-4
    return cfg.cosmic_ray_flux_cm2_s * side_cm * side_cm * exposure_s


def cosmic_rays(cfg: CameraConfig, exposure_s: float, rng: np.random.Generator) -> CosmicRays:
    """Draw the hits of one exposure. At most one hit per four pixels is kept: beyond that the frame is a sea of
    charge whatever the count, and the work stays bounded for any flux and exposure."""
    size = cfg.resolution_px
    n = min(int(rng.poisson(expected_hits(cfg, exposure_s))), size * size // 4)
    col = rng.uniform(-0.5, size - 0.5, n)
    row = rng.uniform(-0.5, size - 0.5, n)
    angle = rng.uniform(0.0, math.pi, n)
    cos2 = 1.0 - rng.random(n)  # (0, 1]
    depth_px = cfg.cosmic_ray_depth_um / cfg.pixel_pitch_um
    length = np.minimum(depth_px * np.sqrt(1.0 / cos2 - 1.0), math.sqrt(2.0) * size)
    path_um = np.hypot(length * cfg.pixel_pitch_um, cfg.cosmic_ray_depth_um)
    return CosmicRays(col=col, row=row, angle_rad=angle, length_px=length,
                      charge_e=cfg.cosmic_ray_charge_e_per_um * path_um)


def deposit(hits: CosmicRays, size: int) -> tuple[np.ndarray, np.ndarray]:
    """The charge of the hits on a ``size`` x ``size`` sensor: flat pixel indices and electrons (float32), one entry
    per charge sample (samples every quarter pixel along each streak; indices repeat)."""
    if hits.col.size == 0:
        return np.empty(0, dtype=np.int64), np.empty(0, dtype=np.float32)
    samples = np.maximum(np.ceil(hits.length_px / _STEP_PX).astype(np.int64), 1)
    which = np.repeat(np.arange(samples.size), samples)
    start = np.cumsum(samples) - samples
    frac = (np.arange(which.size) - start[which] + 0.5) / samples[which] - 0.5  # along the streak, in (-1/2, 1/2)
    along = frac * hits.length_px[which]
    x = hits.col[which] + along * np.cos(hits.angle_rad[which])
    y = hits.row[which] + along * np.sin(hits.angle_rad[which])
    ic, ir = np.rint(x).astype(np.int64), np.rint(y).astype(np.int64)
    on = (ic >= 0) & (ic < size) & (ir >= 0) & (ir < size)
    electrons = (hits.charge_e / samples)[which]
    return ir[on] * size + ic[on], electrons[on].astype(np.float32)
