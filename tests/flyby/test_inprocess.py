"""The in-process runner: the three cores exchanging what the nodes exchange, to the end of the run."""

from __future__ import annotations

from flyby.inprocess import run_in_process
from scenario.model import scenario_from_dict


def test_a_link_too_slow_to_drain_stops_at_the_drain_limit() -> None:
    """Telemetry still in flight drain_limit_s after the run's end is dropped, counted as lost and logged: a slow
    link's backlog never holds the run for days."""
    sc = scenario_from_dict({"name": "slow", "universe": {"drain_limit_s": 60.0, "link": {"downlink_rate_bps": 1e-3}}})
    out = run_in_process(sc, None, max_steps=20)
    assert any("still in flight 60 s after the run's end (universe.drain_limit_s): dropped" in x for x in out.log)
    assert out.received == []  # one bit per 1000 s: nothing arrived
