"""Compiled steps of the tracking loop (Numba): its exact propagation over a control period and the reference
(desired attitude, body rate and acceleration) it commands, one call each per control period.

The equations are ``obsw.tracking``'s (its module docstring): the type-2 loop on ``e = y - c`` integrated with the
closed-form ``exp(M h)``, Rodrigues' formula and the SO(3) left Jacobian of the correction ``c``, the predicted
attitude ``[los, n, los x n] triad^T`` of the straight-line flyby of ``obsw.trajectory`` and Markley's quaternion
of the commanded matrix. They were dozens of numpy calls on 3-vectors and 3x3 matrices, each mostly interpreter
overhead; here they are plain loops in double precision without fast-math, compiled once and cached next to this
file. A trajectory comes as ``geometry``: ``[t_ca (OBT s), d (m), v (m/s), e_ca (3), e_v (3)]``.
Element-wise array expressions are written as loops (Numba compiles each generic array operation anew in every
cached kernel), the same operations in the same order.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from obsw.vector3_kernels import cross, matmul, matvec


@njit(cache=True, nogil=True)
def transition(kp: float, ki: float, h_s: float) -> tuple[float, float, float, float]:
    """``exp(M h)`` for ``M = [[-kp, -1], [ki, 0]]`` in closed form (``M = a I + N`` with ``N^2 = delta I``), row by
    row: ``(m00, m01, m10, m11)``."""
    a = -0.5 * kp
    delta = 0.25 * kp * kp - ki
    root = math.sqrt(abs(delta))
    x = root * h_s
    if x < 1e-4:
        # series of cosh/cos and sinh(x)/x, sin(x)/x to well below double precision at this size
        sgn = 1.0 if delta >= 0 else -1.0
        even = 1.0 + sgn * x * x / 2.0
        odd = h_s * (1.0 + sgn * x * x / 6.0)
    elif delta > 0:
        even, odd = math.cosh(x), math.sinh(x) / root
    else:
        even, odd = math.cos(x), math.sin(x) / root
    scale = math.exp(a * h_s)
    return (scale * (even + odd * (-kp - a)), scale * (odd * -1.0), scale * (odd * ki), scale * (even + odd * -a))


@njit(cache=True, nogil=True)
def input_at(t_k: float, y_k: np.ndarray, slope: np.ndarray, limit_s: float,
             t: float) -> tuple[np.ndarray, np.ndarray]:
    """Input offset and its rate at loop time ``t`` on the line through ``y_k`` at ``t_k`` with ``slope``, held
    ``limit_s`` after ``t_k``."""
    # against the knot t_k + limit_s as propagate() computes it: t - t_k < limit_s can round the other way at the
    # knot itself, and the held piece would go on sloping for a whole period
    y, rate = np.empty(3), np.empty(3)
    if t < t_k + limit_s:
        h = t - t_k
        for j in range(3):
            y[j], rate[j] = y_k[j] + slope[j] * h, slope[j]
        return y, rate
    for j in range(3):
        y[j], rate[j] = y_k[j] + slope[j] * limit_s, 0.0
    return y, rate


@njit(cache=True, nogil=True)
def propagate(c: np.ndarray, i: np.ndarray, t0: float, dt_s: float, has_line: bool, t_k: float, y_k: np.ndarray,
              slope: np.ndarray, limit_s: float, kp: float, ki: float) -> np.ndarray:
    """``[c, i]``: the correction ``c`` and integral ``i`` advanced exactly from loop time ``t0`` over ``dt_s``: with
    ``e = y - c`` and an input linear on each piece (split where it stops sloping), ``(e, i - y')`` obeys
    ``z' = M z``. One array out, since each array returned costs more than the arithmetic."""
    out = np.empty(6)
    if not has_line:
        for j in range(3):
            out[j] = c[j] + i[j] * dt_s  # no measurement yet: nothing to correct against
            out[3 + j] = i[j]
        return out
    t1 = t0 + dt_s
    knot = t_k + limit_s
    starts = np.array([t0, knot])
    ends = np.array([knot, t1])
    first = 0 if t0 < knot < t1 else 1
    if first == 1:
        starts[1] = t0
    c_out, i_out = c.copy(), i.copy()
    for p in range(first, 2):
        a, b = starts[p], ends[p]
        y_a, rate = input_at(t_k, y_k, slope, limit_s, a)
        m00, m01, m10, m11 = transition(kp, ki, b - a)
        for j in range(3):
            z0, z1 = y_a[j] - c_out[j], i_out[j] - rate[j]
            c_out[j] = y_a[j] + rate[j] * (b - a) - (m00 * z0 + m01 * z1)
            i_out[j] = (m10 * z0 + m11 * z1) + rate[j]
    for j in range(3):
        out[j], out[3 + j] = c_out[j], i_out[j]
    return out


@njit(cache=True, nogil=True)
def correction_rate(c: np.ndarray, i: np.ndarray, kp: float, has_line: bool, t_k: float, y_k: np.ndarray,
                    slope: np.ndarray, limit_s: float, t: float) -> np.ndarray:
    """``c' = i + kp (y - c)`` at loop time ``t`` (``i`` before any measurement)."""
    if not has_line:
        return i.copy()
    y, _ = input_at(t_k, y_k, slope, limit_s, t)
    out = np.empty(3)
    for j in range(3):
        out[j] = i[j] + kp * (y[j] - c[j])
    return out


@njit(cache=True, nogil=True)
def _skew_terms(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``[v x]`` and ``[v x]^2``."""
    k = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    return k, matmul(k, k)


@njit(cache=True, nogil=True)
def _eye_plus(first: float, k: np.ndarray, second: float, kk: np.ndarray, divisor: float) -> np.ndarray:
    """``I + first k + second kk / divisor``, term by term in that order."""
    out = np.empty((3, 3))
    for r in range(3):
        for s in range(3):
            out[r, s] = (1.0 if r == s else 0.0) + first * k[r, s] + second * kk[r, s] / divisor
    return out


@njit(cache=True, nogil=True)
def rotation_matrix(rotvec: np.ndarray) -> np.ndarray:
    """Rodrigues: the rotation matrix of a rotation vector (rad)."""
    angle = math.sqrt(rotvec[0] * rotvec[0] + rotvec[1] * rotvec[1] + rotvec[2] * rotvec[2])
    k, kk = _skew_terms(rotvec)
    if angle < 1e-8:
        first, second = 1.0, 0.5
    else:
        first, second = math.sin(angle) / angle, (1 - math.cos(angle)) / angle**2
    return _eye_plus(first, k, second, kk, 1.0)


@njit(cache=True, nogil=True)
def left_jacobian(phi: np.ndarray) -> np.ndarray:
    """SO(3) left Jacobian: the angular velocity of ``R(phi(t))`` is ``J(phi) phi'``."""
    angle = math.sqrt(phi[0] * phi[0] + phi[1] * phi[1] + phi[2] * phi[2])
    k, kk = _skew_terms(phi)
    if angle < 1e-6:
        return _eye_plus(0.5, k, 1.0, kk, 6.0)
    return _eye_plus((1 - math.cos(angle)) / angle**2, k, (angle - math.sin(angle)) / angle**3, kk, 1.0)


@njit(cache=True, nogil=True)
def quaternion_of_matrix(m: np.ndarray) -> tuple[np.ndarray, bool]:
    """Scalar-last unit quaternion of a rotation matrix by Markley's method in the operations and order of SciPy's
    implementation, and whether ``m`` is one SciPy takes as it is (Gram matrix within 0.5e-12 of the identity,
    determinant > 0.5); when not, the quaternion is zeros and the caller asks SciPy."""
    m00, m01, m02 = m[0, 0], m[0, 1], m[0, 2]
    m10, m11, m12 = m[1, 0], m[1, 1], m[1, 2]
    m20, m21, m22 = m[2, 0], m[2, 1], m[2, 2]
    gram = np.array([m00 * m00 + m01 * m01 + m02 * m02 - 1.0, m10 * m10 + m11 * m11 + m12 * m12 - 1.0,
                     m20 * m20 + m21 * m21 + m22 * m22 - 1.0, m00 * m10 + m01 * m11 + m02 * m12,
                     m00 * m20 + m01 * m21 + m02 * m22, m10 * m20 + m11 * m21 + m12 * m22])
    det = m00 * (m11 * m22 - m12 * m21) - m01 * (m10 * m22 - m12 * m20) + m02 * (m10 * m21 - m11 * m20)
    q = np.zeros(4)
    # not (all |g| < tol): a NaN fails the test, as it does in the interpreter's max()
    for g in gram:
        if not abs(g) < 0.5e-12:
            return q, False
    if not det > 0.5:
        return q, False
    trace = m00 + m11 + m22
    decision = np.array([m00, m11, m22, trace])
    choice = 0
    for i in range(1, 4):
        if decision[i] > decision[choice]:
            choice = i
    if choice != 3:
        i = choice
        j, k = (i + 1) % 3, (i + 2) % 3
        q[i] = 1 - trace + 2 * m[i, i]
        q[j] = m[j, i] + m[i, j]
        q[k] = m[k, i] + m[i, k]
        q[3] = m[k, j] - m[j, k]
    else:
        q[0] = m21 - m12
        q[1] = m02 - m20
        q[2] = m10 - m01
        q[3] = 1 + trace
    norm = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    for j in range(4):
        q[j] = q[j] / norm
    return q, True


@njit(cache=True, nogil=True)
def _quaternion_of_rotvec(v: np.ndarray) -> np.ndarray:
    """Scalar-last unit quaternion of a rotation vector (SciPy's ``from_rotvec``: a series below 1e-3 rad)."""
    angle = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    if angle <= 1e-3:
        angle2 = angle * angle
        scale = 0.5 - angle2 / 48 + angle2 * angle2 / 3840
    else:
        scale = math.sin(angle / 2) / angle
    return np.array([scale * v[0], scale * v[1], scale * v[2], math.cos(angle / 2)])


@njit(cache=True, nogil=True)
def compose_rotvec(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Rotation vector of ``R(a) R(b)`` (rad, angle <= pi), through the quaternions as SciPy's ``Rotation`` does."""
    p, q = _quaternion_of_rotvec(a), _quaternion_of_rotvec(b)
    x = p[3] * q[0] + p[0] * q[3] + p[1] * q[2] - p[2] * q[1]
    y = p[3] * q[1] - p[0] * q[2] + p[1] * q[3] + p[2] * q[0]
    z = p[3] * q[2] + p[0] * q[1] - p[1] * q[0] + p[2] * q[3]
    w = p[3] * q[3] - p[0] * q[0] - p[1] * q[1] - p[2] * q[2]
    if w < 0:
        x, y, z, w = -x, -y, -z, -w
    angle = 2 * math.atan2(math.sqrt(x * x + y * y + z * z), w)
    if angle <= 1e-3:
        angle2 = angle * angle
        scale = 2 + angle2 / 12 + 7 * angle2 * angle2 / 2880
    else:
        scale = angle / math.sin(angle / 2)
    return np.array([scale * x, scale * y, scale * z])


@njit(cache=True, nogil=True)
def los_inertial(geometry: np.ndarray, obt_s: float) -> np.ndarray:
    """Unit line of sight spacecraft -> asteroid of the straight-line flyby ``geometry`` at ``obt_s``."""
    d, vt = geometry[1], geometry[2] * (obt_s - geometry[0])
    rx = d * geometry[3] + vt * geometry[6]
    ry = d * geometry[4] + vt * geometry[7]
    rz = d * geometry[5] + vt * geometry[8]
    norm = math.sqrt(rx * rx + ry * ry + rz * rz)
    return np.array([-rx / norm, -ry / norm, -rz / norm])


@njit(cache=True, nogil=True)
def plane_normal(geometry: np.ndarray) -> np.ndarray:
    """Unit normal ``e_ca x e_v`` of the flyby plane."""
    return cross(geometry[3:6], geometry[6:9])


@njit(cache=True, nogil=True)
def predicted_matrix(geometry: np.ndarray, los: np.ndarray, body_triad: np.ndarray) -> np.ndarray:
    """``[los, n, los x n] triad^T``: the attitude putting the triad's columns on ``los`` and the plane normal."""
    n = plane_normal(geometry)
    side = cross(los, n)
    out = np.empty((3, 3))
    for r in range(3):
        for s in range(3):
            out[r, s] = los[r] * body_triad[s, 0] + n[r] * body_triad[s, 1] + side[r] * body_triad[s, 2]
    return out


@njit(cache=True, nogil=True)
def reference(c: np.ndarray, i: np.ndarray, kp: float, ki: float, t: float, has_line: bool, t_k: float,
              y_k: np.ndarray, slope: np.ndarray, limit_s: float, geometry: np.ndarray, obt_s: float,
              body_triad: np.ndarray) -> tuple[np.ndarray, bool]:
    """``R_des = R(c) R_pred`` at ``obt_s`` with the body rate and acceleration from ``theta'``, ``theta''`` about
    the plane normal plus the correction's motion: ``[q_des (4), omega_des_body (3), alpha_des_body (3), commanded
    LOS (3), R_des (9, by rows)]`` in one array (each array returned costs more than the arithmetic), and whether
    ``q_des`` is valid (not when ``R_des`` is one SciPy would first orthogonalise)."""
    r_c = rotation_matrix(c)
    los = los_inertial(geometry, obt_s)
    r_des = matmul(r_c, predicted_matrix(geometry, los, body_triad))
    n_c = matvec(r_c, plane_normal(geometry), False)
    tau = obt_s - geometry[0]
    d, v = geometry[1], geometry[2]
    rate = v * d / (d * d + (v * tau) ** 2)
    accel = -2.0 * v**3 * d * tau / (d * d + (v * tau) ** 2) ** 2
    c_dot = correction_rate(c, i, kp, has_line, t_k, y_k, slope, limit_s, t)
    c_ddot = np.zeros(3)
    if has_line:
        y, y_dot = input_at(t_k, y_k, slope, limit_s, t)
        for j in range(3):
            c_ddot[j] = ki * (y[j] - c[j]) + kp * (y_dot[j] - c_dot[j])
    jac = left_jacobian(c)
    omega_c = matvec(jac, c_dot, False)  # angular velocity of R(c), inertial
    # d/dt omega_in, neglecting J' c' (second order in the small correction)
    alpha_c, turn = matvec(jac, c_ddot, False), cross(omega_c, n_c)
    omega_in, alpha_in = np.empty(3), np.empty(3)
    for j in range(3):
        omega_in[j] = omega_c[j] + rate * n_c[j]
        alpha_in[j] = alpha_c[j] + rate * turn[j] + accel * n_c[j]
    q, valid = quaternion_of_matrix(r_des)
    body_rate, body_accel, los_c = matvec(r_des, omega_in, True), matvec(r_des, alpha_in, True), matvec(r_c, los, False)
    out = np.empty(22)
    for j in range(4):
        out[j] = q[j]
    for j in range(3):
        out[4 + j], out[7 + j], out[10 + j] = body_rate[j], body_accel[j], los_c[j]
        for k in range(3):
            out[13 + 3 * j + k] = r_des[j, k]
    return out, valid
