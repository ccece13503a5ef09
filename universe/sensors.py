"""Attitude sensors: star tracker quaternion, gyro rate, wheel tachometers, with seeded noise and bias.

Every random number comes from the Generator given at construction, drawn in a fixed order per call (gyro bias
walk 3, gyro white noise 3, tachometers N, then the star tracker 3 on an update), whatever the sigmas are, so a run
is reproducible from its seed and changing one sigma does not reshuffle the other sensors' noise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from universe.config import SensorsConfig
from universe.dynamics import AttitudeState
from universe.sensor_kernels import gyro_and_tachometers, star_tracker_q

ARCSEC_RAD = math.pi / (180.0 * 3600.0)
DEG_H_RAD_S = math.pi / 180.0 / 3600.0
DEG_SQRT_H_RAD_SQRT_S = math.pi / 180.0 / 60.0
_NO_STEP = np.zeros(3)  # the gyro's fault step when there is none (not added)


class SensorError(ValueError):
    """A sensor input has the wrong shape or value."""


@dataclass(frozen=True)
class SensorReadings:
    """What the hardware reports at one instant."""

    star_tracker_q: np.ndarray | None
    """scalar-last body -> inertial quaternion, held between updates; None during an outage"""
    gyro_rad_s: np.ndarray
    """body rate, rad/s, with bias and noise"""
    wheel_speed_rad_s: np.ndarray
    """rotor speeds relative to the body, rad/s, with noise"""


class Sensors:
    """The spacecraft's star tracker, gyro and wheel tachometers; `measure` samples them from the true state."""

    def __init__(self, cfg: SensorsConfig, n_wheels: int, rng: np.random.Generator) -> None:
        if n_wheels < 1:
            raise SensorError(f"n_wheels must be >= 1, got {n_wheels}")
        self.cfg = cfg
        self.n_wheels = n_wheels
        self._rng = rng
        st = cfg.star_tracker
        self._st_sigma_rad = np.asarray(st.noise_arcsec, dtype=float) * ARCSEC_RAD
        self._st_bias_rad = np.asarray(st.bias_arcsec, dtype=float) * ARCSEC_RAD
        self._st_rate_hz = float(st.rate_hz)
        self._st_held: np.ndarray | None = None
        self._st_slot: int | None = None
        g = cfg.gyro
        self._arw_rad_sqrt_s = float(g.arw_deg_sqrt_h) * DEG_SQRT_H_RAD_SQRT_S
        # Rate random walk chosen so the bias drifts one bias instability (1 sigma) in bias_walk_time_s.
        self._rrw_rad_s_sqrt_s = float(g.bias_instability_deg_h) * DEG_H_RAD_S / math.sqrt(g.bias_walk_time_s)
        self._gyro_bias_rad_s = np.asarray(g.initial_bias_deg_h, dtype=float) * DEG_H_RAD_S
        self._wheel_sigma_rad_s = float(cfg.wheel_speed_noise_rad_s)

    @property
    def gyro_bias_rad_s(self) -> np.ndarray:
        """Return the gyro's current true bias (without a fault step), rad/s, for truth logging."""
        return self._gyro_bias_rad_s.copy()

    def measure(
        self,
        t_s: float,
        state: AttitudeState,
        dt_s: float,
        star_tracker_out: bool = False,
        gyro_bias_step_rad_s: np.ndarray | None = None,
    ) -> SensorReadings:
        """Return the readings at true time t_s of the true state; dt_s is the time since the previous call.

        The star tracker updates when t_s enters a new 1/rate_hz slot of true time and holds its reading otherwise;
        gyro_bias_step_rad_s (3,) is a fault's extra bias, added while it is given.
        """
        if not dt_s > 0.0:
            raise SensorError(f"dt_s must be > 0, got {dt_s}")
        omega = np.asarray(state.omega_rad_s, dtype=float)
        speeds = np.asarray(state.wheel_speed_rad_s, dtype=float)
        if omega.shape != (3,):
            raise SensorError(f"state.omega_rad_s must have shape (3,), got {omega.shape}")
        if speeds.shape != (self.n_wheels,):
            raise SensorError(f"state.wheel_speed_rad_s must have shape ({self.n_wheels},), got {speeds.shape}")
        slot = None if star_tracker_out else math.floor(t_s * self._st_rate_hz + 1e-9)
        fresh = slot is not None and (self._st_held is None or slot != self._st_slot)  # a new tracker solution
        q_true = np.asarray(state.q, dtype=float)
        if fresh and q_true.shape != (4,):
            raise SensorError(f"state.q must have shape (4,), got {q_true.shape}")
        # the tracker's 3 normals come after the gyro's and tachometers' in the stream: drawn with them, in one call
        noise = self._rng.standard_normal(6 + self.n_wheels + (3 if fresh else 0))
        step = _NO_STEP
        if gyro_bias_step_rad_s is not None:
            step = np.asarray(gyro_bias_step_rad_s, dtype=float)
            if step.shape != (3,):
                raise SensorError(f"gyro_bias_step_rad_s must have shape (3,), got {step.shape}")
        gyro, wheels = np.empty(3), np.empty(self.n_wheels)
        # the bias walks in place: the property hands out copies, so no caller holds this array
        gyro_and_tachometers(omega, speeds, self._gyro_bias_rad_s, noise, self._rrw_rad_s_sqrt_s * math.sqrt(dt_s),
                             self._arw_rad_sqrt_s / math.sqrt(dt_s), self._wheel_sigma_rad_s, step,
                             gyro_bias_step_rad_s is not None, gyro, wheels)
        return SensorReadings(
            star_tracker_q=self._star_tracker(q_true, slot, noise[6 + self.n_wheels:] if fresh else None),
            gyro_rad_s=gyro,
            wheel_speed_rad_s=wheels,
        )

    def _star_tracker(self, q_true: np.ndarray, slot: int | None, z: np.ndarray | None) -> np.ndarray | None:
        """Return the star tracker quaternion in update ``slot`` of true time (None: an outage): a fresh noisy one
        from the normals ``z`` at each new slot, else the held one."""
        if slot is None:
            # After an outage the tracker reacquires with a fresh solution rather than a stale one.
            self._st_held = None
            self._st_slot = None
            return None
        if z is not None:
            held = np.empty(4)
            star_tracker_q(q_true, self._st_bias_rad, self._st_sigma_rad, z, held)
            self._st_held = held
            self._st_slot = slot
        assert self._st_held is not None  # a slot's first reading is fresh
        return self._st_held.copy()
