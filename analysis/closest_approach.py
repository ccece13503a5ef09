"""The true closest approach (C/A) of a run: to Dimorphos, the body the camera measures, and to the Didymos
barycentre, the point the scenario's flyby (``universe.flyby``) is defined about.

The C/A to Dimorphos comes from the truth. Where the truth holds the smallest range to Dimorphos between two
other rows, it is the vertex of the parabola through the squared range of those three rows: on a straight line
past a point, range^2 = d^2 + v^2 (t - t_ca)^2 is exactly a parabola, and Dimorphos' orbital motion (0.17 m/s,
curving over 12 h) makes it one to well under a millimetre over 0.2 s. Where the truth stops before (or starts
after) C/A, a straight line fitted to the spacecraft-to-Dimorphos vectors (range times line of sight) is solved
for its closest point. Without any truth, the scenario's geometry is sampled around its C/A and solved the same way.
Times become on-board time through the truth's (t_s, obt_s), or the oscillator model outside the truth.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from scenario.model import Scenario
from universe.geometry import FlybyGeometry
from universe.oscillator import Oscillator, clock_jumps_s
from analysis.truth import Truth

GEOMETRY_HALF_SPAN_S = 10.0  # scenario geometry sampled over C/A +- this, s: Dimorphos' curve bends it by ~1 mm


@dataclass(frozen=True)
class ClosestApproach:
    """A closest approach: true time (s after the scenario epoch), on-board time, distance, and how each was found."""

    t_s: float
    obt_s: float
    distance_km: float
    how: str


def parabola_vertex(t_s: NDArray[np.float64], y: NDArray[np.float64]) -> tuple[float, float] | None:
    """(t, y) of the vertex of the parabola through three points; None if it opens downward or is degenerate."""
    t0, t1, t2 = (float(v) for v in t_s)
    y0, y1, y2 = (float(v) for v in y)
    if not t0 < t1 < t2:
        return None
    f01, f12 = (y1 - y0) / (t1 - t0), (y2 - y1) / (t2 - t1)  # Newton's divided differences
    a = (f12 - f01) / (t2 - t0)
    if not a > 0.0:
        return None
    t = 0.5 * (t0 + t1) - f01 / (2.0 * a)  # where y0 + f01 (t - t0) + a (t - t0)(t - t1) has zero slope
    return t, y0 + f01 * (t - t0) + a * (t - t0) * (t - t1)


def straight_line_ca(t_s: NDArray[np.float64], rel_m: NDArray[np.float64]) -> tuple[float, float] | None:
    """(t_ca s, d_ca m) of the line fitted (least squares) to positions rel_m (N, 3) at times t_s: the time and
    distance of its closest point to the origin; None with fewer than two distinct times or no motion."""
    t = np.asarray(t_s, dtype=float)
    if t.size < 2 or np.ptp(t) <= 0.0:
        return None
    tm = float(t.mean())
    a = rel_m.mean(axis=0)  # the line's point at tm
    b = ((t - tm)[:, None] * (rel_m - a)).sum(axis=0) / float(((t - tm) ** 2).sum())  # its velocity
    vv = float(b @ b)
    if vv <= 0.0:
        return None
    t_ca = tm - float(a @ b) / vv
    return t_ca, float(np.linalg.norm(a + b * (t_ca - tm)))


def obt_of_true_time(scenario: Scenario, truth: Truth | None, t_s: float) -> tuple[float, str]:
    """On-board time of a true time, s, and how: the truth's (t_s, obt_s) interpolated, or the oscillator model."""
    if truth is not None and len(truth) >= 2 and truth.t_s[0] <= t_s <= truth.t_s[-1]:
        return float(np.interp(t_s, truth.t_s, truth.obt_s)), "OBT from the truth"
    u = scenario.universe
    # obt_mean_s is the jitter-free model: the generator is never drawn from
    osc = Oscillator(u.oscillator, np.random.default_rng(0), clock_jumps_s(u.faults))
    return float(osc.obt_mean_s(t_s)), "OBT from the oscillator model (the truth does not reach it)"


def _dimorphos_true_time(scenario: Scenario, truth: Truth | None) -> tuple[float, float, str]:
    """(t_s, d_m, how) of the closest approach to Dimorphos, from the truth where it can be."""
    if truth is not None and len(truth) >= 3:
        r = truth.range_m
        if np.isfinite(r).any():
            i = int(np.nanargmin(r))
            if 0 < i < len(truth) - 1 and np.all(np.isfinite(r[i - 1 : i + 2])):
                vertex = parabola_vertex(truth.t_s[i - 1 : i + 2], r[i - 1 : i + 2] ** 2)
                if vertex is not None:
                    return vertex[0], float(np.sqrt(max(vertex[1], 0.0))), "parabola through the truth's range^2"
    if truth is not None:
        rel = truth.range_m[:, None] * truth.los_dimorphos_inertial
        ok = np.all(np.isfinite(rel), axis=1)
        line = straight_line_ca(truth.t_s[ok], rel[ok])
        if line is not None:
            return *line, "straight line fitted to the truth's range x line of sight (C/A outside the truth)"
    u = scenario.universe
    g = FlybyGeometry(u.flyby, u.bodies)
    t = u.flyby.ca_time_s + np.linspace(-GEOMETRY_HALF_SPAN_S, GEOMETRY_HALF_SPAN_S, 21)
    line = straight_line_ca(t, g.dimorphos_position_m(t) - g.spacecraft_position_m(t))
    assert line is not None  # the scenario's flyby has a non-zero speed (validated)
    return *line, "the scenario's geometry (no truth with ranges and lines of sight)"


def dimorphos_ca(scenario: Scenario, truth: Truth | None) -> ClosestApproach:
    """The true closest approach of the spacecraft to Dimorphos (see the module docstring for how)."""
    t, d_m, how = _dimorphos_true_time(scenario, truth)
    obt, obt_how = obt_of_true_time(scenario, truth, t)
    return ClosestApproach(t_s=t, obt_s=obt, distance_km=d_m / 1e3, how=f"{how}; {obt_how}")


def didymos_barycentre_ca(scenario: Scenario, truth: Truth | None) -> ClosestApproach:
    """The closest approach to the Didymos barycentre: the scenario's ``universe.flyby`` by construction."""
    f = scenario.universe.flyby
    obt, obt_how = obt_of_true_time(scenario, truth, f.ca_time_s)
    return ClosestApproach(t_s=f.ca_time_s, obt_s=obt, distance_km=f.ca_distance_km,
                           how=f"the scenario's universe.flyby; {obt_how}")
