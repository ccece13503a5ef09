"""Compiled steps of the attitude MEKF (Numba): the prediction and the star tracker update of its 6x6 error
covariance, with the quaternion's own steps (``propagate``, ``correct``), one call each per control period.

The equations are ``obsw.attitude``'s (its module docstring): the discrete transition ``Phi`` and process noise
``Q_d`` of ``x = [dtheta, db]`` under ``dtheta' = -[w x] dtheta - db - n_v, db' = n_u``, and the Kalman update with
``H = [I 0]`` in Joseph form, ``P = (I - K H) P (I - K H)^T + K R K^T``, which keeps ``P`` symmetric and positive
for any gain. They were generic 6x6 matrix products through filterpy, a fifth of the flight software's time per
period; here they are plain loops in double precision without fast-math (no reassociation), compiled once and
cached next to this file (``warm_up`` lets the OBSW node pay it before its first control period). Element-wise
array expressions are written as loops: Numba compiles each generic array operation anew in every cached kernel
that uses it, which made up half of this module's compile time (the same operations in the same order: the
results are identical).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from obsw.control_kernels import error_quaternion, rotvec


@njit(cache=True, nogil=True)
def _mul(a: np.ndarray, b: np.ndarray, transpose_b: bool) -> np.ndarray:
    """``a b`` (or ``a b^T``), summed in index order."""
    n, m = a.shape[0], b.shape[0] if transpose_b else b.shape[1]
    out = np.zeros((n, m))
    for i in range(n):
        for j in range(m):
            acc = 0.0
            for k in range(a.shape[1]):
                acc += a[i, k] * (b[j, k] if transpose_b else b[k, j])
            out[i, j] = acc
    return out


@njit(cache=True, nogil=True)
def _inverse3(s: np.ndarray) -> np.ndarray:
    """The inverse of a 3x3 matrix by its adjugate (S = P_tt + R is symmetric positive definite: never singular)."""
    a, b, c = s[0, 0], s[0, 1], s[0, 2]
    d, e, f = s[1, 0], s[1, 1], s[1, 2]
    g, h, i = s[2, 0], s[2, 1], s[2, 2]
    co_a, co_b, co_c = e * i - f * h, f * g - d * i, d * h - e * g
    det = a * co_a + b * co_b + c * co_c
    out = np.empty((3, 3))
    out[0, 0], out[1, 0], out[2, 0] = co_a / det, co_b / det, co_c / det
    out[0, 1], out[1, 1], out[2, 1] = (c * h - b * i) / det, (a * i - c * g) / det, (b * g - a * h) / det
    out[0, 2], out[1, 2], out[2, 2] = (b * f - c * e) / det, (c * d - a * f) / det, (a * e - b * d) / det
    return out


@njit(cache=True, nogil=True)
def transition(w: np.ndarray, dt_s: float) -> np.ndarray:
    """``Phi`` over ``dt_s`` at body rate ``w`` (rad/s): second order in ``w dt``, exact for ``w = 0``."""
    sk = np.zeros((3, 3))
    sk[0, 1], sk[0, 2], sk[1, 0] = -w[2], w[1], w[2]
    sk[1, 2], sk[2, 0], sk[2, 1] = -w[0], -w[1], w[0]
    phi = np.eye(6)
    for i in range(3):
        for j in range(3):
            sk2 = sk[i, 0] * sk[0, j] + sk[i, 1] * sk[1, j] + sk[i, 2] * sk[2, j]
            phi[i, j] = (1.0 if i == j else 0.0) - sk[i, j] * dt_s + 0.5 * sk2 * dt_s * dt_s
            phi[i, 3 + j] = (-dt_s if i == j else 0.0) + 0.5 * sk[i, j] * dt_s * dt_s
    return phi


@njit(cache=True, nogil=True)
def predict(p: np.ndarray, w: np.ndarray, dt_s: float, sigma_v: float, sigma_u: float) -> np.ndarray:
    """``Phi P Phi^T + Q_d``: the error covariance ``p`` carried over ``dt_s`` at body rate ``w`` (rad/s), with the
    gyro's angle random walk ``sigma_v`` (rad/sqrt(s)) and the bias walk ``sigma_u`` (rad/s/sqrt(s))."""
    phi = transition(w, dt_s)
    out = _mul(_mul(phi, p, False), phi, True)
    sv2, su2 = sigma_v * sigma_v, sigma_u * sigma_u
    q_tt = sv2 * dt_s + su2 * dt_s ** 3 / 3.0
    q_tb = -(su2 * dt_s ** 2 / 2.0)
    q_bb = su2 * dt_s
    for i in range(3):
        out[i, i] += q_tt
        out[i, 3 + i] += q_tb
        out[3 + i, i] += q_tb
        out[3 + i, 3 + i] += q_bb
    return out


@njit(cache=True, nogil=True)
def update(p: np.ndarray, r: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The Kalman update of a zero error state with covariance ``p`` on a measurement ``z`` of ``dtheta`` with
    noise covariance ``r`` (3x3): the state correction ``dx`` (6) and the updated covariance (Joseph form)."""
    s = np.empty((3, 3))
    p_h = np.empty((6, 3))
    for i in range(6):
        for j in range(3):
            p_h[i, j] = p[i, j]
            if i < 3:
                s[i, j] = p[i, j] + r[i, j]
    k = _mul(p_h, _inverse3(s), False)  # P H^T S^-1
    dx = np.zeros(6)
    for i in range(6):
        dx[i] = k[i, 0] * z[0] + k[i, 1] * z[1] + k[i, 2] * z[2]
    i_kh = np.eye(6)
    for i in range(6):
        for j in range(3):
            i_kh[i, j] -= k[i, j]
    out = _mul(_mul(i_kh, p, False), i_kh, True)
    noise = _mul(_mul(k, r, False), k, True)
    for i in range(6):
        for j in range(6):
            out[i, j] += noise[i, j]
    return dx, out


@njit(cache=True, nogil=True)
def _normalised(q: np.ndarray) -> np.ndarray:
    """``q / |q|`` in place (``|q|`` from ``np.dot``), returned."""
    norm = np.sqrt(np.dot(q, q))
    for i in range(q.shape[0]):
        q[i] = q[i] / norm
    return q


@njit(cache=True, nogil=True)
def product(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton product ``p (x) q`` of scalar-last quaternions (rotate by ``q``, then by ``p``)."""
    px, py, pz, pw = p[0], p[1], p[2], p[3]
    qx, qy, qz, qw = q[0], q[1], q[2], q[3]
    out = np.empty(4)
    out[0] = pw * qx + px * qw + py * qz - pz * qy
    out[1] = pw * qy - px * qz + py * qw + pz * qx
    out[2] = pw * qz + px * qy - py * qx + pz * qw
    out[3] = pw * qw - px * qx - py * qy - pz * qz
    return out


@njit(cache=True, nogil=True)
def of_rotvec(v: np.ndarray) -> np.ndarray:
    """Unit quaternion (scalar-last) of a rotation vector, rad."""
    angle = np.sqrt(np.dot(v, v))
    out = np.empty(4)
    if angle < 1e-12:
        out[0], out[1], out[2], out[3] = 0.5 * v[0], 0.5 * v[1], 0.5 * v[2], 1.0
        return _normalised(out)
    s = np.sin(0.5 * angle) / angle
    out[0], out[1], out[2], out[3] = s * v[0], s * v[1], s * v[2], np.cos(0.5 * angle)
    return out


@njit(cache=True, nogil=True)
def propagate(q: np.ndarray, p: np.ndarray, w: np.ndarray, dt_s: float, sigma_v: float,
              sigma_u: float) -> tuple[np.ndarray, np.ndarray]:
    """The attitude ``q`` turned by ``w dt_s`` (renormalised) and its error covariance carried (``predict``)."""
    turn = np.empty(3)
    for i in range(3):
        turn[i] = w[i] * dt_s
    return _normalised(product(q, of_rotvec(turn))), predict(p, w, dt_s, sigma_v, sigma_u)


@njit(cache=True, nogil=True)
def correct(q: np.ndarray, bias: np.ndarray, p: np.ndarray, r: np.ndarray,
            q_meas: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A star tracker solution ``q_meas`` (unit) taken: the attitude, bias and covariance after the update, and the
    innovation (rotation vector, body, rad)."""
    z = rotvec(error_quaternion(q_meas, q))  # conj(q) (x) q_meas: the innovation in body axes
    dx, p_new = update(p, r, z)
    bias_new = np.empty(3)
    for i in range(3):
        bias_new[i] = bias[i] + dx[3 + i]
    return _normalised(product(q, of_rotvec(dx[:3].copy()))), bias_new, p_new, z


def warm_up() -> None:
    """Compile the kernels now (or load them from the cache): seconds on the first run after an install."""
    p = np.eye(6)
    q = np.array([0.0, 0.0, 0.0, 1.0])
    q, p = propagate(q, p, np.zeros(3), 0.1, 1e-5, 1e-6)
    correct(q, np.zeros(3), p, np.eye(3), q)
