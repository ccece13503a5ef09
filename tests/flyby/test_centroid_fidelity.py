"""Centroid-level fidelity in the closed loop: the flight software flies on the universe's modelled measurements."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from analysis.runfolder import RunData
from analysis.scoring import centroid_errors_px
from analysis.telemetry import decoded_telemetry
from analysis.truth import Truth
from contracts.mode import Mode
from flyby.inprocess import run_in_process
from flyby.montecarlo.centroidfit import frame_samples
from scenario.model import load_run_inputs
from universe.config import CentroidModelConfig

ROOT = Path(__file__).resolve().parents[2]
PERFECT = CentroidModelConfig(phase_deg=(0.0,), bias_radius_fraction=(0.0,), dimorphos_dropout=(0.0,), noise_px=0.0,
                              noise_radius_fraction=0.0, merge_gap_px=(0.0,), merge_probability=(0.0,),
                              didymos_dropout=0.0, misidentification=0.0, misidentification_frames=1.0)


def test_a_perfect_measurement_model_reports_the_true_centroids_on_board() -> None:
    """With a model without error, every Dimorphos centroid the flight software reports (through the bus codec) is
    the truth's projection binned, so the report's scoring finds no centroid error, and tracking starts on it; the
    fit's frame samples rebuild the same projections from the truth records."""
    scenario, timeline = load_run_inputs(ROOT / "configs" / "scenarios" / "nominal.yaml")
    u = scenario.universe.model_copy(update={"fidelity": "centroid", "centroid_model": PERFECT})
    scenario = scenario.model_copy(update={"universe": u})
    frames_before_ca = int((u.flyby.ca_time_s - 20.0 - u.start_s) / u.control_period_s)
    run = run_in_process(scenario, timeline, through_codec=True, max_steps=frames_before_ca)
    tm = decoded_telemetry([p.raw for p in run.received], "in-process")
    data = RunData(Path("<in-process>"), scenario, Truth.from_records(run.truth), tm)
    ids, errs = centroid_errors_px(data)
    assert ids.size > 100
    assert float(errs.max()) < 1e-3  # the NavigationReport carries centroids as 32-bit floats
    assert Mode.NOMINAL_TRACKING in [m.to_mode for _, m in tm.mode_changes]
    # the fit's reconstruction of each frame from the truth record finds the universe's projections again
    s = frame_samples(scenario, run.truth, tm.navigation)
    frames = [r for r in run.truth if r.frame_id is not None]
    np.testing.assert_allclose(s.true_dim, [r.dimorphos_px for r in frames], atol=1e-6)
    np.testing.assert_allclose(s.true_did, [r.didymos_px for r in frames], atol=1e-6)
    seen = np.all(np.isfinite(s.reported_dim), axis=1)
    assert seen.sum() == ids.size and np.abs(s.reported_dim[seen] - s.true_dim[seen]).max() < 2e-3
