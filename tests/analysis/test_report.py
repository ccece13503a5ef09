"""The flyby report: the page, its images and figures.json from synthetic run folders, partial runs included, and
the `flyby report` command."""

from __future__ import annotations

import base64
import json
import re
from pathlib import Path

import numpy as np
import pytest

from analysis.plots import los_offset_series
from analysis.report import build_report, write_report
from analysis.runfolder import RunFolderError
from contracts import pus
from ground.config import ReportConfig
from tests.analysis.synthetic import CA_OBT, IN_VIEW_EXPECTED, LOS_OFFSET_RAD, make_run, telemetry_reports


def test_requirement_verdicts_in_the_table(full_run) -> None:
    """The HTML requirements table shows the figures' verdicts in order: the 97% in view fails, the rest pass."""
    _, path, _ = full_run
    table = re.search(r'<table id="requirements">.*?</table>', path.read_text(), re.S).group(0)
    assert re.findall(r'<td class="(pass|fail|na)">', table) == ["fail", "pass", "pass", "pass"]


def test_html_embeds_every_plot_and_files_match(full_run) -> None:
    """Every image is a base64 PNG data URI equal to its file under report/; figures.json holds the figures."""
    run, path, figs = full_run
    page = path.read_text()
    uris = re.findall(r"src='data:image/png;base64,([A-Za-z0-9+/=]+)'", page)
    files = sorted((run / "report").glob("*.png"))
    assert len(uris) == len(files) == 9
    embedded = sorted(base64.b64decode(u) for u in uris)
    assert embedded == sorted(f.read_bytes() for f in files)
    assert all(b.startswith(b"\x89PNG\r\n\x1a\n") for b in embedded)
    assert json.loads((run / "figures.json").read_text()) == json.loads(figs.model_dump_json())
    assert "time correlation: OBT - UTC offset" in page


def test_notes_tell_dimorphos_from_the_barycentre(full_run) -> None:
    """The page says which C/A is scored (Dimorphos) and shows the barycentre's beside it."""
    _, path, _ = full_run
    page = path.read_text()
    assert "closest approach to Dimorphos, the body the camera measures" in page
    assert "Didymos barycentre C/A (the scenario&#x27;s universe.flyby" in page
    table = re.search(r'<table id="ca-estimates">.*?</table>', page, re.S).group(0)
    assert table.count("<td>Dimorphos</td>") == 2 and table.count("<td>Didymos barycentre</td>") == 2


def test_the_on_board_los_offset_is_shown_beside_the_true_boresight(full_run) -> None:
    """The C/A estimates section states the last on-board LOS offsets (mrad) and the scenario's true boresight."""
    _, path, _ = full_run
    page = path.read_text()
    assert (f"in plane {LOS_OFFSET_RAD[0] * 1e3:+.3f} mrad, out of plane {LOS_OFFSET_RAD[1] * 1e3:+.3f} mrad; the "
            "true camera boresight is 0.000 mrad off body +Z") in page


def test_the_los_offsets_are_plotted_over_time_from_the_estimate_reports() -> None:
    """The offsets panel plots every EstimateReport carrying offsets, in mrad against the time from the true C/A, and
    nothing for reports without them."""
    reports = [(t, r) for t, r in telemetry_reports(None) if isinstance(r, pus.EstimateReport)]
    series = los_offset_series(reports, CA_OBT)
    assert series.shape == (len(reports), 3) and len(reports) == 160
    assert np.allclose(series[:, 0], [t - CA_OBT for t, _ in reports], rtol=0.0, atol=1e-9)
    assert np.allclose(series[:, 1:], np.array(LOS_OFFSET_RAD) * 1e3, rtol=0.0, atol=1e-12)
    bare = [(t, r.model_copy(update={"los_offset_in_plane_rad": None, "los_offset_out_of_plane_rad": None}))
            for t, r in reports[:3]]
    assert los_offset_series(bare, CA_OBT).shape == (0, 3)


def test_scenario_report_config_is_used(tmp_path: Path) -> None:
    """write_report takes its thresholds from the scenario's ground.report."""
    run = make_run(tmp_path / "wc", telemetry=False, frames=False, cfg=ReportConfig(in_view_required=0.9))
    write_report(run)
    figs = json.loads((run / "figures.json").read_text())
    assert figs["in_view_fraction"] == pytest.approx(IN_VIEW_EXPECTED)
    assert figs["in_view_pass"] is True


def test_partial_run_truth_only_says_what_is_missing(tmp_path: Path) -> None:
    """No tm.bin, no frames, a truth.csv cut mid-row: a report still comes out, naming what is missing."""
    run = make_run(tmp_path / "partial", telemetry=False, frames=False)
    text = (run / "truth.csv").read_text()
    (run / "truth.csv").write_text(text + "503.2,26499")  # a row cut by a dying node
    path, figs = build_report(run)
    page = path.read_text()
    assert "no tm.bin and no archive.sqlite" in page
    assert "no camera frames" in page
    assert "1 incomplete row(s) skipped" in page
    assert "NOT ASSESSED" in page
    assert not (run / "tm.bin").exists() and not (run / "archive.sqlite").exists()
    # no ACQUISITION event: the window opens at C/A - obsw.modes.acquisition_before_ca_s (240 s)
    assert figs.window_obt_s[0] == pytest.approx(CA_OBT - 240.0, abs=1e-6)
    assert figs.in_view_fraction == pytest.approx(IN_VIEW_EXPECTED)
    assert figs.centroid_pass is None and figs.max_centroid_error_px is None
    assert figs.ca_time_error_grid_s is None
    assert not (run / "report" / "flyby.gif").exists()


def test_telemetry_only_run(tmp_path: Path) -> None:
    """No truth.csv: the truth figures are not assessed, telemetry sections still drawn, nothing crashes."""
    run = make_run(tmp_path / "tmonly", frames=False)
    (run / "truth.csv").unlink()
    path, figs = build_report(run)
    assert figs.in_view_pass is None and figs.peak_rate_deg_s is None and figs.centroid_count == 0
    assert "the scenario's geometry" in path.read_text().replace("&#x27;", "'")
    assert figs.ca_time_error_grid_s is not None
    page = path.read_text()
    assert "no truth.csv" in page
    assert (run / "report" / "modes.png").exists() and (run / "report" / "ca_estimates.png").exists()


def test_missing_scenario_is_a_run_folder_error(tmp_path: Path) -> None:
    """A folder without scenario.yaml cannot be reported on: RunFolderError naming the scenario."""
    with pytest.raises(RunFolderError, match="scenario"):
        write_report(tmp_path)


def test_truncated_tm_bin_without_archive(tmp_path: Path) -> None:
    """tm.bin cut mid-packet and no archive.sqlite: every whole packet is used, the cut tail is reported."""
    run = make_run(tmp_path / "cut", frames=False, truth_rows=0)
    (run / "archive.sqlite").unlink()
    raw = (run / "tm.bin").read_bytes()
    packets = pus.split_packets(raw)
    (run / "tm.bin").write_bytes(raw[: len(raw) - 10])
    path, figs = build_report(run)
    page = path.read_text()
    assert f"tm.bin ends with {len(packets[-1]) - 10} octets of an incomplete packet" in page
    assert "no archive.sqlite: counts from the packet stream" in page
    assert f"<td>packets in tm.bin</td><td>{len(packets) - 1}</td>" in page
    assert figs.ca_time_error_grid_s is not None


def test_header_only_truth_and_no_navigation(tmp_path: Path) -> None:
    """A header-only truth.csv and telemetry without NavigationReports: each section says so."""
    run = make_run(tmp_path / "bare", frames=False, truth_rows=1)
    first_line = (run / "truth.csv").read_text().splitlines()[0]
    (run / "truth.csv").write_text(first_line + "\n")
    kept = [p for p in pus.split_packets((run / "tm.bin").read_bytes())
            if not isinstance(pus.decode_tm(p)[1], pus.NavigationReport)]
    (run / "archive.sqlite").unlink()
    (run / "tm.bin").write_bytes(b"".join(kept))
    path, figs = build_report(run)
    page = path.read_text()
    assert "truth.csv has no rows" in page
    assert "no NavigationReport with a measured line of sight" in page
    assert figs.in_view_fraction is None and figs.max_pointing_error_deg is None
    table = re.search(r'<table id="requirements">.*?</table>', page, re.S).group(0)
    assert re.findall(r'<td class="(pass|fail|na)">', table) == ["na"] * 4


def test_flyby_report_command(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """`flyby report RUN_DIR` rewrites the report and exits 0; a folder without scenario exits 2 naming it."""
    from flyby.cli import main

    run = make_run(tmp_path / "cli", telemetry=False, frames=False, truth_rows=600)
    assert main(["report", str(run)]) == 0
    assert f"{run / 'report.html'}: some requirement FAILS or was not assessed" in capsys.readouterr().out
    assert (run / "report.html").exists() and (run / "figures.json").exists()
    assert main(["report", str(tmp_path / "nowhere")]) == 2
    assert "nowhere: no such run folder" in capsys.readouterr().err


def test_the_animation_drawn_in_a_helper_process_gives_the_same_report(full_run, tmp_path: Path,
                                                                       caplog: pytest.LogCaptureFixture) -> None:
    """With the animation drawn in a helper process (which did not fail), the page, the GIF and figures.json are the
    octets of the report drawn in one process."""
    import shutil

    run, path, _ = full_run
    twin = tmp_path / "twin"
    shutil.copytree(run, twin)
    shutil.rmtree(twin / "report")
    (twin / "report.html").unlink()
    with caplog.at_level("WARNING", logger="analysis.report"):
        twin_path, _ = build_report(twin, parallel=True)
    assert not [r for r in caplog.records if r.name == "analysis.report"], caplog.text
    assert (run / "report" / "flyby.gif").is_file()
    assert twin_path.read_bytes() == path.read_bytes()
    assert (twin / "report" / "flyby.gif").read_bytes() == (run / "report" / "flyby.gif").read_bytes()
    assert (twin / "figures.json").read_bytes() == (run / "figures.json").read_bytes()
