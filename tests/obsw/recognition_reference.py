"""A plain numpy MAP estimate of the C/A time, distance and in-plane LOS offset (the flight code's before it was
compiled, with the offset added), the reference the compiled ``obsw.recognition_kernels.solve`` is checked against:
Gauss-Newton in sigmas of the prior, step halving, a wide then a tight residual gate, the covariance from the final
inliers' Fisher information plus the prior's."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from obsw.config import RecognitionConfig


def _theta(times: NDArray, p: NDArray, v: float) -> NDArray:
    return np.arctan2(p[1], -v * (times - p[0])) + p[2]


def _jacobian(times: NDArray, p: NDArray, v: float, scale: NDArray) -> NDArray:
    tau = times - p[0]
    r2 = p[1] * p[1] + (v * tau) ** 2
    return np.column_stack([-v * p[1] / r2 * scale[0], -v * tau / r2 * scale[1], np.full(times.size, scale[2])])


def reference_solve(times: NDArray, theta: NDArray, origin: tuple[float, float, float],
                    sigma: tuple[float, float, float], start: tuple[float, float, float], v: float,
                    cfg: RecognitionConfig) -> tuple[NDArray, NDArray]:
    """((C/A time s, C/A distance m, offset rad), covariance in s, m, rad) from the measurements, prior and start."""
    o = np.asarray(origin, dtype=float)
    free = np.asarray(sigma, dtype=float) > 0
    scale = np.where(free, sigma, 1.0)
    noise = cfg.angle_noise_rad

    def predict(x: NDArray, t: NDArray) -> NDArray:
        return _theta(t, o + x * scale, v)

    def gauss_newton(x: NDArray, t: NDArray, th: NDArray) -> NDArray:
        def cost(p: NDArray) -> float:
            r = (th - predict(p, t)) / noise
            return float(r @ r + p[free] @ p[free])

        current = cost(x)
        for _ in range(cfg.max_iterations):
            r = (th - predict(x, t)) / noise
            jac = _jacobian(t, o + x * scale, v, scale)[:, free] / noise
            step = np.zeros(3)
            step[free] = np.linalg.solve(jac.T @ jac + np.eye(int(free.sum())), jac.T @ r - x[free])
            length = 1.0
            while True:
                trial = x + length * step
                if o[1] + trial[1] * scale[1] > 0 and (new := cost(trial)) <= current:
                    break
                length *= 0.5
                if length < 1e-6:
                    return x
            x, improvement, current = trial, current - new, new
            if improvement <= 1e-12 * max(current, 1.0) or float(np.max(np.abs(length * step))) < 1e-10:
                break
        return x

    x = (np.asarray(start, dtype=float) - o) / scale
    x[~free] = 0.0
    tight = cfg.outlier_gate_sigma * noise
    for gate in (cfg.residual_cap_rad, tight):
        inliers = np.zeros(times.size, dtype=bool)
        for _ in range(5):
            new = np.abs(theta - predict(x, times)) <= gate
            if not new.any() or np.array_equal(new, inliers):
                break
            inliers = new
            x = gauss_newton(x, times[inliers], theta[inliers])
    inliers = np.abs(theta - predict(x, times)) <= tight
    p = o + x * scale
    jac = _jacobian(times[inliers], p, v, scale) / noise
    info = jac[:, free].T @ jac[:, free] + np.eye(int(free.sum()))
    cov = np.zeros((3, 3))
    cov[np.ix_(free, free)] = np.linalg.inv(info)
    return p, np.diag(scale) @ cov @ np.diag(scale)
