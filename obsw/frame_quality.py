"""Camera frames that cannot be used: missing (requested, never delivered), saturated or blank, by image statistics.

- saturated: at least ``frame_saturated_fraction`` of a sample of the raw pixels (every
  ``frame_sample_stride``-th row and column) is at full scale, which no scene of the flyby gives (a lit surface at
  zero phase sits near 90 % of the range);
- blank: nothing in the frame is large enough to be a body (no region of ``imaging.min_body_area_px``) although
  the target was seen in the previous frame: no light from the scene, a blind camera or a target gone within a
  frame period, either way no measurement;
- missing: a frame requested at a tick has not arrived ``frame_timeout_s`` later (a frame requested at one tick is
  exposed at the next).

A discarded frame gives no line of sight; the control holds on the trajectory's prediction. Pure.
"""

from __future__ import annotations

import numpy as np

from contracts import pus
from obsw.config import FdirConfig


def saturated_fraction(frame: np.ndarray, bit_depth: int, stride: int) -> float:
    """Fraction of the sampled raw pixels at full scale."""
    sample = frame[::stride, ::stride]
    return float(np.count_nonzero(sample >= (1 << bit_depth) - 1)) / sample.size


class FrameWatch:
    """Frames requested and not yet delivered, and whether the run of unusable frames has been reported."""

    def __init__(self, cfg: FdirConfig) -> None:
        self.cfg = cfg
        self._pending: list[float] = []  # OBT of the ticks that requested a frame still to come
        self.discarded = 0
        self.reporting: pus.FrameAnomaly | None = None  # the anomaly of the run being reported (None: frames fine)

    def requested(self, obt_s: float) -> None:
        """A frame was requested at this tick."""
        self._pending.append(obt_s)

    def delivered(self, exposure_obt_s: float) -> None:
        """A frame arrived, exposed at ``exposure_obt_s``: the latest request before it is served (an older one was
        lost, and stays to be found overdue)."""
        for i in range(len(self._pending) - 1, -1, -1):
            if self._pending[i] <= exposure_obt_s + 1e-9:
                del self._pending[i]
                return

    def overdue(self, now_obt_s: float) -> float | None:
        """How long the oldest request is overdue, s, and it is forgotten; None if none is."""
        if self._pending and now_obt_s - self._pending[0] > self.cfg.frame_timeout_s:
            return now_obt_s - self._pending.pop(0)
        return None

    def anomaly(self, kind: pus.FrameAnomaly) -> bool:
        """Count an unusable frame; whether it opens a new run of them (to report)."""
        self.discarded += 1
        new = self.reporting != kind
        self.reporting = kind
        return new

    def good(self) -> None:
        """A usable frame ends the run of unusable ones."""
        self.reporting = None

    def shift(self, step_s: float) -> None:
        """On-board time stepped: move the pending requests with it."""
        self._pending = [t + step_s for t in self._pending]
