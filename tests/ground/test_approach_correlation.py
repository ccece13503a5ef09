"""Ground's OBT-UTC fit from the approach's time reports matches the true oscillator within its stated bound."""

from __future__ import annotations

from pathlib import Path

from contracts.cuc import TICK_S
from scenario.model import load_run_inputs
from scenario import compose

SCENARIO = Path(__file__).parents[2] / "configs" / "scenarios" / "clock-drift.yaml"


def test_correlation_over_the_approach_meets_its_bound() -> None:
    """20 ppm, 0.75 s offset, ten days of reports: OBT predicted at C/A within the worst-case bound of the fit."""
    sc, timeline = load_run_inputs(SCENARIO)
    u = compose.universe(sc)
    g = compose.ground_segment(sc, timeline)
    u.begin()
    gs = u.ground_step()
    g.step(gs.utc_s, gs.downlink, gs.downlink_utc_s)
    c = g.correlation
    assert c.n_reports >= 3
    osc = sc.universe.oscillator
    # each stamp is off the model by at most the clipped jitter plus half a CUC tick
    envelope = osc.jitter_bound_sigma * osc.jitter_s + TICK_S / 2
    ca = sc.universe.flyby.ca_time_s
    error = c.to_obt(ca) - u.oscillator.obt_mean_s(ca)
    assert abs(error) <= c.obt_error_bound_s(ca, envelope)
    assert abs(c.drift_ppm - osc.drift_ppm) < 1e-3
    # without the fit, ground's a priori clock would be off by the whole launch offset error
    assert abs(g.cfg.a_priori_obt_offset_s - osc.initial_offset_s) > 0.5
