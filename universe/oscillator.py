"""The on-board oscillator: how the spacecraft's clock (OBT) reads against true time.

Model (true time ``t`` in s after the scenario epoch, OBT in s)::

    obt_model(t) = t + offset + d * t + r * t**2 / 2 + sum(delta_i for every jump i with at_i <= t)

with ``d = drift_ppm * 1e-6`` (fractional frequency error at the epoch) and
``r = drift_rate_ppm_per_day * 1e-6 / 86400`` (its change per second). The model is only defined while the
oscillator runs forward, i.e. while its rate ``1 + d + r * t`` is positive; outside that it raises.

Readings and the jitter rule. The hardware latches the counter once per tick, in true-time order, so
``obt_s`` must be called with non-decreasing true time. Each reading is the model plus a white Gaussian
jitter clipped at ``jitter_bound_sigma`` sigmas (``b = jitter_bound_sigma * jitter_s``), floored so that
OBT never runs backwards except by a commanded or injected jump::

    reading_k = max(reading_{k-1} + sum(jumps in (t_{k-1}, t_k]), obt_model(t_k) + e_k),   |e_k| <= b

which guarantees both (induction on k, using that the model rises between jumps):

- ``|reading_k - obt_model(t_k)| <= b`` (jitter stays bounded), and
- ``reading_k - reading_{k-1} >= sum of the jumps crossed`` (monotonic between jumps; across a jump OBT moves
  by at least the jump).

The inverse ``true_s(obt)`` is that of the jitter-free model, generalised over jumps as "the first true time
at which the clock reads at least ``obt``": exact between jumps, and what a scheduler releasing at the first
tick at or after a tag sees when a backward jump makes a reading happen twice.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Iterable, Sequence

import numpy as np

from universe.config import FaultConfig, OscillatorConfig

SECONDS_PER_DAY = 86400.0


class ClockModelError(ValueError):
    """The oscillator was configured, read or jumped outside what its model defines; the message says why."""


def clock_jumps_s(faults: Sequence[FaultConfig]) -> list[tuple[float, float]]:
    """The (true time s, OBT step s) of every ``clock_jump`` fault: it steps OBT at its ``start_s`` by ``magnitude``."""
    jumps = []
    for i, f in enumerate(faults):
        if f.kind != "clock_jump":
            continue
        if f.magnitude is None:
            raise ClockModelError(f"faults[{i}] (clock_jump at {f.start_s} s) has no magnitude: the OBT step, s")
        jumps.append((f.start_s, f.magnitude))
    return jumps


class Oscillator:
    """The on-board clock: reads OBT at true times, with offset, drift, drift rate, bounded jitter and jumps."""

    def __init__(
        self,
        cfg: OscillatorConfig,
        rng: np.random.Generator,
        jumps: Iterable[tuple[float, float]] = (),
    ) -> None:
        """Build the clock of ``cfg``; ``jumps`` are (true time s, OBT step s) pairs, e.g. ``clock_jumps_s(faults)``."""
        self.cfg = cfg
        self._rng = rng
        self._d = cfg.drift_ppm * 1e-6
        self._r = cfg.drift_rate_ppm_per_day * 1e-6 / SECONDS_PER_DAY
        if 1.0 + self._d <= 0.0:
            raise ClockModelError(f"drift_ppm={cfg.drift_ppm} stops or reverses the clock: it must be > -1e6")
        self._bound_s = cfg.jitter_bound_sigma * cfg.jitter_s
        # jump times, sorted, and the cumulative OBT step in force from each of them on
        self._jump_at: list[float] = []
        self._jump_delta: list[float] = []
        self._last_t: float | None = None
        self._last_obt: float | None = None
        for at, delta in sorted(jumps):
            self.jump(at, delta)

    # --- the jitter-free model -------------------------------------------------------------------

    def rate(self, t_true_s: float) -> float:
        """d OBT / d true time of the model at ``t_true_s`` (1 for a perfect clock)."""
        return 1.0 + self._d + self._r * t_true_s

    def _base_s(self, t: float) -> float:
        return t + self.cfg.initial_offset_s + self._d * t + 0.5 * self._r * t * t

    def _base_inverse_s(self, y: float) -> float:
        """True time at which the jump-free model reads ``y`` (root on the rising branch; inf if never)."""
        b = 1.0 + self._d
        u = y - self.cfg.initial_offset_s
        disc = b * b + 2.0 * self._r * u
        if disc < 0.0:
            return math.inf  # a decelerating clock (r < 0) stops before it reads y
        # rationalised root: no cancellation when r is tiny (or zero)
        return 2.0 * u / (b + math.sqrt(disc))

    def _check_domain(self, t: float) -> None:
        if not math.isfinite(t):
            raise ClockModelError(f"true time must be finite, got {t}")
        if self.rate(t) <= 0.0:
            raise ClockModelError(
                f"true time {t} s is outside the oscillator model: "
                f"its rate 1 + d + r t = {self.rate(t)} is not positive"
            )

    def _jumps_up_to(self, t: float) -> float:
        """Sum of the jumps with at <= t."""
        return sum(self._jump_delta[: bisect.bisect_right(self._jump_at, t)])

    def obt_mean_s(self, t_true_s: float) -> float:
        """OBT of the jitter-free model at ``t_true_s`` (pure: any order, no state change)."""
        self._check_domain(t_true_s)
        return self._base_s(t_true_s) + self._jumps_up_to(t_true_s)

    def true_s(self, obt_s: float) -> float:
        """First true time at which the jitter-free clock reads at least ``obt_s`` (its inverse between jumps)."""
        if not math.isfinite(obt_s):
            raise ClockModelError(f"OBT must be finite, got {obt_s}")
        starts = [-math.inf, *self._jump_at]
        ends = [*self._jump_at, math.inf]
        cumulative = 0.0
        for i, (start, end) in enumerate(zip(starts, ends, strict=True)):
            if i > 0:
                cumulative += self._jump_delta[i - 1]
            t = max(start, self._base_inverse_s(obt_s - cumulative))
            if t < end:
                self._check_domain(t)
                return t
        raise ClockModelError(
            f"OBT {obt_s} s is never reached: the clock (drift_rate_ppm_per_day="
            f"{self.cfg.drift_rate_ppm_per_day}) stops before it"
        )

    # --- readings and jumps ------------------------------------------------------------------------

    def obt_s(self, t_true_s: float) -> float:
        """One OBT reading at ``t_true_s`` (non-decreasing true times): model + bounded jitter, never backwards."""
        self._check_domain(t_true_s)
        if self._last_t is not None and t_true_s < self._last_t:
            raise ClockModelError(
                f"OBT readings must come in true-time order: "
                f"{t_true_s} s is before the last reading at {self._last_t} s"
            )
        # obt_mean_s, its domain checked just above; without jumps their sums are all the integer 0, as _jumps_up_to's
        jumps = self._jumps_up_to(t_true_s) if self._jump_at else 0
        reading = self._base_s(t_true_s) + jumps
        if self._bound_s > 0.0:
            e = float(self._rng.normal(0.0, self.cfg.jitter_s))
            reading += min(max(e, -self._bound_s), self._bound_s)
        if self._last_t is not None and self._last_obt is not None:
            crossed = jumps - self._jumps_up_to(self._last_t) if self._jump_at else 0
            reading = max(reading, self._last_obt + crossed)
        self._last_t = t_true_s
        self._last_obt = reading
        return reading

    def jump(self, at_true_s: float, delta_s: float) -> None:
        """Step OBT by ``delta_s`` from true time ``at_true_s`` on (later than every reading already taken)."""
        if not (math.isfinite(at_true_s) and math.isfinite(delta_s)):
            raise ClockModelError(f"a clock jump needs a finite time and step, got at={at_true_s}, delta={delta_s}")
        if self._last_t is not None and at_true_s <= self._last_t:
            raise ClockModelError(
                f"a clock jump at {at_true_s} s would rewrite the reading already taken at {self._last_t} s"
            )
        i = bisect.bisect_right(self._jump_at, at_true_s)
        self._jump_at.insert(i, at_true_s)
        self._jump_delta.insert(i, delta_s)

    @property
    def jumps(self) -> list[tuple[float, float]]:
        """Every jump as (true time s, OBT step s), in time order."""
        return list(zip(self._jump_at, self._jump_delta, strict=True))
