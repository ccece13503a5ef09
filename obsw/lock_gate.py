"""False lock: a measured line of sight that the recognised trajectory cannot explain is refused.

The recognised trajectory predicts how the line of sight to the target moves; between two frames the measured one
must follow it, up to the slowly varying offset of Dimorphos from the trajectory's barycentre and the trajectory's
own error. So the innovation of a measurement is the change of its offset from the recognised trajectory since the
last accepted measurement (both offsets against the same, current trajectory). Beyond ``false_lock_gate_deg`` (grown
by ``false_lock_gate_growth_deg_s`` per second since that measurement, as the offset's prediction ages) the imaging
chain has locked onto something else, the plume or a star, and the measurement is refused; a run of refusals is
reported once. Before the recognition is trusted every measurement is accepted. Pure.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from obsw.config import FdirConfig
from obsw.tracking import offset_rotvec
from obsw.trajectory import NominalTrajectory


@dataclass(frozen=True, slots=True)
class GateResult:
    """What the gate made of one measurement."""

    accepted: bool
    innovation_rad: float
    gate_rad: float


class LockGate:
    """The last accepted measurement and the run of refusals since."""

    def __init__(self, cfg: FdirConfig) -> None:
        self.cfg = cfg
        self._last: tuple[float, NDArray[np.float64]] | None = None
        self.rejected = 0  # refused since start
        self.run = 0  # refused since the last accepted one

    def check(self, trajectory: NominalTrajectory | None, obt_s: float, los: NDArray[np.float64]) -> GateResult:
        """Judge the line of sight ``los`` (inertial) exposed at ``obt_s`` against ``trajectory`` (None: the
        recognition is not trusted yet, accept)."""
        if trajectory is None or self._last is None:
            self._accept(obt_s, los)
            return GateResult(True, 0.0, 0.0)
        t0, los0 = self._last
        y = offset_rotvec(trajectory.los_inertial(obt_s), los)
        y0 = offset_rotvec(trajectory.los_inertial(t0), los0)
        innovation = float(np.linalg.norm(y - y0))
        gate = math.radians(self.cfg.false_lock_gate_deg + self.cfg.false_lock_gate_growth_deg_s * abs(obt_s - t0))
        if innovation > gate:
            self.rejected += 1
            self.run += 1
            return GateResult(False, innovation, gate)
        self._accept(obt_s, los)
        return GateResult(True, innovation, gate)

    def _accept(self, obt_s: float, los: NDArray[np.float64]) -> None:
        self._last = (obt_s, np.asarray(los, dtype=float))
        self.run = 0

    def shift(self, step_s: float) -> None:
        """On-board time stepped: move the last accepted measurement's time with it."""
        if self._last is not None:
            self._last = (self._last[0] + step_s, self._last[1])
