"""Compiled optical depth of the ejecta plume seen from outside it, node by node of the coarse grid (Numba).

Theory of operation (``universe.camera.plume``): the cloud's density falls as 1/r^2 from the source inside a cone;
along a line of sight whose closest point to the source is at distance ``b`` the depth is sampled uniformly in the
angle ``phi`` seen from the source, symmetrically about that closest point (``x = q + ell d`` with ``q . d = 0``, so
``|x|^2 = b^2 + ell^2`` at ``+-ell``), ``ell = b_eff tan(phi)``. Each node's tangents come from rotating (cos, sin)
of the first sample's angle by the step (four trigonometric calls per node, not one per sample). One pass per node
replaces some twenty whole-array NumPy operations on (steps, rows, cols) arrays, with the same operations in the
same order on each element: the depth is that array formula's to the last bit (``tests/universe/camera/
test_plume_depth.py`` keeps it as the reference; the arc tangents, whose NumPy and C library values differ in the
last bit, stay in NumPy).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def depth_outside(
    b: np.ndarray, b_eff: np.ndarray, phi_max: np.ndarray, q_axis: np.ndarray, d_axis: np.ndarray,
    t_c: np.ndarray, frac: np.ndarray, radius_m: float, c_out: float, ramp: float, scale: float, steps: int,
) -> np.ndarray:
    """Optical depth (rows, cols) at each node of lines of sight from a camera outside the cloud: ``b`` distance of
    the line's closest point to the source (m), ``b_eff`` its floor at the source's core, ``phi_max`` the half-angle
    of the line's chord through the cloud seen from the source, ``q_axis`` and ``d_axis`` the closest point's and
    the direction's components along the cone axis, ``t_c`` the distance to the closest point along the line (a
    line whose closest point is behind the camera meets none of the cloud), ``frac`` the sample fractions of
    ``phi_max`` (len ``steps // 2``, equally spaced), ``radius_m`` the source's radius (samples inside it count
    nothing), ``c_out`` and ``ramp`` the cone wall's cosine ramp, ``scale`` = A / (Omega R)."""
    rows, cols = b.shape
    half = frac.shape[0]
    f0 = frac[0]
    df = frac[1] - frac[0] if half > 1 else 0.0
    tau = np.empty((rows, cols))
    for i in range(rows):
        for k in range(cols):
            angle = phi_max[i, k]
            step = df * angle
            c = np.cos(f0 * angle)
            s = np.sin(f0 * angle)
            cs = np.cos(step)
            sn = np.sin(step)
            bi, be, qa, da = b[i, k], b_eff[i, k], q_axis[i, k], d_axis[i, k]
            total = 0.0
            for _ in range(half):
                ell = be * (s / c)
                rr = np.sqrt(bi * bi + ell * ell)
                inv_rr = 1.0 / max(rr, 1e-9)
                along = ell * da
                w = min(max(((qa + along) * inv_rr - c_out) * ramp, 0.0), 1.0) + min(
                    max(((qa - along) * inv_rr - c_out) * ramp, 0.0), 1.0)
                total += w * (1.0 if rr >= radius_m else 0.0)
                c, s = c * cs - s * sn, s * cs + c * sn
            dphi = 2.0 * angle / steps
            tau[i, k] = scale * total * dphi / be if t_c[i, k] > 0.0 else 0.0
    return tau


def warm_up() -> None:
    """Compile the kernel now (or load it from the cache)."""
    one = np.ones((2, 2))
    depth_outside(one, one, 0.5 * one, one, one, one, np.array([0.25, 0.75]), 0.5, 0.5, 10.0, 1.0, 4)
