"""Irregular body shape models: a seeded, smooth, star-shaped surface around a centre.

The surface is ``r(u) = R * e(u) * (1 + p(u))`` along each unit direction ``u`` of the body frame:

- ``e(u) = (u_x^2/a^2 + u_y^2/b^2 + u_z^2/c^2)^(-1/2)`` is a tri-axial ellipsoid with ``a*b*c = 1`` (so ``R`` is
  the volume-equivalent radius of the ellipsoid);
- ``p(u) = sum_k A_k (exp((u.v_k - 1)/w_k^2) - m_k)`` is a sum of smooth random bumps (von Mises-Fisher-like
  kernels of angular width ``w_k`` centred on seeded directions ``v_k``), each made zero-mean over the sphere
  (``m_k``) and the sum scaled so that its RMS over the sphere equals ``irregularity``.

A star-shaped surface lets the renderer ray-cast it by a fixed-point iteration on the radius (see
``universe.camera``); the analytic gradient gives the outward normal used for shading.
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass, field
from functools import cached_property

import cv2
import numpy as np


class ShapeError(ValueError):
    """A shape model parameter is out of its valid range."""


def fibonacci_sphere(n: int) -> np.ndarray:
    """Return ``n`` nearly uniformly spread unit vectors (a Fibonacci lattice), shape (n, 3)."""
    if n < 1:
        raise ShapeError(f"fibonacci_sphere: n must be >= 1, got {n}")
    k = np.arange(n, dtype=np.float64) + 0.5
    z = 1.0 - 2.0 * k / n
    phi = np.pi * (1.0 + 5.0**0.5) * k
    rho = np.sqrt(1.0 - z * z)
    return np.stack([rho * np.cos(phi), rho * np.sin(phi), z], axis=1)


@dataclass(frozen=True)
class ShapeModel:
    """A seeded irregular shape, dimensionless (radii relative to the body's mean radius).

    ``irregularity`` is the RMS of the relative radius perturbation (0 gives the bare ellipsoid, and a sphere
    when ``axis_ratios`` are equal); ``axis_ratios`` are rescaled to a unit product.
    """

    seed: int = 0
    irregularity: float = 0.08
    axis_ratios: tuple[float, float, float] = (1.0, 1.0, 1.0)
    n_bumps: int = 40
    bump_width_deg: tuple[float, float] = (15.0, 40.0)
    _cache: dict = field(default_factory=dict, init=False, repr=False, compare=False, hash=False)

    def __post_init__(self) -> None:
        if not 0.0 <= self.irregularity <= 0.3:
            raise ShapeError(f"ShapeModel.irregularity must be within [0, 0.3], got {self.irregularity}")
        if len(self.axis_ratios) != 3 or min(self.axis_ratios) <= 0:
            raise ShapeError(f"ShapeModel.axis_ratios must be three positive numbers, got {self.axis_ratios}")
        if max(self.axis_ratios) / min(self.axis_ratios) > 2.0:
            raise ShapeError(f"ShapeModel.axis_ratios must be within a factor 2 of each other, got {self.axis_ratios}")
        if self.n_bumps < 0:
            raise ShapeError(f"ShapeModel.n_bumps must be >= 0, got {self.n_bumps}")
        lo, hi = self.bump_width_deg
        if not 5.0 <= lo <= hi <= 90.0:
            raise ShapeError(f"ShapeModel.bump_width_deg must satisfy 5 <= lo <= hi <= 90, got {self.bump_width_deg}")
        object.__setattr__(self, "_cache", _shared_cache(self))

    @cached_property
    def _semi_axes(self) -> np.ndarray:
        a = np.asarray(self.axis_ratios, dtype=np.float64)
        return a / np.prod(a) ** (1.0 / 3.0)

    @property
    def _bumps(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Centres (K,3), 1/w^2 (K,), amplitudes (K,) and means (K,) of the bumps, RMS-normalised (cached)."""
        if "bumps" not in self._cache:
            self._cache["bumps"] = self._draw_bumps()
        return self._cache["bumps"]

    def _draw_bumps(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        rng = np.random.default_rng(self.seed)
        k = self.n_bumps
        centres = rng.normal(size=(k, 3))
        centres /= np.linalg.norm(centres, axis=1, keepdims=True)
        w = np.deg2rad(rng.uniform(self.bump_width_deg[0], self.bump_width_deg[1], size=k))
        inv_w2 = 1.0 / (w * w)
        amp = rng.normal(size=k)
        # mean of exp((u.v - 1)/w^2) over the unit sphere, closed form
        means = 0.5 / inv_w2 * (1.0 - np.exp(-2.0 * inv_w2))
        if k and self.irregularity > 0:
            probe = fibonacci_sphere(20000)
            raw = (np.exp((probe @ centres.T - 1.0) * inv_w2) - means) @ amp
            amp = amp * (self.irregularity / float(np.sqrt(np.mean(raw * raw))))
        else:
            amp = np.zeros(k)
        for a in (centres, inv_w2, amp, means):
            a.setflags(write=False)  # shared by every model of the same parameters
        return centres, inv_w2, amp, means

    def radius(self, u: np.ndarray) -> np.ndarray:
        """Relative radius along unit directions ``u`` (..., 3) of the body frame."""
        return self.radius_and_normal(u)[0]

    def radius_and_normal(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Relative radius (...) and outward unit surface normal (..., 3) at unit directions ``u`` (..., 3)."""
        u = np.asarray(u, dtype=np.float64)
        shape = u.shape[:-1]
        u = u.reshape(-1, 3)
        if len(u) > _ROWS_PER_PASS:
            # a table's 132,000 directions at once make (n, K) temporaries of 40 MB, each page-faulted afresh: in
            # passes that stay in the cache the same arithmetic runs 9x faster
            parts = [self.radius_and_normal(u[i:i + _ROWS_PER_PASS]) for i in range(0, len(u), _ROWS_PER_PASS)]
            return (np.concatenate([p[0] for p in parts]).reshape(shape),
                    np.concatenate([p[1] for p in parts]).reshape(*shape, 3))
        inv_a2 = 1.0 / self._semi_axes**2
        q = (u * u) @ inv_a2
        e = q**-0.5
        de = -(e**3)[:, None] * (u * inv_a2)  # d e / d u
        centres, inv_w2, amp, means = self._bumps
        if amp.size and self.irregularity > 0:
            b = np.exp((u @ centres.T - 1.0) * inv_w2)  # (n, K)
            p = (b - means) @ amp
            dp = (b * (amp * inv_w2)) @ centres
        else:
            p = np.zeros(len(u))
            dp = np.zeros_like(u)
        r = e * (1.0 + p)
        g = de * (1.0 + p)[:, None] + e[:, None] * dp
        g_t = g - np.sum(g * u, axis=1, keepdims=True) * u  # tangential gradient on the unit sphere
        n = u - g_t / r[:, None]
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        return r.reshape(shape), n.reshape(*shape, 3)

    def max_radius(self) -> float:
        """An upper bound of the relative radius (dense sampling plus a 2 % margin)."""
        return self._extremes()[1]

    def min_radius(self) -> float:
        """A lower bound of the relative radius (dense sampling less a 2 % margin)."""
        return self._extremes()[0]

    def _extremes(self) -> tuple[float, float]:
        """Cached (min, max) bounds of the relative radius: one dense sampling for both."""
        if "extremes" not in self._cache:
            r = self.radius(fibonacci_sphere(40000))
            exact_sphere = self.irregularity == 0 and np.ptp(self._semi_axes) == 0
            self._cache["extremes"] = (float(r.min()) * (1.0 if exact_sphere else 0.98),
                                       float(r.max()) * (1.0 if exact_sphere else 1.02))
        return self._cache["extremes"]

    def surface_table(self) -> np.ndarray:
        """Cached (n_lat, n_lon, 4) float32 table of relative radius and body-frame normal over latitude/longitude.

        Rows run from latitude -90 to +90 deg, columns from longitude -180 to +180 deg (both ends included), in
        steps of ``180 / (n_lat - 1)`` deg; ``lookup`` interpolates it bilinearly.
        """
        if "table" not in self._cache:
            lat = np.linspace(-np.pi / 2, np.pi / 2, _TABLE_LAT)
            lon = np.linspace(-np.pi, np.pi, 2 * _TABLE_LAT - 1)
            lo, la = np.meshgrid(lon, lat)
            u = np.stack([np.cos(la) * np.cos(lo), np.cos(la) * np.sin(lo), np.sin(la)], axis=-1)
            r, n = self.radius_and_normal(u)
            table = np.concatenate([r[..., None], n], axis=-1).astype(np.float32)
            table.setflags(write=False)
            self._cache["table"] = table
        return self._cache["table"]

    def lookup(self, ux: np.ndarray, uy: np.ndarray, uz: np.ndarray) -> np.ndarray:
        """Bilinear table look-up at body-frame unit directions given by components: (..., 4) [r, nx, ny, nz].

        The normal is interpolated, not renormalised; the radius agrees with ``radius`` to about 1e-4.
        """
        table = self.surface_table()
        inv_step = np.float32((_TABLE_LAT - 1) / np.pi)
        ux, uy, uz = (np.asarray(a, dtype=np.float32) for a in (ux, uy, uz))
        mx = (np.arctan2(uy, ux) + np.float32(np.pi)) * inv_step
        my = (np.arcsin(np.clip(uz, np.float32(-1.0), np.float32(1.0))) + np.float32(np.pi / 2)) * inv_step
        shape = mx.shape
        mx2 = mx.reshape(-1, shape[-1]) if mx.ndim > 1 else mx.reshape(1, -1)
        my2 = my.reshape(mx2.shape)
        out = cv2.remap(table, mx2, my2, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        return out.reshape(*shape, 4)


_SHARED_MODELS = 8  # parameter sets whose tables are kept: a campaign's runs mostly share their bodies' shapes
_shared: OrderedDict[ShapeModel, dict] = OrderedDict()


def _shared_cache(model: ShapeModel) -> dict:
    """The cache of every model with ``model``'s parameters (its tables cost 0.19 s a run to build): a process
    running many runs of one scenario (a campaign's worker) builds them once. Least recently used sets go first."""
    try:
        cache = _shared.pop(model)
    except TypeError:  # parameters given as lists: not hashable, so a cache of its own
        return {}
    except KeyError:
        cache = {}
    _shared[model] = cache
    while len(_shared) > _SHARED_MODELS:
        _shared.popitem(last=False)
    return cache


_ROWS_PER_PASS = 4096  # directions evaluated together by ``radius_and_normal``
_TABLE_LAT = 257  # 0.7 deg steps: far finer than the narrowest (12 deg) bump
