"""Compiled sampling of the attitude sensors (Numba): the arithmetic of ``universe.sensors`` on drawn noise.

The random numbers are drawn by ``Sensors`` from its Generator, in its fixed order; these kernels only combine them
with the true state, with the operations of the NumPy expressions they replace in the same order and in double
precision (no fast-math: no reassociation, no fused multiply-adds; the dot products of three and four values summed
in order, as NumPy sums them): the readings are the same to the last bit, for a few microseconds less a period.

Compiled on first use and cached next to this file (``cache=True``); ``warm_up`` lets a node pay it before its
first control period.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def gyro_and_tachometers(omega: np.ndarray, speeds: np.ndarray, bias: np.ndarray, noise: np.ndarray,
                         walk_step: float, white_sigma: float, wheel_sigma: float, bias_step: np.ndarray,
                         stepped: bool, gyro_out: np.ndarray, wheels_out: np.ndarray) -> None:
    """One period of the gyro and the tachometers: the gyro's bias (3,) walks in place by ``walk_step`` times
    ``noise[0:3]``; ``gyro_out`` = rate + bias + ``white_sigma`` times ``noise[3:6]``, plus a fault's ``bias_step``
    if ``stepped``; ``wheels_out`` = rotor speeds + ``wheel_sigma`` times ``noise[6:]``."""
    for i in range(3):
        bias[i] = bias[i] + walk_step * noise[i]
    for i in range(3):
        g = omega[i] + bias[i] + white_sigma * noise[3 + i]
        gyro_out[i] = g + bias_step[i] if stepped else g
    for i in range(speeds.shape[0]):
        wheels_out[i] = speeds[i] + wheel_sigma * noise[6 + i]


@njit(cache=True, nogil=True)
def star_tracker_q(q_true: np.ndarray, bias: np.ndarray, sigma: np.ndarray, z: np.ndarray, out: np.ndarray) -> None:
    """The tracker's unit quaternion (scalar-last, body -> inertial) into ``out``: the true one turned by the small
    rotation ``bias + sigma z`` about the tracker (body) axes, R_meas = R_true R(error), normalised."""
    e0 = bias[0] + sigma[0] * z[0]
    e1 = bias[1] + sigma[1] * z[1]
    e2 = bias[2] + sigma[2] * z[2]
    angle = math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
    if angle < 1e-12:  # sin(a/2)/a -> 1/2 as a -> 0
        k = math.sqrt(1.0 + 0.25 * (angle * angle))
        rx, ry, rz, rw = 0.5 * e0 / k, 0.5 * e1 / k, 0.5 * e2 / k, 1.0 / k
    else:
        s = math.sin(0.5 * angle) / angle
        rx, ry, rz, rw = s * e0, s * e1, s * e2, math.cos(0.5 * angle)
    px, py, pz, pw = q_true[0], q_true[1], q_true[2], q_true[3]
    qx = pw * rx + px * rw + py * rz - pz * ry
    qy = pw * ry - px * rz + py * rw + pz * rx
    qz = pw * rz + px * ry - py * rx + pz * rw
    qw = pw * rw - px * rx - py * ry - pz * rz
    norm = math.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
    out[0], out[1], out[2], out[3] = qx / norm, qy / norm, qz / norm, qw / norm


def warm_up() -> None:
    """Compile (or load from the cache) the kernels now, for a body of three wheels."""
    three = np.zeros(3)
    gyro_and_tachometers(three, three, np.zeros(3), np.zeros(9), 0.0, 0.0, 0.0, three, False, np.empty(3),
                         np.empty(3))
    star_tracker_q(np.array([0.0, 0.0, 0.0, 1.0]), three, three, three, np.empty(4))
