"""A run judged against its scenario's ``expect:`` block (``scenario.expectation``): one check per expectation, each
with the figure that decided it, and the detection latency of every expected event.

Besides the block, every run must end without a node failure and with finite truth: a crash or a NaN is a failed
check whatever the scenario expects.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from analysis.runfolder import RunData
from analysis.scoring import RunFigures
from contracts import pus
from contracts.messages import TruthRecord
from scenario.expectation import Expectation


@dataclass(frozen=True)
class Check:
    """One expectation: what was expected, whether it held, and the figure that decided it."""

    name: str
    passed: bool
    detail: str


@dataclass
class Verdict:
    """Every check of one run, and the detection latency of each expected event (None: it never came)."""

    checks: list[Check] = field(default_factory=list)
    latencies: dict[str, float | None] = field(default_factory=dict)
    fault_start_s: float | None = None

    @property
    def passed(self) -> bool:
        """Every check held."""
        return all(c.passed for c in self.checks)

    @property
    def failures(self) -> list[Check]:
        """The checks that did not hold."""
        return [c for c in self.checks if not c.passed]


def nonfinite_truth(records: list[TruthRecord]) -> str | None:
    """The first truth record with a non-finite value (a tuple field, or a frame's true target position), or None."""
    for rec in records:
        for name, value in rec.model_dump().items():
            values = value if isinstance(value, (tuple, list)) else (value,)
            if any(isinstance(x, float) and not math.isfinite(x) for x in values):
                return f"t = {rec.t_s:.2f} s: {name} = {value}"
    return None


def _obt_to_true_s(data: RunData, obt_s: float) -> float:
    truth = data.truth
    assert truth is not None
    return float(np.interp(obt_s, truth.obt_s, truth.t_s))


def judge(data: RunData, figures: RunFigures, error: str | None, nonfinite: str | None,
          ground_log: list[str]) -> Verdict:
    """Check the run of ``data`` against its scenario's expectations; ``error``: why the run failed (None: it ran to
    its end); ``nonfinite``: the first non-finite truth (``nonfinite_truth``)."""
    sc = data.scenario
    expect = sc.expect or Expectation()
    v = Verdict()
    faults = sorted(f.start_s for f in sc.universe.faults)
    v.fault_start_s = faults[0] if faults else None
    v.checks.append(Check("ran to the end without a node failure", error is None, error or "ran to the end"))
    v.checks.append(Check("finite truth", nonfinite is None, nonfinite or "every truth value finite"))
    tm, truth = data.telemetry, data.truth
    if expect.in_view_min is not None:
        f = figures.in_view_fraction
        v.checks.append(Check(f"target in view >= {100 * expect.in_view_min:g} %",
                              f is not None and f >= expect.in_view_min,
                              "no truth in the window" if f is None else f"{100 * f:.2f} % of {figures.in_view_basis}"))
    if expect.pointing_error_max_deg is not None:
        e = figures.max_pointing_error_deg
        v.checks.append(Check(f"pointing error <= {expect.pointing_error_max_deg:g} deg",
                              e is not None and e <= expect.pointing_error_max_deg,
                              "no truth in the window" if e is None else f"{e:.3f} deg max"))
    if expect.paper_requirements:
        rows = figures.requirement_rows()
        failed = [r.requirement for r in rows if r.passed is not True]
        v.checks.append(Check("every requirement of the paper", not failed,
                              "; ".join(f"{r.requirement}: {r.figure}" for r in rows)))
    events = [] if tm is None else tm.events
    start = v.fault_start_s if v.fault_start_s is not None else sc.universe.start_s
    for want in expect.events:
        # earliest first by on-board time: the archive's order is the order of receipt, not of detection
        found = sorted(((t, e) for t, e in events if type(e).__name__ == want.event
                        and (want.severity is None or e.severity.name == want.severity)), key=lambda te: te[0])
        what = want.event + (f" ({want.severity})" if want.severity else "")
        latency = None if not found or truth is None else _obt_to_true_s(data, found[0][0]) - start
        v.latencies[want.event] = latency
        ok = len(found) >= want.count_min and (want.within_s is None or (latency is not None and
                                                                        0 <= latency <= want.within_s))
        bound = "" if want.within_s is None else f" within {want.within_s:g} s"
        detail = f"{len(found)} reported" + ("" if latency is None else f", the first {latency:+.2f} s after the "
                                             f"{'fault' if faults else 'run'} began")
        v.checks.append(Check(f"{what} reported{bound}" + (f" (at least {want.count_min})" if want.count_min > 1
                                                          else ""), ok, detail))
    for name in expect.no_events:
        n = sum(type(e).__name__ == name for _, e in events)
        v.checks.append(Check(f"no {name}", n == 0, f"{n} reported"))
    if expect.final_mode is not None:
        last = tm.housekeeping.last[1].mode if tm is not None and tm.housekeeping.last is not None else None
        v.checks.append(Check(f"final mode {expect.final_mode.name}", last == expect.final_mode,
                              "no housekeeping" if last is None else f"{pus.Mode(last).name} in the last housekeeping"))
    if expect.wheel_momentum_max_nms is not None:
        peak = None
        if truth is not None:
            rows = truth.t_s >= start
            peak = float(np.max(np.abs(truth.wheel_momentum_nms[rows]))) if rows.any() else None
        v.checks.append(Check(f"wheel momentum <= {expect.wheel_momentum_max_nms:g} N m s",
                              peak is not None and peak <= expect.wheel_momentum_max_nms,
                              "no truth" if peak is None else f"{peak:.4f} N m s at most"))
    for text in expect.ground_lines:
        n = sum(text in line for line in ground_log)
        v.checks.append(Check(f"ground says {text!r}", n > 0, f"{n} line(s)"))
    return v
