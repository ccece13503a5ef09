"""The sensor's fixed defects, drawn once from its seed: hot, warm and dead pixels, dead columns, and the per-pixel
dark current (dark signal non-uniformity).

Every map comes from ``CameraConfig.hot_pixel_seed`` (hot pixels from the seed itself, as they always have, the others
from their own child streams of it), so a sensor keeps its defects in every frame and every run, and turning one
effect on does not move another's pixels. Hot pixels add a fixed charge per frame; warm pixels a fixed excess dark
current, so their charge grows with the exposure; dead pixels and columns read the bias only; with a non-uniformity,
each pixel has its own dark current, lognormal (dark current is positive, with a long tail) with the configured mean
and spread.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from universe.config import CameraConfig

_WARM, _DEAD, _COLUMNS, _DSNU = 1, 2, 3, 4  # child streams of the sensor seed, one per map


@dataclass(frozen=True, eq=False)
class SensorDefects:
    """The fixed defects of one sensor; pixel indices are flat (row * side + column)."""

    hot_idx: np.ndarray
    hot_e: np.ndarray
    """excess electrons of each hot pixel in every frame, float32"""
    warm_idx: np.ndarray
    warm_e_s: np.ndarray
    """excess dark current of each warm pixel, electrons per second"""
    dead_idx: np.ndarray
    dead_columns: np.ndarray
    dark_e_s: np.ndarray | None
    """dark current of each pixel (side, side) float32, electrons per second; None when uniform"""


@lru_cache(maxsize=16)
def hot_pixels(seed: int, count: int, size: int, signal_e: float) -> tuple[np.ndarray, np.ndarray]:
    """Fixed hot pixels of a ``size`` x ``size`` sensor: flat indices and excess electrons per frame."""
    rng = np.random.default_rng(seed)
    idx = rng.choice(size * size, size=min(count, size * size), replace=False)
    level = signal_e * rng.uniform(0.2, 1.0, idx.size)
    idx.setflags(write=False)
    level.setflags(write=False)
    return idx, level


@lru_cache(maxsize=4)
def sensor_defects(cfg: CameraConfig) -> SensorDefects:
    """The fixed defects of the sensor ``cfg`` describes (cached: the same arrays for every frame)."""
    size = cfg.resolution_px
    n = size * size
    seed = cfg.hot_pixel_seed
    hot_idx, hot_level = hot_pixels(seed, cfg.hot_pixel_count, size, cfg.hot_pixel_signal_e)
    rng = np.random.default_rng([seed, _WARM])
    warm_idx = rng.choice(n, size=int(round(cfg.warm_pixel_fraction * n)), replace=False)
    warm_e_s = cfg.warm_pixel_dark_current_e_s * rng.uniform(0.2, 1.0, warm_idx.size)
    dead_idx = np.random.default_rng([seed, _DEAD]).choice(n, size=min(cfg.dead_pixel_count, n), replace=False)
    dead_columns = np.random.default_rng([seed, _COLUMNS]).choice(size, size=cfg.dead_column_count, replace=False)
    dark: np.ndarray | None = None
    if cfg.dark_current_dsnu_e_s > 0:
        # lognormal with the configured mean m and spread s: sigma^2 = ln(1 + s^2/m^2), mu = ln m - sigma^2 / 2
        s2 = math.log1p((cfg.dark_current_dsnu_e_s / cfg.dark_current_e_s) ** 2)
        z = np.random.default_rng([seed, _DSNU]).standard_normal((size, size))
        dark = np.exp(math.log(cfg.dark_current_e_s) - 0.5 * s2 + math.sqrt(s2) * z).astype(np.float32)
    out = SensorDefects(hot_idx=hot_idx, hot_e=hot_level.astype(np.float32), warm_idx=warm_idx, warm_e_s=warm_e_s,
                        dead_idx=dead_idx, dead_columns=np.sort(dead_columns), dark_e_s=dark)
    for a in (out.hot_e, warm_idx, warm_e_s, dead_idx, out.dead_columns) + ((dark,) if dark is not None else ()):
        a.setflags(write=False)
    return out
