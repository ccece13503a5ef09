"""Tests of analysis.candidates: the analysis rebuilds the nominal trajectory ground uploads."""

from __future__ import annotations

from pathlib import Path

import pytest

from analysis.candidates import uploaded_nominal
from scenario import compose
from scenario.model import load_run_inputs

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("name", ["nominal.yaml", "detector.yaml", "worst-early-far.yaml"])
def test_uploaded_nominal_is_the_one_the_calibrated_ground_uploads(name: str) -> None:
    """The nominal the analysis rebuilds (without the bad-pixel calibration) is the one ground uploads in a run."""
    scenario, _ = load_run_inputs(ROOT / "configs" / "scenarios" / name)
    tc = compose.ground_segment(scenario).nominal_trajectory_tc()
    nominal = uploaded_nominal(scenario)
    assert (nominal.ca_time_obt_s, nominal.ca_distance_km, nominal.speed_km_s) == (
        tc.ca_obt_s, tc.ca_distance_km, tc.speed_km_s)
    assert tuple(nominal.approach_direction) == tuple(tc.approach_direction)
    assert tuple(nominal.ca_direction) == tuple(tc.ca_direction)
    assert (nominal.ca_time_sigma_s, nominal.ca_distance_sigma_km) == (tc.sigma_ca_time_s, tc.sigma_ca_distance_km)
