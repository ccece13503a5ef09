"""Compiled steps of the attitude control (Numba): the PD law with its feedforward and one pass of the torque split
over the reaction wheels, one call each per control period.

The equations are ``obsw.control``'s (its module docstring and ``pd_torque_nm``, ``wheel_torques_nm``). They were
some forty numpy calls on 3-vectors and 3x3 matrices per period, each mostly interpreter overhead; here they are
plain loops in double precision without fast-math, compiled once and cached next to this file. Each also reports
whether its inputs were usable (finite, non-zero quaternions), so that the caller can name the bad one.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from obsw.vector3_kernels import cross, matvec


@njit(cache=True, nogil=True)
def error_quaternion(q: np.ndarray, q_des: np.ndarray) -> np.ndarray:
    """``conj(q_des) (x) q`` of unit quaternions, scalar-last, with a non-negative scalar part (the shortest way
    round)."""
    dx, dy, dz, dw = -q_des[0], -q_des[1], -q_des[2], q_des[3]
    bx, by, bz, bw = q[0], q[1], q[2], q[3]
    e = np.array([
        dw * bx + dx * bw + dy * bz - dz * by,
        dw * by - dx * bz + dy * bw + dz * bx,
        dw * bz + dx * by - dy * bx + dz * bw,
        dw * bw - dx * bx - dy * by - dz * bz,
    ])
    return -e if e[3] < 0 else e


@njit(cache=True, nogil=True)
def rotvec(e: np.ndarray) -> np.ndarray:
    """Rotation vector of a unit quaternion with non-negative scalar part, rad."""
    v = e[:3].copy()
    s = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    if s < 1e-12:
        return 2.0 * v  # first order, exact to 1e-36
    return v * (2.0 * math.atan2(s, e[3]) / s)


@njit(cache=True, nogil=True)
def _to_body(e: np.ndarray) -> np.ndarray:
    """Transpose of the rotation matrix of the unit quaternion ``e`` (scalar-last): desired frame -> body."""
    x, y, z, w = e[0], e[1], e[2], e[3]
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y + z * w), 2 * (x * z - y * w)],
        [2 * (x * y - z * w), 1 - 2 * (x * x + z * z), 2 * (y * z + x * w)],
        [2 * (x * z + y * w), 2 * (y * z - x * w), 1 - 2 * (x * x + y * y)],
    ])


@njit(cache=True, nogil=True)
def all_finite(a: np.ndarray) -> bool:
    """Whether every element of ``a`` is finite."""
    for x in a.flat:
        if not math.isfinite(x):
            return False
    return True


@njit(cache=True, nogil=True)
def _unit(q: np.ndarray) -> tuple[np.ndarray, bool]:
    """``q / |q|`` and whether ``q`` is finite and of norm >= 1e-9."""
    if not all_finite(q):
        return q, False
    norm = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    if norm < 1e-9:
        return q, False
    return q / norm, True


@njit(cache=True, nogil=True)
def pd_torque(q: np.ndarray, omega: np.ndarray, q_des: np.ndarray, omega_des: np.ndarray, alpha_des: np.ndarray,
              inertia: np.ndarray, kp: float, kd: float, feedforward: bool, wheel_momentum: np.ndarray,
              with_wheels: bool) -> tuple[np.ndarray, bool]:
    """Body torque of the PD law (``-kp e - kd (omega - C omega_des)``) plus, with ``feedforward``, ``I (C alpha_des -
    omega x C omega_des) + omega x (I omega + h_wheels)`` (``h_wheels`` only ``with_wheels``); and whether every
    input was usable (finite vectors, non-zero quaternions): when not, the torque is zeros."""
    q_unit, q_ok = _unit(q)
    q_des_unit, q_des_ok = _unit(q_des)
    usable = q_ok and q_des_ok and all_finite(omega) and all_finite(omega_des) and all_finite(alpha_des)
    if feedforward and with_wheels:
        usable = usable and all_finite(wheel_momentum)
    if not usable:
        return np.zeros(3), False
    e_q = error_quaternion(q_unit, q_des_unit)  # body -> desired
    error = rotvec(e_q)
    to_body = _to_body(e_q)
    omega_des_b = matvec(to_body, omega_des, False)
    rate_error = omega - omega_des_b
    torque = -kp * error - kd * rate_error
    if feedforward:
        h_total = matvec(inertia, omega, False)
        if with_wheels:
            h_total = h_total + wheel_momentum
        # d/dt of (C omega_des) in the body frame is C alpha_des - omega x C omega_des
        torque = torque + matvec(inertia, matvec(to_body, alpha_des, False) - cross(omega, omega_des_b), False) \
            + cross(omega, h_total)
    return torque, True


@njit(cache=True, nogil=True)
def split_pass(share: np.ndarray, usable: np.ndarray, momentum: np.ndarray,
               max_momentum_nms: float) -> tuple[np.ndarray, np.ndarray, int, float]:
    """One pass of the wheel allocation: the torques ``tau`` with ``share`` (the split of the body torque over the
    ``usable`` wheels, in wheel order) on those wheels and zeros elsewhere, the wheels it would push beyond
    ``max_momentum_nms`` (already at or past it, and ``tau`` of the momentum's sign), their number and the largest
    ``|tau|``."""
    n = usable.shape[0]
    tau = np.zeros(n)
    row = 0
    for k in range(n):
        if usable[k]:
            tau[k] = share[row]
            row += 1
    pushing = np.zeros(n, dtype=np.bool_)
    count = 0
    for k in range(n):
        if usable[k] and abs(momentum[k]) >= max_momentum_nms and tau[k] * momentum[k] > 0:
            pushing[k] = True
            count += 1
    peak = 0.0
    for k in range(n):
        peak = max(peak, abs(tau[k]))
    return tau, pushing, count, peak


@njit(cache=True, nogil=True)
def boresight_error_rad(q: np.ndarray, boresight_body: np.ndarray, los_inertial: np.ndarray) -> float:
    """Angle between ``boresight_body`` turned to inertial by the attitude ``q`` (body->inertial, scalar-last, any
    norm) and the unit ``los_inertial``, rad: ``v + 2 w (u x v) + 2 u x (u x v)`` of the unit quaternion."""
    norm = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    u = q[:3] / norm
    t = 2.0 * cross(u, boresight_body)
    turned = boresight_body + (q[3] / norm) * t + cross(u, t)
    dot = turned[0] * los_inertial[0] + turned[1] * los_inertial[1] + turned[2] * los_inertial[2]
    return math.acos(min(max(dot, -1.0), 1.0))
