"""Attitude determination: a multiplicative extended Kalman filter (MEKF) on the star tracker and the gyro.

The state is the attitude quaternion ``q`` (body -> inertial, scalar-last) and the gyro bias ``b`` (rad/s, body);
the filter holds the covariance ``P`` of their small errors, ``x = [dtheta, db]`` (its steps compiled in
``obsw.mekf_kernels``), with
the true attitude ``q (x) exp(dtheta)`` (``dtheta`` in body axes) and the true bias ``b + db``. Between star tracker
solutions the attitude is propagated with the gyro rate (the mean of the period's two readings) less the estimated
bias; the error obeys

    dtheta' = -[w x] dtheta - db - n_v,        db' = n_u,

with ``n_v`` the gyro's angle random walk and ``n_u`` the rate random walk the filter allows for its bias. A star
tracker solution measures ``dtheta`` directly (its noise is a small rotation about the tracker's body axes), so the
error is folded into ``q`` and ``b`` after each update and ``x`` goes back to zero.

With ``w = 0`` the propagation is exact: over ``t`` without a solution the attitude variance of an axis grows as
``P_tt - 2 P_tb t + P_bb t^2 + s_v^2 t + s_u^2 t^3 / 3`` (the tests check this closed form), and a constant bias is
observed from the drift of the solutions, its variance going as that of the slope of a line fitted to them.

A reading equal to the last one is a tracker slower than the control holding its solution: it is not taken twice.
An outage is declared when the tracker has given no reading for ``cfg.outage_after_s``; the attitude is then
propagated alone and its uncertainty grows as above. Pure: time and readings come as arguments.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from obsw import mekf_kernels
from obsw.config import AttitudeConfig

ARCSEC_RAD = math.pi / (180.0 * 3600.0)
DEG_SQRT_H_RAD_SQRT_S = math.pi / 180.0 / 60.0  # 1 deg/sqrt(h) = 1/60 deg/sqrt(s)
_IDENTITY_Q = np.array([0.0, 0.0, 0.0, 1.0])


@dataclass(frozen=True, slots=True)
class AttitudeEstimate:
    """What the estimator gives the control each period."""

    q: NDArray[np.float64]  # body -> inertial, scalar-last
    omega_rad_s: NDArray[np.float64]  # gyro rate less the estimated bias, body
    bias_rad_s: NDArray[np.float64]  # estimated gyro bias, body
    sigma_rad: float  # one-sigma attitude uncertainty of the worst axis
    outage: bool  # a star tracker outage is declared


class AttitudeEstimator:
    """The MEKF; one ``step`` per control period."""

    def __init__(self, cfg: AttitudeConfig) -> None:
        self.cfg = cfg
        self.sigma_v = cfg.gyro_arw_deg_sqrt_h * DEG_SQRT_H_RAD_SQRT_S  # angle random walk, rad/sqrt(s)
        self.sigma_u = math.radians(cfg.gyro_bias_walk_deg_s_sqrt_s)  # bias random walk, rad/s/sqrt(s)
        st = np.asarray(cfg.star_tracker_noise_arcsec, dtype=float) * ARCSEC_RAD
        # a noiseless tracker would make S singular: keep a floor far below any real tracker's noise
        self.R = np.diag(np.maximum(st, 1e-9) ** 2)
        self.P = np.diag([math.radians(cfg.initial_attitude_sigma_deg) ** 2] * 3
                         + [math.radians(cfg.initial_bias_sigma_deg_s) ** 2] * 3)
        self.q: NDArray[np.float64] | None = None
        self.bias = np.zeros(3)
        self._last_solution: tuple[float, ...] | None = None
        self.since_solution_s = 0.0
        self.outage = False
        self.updates = 0
        self._last_gyro: NDArray[np.float64] | None = None

    @property
    def bias_sigma_rad_s(self) -> float:
        """One-sigma gyro bias uncertainty of the worst axis, rad/s."""
        p = self.P
        return math.sqrt(max(float(p[3, 3]), float(p[4, 4]), float(p[5, 5]), 0.0))

    @property
    def bias_known(self) -> bool:
        """Whether the bias estimate is known well enough to be monitored (``cfg.bias_known_sigma_deg_s``)."""
        return self.q is not None and self.bias_sigma_rad_s < math.radians(self.cfg.bias_known_sigma_deg_s)

    @property
    def attitude_sigma_rad(self) -> float:
        """One-sigma attitude uncertainty of the worst axis, rad."""
        p = self.P
        return math.sqrt(max(float(p[0, 0]), float(p[1, 1]), float(p[2, 2]), 0.0))

    def propagate(self, gyro_rad_s: NDArray[np.float64], dt_s: float) -> None:
        """Advance the attitude by the gyro rate less the bias over ``dt_s``, and its error covariance."""
        w = np.asarray(gyro_rad_s, dtype=float) - self.bias
        if self.q is not None:
            self.q, self.P = mekf_kernels.propagate(self.q, self.P, w, float(dt_s), self.sigma_v, self.sigma_u)
        else:
            self.P = mekf_kernels.predict(self.P, w, float(dt_s), self.sigma_v, self.sigma_u)

    def update(self, star_tracker_q: NDArray[np.float64]) -> NDArray[np.float64]:
        """Take one star tracker solution; return its innovation (rotation vector, body, rad)."""
        q_meas = np.asarray(star_tracker_q, dtype=float)
        q_meas = q_meas / math.sqrt(q_meas @ q_meas)
        if self.q is None:  # the first solution is the attitude
            self.q = q_meas
            return np.zeros(3)
        # the quaternion steps compiled with the covariance's (Hamilton product, exp of the rotation vector)
        self.q, self.bias, self.P, z = mekf_kernels.correct(self.q, self.bias, self.P, self.R, q_meas)
        self.updates += 1
        return z

    def step(self, gyro_rad_s: NDArray[np.float64], star_tracker_q: NDArray[np.float64] | None,
             dt_s: float) -> AttitudeEstimate:
        """One control period: propagate over ``dt_s``, take the star tracker's solution if it is a new one, and
        declare an outage after ``cfg.outage_after_s`` without a reading (the caller reports the changes of
        ``outage``)."""
        gyro = np.asarray(gyro_rad_s, dtype=float)
        if self.q is not None:
            # the mean of the rates at both ends of the period: the body accelerates by up to 0.02 rad/s^2 near C/A,
            # which the rate of one end would turn into an attitude error of 1e-4 rad per period, a false bias
            self.propagate(gyro if self._last_gyro is None else 0.5 * (gyro + self._last_gyro), dt_s)
        self._last_gyro = gyro
        if star_tracker_q is not None:
            reading = np.asarray(star_tracker_q, dtype=float)
            solution = tuple(reading.tolist())  # Python floats at once (a generator of float() cost 2 us a period)
            if solution != self._last_solution:  # a tracker slower than the control holds its reading
                self.update(reading)
                self._last_solution = solution
            self.since_solution_s = 0.0
            self.outage = False
        else:
            self.since_solution_s += dt_s
            self._last_solution = None  # a tracker back from an outage gives a fresh solution
            if self.q is not None and self.since_solution_s >= self.cfg.outage_after_s:
                self.outage = True
        q = _IDENTITY_Q.copy() if self.q is None else self.q.copy()
        return AttitudeEstimate(q, gyro - self.bias, self.bias.copy(), self.attitude_sigma_rad, self.outage)
