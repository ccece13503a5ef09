"""False lock: a measured line of sight that the recognised trajectory cannot explain is refused.

The recognised trajectory predicts how the line of sight to the target moves; between two frames the measured one
must follow it, up to the slowly varying offset of Dimorphos from the trajectory's barycentre and the trajectory's
own error. So the innovation of a measurement is the change of its offset from the recognised trajectory since the
last accepted measurement (both offsets against the same, current trajectory). Beyond ``false_lock_gate_deg`` (grown
by ``false_lock_gate_growth_deg_s`` per second since that measurement, as the offset's prediction ages) the imaging
chain has locked onto something else, the plume or a star, and the measurement is refused; a run of refusals is
reported once. Before the recognition is trusted every measurement is accepted. Pure.

A lock that creeps (the plume's centroid pulled away a little more each frame) passes that frame-to-frame test, so
each line of sight is also judged by its residual from a reference continuous C/A estimate (``Prediction``), which
only accepted lines of sight shape: a rigid body on a straight-line flyby stays on the line of sight that estimate
predicts (with the constant offsets of the measured line of sight it solves, a misaligned camera's: held at zero, a
0.04 deg misalignment had true lines of sight refused near C/A), to within the measurement noise (the centroid's,
the attitude's and the estimate's own, combined) and the apparent radius of Dimorphos (a centroid of the right blob
lies on the body's disc). Beyond ``false_lock_residual_sigma`` of that noise past that radius the line of sight is refused. The reference is the
estimate as it stood ``false_lock_reference_lag_s`` before the exposure (``ReferenceEstimates``), and during a run
of refusals the one that lag before the run's first: a creep absorbed little by little into the newest estimate
accumulates against that older one, and once refused it is judged against an estimate from before it began (if it
passed the bound within the lag), so it cannot drag its own reference along.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from obsw.config import FdirConfig
from obsw.recognition import ContinuousEstimate, measured_theta_rad, out_of_plane_rad, predicted_theta
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
    sigma_rad: float  # one-sigma of the predicted direction from the estimate's covariance, in and out of plane
    noise_rad: float  # one-sigma of the measurement: centroid and attitude combined
    radius_rad: float  # apparent radius of Dimorphos at the estimate's range
    out_of_plane_rad: float = 0.0  # angle out of the flyby plane (obsw.recognition.out_of_plane_rad)


@dataclass(frozen=True, slots=True)
class Estimate:
    """The recognition's continuous estimate (C/A, LOS offsets and covariance) as solved from the lines of sight
    exposed up to ``newest_obt_s``."""

    newest_obt_s: float
    solved: ContinuousEstimate

    def prediction(self, obt_s: float, speed_m_s: float, noise_rad: float, radius_m: float) -> Prediction:
        """What this estimate predicts at ``obt_s`` of the measured line of sight to a body of ``radius_m``, measured
        with ``noise_rad`` of one-sigma noise, on a flyby at ``speed_m_s``."""
        e = self.solved
        theta, sigma = predicted_theta(e.ca_time_obt_s, e.ca_distance_km, e.cov, speed_m_s, obt_s,
                                       e.in_plane_offset_rad)
        range_m = math.hypot(e.ca_distance_km * 1e3, speed_m_s * (obt_s - e.ca_time_obt_s))
        return Prediction(theta_rad=theta, sigma_rad=math.hypot(sigma, e.out_of_plane_sigma_rad),
                          noise_rad=noise_rad, radius_rad=radius_m / range_m,
                          out_of_plane_rad=e.out_of_plane_offset_rad)


class ReferenceEstimates:
    """The estimates solved over the last ``lag_s`` and the newest one before them, which is the reference."""

    def __init__(self, lag_s: float) -> None:
        self.lag_s = lag_s
        self._kept: deque[Estimate] = deque()

    def add(self, estimate: Estimate) -> None:
        """Keep ``estimate`` if it includes a line of sight newer than the last kept."""
        if not self._kept or estimate.newest_obt_s > self._kept[-1].newest_obt_s:
            self._kept.append(estimate)

    def reference(self, obt_s: float) -> Estimate | None:
        """The newest estimate from lines of sight exposed at least ``lag_s`` before ``obt_s`` (the oldest kept while
        none is that old; None before any); older ones are dropped."""
        horizon = obt_s - self.lag_s
        while len(self._kept) > 1 and self._kept[1].newest_obt_s <= horizon:
            self._kept.popleft()
        return self._kept[0] if self._kept else None

    def shift(self, step_s: float) -> None:
        """On-board time stepped: the kept estimates' times move with it."""
        self._kept = deque(Estimate(e.newest_obt_s + step_s,
                                    replace(e.solved, ca_time_obt_s=e.solved.ca_time_obt_s + step_s))
                           for e in self._kept)


def residual_rad(trajectory: NominalTrajectory, prediction: Prediction, los: NDArray[np.float64]) -> float:
    """Angle between ``los`` (inertial unit vector) and the predicted line of sight: the in-plane residual from the
    predicted angle and the out-of-plane one (the flyby plane holds every true line of sight; a measured one is off it
    by the estimated constant offset), combined."""
    in_plane = measured_theta_rad(trajectory, los) - prediction.theta_rad
    return math.hypot(in_plane, out_of_plane_rad(trajectory, los) - prediction.out_of_plane_rad)


def residual_bound_rad(cfg: FdirConfig, prediction: Prediction) -> float:
    """Largest residual of a line of sight to Dimorphos: the body's apparent radius plus
    ``false_lock_residual_sigma`` of the measurement's and the prediction's noise combined."""
    return prediction.radius_rad + cfg.false_lock_residual_sigma * math.hypot(prediction.noise_rad,
                                                                              prediction.sigma_rad)


class LockGate:
    """The last accepted measurement and the run of refusals since."""

    def __init__(self, cfg: FdirConfig) -> None:
        self.cfg = cfg
        self.references = ReferenceEstimates(cfg.false_lock_reference_lag_s)
        self._last: tuple[float, NDArray[np.float64]] | None = None
        self.rejected = 0  # refused since start
        self.run = 0  # refused since the last accepted one
        self._run_start_obt: float | None = None  # exposure of the run's first refusal

    def reference(self, obt_s: float) -> Estimate | None:
        """The reference estimate for a line of sight exposed at ``obt_s``: the estimate ``lag`` before it, or
        during a run of refusals ``lag`` before the run's first."""
        return self.references.reference(obt_s if self._run_start_obt is None else min(obt_s, self._run_start_obt))

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
            if self._run_start_obt is None:
                self._run_start_obt = obt_s
            return GateResult(False, value, bound)
        self._accept(obt_s, los)
        return GateResult(True, value, bound)

    def _accept(self, obt_s: float, los: NDArray[np.float64]) -> None:
        self._last = (obt_s, np.asarray(los, dtype=float))
        self.run = 0
        self._run_start_obt = None

    def shift(self, step_s: float) -> None:
        """On-board time stepped: move the last accepted measurement's time with it."""
        if self._last is not None:
            self._last = (self._last[0] + step_s, self._last[1])
        self.references.shift(step_s)
        if self._run_start_obt is not None:
            self._run_start_obt += step_s
