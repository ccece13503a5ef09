"""False lock: the innovation of a line of sight against the recognised trajectory's prediction."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from obsw.config import FdirConfig
from obsw.lock_gate import LockGate
from obsw.trajectory import NominalTrajectory

TRAJ = NominalTrajectory(ca_time_obt_s=1000.0, ca_distance_km=55.0, speed_km_s=7.0, approach_direction=(1, 0, 0),
                         ca_direction=(0, 1, 0))
CFG = FdirConfig(false_lock_gate_deg=0.25, false_lock_gate_growth_deg_s=0.02)


def _off(los: np.ndarray, deg: float) -> np.ndarray:
    """``los`` turned by ``deg`` about the flyby-plane normal."""
    return Rotation.from_rotvec(math.radians(deg) * TRAJ.plane_normal).apply(los)


def test_a_target_following_the_trajectory_with_a_constant_offset_is_accepted() -> None:
    """Dimorphos 1 deg off the barycentre's line of sight, moving with it from C/A-60 s to C/A: never refused."""
    gate = LockGate(CFG)
    for t in np.arange(940.0, 1000.0, 0.5):
        assert gate.check(TRAJ, t, _off(TRAJ.los_inertial(t), 1.0)).accepted
    assert gate.rejected == 0


def test_a_jump_beyond_the_gate_is_refused_and_the_gate_grows_with_time() -> None:
    """A blob 2 deg off the prediction is refused (one run, counted); the gate then grows by 0.02 deg/s, so 0.4 deg
    off is refused 1 s after the last accepted line of sight and taken 10 s after it."""
    gate = LockGate(CFG)
    assert gate.check(TRAJ, 900.0, TRAJ.los_inertial(900.0)).accepted
    r = gate.check(TRAJ, 901.0, _off(TRAJ.los_inertial(901.0), 2.0))
    assert not r.accepted and math.degrees(r.innovation_rad) == pytest.approx(2.0, rel=1e-9)
    assert math.degrees(r.gate_rad) == pytest.approx(0.27, rel=1e-9)
    assert not gate.check(TRAJ, 901.0, _off(TRAJ.los_inertial(901.0), 0.4)).accepted
    assert gate.check(TRAJ, 910.0, _off(TRAJ.los_inertial(910.0), 0.4)).accepted
    assert (gate.rejected, gate.run) == (2, 0)


def test_without_a_trusted_trajectory_everything_is_accepted() -> None:
    """Before the recognition is trusted (trajectory None) the gate takes every line of sight."""
    gate = LockGate(CFG)
    assert gate.check(None, 900.0, TRAJ.los_inertial(900.0)).accepted
    assert gate.check(None, 901.0, _off(TRAJ.los_inertial(901.0), 20.0)).accepted

