"""Scoring: figures and verdicts on synthetic run folders whose answers are set by construction, and the summary
lines, requirement rows and C/A estimate rows all saying the figures' numbers."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from analysis.runfolder import load_run
from analysis.scoring import RunFigures, binned_px, score_run
from ground.config import ReportConfig
from tests.analysis.synthetic import (
    BARY_D_KM,
    BARY_T,
    CA_D_KM,
    CA_OBT,
    IN_VIEW_EXPECTED,
    MAX_ERR_IN_WINDOW_DEG,
    OFF,
    OUT_OF_VIEW_KS,
    PEAK_RATE_DEG_S,
    frame_k,
    make_run,
)


def test_figures_match_the_construction(full_run) -> None:
    """In-view fraction counts frames in the window (from ACQUISITION's first frame), max pointing error is the
    window's, rate peak and centroids."""
    _, _, figs = full_run
    assert figs.true_ca_obt_s == pytest.approx(CA_OBT, abs=1e-6)
    assert figs.true_ca_distance_km == pytest.approx(CA_D_KM, abs=1e-9)
    assert figs.window_obt_s == pytest.approx((CA_OBT - 239.5, CA_OBT + 60.0), abs=1e-4)
    assert figs.in_view_fraction == pytest.approx(IN_VIEW_EXPECTED)
    assert figs.max_pointing_error_deg == pytest.approx(MAX_ERR_IN_WINDOW_DEG)
    assert figs.peak_rate_deg_s == pytest.approx(PEAK_RATE_DEG_S)
    assert figs.centroid_count == 100
    assert figs.max_centroid_error_px == pytest.approx(5.0, abs=1e-3)


def test_ca_errors_are_against_dimorphos_at_ca_minus_30s(full_run) -> None:
    """The C/A errors are the last estimate stamped before C/A-30 s minus the Dimorphos C/A, not the barycentre's."""
    _, _, figs = full_run
    assert figs.ca_time_error_grid_s == pytest.approx(2.0, abs=1e-6)
    assert figs.ca_distance_error_grid_km == pytest.approx(1.5, abs=1e-9)
    assert figs.ca_time_error_continuous_s == pytest.approx(-1.5, abs=1e-6)
    assert figs.ca_distance_error_continuous_km == pytest.approx(-0.75, abs=1e-9)
    assert figs.didymos_ca_obt_s == pytest.approx(BARY_T + OFF, abs=1e-6)
    assert figs.didymos_ca_distance_km == BARY_D_KM


def test_estimate_rows_against_both_bodies(full_run) -> None:
    """The barycentre rows are the same estimates minus the barycentre's C/A (167.75 s, 55 km)."""
    _, _, figs = full_run
    rows = {(r.estimate, r.reference): (r.time_error_s, r.distance_error_km) for r in figs.estimate_rows()}
    grid_obt, grid_km = CA_OBT + 2.0, CA_D_KM + 1.5
    cont_obt, cont_km = CA_OBT - 1.5, CA_D_KM - 0.75
    assert rows["grid", "Dimorphos"] == pytest.approx((2.0, 1.5), abs=1e-6)
    assert rows["grid", "Didymos barycentre"] == pytest.approx((grid_obt - (BARY_T + OFF), grid_km - BARY_D_KM),
                                                              abs=1e-6)
    assert rows["continuous", "Didymos barycentre"] == pytest.approx(
        (cont_obt - (BARY_T + OFF), cont_km - BARY_D_KM), abs=1e-6)


def test_verdicts(full_run) -> None:
    """97% in view fails the 98% nominal requirement; the other three pass; the run does not pass."""
    _, _, figs = full_run
    assert (figs.in_view_pass, figs.pointing_pass, figs.rate_pass, figs.centroid_pass) == (False, True, True, True)
    assert [r.passed for r in figs.requirement_rows()] == [False, True, True, True]
    assert not figs.all_pass


def test_summary_lines_say_the_figures(full_run) -> None:
    """Each number of the summary lines is the figure rounded as printed; the verdict line names each verdict."""
    _, _, figs = full_run
    first, estimates, verdicts = figs.summary_lines()
    nums = [float(x) for x in re.findall(r"[-+]?\d+\.\d+", first)]
    assert nums == [round(100 * figs.in_view_fraction, 2), round(figs.max_pointing_error_deg, 3),
                    round(figs.peak_rate_deg_s, 2), round(figs.max_centroid_error_px, 2)]
    m = re.search(r"grid ([-+]\d+\.\d+) s, ([-+]\d+\.\d+) km; continuous ([-+]\d+\.\d+) s, ([-+]\d+\.\d+) km",
                  estimates)
    assert m is not None
    assert [float(x) for x in m.groups()] == pytest.approx(
        [figs.ca_time_error_grid_s, figs.ca_distance_error_grid_km, figs.ca_time_error_continuous_s,
         figs.ca_distance_error_continuous_km], abs=5e-4)
    assert verdicts == ("requirements: some FAIL or were not assessed "
                        "(in view FAIL, pointing PASS, rate PASS, centroids PASS)")


def test_thresholds_are_those_scored_with(full_run) -> None:
    """A 90% in-view requirement passes the same 97% run and is recorded in the figures."""
    run, _, _ = full_run
    figs, _ = score_run(load_run(run), ReportConfig(in_view_required=0.90))
    assert figs.in_view_pass is True and figs.in_view_required == 0.90
    assert figs.all_pass
    assert figs.summary_lines()[2].startswith("requirements: all PASS")


def test_pointing_and_centroid_failures(tmp_path: Path) -> None:
    """A 1.5 deg pointing error (> 1.45) and one 20 px centroid fail their requirements."""
    run = make_run(tmp_path / "bad", max_err_deg=1.5, outlier_px=20.0, frames=False)
    figs, _ = score_run(load_run(run), ReportConfig(in_view_required=0.9))
    assert figs.max_pointing_error_deg == pytest.approx(1.5)
    assert figs.pointing_pass is False
    assert figs.max_centroid_error_px == pytest.approx(20.0, abs=1e-3)
    assert figs.centroid_pass is False
    assert figs.in_view_pass and figs.rate_pass and not figs.all_pass


def test_the_slew_before_acquisitions_first_frame_is_not_scored(tmp_path: Path) -> None:
    """The pointing window opens at ACQUISITION's first frame: 3 deg off between the entry and that frame (the slew
    onto the target) fails nothing; the same 3 deg on a row after it fails the pointing requirement."""
    run = make_run(tmp_path / "slew", entry_err_deg=3.0, telemetry=True, frames=False)
    figs, _ = score_run(load_run(run), ReportConfig(in_view_required=0.9))
    assert figs.window_obt_s[0] == pytest.approx(CA_OBT - 239.5, abs=1e-4)
    assert figs.max_pointing_error_deg == pytest.approx(MAX_ERR_IN_WINDOW_DEG) and figs.pointing_pass
    late = make_run(tmp_path / "late", max_err_deg=3.0, frames=False)
    assert score_run(load_run(late), ReportConfig(in_view_required=0.9))[0].pointing_pass is False


def test_truth_cut_before_ca(tmp_path: Path) -> None:
    """Truth ending before C/A: the Dimorphos C/A from the straight line of the truth, OBT from the clock model."""
    run = make_run(tmp_path / "short", telemetry=False, frames=False, truth_rows=2500)  # ends at C/A-50 s
    figs, notes = score_run(load_run(run), ReportConfig())
    assert figs.true_ca_obt_s == pytest.approx(CA_OBT, abs=1e-6)
    assert figs.true_ca_distance_km == pytest.approx(CA_D_KM, abs=1e-9)
    assert any("straight line fitted" in n and "oscillator model" in n for n in notes)
    assert any("the truth ends at C/A-50" in n for n in notes)
    n_frames = sum(1 for j in range(2500) if (k := frame_k(j)) is not None and k >= -240)
    out = sum(1 for k in OUT_OF_VIEW_KS)
    assert figs.in_view_fraction == pytest.approx((n_frames - out) / n_frames)


def test_missing_data_is_not_assessed(tmp_path: Path) -> None:
    """Without truth no requirement is assessed: every verdict is None and the run does not pass."""
    run = make_run(tmp_path / "tmonly", frames=False)
    (run / "truth.csv").unlink()
    figs, _ = score_run(load_run(run), ReportConfig())
    assert [r.passed for r in figs.requirement_rows()] == [None] * 4
    assert all(r.figure.startswith("missing: ") for r in figs.requirement_rows())
    assert not figs.all_pass
    assert "NOT ASSESSED" in figs.summary_lines()[2]


def test_figures_json_round_trips(full_run) -> None:
    """figures.json reads back into the same RunFigures."""
    run, _, figs = full_run
    assert RunFigures.model_validate_json((run / "figures.json").read_text()) == figs


@settings(max_examples=40, deadline=None)
@given(cx=st.floats(50, 78), cy=st.floats(50, 78), sigma=st.floats(5.0, 7.0), b=st.sampled_from([2, 4]))
def test_binned_px_is_the_centroid_of_the_block_mean_image(cx: float, cy: float, sigma: float, b: int) -> None:
    """Binning a well-sampled blob by b x b block means moves its centroid to (x - (b - 1) / 2) / b."""
    n = 128
    y, x = np.mgrid[0:n, 0:n].astype(float)
    img = np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / (2 * sigma**2))
    full = np.array([(img * x).sum(), (img * y).sum()]) / img.sum()
    small = img.reshape(n // b, b, n // b, b).mean(axis=(1, 3))
    ys, xs = np.mgrid[0 : n // b, 0 : n // b].astype(float)
    binned = np.array([(small * xs).sum(), (small * ys).sum()]) / small.sum()
    assert binned_px(full, b) == pytest.approx(binned, abs=1e-9)
