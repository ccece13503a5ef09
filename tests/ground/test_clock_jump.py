"""Ground's time correlation follows an on-board time step reported by a ClockJumpEvent."""

from __future__ import annotations

import pytest

from contracts import pus
from scenario.model import scenario_from_dict
from scenario import compose

OFFSET_S, DRIFT = 1_000.0, 20e-6  # the true clock before the step: OBT = offset + (1 + drift) UTC


def downlink(seg: GroundSegment, reports: list[tuple[pus.TmReport, float]], step_s: float, first_seq: int):
    """Give ``seg`` the (report, generation UTC) pairs as TM stamped by the clock stepped by ``step_s``, each arriving
    one light time plus its transmission time after it was generated."""
    raws, arrivals = [], []
    for k, (report, utc) in enumerate(reports):
        raw = pus.encode_tm(report, seg.cfg.apid, first_seq + k, OFFSET_S + step_s + (1 + DRIFT) * utc, first_seq + k)
        raws.append(raw)
        arrivals.append(utc + seg.cfg.link.one_way_light_time_s + len(raw) * 8.0 / seg.cfg.link.downlink_rate_bps)
    return seg.step(arrivals[-1], tuple(raws), tuple(arrivals))


def time_reports(utc: range, step_s: float) -> list[tuple[pus.TmReport, float]]:
    """Time reports of the clock stepped by ``step_s`` at the given generation UTCs."""
    return [(pus.TimeReport(obt_s=OFFSET_S + step_s + (1 + DRIFT) * t), float(t)) for t in utc]


@pytest.mark.parametrize("step_s", [5.0, -0.75])
def test_reports_before_a_clock_step_are_moved_onto_the_new_time_scale(step_s: float) -> None:
    """20 reports, a step of the clock, 20 more: the fit is the stepped clock's line (offset + step, same drift)."""
    seg = compose.ground_segment(scenario_from_dict({"name": "x"}))
    downlink(seg, time_reports(range(0, 200, 10), 0.0), 0.0, 0)
    _, _, log = downlink(seg, [(pus.ClockJumpEvent(step_s=step_s), 200.0)], step_s, 20)
    assert any("moved by the on-board time step" in line for line in log)
    downlink(seg, time_reports(range(205, 400, 10), step_s), step_s, 21)
    c = seg.correlation
    assert c.n_reports >= 20
    assert c.offset_s == pytest.approx(OFFSET_S + step_s, abs=1e-3)
    assert c.drift_ppm == pytest.approx(DRIFT * 1e6, abs=0.05)
    assert c.residual_rms_s < 1e-3  # a fit through the step would leave residuals of a good part of the step
