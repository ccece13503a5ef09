"""Attitude dynamics of a rigid spacecraft with reaction wheels (a gyrostat), integrated with fixed-step RK4 (the
substeps compiled in ``universe.attitude_rk4``).

Model (body axes; A is the 3 x N matrix of wheel spin axes, J the rotor axial inertia, I the spacecraft inertia
without the rotors' axial inertia):

    h_i   = J (a_i . w + Omega_i)                 absolute axial momentum of rotor i
    H     = I w + A h                             total angular momentum, conserved in the inertial frame
    tau_i = u_i + f_i(Omega_i)                    motor torque on the rotor plus bearing friction (rotor <-> body)
    dh/dt = tau                                   (a stuck rotor instead turns with the body: Omega_i = 0)
    I dw/dt = -A tau - w x H                      (stuck rotors join I: I_eff = I + J sum a_i a_i^T)
    dq/dt = 1/2 q (x) [w, 0]                      scalar-last quaternion, body -> inertial

The wheel momentum limit applies to the rotor speed relative to the body (what the motor and tachometer see):
the motor torque is cut back so that |J Omega_i| does not grow past max_momentum_nms.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from universe.attitude_rk4 import period
from universe.config import SpacecraftConfig


class DynamicsError(ValueError):
    """An input to the attitude dynamics has the wrong shape or value."""


@dataclass(frozen=True)
class AttitudeState:
    """True attitude state: q scalar-last body -> inertial, body rate rad/s, wheel rotor speeds relative to the body."""

    q: np.ndarray
    omega_rad_s: np.ndarray
    wheel_speed_rad_s: np.ndarray


def body_to_inertial_matrices(q: np.ndarray) -> np.ndarray:
    """The rotation matrix of each row of an (N, 4) array of unit scalar-last quaternions: shape (N, 3, 3) (body ->
    inertial for body->inertial quaternions)."""
    x, y, z, w = (np.asarray(q, dtype=float)[:, k] for k in range(4))
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], axis=-1),
        np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], axis=-1),
        np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], axis=-1),
    ], axis=1)


def quaternion_rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Return v rotated by the unit scalar-last quaternion q (body vector -> inertial vector for a body->inertial q)."""
    return body_to_inertial_matrices(np.asarray(q, dtype=float)[None, :])[0] @ np.asarray(v, dtype=float)


def pyramid_axes_body(elevation_deg: float) -> np.ndarray:
    """Return the 3 x 4 spin axes of a pyramid: elevation_deg above the body XY plane, azimuths 45/135/225/315 deg."""
    el = math.radians(elevation_deg)
    az = np.radians([45.0, 135.0, 225.0, 315.0])
    return np.vstack([math.cos(el) * np.cos(az), math.cos(el) * np.sin(az), np.full(4, math.sin(el))])


@dataclass(frozen=True)
class _Mode:
    """Matrices precomputed for one set of stuck wheels, as the compiled integrator takes them."""

    free: np.ndarray  # (N,) 1.0 for a free rotor, 0.0 for a stuck one
    i_eff: np.ndarray  # (3, 3) spacecraft inertia plus the stuck rotors' axial inertia
    i_eff_inv: np.ndarray
    gain: np.ndarray  # (N,) d(J Omega_i)/d(u_i) = 1 + J a_i^T I_eff^-1 a_i
    i_eff_flat: np.ndarray  # (9,) row-major
    i_eff_inv_flat: np.ndarray
    free_axes: np.ndarray  # (F, 4) index, ax, ay, az of each free rotor


class SpacecraftDynamics:
    """Rigid spacecraft with N reaction wheels; `step` advances an AttitudeState under held wheel torque commands."""

    def __init__(self, sc: SpacecraftConfig) -> None:
        self.sc = sc
        w = sc.wheels
        self.inertia_kgm2 = np.asarray(sc.inertia_kgm2, dtype=float)
        if not np.allclose(self.inertia_kgm2, self.inertia_kgm2.T):
            raise DynamicsError(f"spacecraft.inertia_kgm2 must be symmetric, got {self.inertia_kgm2.tolist()}")
        if np.any(np.linalg.eigvalsh(self.inertia_kgm2) <= 0):
            raise DynamicsError(f"spacecraft.inertia_kgm2 must be positive definite, got {self.inertia_kgm2.tolist()}")
        if w.layout == "orthogonal":
            self.wheel_axes_body = np.eye(3)
        else:
            self.wheel_axes_body = pyramid_axes_body(w.pyramid_angle_deg)
        self.n_wheels = self.wheel_axes_body.shape[1]
        self.rotor_inertia_kgm2 = float(w.inertia_kgm2)
        self.max_torque_nm = float(w.max_torque_nm)
        self.max_momentum_nms = float(w.max_momentum_nms)
        self._viscous = float(w.viscous_friction_nms)
        self._coulomb = float(w.coulomb_friction_nm)
        self._smooth = float(w.coulomb_smoothing_rad_s)
        self._max_substep_s = float(sc.integration_substep_s)
        self._modes: dict[frozenset[int], _Mode] = {}
        self._stepped: AttitudeState | None = None  # the state the last step returned
        # Friction's stiffness on the rotor speed, 1/s: RK4 substeps are kept below 0.5 / this.
        self._friction_rate_s = (self._viscous + self._coulomb / self._smooth) / self.rotor_inertia_kgm2 * 1.01

    def _mode(self, stuck: frozenset[int]) -> _Mode:
        """Return (and cache) the matrices for a set of stuck wheels."""
        mode = self._modes.get(stuck)
        if mode is None:
            free = np.ones(self.n_wheels)
            i_eff = self.inertia_kgm2.copy()
            for i in stuck:
                free[i] = 0.0
                a = self.wheel_axes_body[:, i]
                i_eff += self.rotor_inertia_kgm2 * np.outer(a, a)
            i_eff_inv = np.linalg.inv(i_eff)
            a = self.wheel_axes_body
            gain = 1.0 + self.rotor_inertia_kgm2 * np.einsum("ij,ik,kj->j", a, i_eff_inv, a)
            mode = _Mode(
                free=free,
                i_eff=i_eff,
                i_eff_inv=i_eff_inv,
                gain=np.array([float(g) for g in gain]),
                i_eff_flat=np.array([float(c) for c in i_eff.ravel()]),
                i_eff_inv_flat=np.array([float(c) for c in i_eff_inv.ravel()]),
                free_axes=np.array(
                    [(i, float(a[0, i]), float(a[1, i]), float(a[2, i])) for i in range(self.n_wheels) if free[i]]
                ).reshape(-1, 4),
            )
            self._modes[stuck] = mode
        return mode

    def _check_wheels(self, wheels: frozenset[int], name: str) -> frozenset[int]:
        """Return wheels as a frozenset after checking every index is a wheel of this spacecraft."""
        wheels = frozenset(int(i) for i in wheels)
        bad = [i for i in wheels if not 0 <= i < self.n_wheels]
        if bad:
            raise DynamicsError(f"{name} {sorted(bad)} out of range: this spacecraft has {self.n_wheels} wheels")
        return wheels

    def _torques(self, torque_nm: np.ndarray, name: str) -> np.ndarray:
        """The motor torques as a float array of one value per wheel, all finite; DynamicsError naming ``name``."""
        u = np.asarray(torque_nm, dtype=float)
        if u.shape != (self.n_wheels,):
            raise DynamicsError(f"{name} must have shape ({self.n_wheels},), got {u.shape}")
        if not all(map(math.isfinite, u.tolist())):  # a few wheels: cheaper than a NumPy reduction
            raise DynamicsError(f"{name} must be finite, got {u.tolist()}")
        return u

    def _check_state(self, state: AttitudeState) -> None:
        """Raise DynamicsError if the state's arrays have the wrong shapes."""
        q = np.asarray(state.q, dtype=float)
        if q.shape != (4,) or np.shape(state.omega_rad_s) != (3,):
            raise DynamicsError(
                f"AttitudeState.q must have shape (4,) and omega_rad_s (3,), "
                f"got {np.shape(state.q)} and {np.shape(state.omega_rad_s)}"
            )
        if abs(math.sqrt(float(q.dot(q))) - 1.0) > 1e-6:
            raise DynamicsError(f"AttitudeState.q must be a unit quaternion, got {np.asarray(state.q).tolist()}")
        if np.shape(state.wheel_speed_rad_s) != (self.n_wheels,):
            raise DynamicsError(
                f"AttitudeState.wheel_speed_rad_s must have shape ({self.n_wheels},), "
                f"got {np.shape(state.wheel_speed_rad_s)}"
            )

    def wheel_momentum_nms(self, state: AttitudeState) -> np.ndarray:
        """Return each rotor's momentum relative to the body, J Omega_i, N m s (the quantity that saturates)."""
        return self.rotor_inertia_kgm2 * np.asarray(state.wheel_speed_rad_s, dtype=float)

    def angular_momentum_body(self, state: AttitudeState) -> np.ndarray:
        """Return the total angular momentum (body plus rotors) in body axes, N m s."""
        w = np.asarray(state.omega_rad_s, dtype=float)
        a = self.wheel_axes_body
        h = self.rotor_inertia_kgm2 * (a.T @ w + np.asarray(state.wheel_speed_rad_s, dtype=float))
        return self.inertia_kgm2 @ w + a @ h

    def angular_momentum_inertial(self, state: AttitudeState) -> np.ndarray:
        """Return the total angular momentum in inertial axes, N m s (constant without external torque)."""
        return quaternion_rotate(state.q, self.angular_momentum_body(state))

    def kinetic_energy(self, state: AttitudeState) -> float:
        """Return the rotational kinetic energy of the body and rotors, J."""
        w = np.asarray(state.omega_rad_s, dtype=float)
        spin = self.wheel_axes_body.T @ w + np.asarray(state.wheel_speed_rad_s, dtype=float)
        return float(0.5 * w @ self.inertia_kgm2 @ w + 0.5 * self.rotor_inertia_kgm2 * spin @ spin)

    def step(
        self,
        state: AttitudeState,
        torque_cmd_nm: np.ndarray,
        dt_s: float,
        stuck_wheels: frozenset[int] = frozenset(),
        failed_wheels: frozenset[int] = frozenset(),
        before_nm: np.ndarray | None = None,
        switch_s: float = 0.0,
    ) -> AttitudeState:
        """Return the state after dt_s with the motor torques held (``before_nm`` for the first ``switch_s`` of them,
        if given: torques that change within the period, in one call).

        torque_cmd_nm (N,) is the motor torque on each rotor about its spin axis (the body feels minus it), clipped to
        max_torque_nm and cut back at the momentum limit. A failed wheel gets no motor torque (friction spins it
        down); a stuck wheel's rotor is locked to the body (its relative momentum passes to the body at once).
        """
        if state is not self._stepped:  # the state returned by the last step has its shapes and a unit q, as made
            self._check_state(state)
        u_cmd = self._torques(torque_cmd_nm, "torque_cmd_nm")
        u_before = u_cmd if before_nm is None else self._torques(before_nm, "before_nm")
        if not dt_s >= 0.0:
            raise DynamicsError(f"dt_s must be >= 0, got {dt_s}")
        if not 0.0 <= switch_s <= dt_s:
            raise DynamicsError(f"switch_s must be within 0..dt_s ({dt_s}), got {switch_s}")
        # no faulted wheels (nearly every period): nothing to check
        stuck = stuck_wheels if not stuck_wheels else self._check_wheels(stuck_wheels, "stuck_wheels")
        failed = failed_wheels if not failed_wheels else self._check_wheels(failed_wheels, "failed_wheels")
        mode = self._mode(frozenset(stuck))
        a = self.wheel_axes_body
        jw = self.rotor_inertia_kgm2

        q = np.asarray(state.q, dtype=float)
        w = np.asarray(state.omega_rad_s, dtype=float)
        speeds = np.asarray(state.wheel_speed_rad_s, dtype=float)
        # ndarray.dot: the same BLAS product as matmul's (tested to the bit), without the generalised ufunc's set-up
        h = jw * (a.T.dot(w) + speeds)
        if stuck and np.any(speeds[list(stuck)] != 0.0):
            # A rotor seizing hands its relative momentum to the body: H is conserved, free rotors keep their h.
            total = self.inertia_kgm2 @ w + a @ h
            w = mode.i_eff_inv @ (total - a @ (mode.free * h))
        motor_on = mode.free
        if failed:
            motor_on = motor_on.copy()
            for i in failed:
                motor_on[i] = 0.0
        # the torques held before the switch, then the new ones, and the rotor speeds after: one compiled call
        out = np.empty(7 + self.n_wheels)
        period(q, w, h, u_before, u_cmd, switch_s, dt_s, motor_on, self.max_torque_nm, self._max_substep_s,
               self._friction_rate_s, mode.free_axes, mode.gain, mode.i_eff_flat, mode.i_eff_inv_flat, jw,
               self.max_momentum_nms, self._viscous, self._coulomb, 1.0 / self._smooth, a, mode.free, out)
        self._stepped = AttitudeState(q=out[:4], omega_rad_s=out[4:7], wheel_speed_rad_s=out[7:])
        return self._stepped
