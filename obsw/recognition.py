"""Trajectory recognition: which (C/A time, C/A distance) explains the measured line-of-sight angles.

Paper ("Tracking and Trajectory Recognition Module"): a precomputed set of candidate trajectories around the
nominal one, each a pair (t_CA, d_CA); the best is the one with the least mean square error between the measured
LOS angle (from the centroid, turned into the inertial frame with the attitude) and each candidate's prediction.

What the LOS direction alone observes: theta(t) = atan2(d, -v (t - t_ca)) fixes t_ca and d / v; the speed is
taken from ground, so d follows. The C/A time is in OBT: any clock offset is absorbed in it.

Beside the grid, a continuous estimate: the maximum a posteriori (t_ca, d) under the ground's Gaussian prior and
Gaussian angle noise, by Gauss-Newton from the best candidate, with the residuals beyond a gate ignored, and the
covariance of that estimate (the inverse of the Fisher information plus the prior's).

The continuous estimate also solves for a constant offset of the measured line of sight, under its own prior
(``RecognitionConfig.los_offset_sigma_rad``): a camera misaligned to the star tracker by a small rotation puts every
measured line of sight off the true one by a fixed vector in body axes. The camera slews about the body axis held on
the flyby plane's normal, so that vector stays fixed in the plane's frame: a constant offset of the in-plane angle,
solved with (t_ca, d), and a constant out-of-plane angle, the mean of the inliers' under the same prior. Left out,
the in-plane offset is absorbed into a biased C/A time, whose error grows as the line of sight turns faster near C/A
(a 0.04 deg misalignment put the prediction 4 mrad off 24 s before C/A); estimated, it costs the C/A time's
uncertainty a factor of two (ten to twenty milliseconds).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from obsw import recognition_kernels
from obsw.config import RecognitionConfig
from obsw.trajectory import NominalTrajectory


def measured_theta_rad(trajectory: NominalTrajectory, los_inertial: ArrayLike) -> float:
    """In-plane LOS angle from the relative velocity, rad: atan2(-los . e_ca, los . e_v) (out-of-plane part ignored)."""
    los = np.asarray(los_inertial, dtype=float)
    return float(np.arctan2(-(los @ trajectory.e_ca), los @ trajectory.e_v))


def out_of_plane_rad(trajectory: NominalTrajectory, los_inertial: ArrayLike) -> float:
    """Angle of the LOS out of the flyby plane, rad, positive along the plane normal."""
    los = np.asarray(los_inertial, dtype=float)
    return math.asin(max(-1.0, min(1.0, float(los @ trajectory.plane_normal))))


@dataclass(frozen=True, slots=True)
class ContinuousEstimate:
    """The continuous estimate: C/A time (OBT s) and distance (km), the constant in-plane offset of the measured LOS
    angle (rad), their covariance (3x3 in s, km, rad), and the constant out-of-plane offset (rad) with its one-sigma."""

    ca_time_obt_s: float
    ca_distance_km: float
    in_plane_offset_rad: float
    cov: NDArray[np.float64]
    out_of_plane_offset_rad: float
    out_of_plane_sigma_rad: float


def estimates_agree(a: ContinuousEstimate, b: ContinuousEstimate, apart_km: float, speed_km_s: float,
                    sigma: float) -> bool:
    """Whether two continuous estimates can be of two points at most ``apart_km`` apart moving together (Dimorphos
    and Didymos): C/A times within ``apart_km / speed_km_s`` (a displacement along the track), C/A distances within
    ``apart_km`` (across it), each plus ``sigma`` of their one-sigma uncertainties combined."""
    dt_allowed = apart_km / speed_km_s + sigma * math.sqrt(max(a.cov[0, 0], 0.0) + max(b.cov[0, 0], 0.0))
    dd_allowed = apart_km + sigma * math.sqrt(max(a.cov[1, 1], 0.0) + max(b.cov[1, 1], 0.0))
    return bool(abs(a.ca_time_obt_s - b.ca_time_obt_s) <= dt_allowed
                and abs(a.ca_distance_km - b.ca_distance_km) <= dd_allowed)


def _theta(times_s: NDArray, ca_time_s: NDArray | float, ca_distance_m: NDArray | float, speed_m_s: float) -> NDArray:
    return np.arctan2(ca_distance_m, -speed_m_s * (times_s - ca_time_s))


def predicted_theta(ca_time_obt_s: float, ca_distance_km: float, cov: NDArray[np.float64], speed_m_s: float,
                    obt_s: float, offset_rad: float = 0.0) -> tuple[float, float]:
    """(measured in-plane LOS angle rad, its one-sigma rad) at ``obt_s`` of the C/A estimate (time OBT s, distance
    km) with the in-plane offset ``offset_rad`` and covariance ``cov`` (2x2 in s, km; or 3x3 in s, km, rad with the
    offset): the covariance carried through the angle's derivatives by those parameters."""
    d_m = ca_distance_km * 1e3
    tau = obt_s - ca_time_obt_s
    r2 = d_m * d_m + (speed_m_s * tau) ** 2
    # per s of C/A time, per km of distance, per rad of offset
    jac = np.array([-speed_m_s * d_m / r2, -speed_m_s * tau / r2 * 1e3, 1.0])[: cov.shape[0]]
    return (float(np.arctan2(d_m, -speed_m_s * tau)) + offset_rad,
            float(np.sqrt(max(float(jac @ cov @ jac), 0.0))))


def predicted_los(trajectory: NominalTrajectory, estimate: ContinuousEstimate, obt_s: float
                  ) -> tuple[NDArray[np.float64], float]:
    """(unit inertial line of sight as it will be measured at ``obt_s``, its one-sigma rad) of the continuous
    ``estimate`` on ``trajectory``'s flyby plane: the in-plane angle with its offset (``predicted_theta``) and the
    out-of-plane offset, their one-sigmas combined."""
    theta, sigma_in = predicted_theta(estimate.ca_time_obt_s, estimate.ca_distance_km, estimate.cov,
                                      trajectory.speed_m_s, obt_s, estimate.in_plane_offset_rad)
    phi = estimate.out_of_plane_offset_rad
    # measured_theta_rad and out_of_plane_rad inverted: theta from the velocity towards -e_ca, phi along the normal
    los = math.cos(phi) * (math.cos(theta) * trajectory.e_v - math.sin(theta) * trajectory.e_ca) \
        + math.sin(phi) * trajectory.plane_normal
    return los, math.hypot(sigma_in, estimate.out_of_plane_sigma_rad)


class TrajectoryRecognizer:
    """Grid and continuous recognition of the C/A time (OBT) and distance. Pure: time and inputs are arguments."""

    def __init__(self, nominal: NominalTrajectory, cfg: RecognitionConfig) -> None:
        self.nominal = nominal
        self.cfg = cfg
        k = cfg.grid_span_sigma
        self._times_s = nominal.ca_time_obt_s + np.linspace(-k, k, cfg.grid_time_points) * nominal.ca_time_sigma_s
        self._distances_km = nominal.ca_distance_km + np.linspace(-k, k, cfg.grid_distance_points) * (
            nominal.ca_distance_sigma_km
        )
        if self._distances_km[0] <= 0:
            raise ValueError(
                f"grid_span_sigma {k} x ca_distance_sigma_km {nominal.ca_distance_sigma_km} reaches a C/A distance "
                f"of {self._distances_km[0]:.3f} km <= 0 below the nominal {nominal.ca_distance_km} km"
            )
        grid_t, grid_d = np.meshgrid(self._times_s, self._distances_km * 1e3, indexing="ij")
        self._cand_t = grid_t.ravel()
        self._cand_d_m = grid_d.ravel()
        # ties (e.g. before any measurement) go to the candidate nearest the nominal, in sigmas
        u, w = np.meshgrid(
            np.linspace(-k, k, cfg.grid_time_points), np.linspace(-k, k, cfg.grid_distance_points), indexing="ij"
        )
        self._tie_order = np.lexsort(((u**2 + w**2).ravel(),))
        self._sum_sq = np.zeros(self._cand_t.size)
        # the measurements (time OBT s, in-plane angle rad, out-of-plane angle rad) in rows of a buffer that doubles
        # as it fills: the solve reads them as arrays at every new one, without converting a list each time
        self._meas = np.empty((3, 64))
        self._n = 0
        self._solved: tuple[int, ContinuousEstimate] | None = None
        # the best grid candidate since the last measurement or step (asked by each housekeeping packet and solve)
        self._best: tuple[float, float, float] | None = None
        self._trajectory: tuple[object, NominalTrajectory] | None = None  # (the _solved it was built from, it)

    def shift_time(self, step_s: float) -> None:
        """On-board time stepped by ``step_s``: the nominal, the candidates and the measurement times move with it,
        so every residual, and the estimates (moved by the step), stay as they were."""
        self.nominal = self.nominal.with_ca(self.nominal.ca_time_obt_s + step_s, self.nominal.ca_distance_km)
        self._times_s = self._times_s + step_s
        self._cand_t = self._cand_t + step_s
        self._meas[0, : self._n] += step_s
        self._solved = self._best = None

    # --- measurements --------------------------------------------------------------------------------------------

    @property
    def measurement_count(self) -> int:
        """Number of measurements accumulated."""
        return self._n

    @property
    def measurement_times_obt_s(self) -> tuple[float, ...]:
        """The time stamps of the measurements accumulated, OBT s, in the order they were added."""
        return tuple(self._meas[0, : self._n].tolist())

    def add_measurement(self, obt_s: float, los_inertial: ArrayLike) -> None:
        """Accumulate one measured LOS (inertial unit vector spacecraft -> target, ``R(q) @ los_body``) at ``obt_s``.

        O(candidates): each candidate's capped squared residual is added to its running sum.
        """
        los = np.asarray(los_inertial, dtype=float)
        # scalar checks on the three floats: NumPy's reductions cost more than the work they guard
        if los.shape != (3,) or not all(math.isfinite(c) for c in los.tolist()) \
                or abs(math.sqrt(float(los @ los)) - 1.0) > 1e-6:
            raise ValueError(f"los_inertial must be a finite unit 3-vector, got {los_inertial}")
        if not math.isfinite(obt_s):
            raise ValueError(f"obt_s must be finite, got {obt_s}")
        theta = measured_theta_rad(self.nominal, los)
        residual = theta - _theta(np.float64(obt_s), self._cand_t, self._cand_d_m, self.nominal.speed_m_s)
        self._sum_sq += np.minimum(residual**2, self.cfg.residual_cap_rad**2)
        if self._n == self._meas.shape[1]:
            self._meas = np.concatenate([self._meas, np.empty_like(self._meas)], axis=1)
        self._meas[:, self._n] = (float(obt_s), theta, out_of_plane_rad(self.nominal, los))
        self._n += 1
        self._best = None

    # --- grid ----------------------------------------------------------------------------------------------------

    def candidate_axes(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The grid's C/A times (OBT s) and C/A distances (km); candidate (i, j) pairs times[i] with distances[j]."""
        return self._times_s.copy(), self._distances_km.copy()

    def mse_grid(self) -> NDArray[np.float64]:
        """Mean capped squared residual of every candidate, rad^2, shape (time points, distance points)."""
        n = max(self.measurement_count, 1)
        return (self._sum_sq / n).reshape(self.cfg.grid_time_points, self.cfg.grid_distance_points)

    def best_grid(self) -> tuple[float, float, float]:
        """(C/A time OBT s, C/A distance km, mean square error rad^2) of the best candidate; the nominal (and an
        mse of nan) before any measurement."""
        if not self._n:
            return self.nominal.ca_time_obt_s, self.nominal.ca_distance_km, float("nan")
        if self._best is None:
            mse = self._sum_sq / self.measurement_count
            # the least in tie order: argmin takes the first of equal minima (every mse is finite: measurements are)
            best = int(self._tie_order[np.argmin(mse[self._tie_order])])
            self._best = float(self._cand_t[best]), float(self._cand_d_m[best] / 1e3), float(mse[best])
        return self._best

    def best_trajectory(self) -> NominalTrajectory:
        """The nominal trajectory moved to the best candidate's C/A time and distance."""
        t, d, _ = self.best_grid()
        return self.nominal.with_ca(t, d)

    # --- continuous estimate ---------------------------------------------------------------------------------------

    def continuous(self) -> tuple[float, float, NDArray[np.float64]]:
        """(C/A time OBT s, C/A distance km, covariance 2x2 in s^2, s km, km^2) of the MAP estimate.

        Before any measurement: the nominal and its prior covariance.
        """
        e = self.continuous_estimate()
        return e.ca_time_obt_s, e.ca_distance_km, e.cov[:2, :2]

    def continuous_estimate(self) -> ContinuousEstimate:
        """The MAP estimate with the LOS offsets (before any measurement: the nominal, no offset, the priors)."""
        if self._solved is None or self._solved[0] != self.measurement_count:
            e = self._solve()
            e.cov.setflags(write=False)  # the one value handed to every caller until the next measurement: read-only
            self._solved = (self.measurement_count, e)
        return self._solved[1]

    def continuous_trajectory(self) -> NominalTrajectory:
        """The nominal trajectory moved to the continuous estimate, with its one-sigma uncertainties (the same value
        until the estimate changes: the lock gate asks for it with every frame)."""
        t, d, cov = self.continuous()
        if self._trajectory is not None and self._trajectory[0] is self._solved:
            return self._trajectory[1]
        traj = NominalTrajectory(
            **{
                **self.nominal.model_dump(),
                "ca_time_obt_s": t,
                "ca_distance_km": d,
                "ca_time_sigma_s": float(np.sqrt(max(cov[0, 0], 0.0))),
                "ca_distance_sigma_km": float(np.sqrt(max(cov[1, 1], 0.0))),
            }
        )
        self._trajectory = (self._solved, traj)
        return traj

    def recent_scatter_rad(self, count: int) -> float:
        """Median absolute residual, rad, of the last ``count`` measurements against the continuous estimate (its
        in-plane angle, offset included): how well the estimate fits what it was last told (0 before any)."""
        if not self._n:
            return 0.0
        e = self.continuous_estimate()
        t = self._meas[0, max(self._n - count, 0): self._n]
        theta = self._meas[1, max(self._n - count, 0): self._n]
        model = _theta(t, e.ca_time_obt_s, e.ca_distance_km * 1e3, self.nominal.speed_m_s) + e.in_plane_offset_rad
        return float(np.median(np.abs(theta - model)))

    @property
    def last_measurement_obt_s(self) -> float | None:
        """The time stamp of the measurement added last, OBT s (None before any)."""
        return float(self._meas[0, self._n - 1]) if self._n else None

    def _solve(self) -> ContinuousEstimate:
        nom = self.nominal
        c = self.cfg
        sig_t, sig_d_m, sig_e = nom.ca_time_sigma_s, nom.ca_distance_sigma_km * 1e3, c.los_offset_sigma_rad
        if not self._n:
            return ContinuousEstimate(nom.ca_time_obt_s, nom.ca_distance_km, 0.0,
                                      np.diag([sig_t**2, (sig_d_m / 1e3) ** 2, sig_e**2]), 0.0, sig_e)
        t0, d0_km, _ = self.best_grid()
        p, cov, inliers = recognition_kernels.solve(
            self._meas[0, : self._n], self._meas[1, : self._n],
            np.array([nom.ca_time_obt_s, nom.ca_distance_m, 0.0]), np.array([sig_t, sig_d_m, sig_e]),
            np.array([t0, d0_km * 1e3, 0.0]), nom.speed_m_s, c.angle_noise_rad,
            c.residual_cap_rad, c.outlier_gate_sigma * c.angle_noise_rad, c.max_iterations)
        # the out-of-plane offset: the mean of the inliers' angles shrunk by the prior (0 without one)
        out = self._meas[2, : self._n][inliers]
        info = out.size / c.angle_noise_rad**2 + (1.0 / sig_e**2 if sig_e > 0 else math.inf)
        eta = float(out.sum()) / c.angle_noise_rad**2 / info
        units = np.array([1.0, 1e-3, 1.0])  # s, m -> km, rad
        return ContinuousEstimate(float(p[0]), float(p[1] / 1e3), float(p[2]), cov * np.outer(units, units), eta,
                                  math.sqrt(1.0 / info))
