"""Compiled truth geometry (Numba): ``FlybyGeometry.truth_samples``'s arithmetic, one sample at a time.

The truth records of a ground step (ten control periods) took some forty NumPy calls on arrays of ten, about 0.4 ms;
this kernel takes a few microseconds. The formulas are ``universe.geometry``'s (its module docstring), written out
per component in the order NumPy evaluated them. NumPy is free to round its matrix products, trigonometry and
reductions differently in the last bit, so the test holds the values to the NumPy forms within 1e-12
(``tests/universe/test_geometry_kernels.py``); the truth records of the nominal and worst-early-near flybys came out
identical, octet for octet. Only the truth records use it: nothing the flight software receives depends on it.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True, inline="always")
def _angle(ax: float, ay: float, az: float, bx: float, by: float, bz: float) -> float:
    """Angle between two non-zero 3-vectors, rad (atan2 of the cross product's norm and the dot product)."""
    cx = ay * bz - az * by
    cy = az * bx - ax * bz
    cz = ax * by - ay * bx
    return math.atan2(math.sqrt(cx * cx + cy * cy + cz * cz), ax * bx + ay * by + az * bz)


@njit(cache=True, nogil=True)
def truth_geometry(t: np.ndarray, q: np.ndarray, orbit: np.ndarray, e_ca: np.ndarray, e_v: np.ndarray,
                   e1: np.ndarray, e2: np.ndarray, sun: np.ndarray, axes: np.ndarray, half_tan: float,
                   scalars: np.ndarray, vectors: np.ndarray, in_fov: np.ndarray) -> None:
    """The truth geometry at the times ``t`` (N,) and attitudes ``q`` (N, 4, scalar-last body -> inertial).

    ``orbit`` = [C/A time s, C/A distance m, speed m/s, orbit phase at t = 0 rad, mean motion rad/s, Dimorphos's arm
    m, Didymos's arm m]; ``e_ca``, ``e_v`` the C/A and velocity directions, ``e1``, ``e2`` the orbit plane's axes,
    ``sun`` the Sun's direction, ``axes`` (3, 3) the camera's axes in body axes (rows), ``half_tan`` the tangent of
    half the field of view. Out: ``scalars`` (N, 5) range to Dimorphos and to Didymos m, theta rad, phase angle deg,
    pointing error rad; ``vectors`` (N, 4, 3) lines of sight to Dimorphos inertial, to Didymos
    inertial, to Dimorphos in body and in camera axes; ``in_fov`` (N,) Dimorphos's centre in the square field."""
    t_ca, d_ca, speed, phase0, motion, arm_dim, arm_did = (orbit[0], orbit[1], orbit[2], orbit[3], orbit[4],
                                                           orbit[5], orbit[6])
    bx, by, bz = axes[2, 0], axes[2, 1], axes[2, 2]
    for n in range(t.shape[0]):
        dt = t[n] - t_ca
        ph = phase0 + motion * t[n]
        c, s = math.cos(ph), math.sin(ph)
        rx = d_ca * e_ca[0] + speed * dt * e_v[0]
        ry = d_ca * e_ca[1] + speed * dt * e_v[1]
        rz = d_ca * e_ca[2] + speed * dt * e_v[2]
        ux, uy, uz = c * e1[0] + s * e2[0], c * e1[1] + s * e2[1], c * e1[2] + s * e2[2]
        dx, dy, dz = arm_dim * ux - rx, arm_dim * uy - ry, arm_dim * uz - rz
        gx, gy, gz = -arm_did * ux - rx, -arm_did * uy - ry, -arm_did * uz - rz
        range_dim = math.sqrt(dx * dx + dy * dy + dz * dz)
        range_did = math.sqrt(gx * gx + gy * gy + gz * gz)
        x, y, z, w = q[n, 0], q[n, 1], q[n, 2], q[n, 3]
        m00, m01, m02 = 1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)
        m10, m11, m12 = 2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)
        m20, m21, m22 = 2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)
        sx = m00 * bx + m01 * by + m02 * bz  # the boresight, inertial
        sy = m10 * bx + m11 * by + m12 * bz
        sz = m20 * bx + m21 * by + m22 * bz
        # at a body's very centre every direction leads to it: the line of sight is taken along the boresight
        if range_dim > 0.0:
            lx, ly, lz = dx / range_dim, dy / range_dim, dz / range_dim
        else:
            lx, ly, lz = sx, sy, sz
        if range_did > 0.0:
            kx, ky, kz = gx / range_did, gy / range_did, gz / range_did
        else:
            kx, ky, kz = sx, sy, sz
        # body axes: the transpose of body -> inertial; camera axes: the camera's rows
        ox = m00 * lx + m10 * ly + m20 * lz
        oy = m01 * lx + m11 * ly + m21 * lz
        oz = m02 * lx + m12 * ly + m22 * lz
        cx = axes[0, 0] * ox + axes[0, 1] * oy + axes[0, 2] * oz
        cy = axes[1, 0] * ox + axes[1, 1] * oy + axes[1, 2] * oz
        cz = axes[2, 0] * ox + axes[2, 1] * oy + axes[2, 2] * oz
        tangent_x = -s * e1[0] + c * e2[0]
        tangent_y = -s * e1[1] + c * e2[1]
        tangent_z = -s * e1[2] + c * e2[2]
        k = arm_dim * motion
        vx, vy, vz = speed * e_v[0] - k * tangent_x, speed * e_v[1] - k * tangent_y, speed * e_v[2] - k * tangent_z
        scalars[n, 0] = range_dim
        scalars[n, 1] = range_did
        scalars[n, 2] = _angle(vx, vy, vz, lx, ly, lz)
        scalars[n, 3] = math.degrees(_angle(sun[0], sun[1], sun[2], -lx, -ly, -lz))
        scalars[n, 4] = _angle(sx, sy, sz, lx, ly, lz)
        vectors[n, 0, 0], vectors[n, 0, 1], vectors[n, 0, 2] = lx, ly, lz
        vectors[n, 1, 0], vectors[n, 1, 1], vectors[n, 1, 2] = kx, ky, kz
        vectors[n, 2, 0], vectors[n, 2, 1], vectors[n, 2, 2] = ox, oy, oz
        vectors[n, 3, 0], vectors[n, 3, 1], vectors[n, 3, 2] = cx, cy, cz
        in_fov[n] = cz > 0.0 and abs(cx) <= half_tan * cz and abs(cy) <= half_tan * cz


def warm_up() -> None:
    """Compile (or load from the cache) the kernel now: one sample."""
    three = np.array([1.0, 0.0, 0.0])
    truth_geometry(np.zeros(1), np.array([[0.0, 0.0, 0.0, 1.0]]), np.ones(7), three, three, three, three, three,
                   np.eye(3), 0.1, np.empty((1, 5)), np.empty((1, 4, 3)), np.empty(1, dtype=bool))
