"""Compiled RK4 substeps of the gyrostat's attitude dynamics (Numba): the inner loop of ``universe.dynamics``.

The model is ``universe.dynamics``'s (its module docstring); this is its integrator, one call per held torque, so
that the ten or so substeps of a control period and their four right-hand sides run without the interpreter (they
were 170,000 Python calls in a 420 s flyby). Every operation is the one the pure-Python integrator did, in the same
order and in double precision (no fast-math, so no reassociation or fused multiply-adds): the states are the same
to the last bit.

Compiled on first use and cached next to this file (``cache=True``); ``warm_up`` lets a node pay it before its
first control period.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True, inline="always")
def _max(a: float, b: float) -> float:
    """Python's ``max(a, b)``: ``a`` unless ``b`` is larger (the same zero's sign and NaN as the interpreter)."""
    return b if b > a else a


@njit(cache=True, nogil=True, inline="always")
def _min(a: float, b: float) -> float:
    """Python's ``min(a, b)``: ``a`` unless ``b`` is smaller."""
    return b if b < a else a


@njit(cache=True, nogil=True, inline="always")
def _rates(wx: float, wy: float, wz: float, h: np.ndarray, u: np.ndarray, free_axes: np.ndarray, inv_jw: float,
           cv: float, cc: float, inv_eps: float, i_eff: np.ndarray, i_eff_inv: np.ndarray,
           taus: np.ndarray) -> tuple[float, float, float]:
    """dw/dt for body rate w and rotor momenta h; dh/dt into ``taus`` (zero for a stuck rotor)."""
    taus[:] = 0.0
    hx = hy = hz = tx = ty = tz = 0.0
    for k in range(free_axes.shape[0]):
        i = int(free_axes[k, 0])
        ax, ay, az = free_axes[k, 1], free_axes[k, 2], free_axes[k, 3]
        hi = h[i]
        speed = hi * inv_jw - (ax * wx + ay * wy + az * wz)
        t = u[i] - cv * speed - cc * math.tanh(speed * inv_eps)
        taus[i] = t
        hx += ax * hi
        hy += ay * hi
        hz += az * hi
        tx += ax * t
        ty += ay * t
        tz += az * t
    bx = i_eff[0] * wx + i_eff[1] * wy + i_eff[2] * wz + hx
    by = i_eff[3] * wx + i_eff[4] * wy + i_eff[5] * wz + hy
    bz = i_eff[6] * wx + i_eff[7] * wy + i_eff[8] * wz + hz
    # right-hand side -A tau - w x H
    rx = -tx - (wy * bz - wz * by)
    ry = -ty - (wz * bx - wx * bz)
    rz = -tz - (wx * by - wy * bx)
    return (i_eff_inv[0] * rx + i_eff_inv[1] * ry + i_eff_inv[2] * rz,
            i_eff_inv[3] * rx + i_eff_inv[4] * ry + i_eff_inv[5] * rz,
            i_eff_inv[6] * rx + i_eff_inv[7] * ry + i_eff_inv[8] * rz)


@njit(cache=True, nogil=True, inline="always")
def _q_rate(qx: float, qy: float, qz: float, qw: float, wx: float, wy: float,
            wz: float) -> tuple[float, float, float, float]:
    """dq/dt = 1/2 q (x) [w, 0] for a body -> inertial quaternion and body rate w."""
    return (0.5 * (qw * wx - qz * wy + qy * wz),
            0.5 * (qz * wx + qw * wy - qx * wz),
            0.5 * (-qy * wx + qx * wy + qw * wz),
            -0.5 * (qx * wx + qy * wy + qz * wz))


@njit(cache=True, nogil=True)
def integrate(x: np.ndarray, u_held: np.ndarray, free_axes: np.ndarray, gain: np.ndarray, i_eff: np.ndarray,
              i_eff_inv: np.ndarray, jw: float, h_max: float, cv: float, cc: float, inv_eps: float, n_sub: int,
              hs: float) -> np.ndarray:
    """Return x = [q (4), w (3), h (N)] after ``n_sub`` RK4 substeps of ``hs`` s with motor torques ``u_held`` (N,).

    ``free_axes`` (F, 4): index and spin axis of each free rotor; ``gain`` (N,): d(J Omega_i)/d(u_i); ``i_eff``,
    ``i_eff_inv`` (9,): the inertia with stuck rotors and its inverse, row-major; ``jw`` rotor axial inertia,
    ``h_max`` momentum limit, ``cv``, ``cc`` viscous and Coulomb friction, ``inv_eps`` 1 / Coulomb smoothing speed.
    """
    n = x.shape[0] - 7
    inv_jw = 1.0 / jw
    qx, qy, qz, qw, wx, wy, wz = x[0], x[1], x[2], x[3], x[4], x[5], x[6]
    h = x[7:].copy()
    u = np.empty(n)
    t1, t2, t3, t4 = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    hh = np.empty(n)
    half, sixth = 0.5 * hs, hs / 6.0
    for _ in range(n_sub):
        # cut the motor torque back so no rotor's relative momentum grows past the limit in this substep
        u[:] = u_held
        for k in range(free_axes.shape[0]):
            i = int(free_axes[k, 0])
            ui = u[i]
            if ui != 0.0:
                p = h[i] - jw * (free_axes[k, 1] * wx + free_axes[k, 2] * wy + free_axes[k, 3] * wz)
                if ui * p >= 0.0:
                    allowed = _max(h_max - abs(p), 0.0) / (gain[i] * hs)
                    u[i] = _min(_max(ui, -allowed), allowed)
        a1x, a1y, a1z = _rates(wx, wy, wz, h, u, free_axes, inv_jw, cv, cc, inv_eps, i_eff, i_eff_inv, t1)
        b10, b11, b12, b13 = _q_rate(qx, qy, qz, qw, wx, wy, wz)
        w2x, w2y, w2z = wx + half * a1x, wy + half * a1y, wz + half * a1z
        for i in range(n):
            hh[i] = h[i] + half * t1[i]
        a2x, a2y, a2z = _rates(w2x, w2y, w2z, hh, u, free_axes, inv_jw, cv, cc, inv_eps, i_eff, i_eff_inv, t2)
        b20, b21, b22, b23 = _q_rate(qx + half * b10, qy + half * b11, qz + half * b12, qw + half * b13,
                                     w2x, w2y, w2z)
        w3x, w3y, w3z = wx + half * a2x, wy + half * a2y, wz + half * a2z
        for i in range(n):
            hh[i] = h[i] + half * t2[i]
        a3x, a3y, a3z = _rates(w3x, w3y, w3z, hh, u, free_axes, inv_jw, cv, cc, inv_eps, i_eff, i_eff_inv, t3)
        b30, b31, b32, b33 = _q_rate(qx + half * b20, qy + half * b21, qz + half * b22, qw + half * b23,
                                     w3x, w3y, w3z)
        w4x, w4y, w4z = wx + hs * a3x, wy + hs * a3y, wz + hs * a3z
        for i in range(n):
            hh[i] = h[i] + hs * t3[i]
        a4x, a4y, a4z = _rates(w4x, w4y, w4z, hh, u, free_axes, inv_jw, cv, cc, inv_eps, i_eff, i_eff_inv, t4)
        b40, b41, b42, b43 = _q_rate(qx + hs * b30, qy + hs * b31, qz + hs * b32, qw + hs * b33, w4x, w4y, w4z)
        wx += sixth * (a1x + 2.0 * (a2x + a3x) + a4x)
        wy += sixth * (a1y + 2.0 * (a2y + a3y) + a4y)
        wz += sixth * (a1z + 2.0 * (a2z + a3z) + a4z)
        for i in range(n):
            h[i] = h[i] + sixth * (t1[i] + 2.0 * (t2[i] + t3[i]) + t4[i])
        qx += sixth * (b10 + 2.0 * (b20 + b30) + b40)
        qy += sixth * (b11 + 2.0 * (b21 + b31) + b41)
        qz += sixth * (b12 + 2.0 * (b22 + b32) + b42)
        qw += sixth * (b13 + 2.0 * (b23 + b33) + b43)
        norm = math.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
        qx, qy, qz, qw = qx / norm, qy / norm, qz / norm, qw / norm
    out = np.empty(x.shape[0])
    out[0], out[1], out[2], out[3], out[4], out[5], out[6] = qx, qy, qz, qw, wx, wy, wz
    out[7:] = h
    return out


@njit(cache=True, nogil=True)
def period(q: np.ndarray, w: np.ndarray, h: np.ndarray, u_before: np.ndarray, u_cmd: np.ndarray, switch_s: float,
           dt_s: float, motor_on: np.ndarray, max_torque: float, max_substep_s: float, friction_rate_s: float,
           free_axes: np.ndarray, gain: np.ndarray, i_eff: np.ndarray, i_eff_inv: np.ndarray, jw: float, h_max: float,
           cv: float, cc: float, inv_eps: float, axes: np.ndarray, free: np.ndarray, out: np.ndarray) -> None:
    """One control period into ``out`` = [q (4), w (3), rotor speeds (N)]: the motor torques ``u_before`` held for
    ``switch_s`` s, then ``u_cmd`` to ``dt_s`` (``u_cmd`` alone when ``switch_s`` is 0), each clipped to
    ``max_torque`` and gated by ``motor_on``, in RK4 substeps of at most ``max_substep_s`` and short against the
    friction's ``friction_rate_s``; ``h`` (N,) the rotors' momenta at the start, ``axes`` (3, N) their spin axes,
    ``free`` (N,) 0 for a stuck rotor. The operations and their order are ``SpacecraftDynamics.step``'s NumPy ones
    (the speeds' dot products summed over the axes in order, as NumPy sums ``axes.T @ w``): the same bits."""
    n = h.shape[0]
    x = np.empty(7 + n)
    x[0:4] = q
    x[4:7] = w
    x[7:] = h
    u_held = np.empty(n)
    for segment in range(2):
        if segment == 0:
            if not switch_s > 0.0:
                continue
            u, span = u_before, switch_s
        else:
            u, span = u_cmd, (dt_s - switch_s) if switch_s > 0.0 else dt_s
        for i in range(n):
            v = u[i] if u[i] > -max_torque else -max_torque  # np.maximum(u, -max): finite torques, checked
            v = v if v < max_torque else max_torque
            u_held[i] = v * motor_on[i]
        n_sub = 0
        if span != 0.0:
            n_sub = max(math.ceil(span / max_substep_s - 1e-9), math.ceil(span * friction_rate_s / 0.5))
        hs = span / n_sub if n_sub else 0.0
        x = integrate(x, u_held, free_axes, gain, i_eff, i_eff_inv, jw, h_max, cv, cc, inv_eps, n_sub, hs)
    out[0:7] = x[0:7]
    wx, wy, wz = x[4], x[5], x[6]
    for i in range(n):
        out[7 + i] = (x[7 + i] / jw - (axes[0, i] * wx + axes[1, i] * wy + axes[2, i] * wz)) * free[i]


def warm_up() -> None:
    """Compile (or load from the cache) the kernels now: one substep and one period of a three-wheel body."""
    free = np.array([[0.0, 1.0, 0.0, 0.0], [1.0, 0.0, 1.0, 0.0], [2.0, 0.0, 0.0, 1.0]])
    eye = np.eye(3).ravel()
    x = np.array([0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    integrate(x, np.zeros(3), free, np.ones(3), eye, eye, 1e-5, 0.1, 0.0, 0.0, 1.0, 1, 0.01)
    ones = np.ones(3)
    period(x[:4], x[4:7], x[7:], ones, ones, 0.004, 0.1, ones, 0.01, 0.01, 10.0, free, ones, eye, eye, 1e-5, 0.1, 0.0,
           0.0, 1.0, np.eye(3), ones, np.empty(10))
