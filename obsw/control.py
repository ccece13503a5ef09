"""Attitude control: PD on the quaternion error and body rate, and the torque split over the reaction wheels.

Paper ("Attitude Control Module"): a PD baseline (the integral term did not improve pointing near C/A), one set
of gains for every trajectory, tuned on the worst case (nearest C/A). Wheels: 0.007 N m and 0.1 N m s each.

Sign convention: the torque commanded to a wheel accelerates its rotor (d h_wheel / dt = tau_wheel); the body
receives the opposite, ``body torque = -A tau_wheel`` with ``A`` the 3xN matrix of unit wheel axes (columns).
"""

from __future__ import annotations

from types import SimpleNamespace
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from obsw import control_kernels as kernels
from obsw.config import ControlConfig


class AttitudeReference(Protocol):
    """What the controller follows (obsw.tracking.Reference satisfies it)."""

    q_des: NDArray[np.float64]
    omega_des_body: NDArray[np.float64]
    alpha_des_body: NDArray[np.float64]


def _vector(name: str, value: ArrayLike, size: int) -> NDArray[np.float64]:
    arr = np.asarray(value, dtype=float)
    if arr.shape != (size,):
        raise ValueError(f"{name} must have shape ({size},), got {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError(f"{name} must be finite, got {arr}")
    return arr


def _unit_quaternion(name: str, value: ArrayLike) -> NDArray[np.float64]:
    q = _vector(name, value, 4)
    norm = float(np.sqrt(q @ q))
    if norm < 1e-9:
        raise ValueError(f"{name} must be a non-zero quaternion, got {q}")
    return q / norm


def attitude_error_rad(q: ArrayLike, q_des: ArrayLike) -> NDArray[np.float64]:
    """Rotation vector of the body frame relative to the desired frame, rad (shortest way, |e| <= pi)."""
    return kernels.rotvec(kernels.error_quaternion(_unit_quaternion("q", q), _unit_quaternion("q_des", q_des)))


def boresight_error_rad(q: ArrayLike, boresight_body: ArrayLike, los_inertial: ArrayLike) -> float:
    """Angle between the body vector ``boresight_body`` turned to inertial by the attitude ``q`` (body->inertial,
    scalar-last) and the unit vector ``los_inertial``, rad."""
    return kernels.boresight_error_rad(_unit_quaternion("q", q), _vector("boresight_body", boresight_body, 3),
                                       _vector("los_inertial", los_inertial, 3))


def pd_torque_nm(
    q: ArrayLike,
    omega_rad_s: ArrayLike,
    ref: AttitudeReference,
    inertia_kgm2: ArrayLike,
    cfg: ControlConfig,
    wheel_momentum_body_nms: ArrayLike | None = None,
) -> NDArray[np.float64]:
    """Body torque, N m: ``-kp e - kd (omega - omega_des)`` plus, if ``cfg.feedforward``, the torque that makes the
    reference an exact solution of Euler's equations.

    ``q`` is the body->inertial attitude (scalar-last), ``omega_rad_s`` the body rate, ``ref`` the desired attitude
    with its body rate and acceleration (in the desired frame). The feedforward is
    ``I (C alpha_des - omega x C omega_des) + omega x (I omega + h_wheels)`` with ``C`` taking desired-frame vectors
    to the body frame; with it the closed-loop error obeys ``I de'' + kd de' + kp e = 0`` for small errors.
    ``wheel_momentum_body_nms`` (``A h``) adds the wheels' gyroscopic term; omit it for a wheel-less body.
    """
    inertia = np.asarray(inertia_kgm2, dtype=float)
    if inertia.shape != (3, 3):
        raise ValueError(f"inertia_kgm2 must be 3x3, got shape {inertia.shape}")
    vectors = (np.asarray(q, dtype=float), np.asarray(omega_rad_s, dtype=float), np.asarray(ref.q_des, dtype=float),
               np.asarray(ref.omega_des_body, dtype=float), np.asarray(ref.alpha_des_body, dtype=float),
               _NO_WHEELS if wheel_momentum_body_nms is None else np.asarray(wheel_momentum_body_nms, dtype=float))
    if tuple(v.shape for v in vectors) == _PD_SHAPES:
        # the kernel checks finiteness and the quaternions' norms; the checks below name what it refused
        torque, usable = kernels.pd_torque(*vectors[:5], inertia, cfg.kp_nm_per_rad, cfg.kd_nms_per_rad,
                                           cfg.feedforward, vectors[5], wheel_momentum_body_nms is not None)
        if usable:
            return torque
    omega = _vector("omega_rad_s", omega_rad_s, 3)
    omega_des = _vector("ref.omega_des_body", ref.omega_des_body, 3)
    alpha_des = _vector("ref.alpha_des_body", ref.alpha_des_body, 3)
    q_unit = _unit_quaternion("q", q)
    q_des_unit = _unit_quaternion("ref.q_des", ref.q_des)
    with_wheels = cfg.feedforward and wheel_momentum_body_nms is not None
    h = _vector("wheel_momentum_body_nms", wheel_momentum_body_nms, 3) if with_wheels else _NO_WHEELS
    return kernels.pd_torque(q_unit, omega, q_des_unit, omega_des, alpha_des, inertia, cfg.kp_nm_per_rad,
                             cfg.kd_nms_per_rad, cfg.feedforward, h, with_wheels)[0]


_NO_WHEELS = np.zeros(3)
_PD_SHAPES = ((4,), (3,), (4,), (3,), (3,), (3,))


def wheel_torques_nm(
    body_torque_nm: ArrayLike,
    wheel_axes: ArrayLike,
    wheel_momentum_nms: ArrayLike,
    max_torque_nm: float,
    max_momentum_nms: float,
    in_use: ArrayLike | None = None,
) -> NDArray[np.float64]:
    """Wheel torques, N m (N,), that give the body ``body_torque_nm`` (``-A tau = T``) within the wheel limits.

    ``in_use`` (N booleans, default all) is the wheel set: a wheel out of it gets no torque (a failed wheel).
    Minimum-norm split (pseudo-inverse) over the wheels that may take it: a wheel at or beyond
    ``max_momentum_nms`` is not pushed further (it is dropped from the split when its share would speed it up).
    If any wheel would exceed ``max_torque_nm`` all torques are scaled down by the same factor, so the body torque
    keeps its direction. Without enough usable wheels to span the request, the least-squares torque is returned.
    """
    torque = np.asarray(body_torque_nm, dtype=float)
    axes = np.asarray(wheel_axes, dtype=float)
    momentum = np.asarray(wheel_momentum_nms, dtype=float)
    n = axes.shape[1] if axes.ndim == 2 else 0
    usable = np.ones(n, dtype=bool) if in_use is None else np.asarray(in_use, dtype=bool).copy()
    # one combined test of every check below; they run, in order, to name what it refused
    if not (torque.shape == (3,) and axes.shape[0] == 3 and n >= 1 and momentum.shape == (n,) and max_torque_nm > 0
            and max_momentum_nms > 0 and usable.shape == (n,) and kernels.all_finite(torque)
            and kernels.all_finite(momentum)):
        _vector("body_torque_nm", body_torque_nm, 3)
        if axes.ndim != 2 or axes.shape[0] != 3 or axes.shape[1] < 1:
            raise ValueError(f"wheel_axes must be 3xN with N >= 1, got shape {axes.shape}")
        _vector("wheel_momentum_nms", wheel_momentum_nms, n)
        if not max_torque_nm > 0:
            raise ValueError(f"max_torque_nm must be > 0, got {max_torque_nm}")
        if not max_momentum_nms > 0:
            raise ValueError(f"max_momentum_nms must be > 0, got {max_momentum_nms}")
        if usable.shape != (n,):
            raise ValueError(f"in_use must have {n} values, got shape {usable.shape}")
    tau = np.zeros(n)
    peak = 0.0
    for _ in range(n):
        # a saturated wheel may only be slowed down, never sped up further
        tau, pushing, count, peak = kernels.split_pass(_split(axes, usable) @ torque, usable, momentum,
                                                       max_momentum_nms)
        if count == 0:
            break
        usable &= ~pushing
    if peak > max_torque_nm:
        tau *= max_torque_nm / peak
    return tau


_SPLITS: dict[tuple[bytes, bytes, tuple[int, ...]], NDArray[np.float64]] = {}
_SPLITS_KEPT = 64  # wheel sets remembered: a spacecraft has a handful (all wheels, each one dropped)


def _split(axes: NDArray[np.float64], usable: NDArray[np.bool_]) -> NDArray[np.float64]:
    """Minus the pseudo-inverse of the usable wheels' axes (their torques per unit body torque, ``-A tau = T``),
    computed once per axes and wheel set (the same matrix every period: its SVD was most of the allocation's time);
    the array returned is the one computed, bit for bit."""
    key = (axes.tobytes(), usable.tobytes(), axes.shape)
    split = _SPLITS.get(key)
    if split is None:
        if len(_SPLITS) >= _SPLITS_KEPT:
            _SPLITS.clear()
        split = -np.linalg.pinv(axes[:, usable])
        split.setflags(write=False)
        _SPLITS[key] = split
    return split


def warm_up() -> None:
    """Compile (or load from the cache) the control kernels now, as a run calls them."""
    unit, zero = np.array([0.0, 0.0, 0.0, 1.0]), np.zeros(3)
    ref = SimpleNamespace(q_des=unit, omega_des_body=zero, alpha_des_body=zero)
    torque = pd_torque_nm(unit, zero, ref, np.eye(3), ControlConfig(), zero)
    wheel_torques_nm(torque, np.eye(3), zero, 1.0, 1.0, np.ones(3, dtype=bool))
    boresight_error_rad(unit, (0.0, 0.0, 1.0), np.array([0.0, 0.0, 1.0]))
