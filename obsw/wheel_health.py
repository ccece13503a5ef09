"""Reaction wheel health: a wheel that does not follow its torque commands is found failed (stopped or stuck).

A wheel's axial momentum ``h = J (a . w + W)`` (rotor inertia ``J``, body rate ``w`` along its axis ``a``, rotor
speed ``W`` from the tachometer) changes only by the motor torque less friction. Over a window of
``wheel_window_s``, the impulse commanded to each wheel (the torques of each period, the previous one until the
control task's modelled finish) is compared with the measured change of ``h``: a healthy wheel's difference is its
friction, a failed wheel (no motor torque) or a stuck one (rotor locked to the body) misses most of the impulse.
A wheel is judged only over a window where its commanded impulse is large enough to tell (``wheel_min_impulse_nms``)
and its momentum is clear of the limit (where the hardware cuts the torque). ``wheel_confirmations`` windows in a
row confirm the failure. Pure: momenta and commands come as arguments.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from obsw.config import FdirConfig


@dataclass(frozen=True, slots=True)
class WheelFailure:
    """A wheel found failed: the impulse commanded over the last window and the momentum change measured."""

    wheel: int
    commanded_nms: float
    measured_nms: float


class WheelHealth:
    """The wheel failure detector; one ``update`` per control period."""

    def __init__(self, cfg: FdirConfig, n_wheels: int, max_momentum_nms: float) -> None:
        self.cfg = cfg
        self.n = n_wheels
        self.max_momentum_nms = max_momentum_nms
        self.failed: set[int] = set()
        # per wheel in Python floats and bools: the same arithmetic as NumPy's on three or four values, a quarter of
        # the cost a period
        self._start: list[float] | None = None
        self._impulse = [0.0] * n_wheels
        self._elapsed_s = 0.0
        self._near_limit = [False] * n_wheels
        self._strikes = [0] * n_wheels

    @property
    def failed_mask(self) -> int:
        """Bit k set for wheel k found failed."""
        return sum(1 << k for k in self.failed)

    def update(self, momentum_nms: NDArray[np.float64], impulse_nms: NDArray[np.float64] | tuple[float, ...],
               dt_s: float) -> list[WheelFailure]:
        """Take this period's measured wheel momenta and the impulse commanded to each wheel over the period that
        ended here; return the wheels newly found failed."""
        h = np.asarray(momentum_nms, dtype=float).reshape(-1).tolist()
        if len(h) != self.n:
            raise ValueError(f"momentum_nms must have {self.n} values, got {len(h)}")
        if self._start is None:
            self._start = h
            return []
        impulse = np.asarray(impulse_nms, dtype=float).reshape(-1).tolist()
        if len(impulse) != self.n:
            raise ValueError(f"impulse_nms must have {self.n} values, got {len(impulse)}")
        self._impulse = [total + new for total, new in zip(self._impulse, impulse)]
        self._elapsed_s += dt_s
        limit = self.cfg.wheel_limit_fraction * self.max_momentum_nms
        self._near_limit = [near or abs(x) >= limit for near, x in zip(self._near_limit, h)]
        if self._elapsed_s < self.cfg.wheel_window_s - 1e-9:
            return []
        out = []
        for k in range(self.n):
            if k in self.failed:
                continue
            commanded = self._impulse[k]
            if self._near_limit[k] or abs(commanded) < self.cfg.wheel_min_impulse_nms:
                continue  # nothing to judge by: keep the count of windows that were
            measured = h[k] - self._start[k]
            if abs(measured - commanded) > self.cfg.wheel_missed_fraction * abs(commanded):
                self._strikes[k] += 1
            else:
                self._strikes[k] = 0
            if self._strikes[k] >= self.cfg.wheel_confirmations:
                self.failed.add(k)
                out.append(WheelFailure(k, commanded, measured))
        self._start, self._impulse, self._elapsed_s = h, [0.0] * self.n, 0.0
        self._near_limit = [False] * self.n
        return out
