"""The continuous trajectory estimate compiled (Numba): the MAP (C/A time, C/A distance, LOS offset) of the measured
LOS angles.

The estimate is ``obsw.recognition``'s (its module docstring): Gauss-Newton on ``|(theta - theta(t_ca, d) - e) /
sigma|^2 + |x|^2`` in sigmas of the prior (``x = (p - origin) / prior sigma``; ``e`` the constant in-plane offset of
the measured angle, a misaligned camera's), from the best grid candidate, with step halving; first over the residuals
within the grid's wide cap, then within the tight noise gate, each gate re-solved until its set of inliers settles (at
most ``ROUNDS`` times); the covariance is the inverse of the Fisher information of the final inliers plus the prior's.
A parameter whose prior sigma is 0 is held at its origin.

It is re-solved at every new measurement over all of them (hundreds near C/A): as numpy on arrays of a few hundred
it cost a tenth of a period's processor time. Double precision without fast-math; 3x3 systems solved in closed form.
Element-wise array expressions are written as loops (Numba compiles each generic array operation anew in every
cached kernel: a third of the compile time), the same operations in the same order.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

ROUNDS = 5  # re-solutions per gate while the inliers change
MIN_STEP_FRACTION = 1e-6  # step halving gives up below this fraction of the Gauss-Newton step
N = 3  # parameters: C/A time s, C/A distance m, in-plane LOS offset rad


@njit(cache=True, nogil=True)
def _point(origin: np.ndarray, x: np.ndarray, s: np.ndarray) -> np.ndarray:
    """``origin + x * s``: the parameters of a scaled point."""
    out = np.empty(N)
    for k in range(N):
        out[k] = origin[k] + x[k] * s[k]
    return out


@njit(cache=True, nogil=True)
def _residuals(times: np.ndarray, theta: np.ndarray, p: np.ndarray, v: float) -> np.ndarray:
    """``theta - atan2(d, -v (t - t_ca)) - e`` of every measurement, rad, for ``p = (t_ca, d, e)``."""
    out = np.empty(times.size)
    for i in range(times.size):
        out[i] = theta[i] - math.atan2(p[1], -v * (times[i] - p[0])) - p[2]
    return out


@njit(cache=True, nogil=True)
def _normal_equations(times: np.ndarray, p: np.ndarray, v: float, s: np.ndarray, r: np.ndarray,
                      use: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``J^T J`` (3x3) and ``J^T r`` over the measurements ``use``, ``J`` the derivative of the modelled angle by the
    scaled parameters (before dividing by sigma): d/dt_ca = -v d / r2, d/dd = -v tau / r2, d/de = 1."""
    a = np.zeros((N, N))
    g = np.zeros(N)
    j = np.empty(N)
    for i in range(times.size):
        if not use[i]:
            continue
        tau = times[i] - p[0]
        r2 = p[1] * p[1] + (v * tau) * (v * tau)
        j[0] = -v * p[1] / r2 * s[0]
        j[1] = -v * tau / r2 * s[1]
        j[2] = s[2]
        for k in range(N):
            g[k] += j[k] * r[i]
            for m in range(N):
                a[k, m] += j[k] * j[m]
    return a, g


@njit(cache=True, nogil=True)
def _inverse(a: np.ndarray, free: np.ndarray) -> np.ndarray:
    """Inverse of the symmetric positive definite ``a`` restricted to the ``free`` parameters (held ones: 0), by
    cofactors."""
    m = a.copy()
    for k in range(N):
        if not free[k]:
            m[k, :] = 0.0
            m[:, k] = 0.0
            m[k, k] = 1.0
    c = np.empty((N, N))
    c[0, 0] = m[1, 1] * m[2, 2] - m[1, 2] * m[2, 1]
    c[0, 1] = m[0, 2] * m[2, 1] - m[0, 1] * m[2, 2]
    c[0, 2] = m[0, 1] * m[1, 2] - m[0, 2] * m[1, 1]
    c[1, 0] = m[1, 2] * m[2, 0] - m[1, 0] * m[2, 2]
    c[1, 1] = m[0, 0] * m[2, 2] - m[0, 2] * m[2, 0]
    c[1, 2] = m[0, 2] * m[1, 0] - m[0, 0] * m[1, 2]
    c[2, 0] = m[1, 0] * m[2, 1] - m[1, 1] * m[2, 0]
    c[2, 1] = m[0, 1] * m[2, 0] - m[0, 0] * m[2, 1]
    c[2, 2] = m[0, 0] * m[1, 1] - m[0, 1] * m[1, 0]
    det = m[0, 0] * c[0, 0] + m[0, 1] * c[1, 0] + m[0, 2] * c[2, 0]
    for k in range(N):
        for n in range(N):
            c[k, n] = c[k, n] / det if free[k] and free[n] else 0.0
    return c


@njit(cache=True, nogil=True)
def _cost(r: np.ndarray, use: np.ndarray, sigma: float, x: np.ndarray, free: np.ndarray) -> float:
    acc = 0.0
    for i in range(r.size):
        if use[i]:
            z = r[i] / sigma
            acc += z * z
    for k in range(N):
        if free[k]:
            acc += x[k] * x[k]
    return acc


@njit(cache=True, nogil=True)
def _gauss_newton(times: np.ndarray, theta: np.ndarray, use: np.ndarray, origin: np.ndarray, s: np.ndarray,
                  free: np.ndarray, v: float, sigma: float, x: np.ndarray, r: np.ndarray,
                  max_iterations: int) -> tuple[np.ndarray, np.ndarray]:
    """The MAP point (scaled) over the measurements ``use`` from ``x``, whose residuals are ``r``, with step halving;
    and its residuals."""
    x = x.copy()
    current = _cost(r, use, sigma, x, free)
    w = sigma * sigma
    for _ in range(max_iterations):
        a, g = _normal_equations(times, _point(origin, x, s), v, s, r, use)
        for k in range(N):
            g[k] = g[k] / w - x[k]
            for m in range(N):
                a[k, m] /= w
            a[k, k] += 1.0
        inv = _inverse(a, free)
        step = inv @ g
        length = 1.0
        while True:
            trial = np.empty(N)
            for k in range(N):
                trial[k] = x[k] + length * step[k]
            # a candidate distance must stay positive: theta is undefined through d = 0
            if origin[1] + trial[1] * s[1] > 0:
                r_trial = _residuals(times, theta, _point(origin, trial, s), v)
                new = _cost(r_trial, use, sigma, trial, free)
                if new <= current:
                    break
            length *= 0.5
            if length < MIN_STEP_FRACTION:
                return x, r
        improvement = current - new
        x, r, current = trial, r_trial, new
        tiny = True  # every component of the step under 1e-10 (a NaN is not)
        for k in range(N):
            tiny = tiny and abs(length * step[k]) < 1e-10
        if improvement <= 1e-12 * max(current, 1.0) or tiny:
            break
    return x, r


@njit(cache=True, nogil=True)
def _inliers(r: np.ndarray, gate: float) -> np.ndarray:
    """The measurements whose residual ``r`` is within ``gate``."""
    out = np.empty(r.size, dtype=np.bool_)
    for i in range(r.size):
        out[i] = abs(r[i]) <= gate
    return out


@njit(cache=True, nogil=True)
def _any(flags: np.ndarray) -> bool:
    """Whether any flag is set (``flags.any()``, written out: the generic reduction compiles slowly)."""
    for i in range(flags.size):
        if flags[i]:
            return True
    return False


@njit(cache=True, nogil=True)
def _equal(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether two flag arrays of one size are equal (``np.array_equal``)."""
    for i in range(a.size):
        if a[i] != b[i]:
            return False
    return True


@njit(cache=True, nogil=True)
def solve(times: np.ndarray, theta: np.ndarray, origin: np.ndarray, sigma: np.ndarray, start: np.ndarray,
          speed_m_s: float, angle_noise_rad: float, cap_rad: float, tight_rad: float,
          max_iterations: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(estimate, covariance 3x3, final inliers) of the MAP estimate of (C/A time s, C/A distance m, in-plane offset
    rad) from the measurements (``times`` s, in-plane angles ``theta`` rad), the prior (``origin``, one-sigmas
    ``sigma``; 0: held) and the start (the best grid candidate)."""
    free = np.empty(N, dtype=np.bool_)
    s = np.empty(N)
    x = np.empty(N)
    for k in range(N):
        free[k] = sigma[k] > 0
        s[k] = sigma[k] if free[k] else 1.0
        x[k] = (start[k] - origin[k]) / s[k] if free[k] else 0.0
    # the residuals at x, carried along with it: each is computed once however many gates and rounds read it
    r = _residuals(times, theta, _point(origin, x, s), speed_m_s)
    for gate in (cap_rad, tight_rad):
        inliers = np.zeros(times.size, dtype=np.bool_)
        for _ in range(ROUNDS):
            new = _inliers(r, gate)
            if not _any(new) or _equal(new, inliers):
                break
            inliers = new
            x, r = _gauss_newton(times, theta, inliers, origin, s, free, speed_m_s, angle_noise_rad, x, r,
                                 max_iterations)
    # the information is that of the measurements the final estimate explains (none: the prior alone)
    p = _point(origin, x, s)
    inliers = _inliers(r, tight_rad)
    a, _ = _normal_equations(times, p, speed_m_s, s, np.zeros(times.size), inliers)
    w = angle_noise_rad * angle_noise_rad
    for k in range(N):
        for m in range(N):
            a[k, m] /= w
        a[k, k] += 1.0
    cov = _inverse(a, free)
    for k in range(N):
        for m in range(N):
            cov[k, m] *= s[k] * s[m]
    return p, cov, inliers


def warm_up() -> None:
    """Compile the kernel now (or load it from the cache)."""
    t = np.linspace(-10.0, 10.0, 5)
    theta = np.arctan2(55e3, -7e3 * t)
    solve(t, theta, np.array([0.0, 55e3, 0.0]), np.array([1.0, 1e3, 1e-4]), np.array([0.0, 55e3, 0.0]), 7e3, 1e-4,
          1e-2, 5e-4, 10)
