"""False lock: a measured line of sight that the recognised trajectory cannot explain is refused.

The recognised trajectory predicts how the line of sight to the target moves; between two frames the measured one
must follow it, up to the slowly varying offset of Dimorphos from the trajectory's barycentre and the trajectory's
own error. So the innovation of a measurement is the change of its offset from the recognised trajectory since the
last accepted measurement (both offsets against the same, current trajectory). Beyond ``false_lock_gate_deg`` (grown
by ``false_lock_gate_growth_deg_s`` per second since that measurement, as the offset's prediction ages) the imaging
chain has locked onto something else, the plume or a star, and the measurement is refused; a run of refusals is
reported once. Before the recognition is trusted every measurement is accepted. Pure.

A lock that creeps (the plume's centroid pulled away a little more each frame) passes that frame-to-frame test, so
each line of sight is also judged by its residual from the continuous C/A estimate (``Prediction``), which only
accepted lines of sight shape: a rigid body on a straight-line flyby stays on the line of sight that estimate
predicts, to within the measurement noise (the centroid's, the attitude's and the estimate's own, combined) and the
apparent radius of Dimorphos (a centroid of the right blob lies on the body's disc). Beyond
``false_lock_residual_sigma`` of that noise past that radius the line of sight is refused, however slowly it got
there: the creep accumulates against the estimate instead of moving it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from obsw.config import FdirConfig
from obsw.recognition import measured_theta_rad
from obsw.tracking import offset_rotvec
from obsw.trajectory import NominalTrajectory


@dataclass(frozen=True, slots=True)
class GateResult:
    """What the gate made of one measurement: the test that decided (the one furthest past its bound) with its
    figure and bound."""

    accepted: bool
    innovation_rad: float
    gate_rad: float


@dataclass(frozen=True, slots=True)
class Prediction:
    """What the continuous C/A estimate predicts of the target's line of sight at the measurement's exposure."""

    theta_rad: float  # in-plane angle from the relative velocity (obsw.recognition.measured_theta_rad)
    sigma_rad: float  # its one-sigma from the estimate's covariance
    noise_rad: float  # one-sigma of the measurement: centroid and attitude combined
    radius_rad: float  # apparent radius of Dimorphos at the estimate's range


def residual_rad(trajectory: NominalTrajectory, prediction: Prediction, los: NDArray[np.float64]) -> float:
    """Angle between ``los`` (inertial unit vector) and the predicted line of sight: the in-plane residual from the
    predicted angle and the out-of-plane angle (the flyby plane holds every line of sight), combined."""
    in_plane = measured_theta_rad(trajectory, los) - prediction.theta_rad
    out_of_plane = math.asin(max(-1.0, min(1.0, float(los @ trajectory.plane_normal))))
    return math.hypot(in_plane, out_of_plane)


def residual_bound_rad(cfg: FdirConfig, prediction: Prediction) -> float:
    """Largest residual of a line of sight to Dimorphos: the body's apparent radius plus
    ``false_lock_residual_sigma`` of the measurement's and the prediction's noise combined."""
    return prediction.radius_rad + cfg.false_lock_residual_sigma * math.hypot(prediction.noise_rad,
                                                                              prediction.sigma_rad)


class LockGate:
    """The last accepted measurement and the run of refusals since."""

    def __init__(self, cfg: FdirConfig) -> None:
        self.cfg = cfg
        self._last: tuple[float, NDArray[np.float64]] | None = None
        self.rejected = 0  # refused since start
        self.run = 0  # refused since the last accepted one

    def check(self, trajectory: NominalTrajectory | None, obt_s: float, los: NDArray[np.float64],
              prediction: Prediction | None = None) -> GateResult:
        """Judge the line of sight ``los`` (inertial) exposed at ``obt_s`` against ``trajectory`` (None: the
        recognition is not trusted yet, accept) and, if given, against the continuous estimate's ``prediction``."""
        if trajectory is None:
            self._accept(obt_s, los)
            return GateResult(True, 0.0, 0.0)
        tests: list[tuple[float, float]] = []
        if self._last is not None:
            t0, los0 = self._last
            y = offset_rotvec(trajectory.los_inertial(obt_s), los)
            y0 = offset_rotvec(trajectory.los_inertial(t0), los0)
            tests.append((float(np.linalg.norm(y - y0)), math.radians(
                self.cfg.false_lock_gate_deg + self.cfg.false_lock_gate_growth_deg_s * abs(obt_s - t0))))
        if prediction is not None:
            tests.append((residual_rad(trajectory, prediction, los), residual_bound_rad(self.cfg, prediction)))
        if not tests:
            self._accept(obt_s, los)
            return GateResult(True, 0.0, 0.0)
        value, bound = max(tests, key=lambda vb: vb[0] / vb[1])
        if value > bound:
            self.rejected += 1
            self.run += 1
            return GateResult(False, value, bound)
        self._accept(obt_s, los)
        return GateResult(True, value, bound)

    def _accept(self, obt_s: float, los: NDArray[np.float64]) -> None:
        self._last = (obt_s, np.asarray(los, dtype=float))
        self.run = 0

    def shift(self, step_s: float) -> None:
        """On-board time stepped: move the last accepted measurement's time with it."""
        if self._last is not None:
            self._last = (self._last[0] + step_s, self._last[1])
