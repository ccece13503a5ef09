"""Flyby report: figures and PASS/FAIL on synthetic run folders whose answers are set by construction."""

from __future__ import annotations

import base64
import json
import math
import re
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st
from PIL import Image

from contracts import pus
from contracts.messages import TruthRecord
from scenario.model import Scenario
from analysis import plots
from ground.archive import Archive
from ground.config import GroundConfig, ReportConfig
from ground.node import TruthLog
from analysis.report import (
    ReportError,
    binned_px,
    build_report,
    complete_packets,
    load_run,
    report_figures,
    write_report,
)

OFF = 26_499_202.0  # OBT at the epoch (oscillator default): OBT = t + OFF exactly, no drift
CA_T = 168.0  # true C/A, s after the epoch (scenario default)
CA_OBT = CA_T + OFF
APID = 0x0C1
OUT_OF_VIEW_KS = range(-200, -191)  # 9 of the 300 frames in the window see no target
IN_VIEW_EXPECTED = 291 / 300
MAX_ERR_IN_WINDOW_DEG = 1.2
PEAK_RATE_DEG_S = 7.3
CENTROID_OFFSET_PX = (3.0, 4.0)  # detection minus truth: 5 px
SAVED_FRAME_KS = list(range(-240, 120, 18))  # 20 saved PNGs


def frame_k(j: int) -> int | None:
    """Frame k (exposed at C/A + k + 0.5 s) of truth row j, or None: frames are rows j = 3005 + 10 k."""
    return (j - 3005) // 10 if j % 10 == 5 else None


def true_binned(k: int) -> tuple[float, float]:
    """Dimorphos' true position in frame k at the binned 512 scale."""
    return 200.0 + 0.25 * k / 3, 300.0 - 0.125 * k / 3


def scenario() -> Scenario:
    """The synthetic scenario: defaults (C/A 168 s, 55 km, 7 km/s, 2.9 deg FOV, 1024 px, 3 wheels)."""
    return Scenario(name="synthetic", seed=3)


def truth_record(j: int, max_err_deg: float) -> TruthRecord:
    """Truth row j (t = j / 10 - 132): pointing, view and rate series set so their figures are known."""
    t = j / 10 - 132.0
    tau = t - CA_T
    k = frame_k(j)
    in_window = -240.25 <= tau <= 60.0
    if tau < -240.25:
        err_deg, in_fov = 30.0, False
    elif tau > 60.05:
        err_deg, in_fov = 5.0, False
    else:
        err_deg, in_fov = 0.5, True
    if abs(tau - 10.2) < 1e-9:
        err_deg = max_err_deg  # the window's worst pointing, on a row without a frame
    if k is not None and k in OUT_OF_VIEW_KS:
        in_fov = False
    if k is None and in_window and j % 10 == 0 and tau < 0:
        in_fov = False  # control periods without a frame do not count: only frames do
    rate = math.radians(PEAK_RATE_DEG_S) / (1.0 + (tau / 10.0) ** 2)
    dim = None
    if k is not None:
        bx, by = true_binned(k)
        dim = (2 * bx + 0.5, 2 * by + 0.5)  # full resolution: x_full = b x_binned + (b - 1) / 2
    return TruthRecord(
        t_s=t, obt_s=t + OFF, q=(0.0, 0.0, 0.0, 1.0), omega_rad_s=(0.6 * rate, 0.0, 0.8 * rate),
        wheel_momentum_nms=(0.01, -0.02, 0.03), wheel_torque_nm=(0.001, 0.0, -0.001),
        pointing_error_rad=math.radians(err_deg), target_in_fov=in_fov, range_m=1e5, theta_rad=0.5,
        phase_angle_deg=50.0, frame_id=None if k is None else k + 300, dimorphos_px=dim,
        didymos_px=None if dim is None else (dim[0] + 40.0, dim[1]),
    )


def los(obt_s: float) -> tuple[float, float, float]:
    """True line of sight of the default flyby (e_v = x, e_ca = y), unit vector."""
    tau = obt_s - CA_OBT
    r = np.array([7000.0 * tau, 55000.0, 0.0])
    u = -r / np.linalg.norm(r)
    return float(u[0]), float(u[1]), float(u[2])


def telemetry_reports(outlier_px: float | None) -> list[tuple[float, pus.TmReport]]:
    """(OBT, report) of the synthetic telemetry: modes, housekeeping, navigation and estimates."""
    out: list[tuple[float, pus.TmReport]] = []
    for t, a, b in ((-240.25, "STANDBY", "ACQUISITION"), (-200.0, "ACQUISITION", "NOMINAL_TRACKING"),
                    (-30.0, "NOMINAL_TRACKING", "AUTONOMOUS_TRACKING"), (90.0, "AUTONOMOUS_TRACKING", "STANDBY")):
        out.append((CA_OBT + t, pus.ModeChangedEvent(from_mode=pus.Mode[a], to_mode=pus.Mode[b], cause="test")))
    for k in range(-300, 120):
        mode = pus.Mode.STANDBY if k < -240 else pus.Mode.ACQUISITION if k < -200 else pus.Mode.NOMINAL_TRACKING
        out.append((CA_OBT + k + 0.25, pus.Housekeeping(
            mode=mode, q=(0.0, 0.0, 0.0, 1.0), rate_rad_s=(0.01, 0.0, 0.0), wheel_speed_rad_s=(1.0, 2.0, 3.0),
            wheel_momentum_nms=(0.01, 0.02, 0.03), pointing_error_rad=0.001,
            best_ca_obt_s=CA_OBT + 2.0, best_ca_distance_km=56.5)))
    for k in range(-240, 60, 3):
        bx, by = true_binned(k)
        det = (bx + CENTROID_OFFSET_PX[0], by + CENTROID_OFFSET_PX[1])
        if outlier_px is not None and k == -120:
            det = (bx + outlier_px, by)
        out.append((CA_OBT + k + 0.5, pus.NavigationReport(frame_id=k + 300, dimorphos_col_row=det,
                                                           dimorphos_area_px=12, los_inertial=los(CA_OBT + k + 0.5))))
    for k in range(-60, 100):
        before = k + 0.5 <= -30.0
        out.append((CA_OBT + k + 0.5, pus.EstimateReport(
            n_measurements=k + 61, grid_ca_obt_s=CA_OBT + (2.0 if before else 99.0),
            grid_ca_distance_km=55.0 + (1.5 if before else 9.0), grid_mse_rad2=1e-8,
            continuous_ca_obt_s=CA_OBT + (-1.5 if before else 77.0), continuous_ca_distance_km=55.0 - 0.75,
            continuous_sigma_time_s=0.5, continuous_sigma_distance_km=0.2)))
    return sorted(out, key=lambda p: p[0])


def make_run(run: Path, *, max_err_deg: float = MAX_ERR_IN_WINDOW_DEG, outlier_px: float | None = None,
             telemetry: bool = True, frames: bool = True, truth_rows: int = 4200, cfg: ReportConfig | None = None
             ) -> Path:
    """Write a synthetic run folder: scenario.yaml, truth.csv, and optionally tm.bin + archive.sqlite and PNGs."""
    run.mkdir(parents=True, exist_ok=True)
    sc = scenario()
    if cfg is not None:
        sc = sc.model_copy(update={"ground": GroundConfig(report=cfg)})
    (run / "scenario.yaml").write_text(yaml.safe_dump(sc.model_dump(mode="json")))
    log = TruthLog(run / "truth.csv")
    for j in range(truth_rows):
        log.add(truth_record(j, max_err_deg))
    log.close()
    if telemetry:
        with Archive(run / "archive.sqlite", tm_bin=run / "tm.bin") as archive:
            for seq, (obt, rep) in enumerate(telemetry_reports(outlier_px)):
                archive.store(pus.encode_tm(rep, APID, seq, obt, seq % 65536), obt - OFF + 33.4)
        (run / "summary.json").write_text(json.dumps({"lines": [
            "scenario synthetic, seed 3", "time correlation: OBT - UTC offset +26499202.0000 s, drift +0.000 ppm"]}))
    if frames:
        (run / "frames").mkdir()
        for k in SAVED_FRAME_KS:
            img = np.full((512, 512), 10, np.uint8)
            bx, by = true_binned(k)
            cv2.circle(img, (round(bx), round(by)), 3 + (k + 240) // 40, 255, -1)
            cv2.imwrite(str(run / "frames" / f"frame_{k + 300:05d}.png"), img)
    return run


@pytest.fixture(scope="module")
def full_run(tmp_path_factory: pytest.TempPathFactory):
    """A complete synthetic run and its report, built once."""
    run = make_run(tmp_path_factory.mktemp("runs") / "full")
    path, figs = build_report(run)
    return run, path, figs


def test_figures_match_the_construction(full_run) -> None:
    """In-view fraction counts frames in the window, max pointing error is the window's, rate peak and centroids."""
    _, _, figs = full_run
    assert figs.true_ca_obt_s == pytest.approx(CA_OBT, abs=1e-6)
    assert figs.window_obt_s == pytest.approx((CA_OBT - 240.25, CA_OBT + 60.0), abs=1e-4)
    assert figs.in_view_fraction == pytest.approx(IN_VIEW_EXPECTED)
    assert figs.max_pointing_error_deg == pytest.approx(MAX_ERR_IN_WINDOW_DEG)
    assert figs.peak_rate_deg_s == pytest.approx(PEAK_RATE_DEG_S)
    assert figs.centroid_count == 100
    assert figs.max_centroid_error_px == pytest.approx(5.0, abs=1e-3)


def test_ca_errors_are_those_standing_at_ca_minus_30s(full_run) -> None:
    """The C/A errors are the last estimate stamped before C/A-30 s, not a later one."""
    _, _, figs = full_run
    assert figs.ca_time_error_grid_s == pytest.approx(2.0, abs=1e-6)
    assert figs.ca_distance_error_grid_km == pytest.approx(1.5, abs=1e-9)
    assert figs.ca_time_error_continuous_s == pytest.approx(-1.5, abs=1e-6)
    assert figs.ca_distance_error_continuous_km == pytest.approx(-0.75, abs=1e-9)


def test_verdicts_in_figures_and_table(full_run) -> None:
    """97% in view fails the 98% nominal requirement; the other three pass; the HTML table says the same in order."""
    _, path, figs = full_run
    assert (figs.in_view_pass, figs.pointing_pass, figs.rate_pass, figs.centroid_pass) == (False, True, True, True)
    verdicts = re.findall(r'<td class="(pass|fail|na)">', path.read_text())
    assert verdicts == ["fail", "pass", "pass", "pass"]


def test_html_embeds_every_plot_and_files_match(full_run) -> None:
    """Every image is a base64 PNG data URI equal to its file under report/; figures.json holds the figures."""
    run, path, figs = full_run
    page = path.read_text()
    uris = re.findall(r"src='data:image/png;base64,([A-Za-z0-9+/=]+)'", page)
    files = sorted((run / "report").glob("*.png"))
    assert len(uris) == len(files) == 8
    embedded = sorted(base64.b64decode(u) for u in uris)
    assert embedded == sorted(f.read_bytes() for f in files)
    assert all(b.startswith(b"\x89PNG\r\n\x1a\n") for b in embedded)
    assert json.loads((run / "figures.json").read_text()) == json.loads(figs.model_dump_json())
    assert "time correlation: OBT - UTC offset" in page


def test_gif_has_one_frame_per_saved_png(full_run) -> None:
    """With fewer saved frames than gif_max_frames, the GIF shows each of them once."""
    run, _, _ = full_run
    with Image.open(run / "report" / "flyby.gif") as gif:
        assert gif.n_frames == len(SAVED_FRAME_KS)
        assert gif.size == (512, 512)


def test_gif_is_thinned_to_max_frames_and_bytes(full_run) -> None:
    """gif_max_frames caps the frame count; a byte budget thins the frames until the file fits."""
    run, _, _ = full_run
    data = load_run(run)
    gif, n = plots.flyby_gif(data, CA_OBT, ReportConfig(gif_max_frames=6))
    assert n == 6
    (run / "six.gif").write_bytes(gif)
    with Image.open(run / "six.gif") as im:
        assert im.n_frames == 6
    budget = len(gif) // 2
    small, m = plots.flyby_gif(data, CA_OBT, ReportConfig(gif_max_frames=6, gif_max_bytes=budget))
    assert len(small) <= budget and m < 6


def test_worst_case_threshold_passes_the_same_run(full_run) -> None:
    """The same 97% passes when the scenario asks 90% (worst case)."""
    run, _, _ = full_run
    figs, _ = report_figures(load_run(run), ReportConfig(in_view_required=0.90))
    assert figs.in_view_pass is True


def test_pointing_and_centroid_failures(tmp_path: Path) -> None:
    """A 1.5 deg pointing error (> 1.45) and one 20 px centroid fail their requirements."""
    run = make_run(tmp_path / "bad", max_err_deg=1.5, outlier_px=20.0, frames=False)
    figs, _ = report_figures(load_run(run), ReportConfig())
    assert figs.max_pointing_error_deg == pytest.approx(1.5)
    assert figs.pointing_pass is False
    assert figs.max_centroid_error_px == pytest.approx(20.0, abs=1e-3)
    assert figs.centroid_pass is False


def test_scenario_report_config_is_used(tmp_path: Path) -> None:
    """write_report takes its thresholds from the scenario's analysis.report."""
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


def test_truth_cut_before_ca_uses_the_oscillator(tmp_path: Path) -> None:
    """Truth ending before C/A: true C/A OBT from the clock model (t + offset), figures over what exists."""
    run = make_run(tmp_path / "short", telemetry=False, frames=False, truth_rows=2500)  # ends at C/A-50 s
    figs, notes = report_figures(load_run(run), ReportConfig())
    assert figs.true_ca_obt_s == pytest.approx(CA_OBT, abs=1e-9)
    assert any("oscillator model" in n for n in notes)
    assert any("the truth ends at C/A-50" in n for n in notes)
    n_frames = sum(1 for j in range(2500) if (k := frame_k(j)) is not None and k >= -240)
    out = sum(1 for k in OUT_OF_VIEW_KS)
    assert figs.in_view_fraction == pytest.approx((n_frames - out) / n_frames)


def test_telemetry_only_run(tmp_path: Path) -> None:
    """No truth.csv: the truth figures are not assessed, telemetry sections still drawn, nothing crashes."""
    run = make_run(tmp_path / "tmonly", frames=False)
    (run / "truth.csv").unlink()
    path, figs = build_report(run)
    assert figs.in_view_pass is None and figs.peak_rate_deg_s is None and figs.centroid_count == 0
    assert figs.ca_time_error_grid_s == pytest.approx(2.0, abs=1e-6)  # C/A OBT from the oscillator model
    page = path.read_text()
    assert "no truth.csv" in page
    assert (run / "report" / "modes.png").exists() and (run / "report" / "ca_estimates.png").exists()


def test_missing_scenario_is_a_report_error(tmp_path: Path) -> None:
    """A folder without scenario.yaml cannot be reported on: ReportError naming the folder."""
    with pytest.raises(ReportError, match="scenario"):
        write_report(tmp_path)


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


@settings(max_examples=40, deadline=None)
@given(n=st.integers(0, 8), cut=st.integers(0, 400))
def test_complete_packets_keeps_every_whole_packet(n: int, cut: int) -> None:
    """A stream cut anywhere yields exactly the packets wholly before the cut, and the rest as the tail."""
    packets = [pus.encode_tm(pus.TimeReport(obt_s=100.0 + i), APID, i, 100.0 + i, i) for i in range(n)]
    stream = b"".join(packets)
    cut = min(cut, len(stream))
    got, tail = complete_packets(stream[:cut])
    whole = []
    pos = 0
    for p in packets:
        if pos + len(p) <= cut:
            whole.append(p)
        pos += len(p)
    assert got == whole
    assert tail == cut - sum(len(p) for p in whole)
    assert got == (pus.split_packets(stream[: cut - tail]) if cut - tail else [])


@settings(max_examples=60, deadline=None)
@given(n=st.integers(1, 500), count=st.integers(1, 40))
def test_spread_ids_is_an_even_subset(n: int, count: int) -> None:
    """spread_ids keeps min(n, count) sorted distinct ids, first and last included."""
    ids = list(range(5, 5 + 3 * n, 3))
    got = plots.spread_ids(ids[::-1], count)
    assert len(got) == min(n, count)
    assert got == sorted(set(got)) and set(got) <= set(ids)
    assert got[0] == ids[0] and (count == 1 or got[-1] == ids[-1])


def test_mode_intervals_from_events() -> None:
    """Mode intervals run from each change to the next, the last to the end of the telemetry."""
    ch = [(10.0, pus.ModeChangedEvent(from_mode=pus.Mode.STANDBY, to_mode=pus.Mode.ACQUISITION)),
          (50.0, pus.ModeChangedEvent(from_mode=pus.Mode.ACQUISITION, to_mode=pus.Mode.NOMINAL_TRACKING))]
    hk = [(0.0, int(pus.Mode.STANDBY)), (99.0, int(pus.Mode.NOMINAL_TRACKING))]
    assert plots.mode_intervals(ch, hk, 99.0) == [(0.0, 10.0, 1), (10.0, 50.0, 2), (50.0, 99.0, 3)]
    assert plots.mode_intervals([], [(0.0, 1), (1.0, 1), (2.0, 2)], 3.0) == [(0.0, 2.0, 1), (2.0, 3.0, 2)]


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
    assert figs.ca_time_error_grid_s == pytest.approx(2.0, abs=1e-6)


def test_header_only_truth_and_no_navigation(tmp_path: Path) -> None:
    """An empty truth.csv (or header only) and telemetry without NavigationReports: each section says so."""
    header_only = make_run(tmp_path / "header", telemetry=False, frames=False, truth_rows=1)
    first_line = (header_only / "truth.csv").read_text().splitlines()[0]
    (header_only / "truth.csv").write_text(first_line + "\n")
    assert load_run(header_only).truth is None
    assert "truth.csv has no rows: the universe sent no truth" in load_run(header_only).missing
    run = make_run(tmp_path / "bare", frames=False, truth_rows=0)
    kept = [p for p in pus.split_packets((run / "tm.bin").read_bytes())
            if not isinstance(pus.decode_tm(p)[1], pus.NavigationReport)]
    (run / "archive.sqlite").unlink()
    (run / "tm.bin").write_bytes(b"".join(kept))
    path, figs = build_report(run)
    page = path.read_text()
    assert "truth.csv is empty" in page
    assert "no NavigationReport with a measured line of sight" in page
    assert figs.in_view_fraction is None and figs.max_pointing_error_deg is None
    assert re.findall(r'<td class="(pass|fail|na)">', page) == ["na"] * 4


def test_flyby_report_command(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """`flyby report RUN_DIR` rewrites the report and exits 0; a folder without scenario exits 2 naming it."""
    from flyby.cli import main

    run = make_run(tmp_path / "cli", telemetry=False, frames=False, truth_rows=600)
    assert main(["report", str(run)]) == 0
    assert f"{run / 'report.html'}: some requirement FAILS or was not assessed" in capsys.readouterr().out
    assert (run / "report.html").exists() and (run / "figures.json").exists()
    assert main(["report", str(tmp_path / "nowhere")]) == 2
    assert "nowhere: no such run folder" in capsys.readouterr().err
