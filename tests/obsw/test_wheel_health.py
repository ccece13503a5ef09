"""Wheel failure detection: commanded impulse against the measured change of wheel momentum over a window."""

from __future__ import annotations

import numpy as np
import pytest

from obsw.config import FdirConfig
from obsw.wheel_health import WheelHealth

DT = 0.1
CFG = FdirConfig()


def _run(torques_nm: np.ndarray, delivered: np.ndarray, periods: int, friction_nm: float = 0.0,
         h0: np.ndarray | None = None) -> tuple[WheelHealth, list[tuple[int, int]]]:
    """Wheels commanded ``torques_nm`` each period; wheel k delivers ``delivered[k]`` of it, less friction."""
    n = len(torques_nm)
    health = WheelHealth(CFG, n, max_momentum_nms=0.1)
    h = np.zeros(n) if h0 is None else h0.copy()
    found = [(0, f.wheel) for f in health.update(h, np.zeros(n), DT)]
    for k in range(1, periods + 1):
        impulse = torques_nm * DT
        h = h + delivered * impulse - np.sign(torques_nm) * friction_nm * DT
        found += [(k, f.wheel) for f in health.update(h, impulse, DT)]
    return health, found


def test_healthy_wheels_with_friction_are_never_found_failed() -> None:
    """Friction of three tenths of the smallest judged impulse (the worst healthy wheel) raises nothing."""
    _, found = _run(np.array([1e-4, -5e-4, 3e-3]), np.ones(3), 300, friction_nm=3e-5)
    assert found == []


def test_a_dead_or_stuck_wheel_is_found_after_the_confirmation_windows() -> None:
    """A wheel that delivers nothing fails every window: found at the end of the second window (2 x 10 periods)."""
    health, found = _run(np.array([1e-3, 1e-3, 1e-3]), np.array([1.0, 0.0, 1.0]), 40)
    assert found == [(CFG.wheel_confirmations * 10, 1)]
    assert health.failed == {1} and health.failed_mask == 0b010


def test_a_wheel_asked_too_little_or_near_its_limit_is_not_judged() -> None:
    """Below the minimum impulse, or with its momentum at the limit (the hardware cuts its torque), nothing is said."""
    _, quiet = _run(np.array([5e-5, 5e-5, 5e-5]), np.zeros(3), 100)
    assert quiet == []
    _, limited = _run(np.array([1e-3, 1e-3, 1e-3]), np.array([0.0, 1.0, 1.0]), 100, h0=np.array([0.095, 0.0, 0.0]))
    assert limited == []


def test_a_reading_or_command_of_the_wrong_number_of_wheels_is_refused_by_name() -> None:
    """Momenta or impulses for another number of wheels raise a ValueError naming the argument, never a silent cut."""
    health = WheelHealth(CFG, 4, max_momentum_nms=0.1)
    with pytest.raises(ValueError, match="momentum_nms must have 4 values, got 3"):
        health.update(np.zeros(3), np.zeros(4), DT)
    health.update(np.zeros(4), np.zeros(4), DT)
    with pytest.raises(ValueError, match="impulse_nms must have 4 values, got 5"):
        health.update(np.zeros(4), np.zeros(5), DT)
