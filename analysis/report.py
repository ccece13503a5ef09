"""The flyby report: did we keep the asteroid in view, and why not, from a run folder at a glance.

``write_report(run_dir)`` reads what the nodes left in the run folder (scenario.yaml, truth.csv, tm.bin or
archive.sqlite, frames/, summary.json), scores the run against the paper's requirements, and writes
``report.html`` (self-contained: every image a base64 data URI), the same images under ``report/``, the animated
``report/flyby.gif`` and ``figures.json``. A partial run (a node died: truth cut short, no frames, no telemetry of
some kind) still gets a report: every section says what it is missing instead of failing.

All times in the plots are on-board time relative to the true closest approach (C/A), s. The true C/A is the
scenario's ``universe.flyby.ca_time_s`` turned into OBT by interpolating the truth's (t_s, obt_s), or by the
oscillator model when the truth does not reach it.
"""

from __future__ import annotations

import argparse
import base64
import csv
import html
import json
import math
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from pydantic import Field

from contracts import pus
from contracts.errors import FlybyError, ScenarioError
from contracts.exitcodes import EXIT_CONFIG
from contracts.model import Frozen
from scenario.model import Scenario, load_scenario
from ground.config import ReportConfig
from scenario import compose
from ground.tmquery import run_archive
from obsw.recognition import TrajectoryRecognizer, measured_theta_rad
from obsw.trajectory import NominalTrajectory
from universe.oscillator import Oscillator, clock_jumps_s

MODE_NAMES = {m.value: m.name for m in pus.Mode}


class ReportError(FlybyError):
    """The run folder cannot be reported on at all (no such folder, no readable scenario.yaml)."""


# ------------------------------------------------------------------------------------------------- inputs


@dataclass(frozen=True)
class Truth:
    """truth.csv as arrays, one row per control period; NaN (or -1 for ``frame_id``) where a cell is empty."""

    t_s: NDArray[np.float64]
    obt_s: NDArray[np.float64]
    omega_rad_s: NDArray[np.float64]  # (N, 3)
    pointing_error_rad: NDArray[np.float64]
    target_in_fov: NDArray[np.bool_]
    theta_rad: NDArray[np.float64]
    range_m: NDArray[np.float64]
    frame_id: NDArray[np.int64]
    dimorphos_px: NDArray[np.float64]  # (N, 2) full-resolution (col, row)
    didymos_px: NDArray[np.float64]  # (N, 2)
    wheel_momentum_nms: NDArray[np.float64]  # (N, wheels)
    wheel_torque_nm: NDArray[np.float64]  # (N, wheels)
    skipped_rows: int = 0

    def __len__(self) -> int:
        return int(self.t_s.size)


_TRUTH_REQUIRED = ("t_s", "obt_s", "wx_rad_s", "wy_rad_s", "wz_rad_s", "pointing_error_rad", "target_in_fov",
                   "range_m", "theta_rad", "frame_id", "dimorphos_col", "dimorphos_row", "didymos_col", "didymos_row")


def _cell(text: str) -> float:
    return float(text) if text else math.nan


def load_truth(path: Path) -> Truth:
    """Read truth.csv; rows with a wrong field count (a node killed mid-write) are skipped and counted.

    Raises ReportError naming the missing columns if the header lacks one the report needs.
    """
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    if not rows:
        raise ReportError(f"{path}: empty file, no header")
    header = rows[0]
    missing = [c for c in _TRUTH_REQUIRED if c not in header]
    if missing:
        raise ReportError(f"{path}: header lacks column(s) {', '.join(missing)}")
    good = [r for r in rows[1:] if len(r) == len(header)]
    skipped = len(rows) - 1 - len(good)
    values = np.array([[_cell(c) for c in r] for r in good], dtype=float).reshape(len(good), len(header))
    col = {name: values[:, i] for i, name in enumerate(header)}
    h_cols = sorted((c for c in header if c.startswith("h") and c.endswith("_nms")), key=lambda c: int(c[1:-4]))
    u_cols = sorted((c for c in header if c.startswith("u") and c.endswith("_nm")), key=lambda c: int(c[1:-3]))
    frame = col["frame_id"]
    return Truth(
        t_s=col["t_s"],
        obt_s=col["obt_s"],
        omega_rad_s=np.column_stack([col["wx_rad_s"], col["wy_rad_s"], col["wz_rad_s"]]),
        pointing_error_rad=col["pointing_error_rad"],
        target_in_fov=col["target_in_fov"] > 0.5,
        theta_rad=col["theta_rad"],
        range_m=col["range_m"],
        frame_id=np.where(np.isfinite(frame), frame, -1).astype(np.int64),
        dimorphos_px=np.column_stack([col["dimorphos_col"], col["dimorphos_row"]]),
        didymos_px=np.column_stack([col["didymos_col"], col["didymos_row"]]),
        wheel_momentum_nms=np.column_stack([col[c] for c in h_cols]) if h_cols else np.zeros((len(good), 0)),
        wheel_torque_nm=np.column_stack([col[c] for c in u_cols]) if u_cols else np.zeros((len(good), 0)),
        skipped_rows=skipped,
    )


@dataclass
class Telemetry:
    """The decoded telemetry of a run, by kind, each entry (packet OBT s, report), in stream order."""

    source: str
    packets: int = 0
    undecodable: int = 0
    truncated_tail_octets: int = 0
    housekeeping: list[tuple[float, pus.Housekeeping]] = field(default_factory=list)
    navigation: list[tuple[float, pus.NavigationReport]] = field(default_factory=list)
    estimates: list[tuple[float, pus.EstimateReport]] = field(default_factory=list)
    mode_changes: list[tuple[float, pus.ModeChangedEvent]] = field(default_factory=list)
    events: list[tuple[float, pus.EventReport]] = field(default_factory=list)
    by_type: dict[tuple[int, int, str], int] = field(default_factory=dict)  # (service, subtype, report): count


def complete_packets(stream: bytes) -> tuple[list[bytes], int]:
    """Cut a stream of concatenated space packets; return the packets and the octets of an incomplete last one.

    Like ``pus.split_packets``, but a stream cut short (a node killed mid-write) keeps every complete packet.
    """
    out: list[bytes] = []
    pos, n = 0, len(stream)
    while n - pos >= pus.PRIMARY_HEADER_LEN:
        size = pus.PRIMARY_HEADER_LEN + int.from_bytes(stream[pos + 4 : pos + 6], "big") + 1  # CCSDS length field
        if pos + size > n:
            break
        out.append(stream[pos : pos + size])
        pos += size
    return out, n - pos


def decoded_telemetry(packets: Sequence[bytes], source: str) -> Telemetry:
    """Decode TM packets into a Telemetry; undecodable ones are counted, never fatal."""
    tm = Telemetry(source=source, packets=len(packets))
    for raw in packets:
        try:
            header, report = pus.decode_tm(raw)
        except pus.PacketError:
            tm.undecodable += 1
            continue
        key = (header.service, header.subservice, type(report).__name__)
        tm.by_type[key] = tm.by_type.get(key, 0) + 1
        t = header.obt_s
        if isinstance(report, pus.Housekeeping):
            tm.housekeeping.append((t, report))
        elif isinstance(report, pus.NavigationReport):
            tm.navigation.append((t, report))
        elif isinstance(report, pus.EstimateReport):
            tm.estimates.append((t, report))
        elif isinstance(report, pus.EventReport):
            tm.events.append((t, report))
            if isinstance(report, pus.ModeChangedEvent):
                tm.mode_changes.append((t, report))
    return tm


def load_telemetry(run_dir: Path) -> Telemetry | None:
    """The run's telemetry from tm.bin, else from the raw packets in archive.sqlite; None if neither exists."""
    tm_bin = run_dir / "tm.bin"
    if tm_bin.is_file():
        packets, tail = complete_packets(tm_bin.read_bytes())
        tm = decoded_telemetry(packets, "tm.bin")
        tm.truncated_tail_octets = tail
        return tm
    db = run_dir / "archive.sqlite"
    if db.is_file():
        import sqlite3

        con = sqlite3.connect(f"file:{db}?mode=ro", uri=True)  # read-only: a report never changes the archive
        try:
            raws = [bytes(r) for (r,) in con.execute("SELECT raw FROM packets ORDER BY id")]
        finally:
            con.close()
        return decoded_telemetry(raws, "archive.sqlite (no tm.bin)")
    return None


def archive_counts(run_dir: Path) -> dict[str, int] | None:
    """Archive.counts() of the run's archive.sqlite, or None if it has none."""
    if not (run_dir / "archive.sqlite").is_file():
        return None
    with run_archive(run_dir) as archive:
        return archive.counts()


def frame_paths(run_dir: Path) -> dict[int, Path]:
    """frame id -> PNG path of every frames/frame_NNNNN.png."""
    out = {}
    for p in sorted((run_dir / "frames").glob("frame_*.png")):
        stem = p.stem.removeprefix("frame_")
        if stem.isdigit():
            out[int(stem)] = p
    return out


@dataclass
class RunData:
    """Everything the report is made of; ``missing`` lists what a partial run lacks, one line each."""

    run_dir: Path
    scenario: Scenario
    truth: Truth | None
    telemetry: Telemetry | None
    frames: dict[int, Path]
    summary_lines: list[str] | None
    counts: dict[str, int] | None
    missing: list[str] = field(default_factory=list)


def load_run(run_dir: Path) -> RunData:
    """Read a run folder; raise ReportError only if the folder or its scenario.yaml is unusable."""
    run_dir = Path(run_dir)
    if not run_dir.is_dir():
        raise ReportError(f"{run_dir}: no such run folder")
    try:
        scenario = load_scenario(run_dir / "scenario.yaml")
    except ScenarioError as err:
        raise ReportError(f"{run_dir}: cannot report without the scenario: {err}") from None
    missing: list[str] = []
    truth = None
    if (run_dir / "truth.csv").is_file() and (run_dir / "truth.csv").stat().st_size == 0:
        missing.append("truth.csv is empty: the universe sent no truth")
    elif (run_dir / "truth.csv").is_file():
        try:
            truth = load_truth(run_dir / "truth.csv")
        except ReportError as err:
            missing.append(f"truth.csv unusable: {err}")
        else:
            if len(truth) == 0:
                missing.append("truth.csv has no rows: the universe sent no truth")
                truth = None
            elif truth.skipped_rows:
                missing.append(f"truth.csv: {truth.skipped_rows} incomplete row(s) skipped")
    else:
        missing.append("no truth.csv: every figure that needs the simulation truth is missing")
    telemetry = load_telemetry(run_dir)
    if telemetry is None:
        missing.append("no tm.bin and no archive.sqlite: no telemetry was received")
    elif telemetry.truncated_tail_octets:
        missing.append(f"tm.bin ends with {telemetry.truncated_tail_octets} octets of an incomplete packet")
    frames = frame_paths(run_dir)
    if not frames:
        missing.append("no camera frames in frames/: no mosaic and no animation")
    summary = None
    if (run_dir / "summary.json").is_file():
        try:
            summary = [str(x) for x in json.loads((run_dir / "summary.json").read_text())["lines"]]
        except (ValueError, KeyError, TypeError) as err:
            missing.append(f"summary.json unreadable: {err!r}")
    else:
        missing.append("no summary.json: the ground node did not finish")
    counts = archive_counts(run_dir)
    return RunData(run_dir, scenario, truth, telemetry, frames, summary, counts, missing)


# ------------------------------------------------------------------------------------------------ figures


class ReportFigures(Frozen):
    """The run's figures against the paper's requirements; None where the run lacks the data."""

    in_view_fraction: float | None = Field(description="fraction of frames with Dimorphos in the FOV in the window")
    in_view_basis: str = Field(description="what the fraction counts (camera frames, or control periods)")
    window_obt_s: tuple[float, float] | None = Field(description="OBT window of the in-view and pointing figures, s")
    max_pointing_error_deg: float | None = Field(description="largest true pointing error in the window, deg")
    peak_rate_deg_s: float | None = Field(description="largest true body rate of the run, deg/s")
    max_centroid_error_px: float | None = Field(description="largest Dimorphos centroid error, binned px")
    centroid_count: int = Field(description="detections compared with the truth, count")
    true_ca_obt_s: float = Field(description="true C/A in OBT, s")
    ca_time_error_grid_s: float | None = Field(description="grid C/A time minus truth at C/A-30 s, s")
    ca_time_error_continuous_s: float | None = Field(description="continuous C/A time minus truth at C/A-30 s, s")
    ca_distance_error_grid_km: float | None = Field(description="grid C/A distance minus truth at C/A-30 s, km")
    ca_distance_error_continuous_km: float | None = Field(description="continuous C/A distance minus truth, km")
    in_view_pass: bool | None
    pointing_pass: bool | None
    rate_pass: bool | None
    centroid_pass: bool | None

    def summary_lines(self) -> list[str]:
        """The figures as the run's summary prints them (the same numbers as figures.json and the report)."""
        def f(x: float | None, fmt: str) -> str:
            return "-" if x is None else format(x, fmt)

        in_view = None if self.in_view_fraction is None else 100 * self.in_view_fraction
        return [f"target in field of view: {f(in_view, '.1f')}% of {self.in_view_basis}; max pointing error "
                f"{f(self.max_pointing_error_deg, '.3f')} deg; peak body rate {f(self.peak_rate_deg_s, '.2f')} deg/s; "
                f"worst centroid {f(self.max_centroid_error_px, '.2f')} px"]

    @property
    def all_pass(self) -> bool:
        """Every requirement was assessed and passed."""
        return all(p is True for p in (self.in_view_pass, self.pointing_pass, self.rate_pass, self.centroid_pass))


def true_ca_obt_s(scenario: Scenario, truth: Truth | None) -> tuple[float, str]:
    """The true C/A as OBT, s, and how it was obtained (truth interpolation, or the oscillator model)."""
    ca = scenario.universe.flyby.ca_time_s
    if truth is not None and len(truth) >= 2 and truth.t_s[0] <= ca <= truth.t_s[-1]:
        return float(np.interp(ca, truth.t_s, truth.obt_s)), "truth (t_s, obt_s) interpolated"
    u = scenario.universe
    # obt_mean_s is the jitter-free model: the generator is never drawn from
    osc = Oscillator(u.oscillator, np.random.default_rng(0), clock_jumps_s(u.faults))
    return osc.obt_mean_s(ca), "oscillator model (the truth does not reach C/A)"


def uploaded_nominal(scenario: Scenario) -> NominalTrajectory:
    """The nominal trajectory ground uploads at the start of the run (a-priori OBT-UTC correlation)."""
    tc = compose.ground_segment(scenario).nominal_trajectory_tc()
    return NominalTrajectory(
        ca_time_obt_s=tc.ca_obt_s, ca_distance_km=tc.ca_distance_km, speed_km_s=tc.speed_km_s,
        approach_direction=tc.approach_direction, ca_direction=tc.ca_direction,
        ca_time_sigma_s=tc.sigma_ca_time_s, ca_distance_sigma_km=tc.sigma_ca_distance_km,
    )


def candidate_axes(scenario: Scenario) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The on-board candidate grid: C/A times (OBT s) and distances (km), as the OBSW builds it."""
    return TrajectoryRecognizer(uploaded_nominal(scenario), scenario.obsw.recognition).candidate_axes()


def binned_px(full_px: NDArray[np.float64], factor: float) -> NDArray[np.float64]:
    """Binned coordinate of a full-resolution pixel coordinate for a binning factor: (x - (b - 1) / 2) / b."""
    return (full_px - (factor - 1.0) / 2.0) / factor


def acquisition_start_obt_s(tm: Telemetry | None) -> float | None:
    """OBT of the first ModeChangedEvent into ACQUISITION, s; None if there is none."""
    if tm is None:
        return None
    starts = [t for t, ev in tm.mode_changes if ev.to_mode == pus.Mode.ACQUISITION]
    return min(starts) if starts else None


def centroid_errors_px(data: RunData) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """(frame ids, distance binned px) between each detected Dimorphos centroid and its true projection."""
    if data.truth is None or data.telemetry is None:
        return np.zeros(0, dtype=np.int64), np.zeros(0)
    factor = data.scenario.universe.camera.resolution_px / data.scenario.obsw.imaging.binned_size_px
    truth = data.truth
    row_of = {int(f): i for i, f in enumerate(truth.frame_id) if f >= 0}
    ids, errs = [], []
    for _, nav in data.telemetry.navigation:
        i = row_of.get(nav.frame_id)
        if nav.dimorphos_col_row is None or i is None or not np.all(np.isfinite(truth.dimorphos_px[i])):
            continue
        ref = binned_px(truth.dimorphos_px[i], factor)
        ids.append(nav.frame_id)
        errs.append(float(np.hypot(*(np.asarray(nav.dimorphos_col_row) - ref))))
    return np.asarray(ids, dtype=np.int64), np.asarray(errs)


def estimate_at(tm: Telemetry | None, obt_s: float) -> tuple[pus.EstimateReport | None, tuple[float, float] | None]:
    """The last EstimateReport, and the last housekeeping grid choice (C/A OBT s, km), stamped at or before obt_s."""
    if tm is None:
        return None, None
    est = None
    for t, e in tm.estimates:
        if t <= obt_s:
            est = e
    hk_best = None
    for t, hk in tm.housekeeping:
        if t <= obt_s and hk.best_ca_obt_s is not None and hk.best_ca_distance_km is not None:
            hk_best = (hk.best_ca_obt_s, hk.best_ca_distance_km)
    return est, hk_best


def report_figures(data: RunData, cfg: ReportConfig) -> tuple[ReportFigures, list[str]]:
    """Score the run; return the figures and notes on how each was obtained (windows, fallbacks)."""
    sc = data.scenario
    truth, tm = data.truth, data.telemetry
    notes: list[str] = []
    ca_obt, how = true_ca_obt_s(sc, truth)
    notes.append(f"true C/A: {sc.universe.flyby.ca_time_s:g} s after the epoch = OBT {ca_obt:.3f} s ({how}), "
                 f"{sc.universe.flyby.ca_distance_km:g} km")
    start = acquisition_start_obt_s(tm)
    if start is None:
        start = ca_obt - sc.obsw.modes.acquisition_before_ca_s
        notes.append(f"no ModeChangedEvent into ACQUISITION in the telemetry: the window starts at C/A-"
                     f"{sc.obsw.modes.acquisition_before_ca_s:g} s (obsw.modes.acquisition_before_ca_s)")
    end = ca_obt + cfg.in_view_after_ca_s
    notes.append(f"window: C/A{start - ca_obt:+.1f} s (first ACQUISITION) to C/A+{cfg.in_view_after_ca_s:g} s")
    in_view = max_err = peak = None
    basis = "camera frames"
    if truth is not None:
        peak = float(np.degrees(np.max(np.linalg.norm(truth.omega_rad_s, axis=1))))
        i = int(np.nanargmin(truth.range_m))
        notes.append(f"closest true range to Dimorphos: {truth.range_m[i] / 1e3:.3f} km at C/A"
                     f"{truth.obt_s[i] - ca_obt:+.1f} s (the C/A figures are about the Didymos barycentre)")
        win = (truth.obt_s >= start) & (truth.obt_s <= end)
        if truth.obt_s[-1] < end:
            notes.append(f"the truth ends at C/A{truth.obt_s[-1] - ca_obt:+.1f} s, before the window ends")
        if win.any():
            frames = win & (truth.frame_id >= 0)
            if frames.any():
                in_view = float(np.mean(truth.target_in_fov[frames]))
                basis = f"camera frames ({int(frames.sum())} in the window)"
            else:
                in_view = float(np.mean(truth.target_in_fov[win]))
                basis = f"control periods ({int(win.sum())}; no camera frame in the window)"
            max_err = float(np.degrees(np.max(truth.pointing_error_rad[win])))
        else:
            notes.append("no truth row falls in the window")
    _, errs = centroid_errors_px(data)
    max_centroid = float(errs.max()) if errs.size else None
    est, hk_best = estimate_at(tm, ca_obt - cfg.estimate_before_ca_s)
    grid_t = grid_d = cont_t = cont_d = None
    true_d = sc.universe.flyby.ca_distance_km
    if est is not None and est.grid_ca_obt_s is not None and est.grid_ca_distance_km is not None:
        grid_t, grid_d = est.grid_ca_obt_s - ca_obt, est.grid_ca_distance_km - true_d
    elif hk_best is not None:
        grid_t, grid_d = hk_best[0] - ca_obt, hk_best[1] - true_d
        notes.append("grid C/A error from housekeeping (no EstimateReport before C/A-"
                     f"{cfg.estimate_before_ca_s:g} s)")
    if est is not None and est.continuous_ca_obt_s is not None and est.continuous_ca_distance_km is not None:
        cont_t, cont_d = est.continuous_ca_obt_s - ca_obt, est.continuous_ca_distance_km - true_d
    pointing_limit_deg = sc.universe.camera.fov_deg * cfg.max_pointing_error_fov_fraction
    figs = ReportFigures(
        in_view_fraction=in_view,
        in_view_basis=basis,
        window_obt_s=(start, end),
        max_pointing_error_deg=max_err,
        peak_rate_deg_s=peak,
        max_centroid_error_px=max_centroid,
        centroid_count=int(errs.size),
        true_ca_obt_s=ca_obt,
        ca_time_error_grid_s=grid_t,
        ca_time_error_continuous_s=cont_t,
        ca_distance_error_grid_km=grid_d,
        ca_distance_error_continuous_km=cont_d,
        in_view_pass=None if in_view is None else in_view >= cfg.in_view_required,
        pointing_pass=None if max_err is None else max_err <= pointing_limit_deg,
        rate_pass=None if peak is None else peak >= cfg.peak_rate_required_deg_s,
        centroid_pass=None if max_centroid is None else max_centroid <= cfg.centroid_tolerance_px,
    )
    return figs, notes


@dataclass(frozen=True)
class RequirementRow:
    """One line of the requirements table."""

    requirement: str
    threshold: str
    figure: str
    passed: bool | None
    source: str


def requirement_rows(figs: ReportFigures, scenario: Scenario, cfg: ReportConfig) -> list[RequirementRow]:
    """The requirements table: each paper requirement, this run's figure, PASS/FAIL (None: not assessed)."""
    fov = scenario.universe.camera.fov_deg
    limit = fov * cfg.max_pointing_error_fov_fraction

    def num(x: float | None, fmt: str, why: str) -> str:
        return f"missing: {why}" if x is None else format(x, fmt)

    return [
        RequirementRow(
            "target in view from the first ACQUISITION to C/A+" + f"{cfg.in_view_after_ca_s:g} s",
            f">= {100 * cfg.in_view_required:g}%",
            num(None if figs.in_view_fraction is None else 100 * figs.in_view_fraction, ".1f", "no truth in the window")
            + ("" if figs.in_view_fraction is None else f"% of {figs.in_view_basis}"),
            figs.in_view_pass,
            "paper: asteroid in the FoV 98% of the time (nominal), > 90% (worst cases)",
        ),
        RequirementRow(
            "pointing error never above half the field of view (same window)",
            f"<= {limit:g} deg",
            num(figs.max_pointing_error_deg, ".3f", "no truth in the window") + ("" if figs.max_pointing_error_deg
                                                                                 is None else " deg max"),
            figs.pointing_pass,
            f"paper: pointing error less than half the camera FoV ({fov:g} deg)",
        ),
        RequirementRow(
            "peak body rate reached",
            f">= {cfg.peak_rate_required_deg_s:g} deg/s",
            num(figs.peak_rate_deg_s, ".2f", "no truth") + ("" if figs.peak_rate_deg_s is None else " deg/s"),
            figs.rate_pass,
            "paper: the satellite reaches the requested body rate of 7 deg/s",
        ),
        RequirementRow(
            "Dimorphos centroids near the truth projection (binned image)",
            f"<= {cfg.centroid_tolerance_px:g} px",
            num(figs.max_centroid_error_px, ".2f", "no detection matched to a true position")
            + ("" if figs.max_centroid_error_px is None else f" px max over {figs.centroid_count} frames"),
            figs.centroid_pass,
            "paper: centroids less than 15 pixels from the reference (OpenCV) pass",
        ),
    ]


# -------------------------------------------------------------------------------------------------- HTML


@dataclass
class Section:
    """One section of the report: a title, what to read in it, an image (or why it is missing), notes."""

    title: str
    caption: str
    png: bytes | None = None
    file_name: str | None = None
    missing: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    html_body: str = ""


_CSS = """
body{font-family:system-ui,sans-serif;margin:1.5em auto;max-width:1100px;color:#222}
h1{font-size:1.5em}h2{font-size:1.2em;margin-top:1.6em;border-bottom:1px solid #ccc}
table{border-collapse:collapse;margin:.5em 0}td,th{border:1px solid #bbb;padding:.25em .6em;text-align:left}
th{background:#eee}.pass{background:#c8f0c8;font-weight:bold}.fail{background:#f5c0c0;font-weight:bold}
.na{background:#eee;color:#666;font-weight:bold}.missing{color:#a40;font-style:italic}
.caption{color:#555}img{max-width:100%;border:1px solid #ddd}
"""


def _verdict(passed: bool | None) -> str:
    if passed is None:
        return '<td class="na">NOT ASSESSED</td>'
    return '<td class="pass">PASS</td>' if passed else '<td class="fail">FAIL</td>'


def _table(head: Sequence[str], rows: Sequence[Sequence[Any]]) -> str:
    h = "".join(f"<th>{html.escape(str(c))}</th>" for c in head)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in r) + "</tr>" for r in rows)
    return f"<table><tr>{h}</tr>{body}</table>"


def _list(items: Sequence[str], cls: str = "") -> str:
    if not items:
        return ""
    attr = f' class="{cls}"' if cls else ""
    return f"<ul{attr}>" + "".join(f"<li>{html.escape(i)}</li>" for i in items) + "</ul>"


def report_html(title: str, requirements: list[RequirementRow], notes: list[str], missing: list[str],
                sections: list[Section]) -> str:
    """The self-contained HTML page: requirements on top, then each section with its image inlined."""
    req = "<table><tr><th>requirement</th><th>threshold</th><th>this run</th><th>verdict</th><th>source</th></tr>"
    for r in requirements:
        req += (f"<tr><td>{html.escape(r.requirement)}</td><td>{html.escape(r.threshold)}</td>"
                f"<td>{html.escape(r.figure)}</td>{_verdict(r.passed)}<td>{html.escape(r.source)}</td></tr>")
    req += "</table>"
    parts = [f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>",
             f"<style>{_CSS}</style></head><body><h1>{html.escape(title)}</h1>", "<h2>Requirements</h2>", req,
             _list(notes)]
    if missing:
        parts += ["<p class='missing'>This run is incomplete:</p>", _list(missing, "missing")]
    for s in sections:
        parts.append(f"<h2>{html.escape(s.title)}</h2><p class='caption'>{html.escape(s.caption)}</p>")
        parts.append(_list(s.missing, "missing"))
        if s.png is not None:
            uri = base64.b64encode(s.png).decode("ascii")
            parts.append(f"<img alt='{html.escape(s.title)}' src='data:image/png;base64,{uri}'>")
        parts.append(s.html_body)
        parts.append(_list(s.notes))
    parts.append("</body></html>")
    return "\n".join(p for p in parts if p)


# ------------------------------------------------------------------------------------------------ sections


def counts_section(data: RunData, figs: ReportFigures) -> Section:
    """Counts of packets, gaps, undecodable packets, frames and events, and the time-correlation line."""
    s = Section("Counts", "What arrived: telemetry packets and their gaps, frames, events; the ground's OBT-UTC fit.")
    tm, truth = data.telemetry, data.truth
    rows: list[tuple[str, Any]] = []
    if data.counts is not None:
        c = data.counts
        rows += [("packets archived", c.get("stored", 0)), ("undecodable", c.get("undecodable", 0)),
                 ("sequence gaps", c.get("gaps", 0)), ("packets missing in gaps", c.get("missing", 0)),
                 ("duplicates / late", f"{c.get('duplicates', 0)} / {c.get('late', 0)}")]
    elif tm is not None:
        s.missing.append("no archive.sqlite: counts from the packet stream, no sequence-gap analysis")
        rows += [("packets in " + tm.source, tm.packets), ("undecodable", tm.undecodable)]
    else:
        s.missing.append("no telemetry: no packet counts")
    if tm is not None:
        rows += [(f"TM[{svc},{sub}] {name}", n) for (svc, sub, name), n in sorted(tm.by_type.items())]
        rows += [("events (service 5)", len(tm.events)), ("mode changes", len(tm.mode_changes))]
    if truth is not None:
        rows += [("control periods of truth", len(truth)), ("camera frames exposed", int((truth.frame_id >= 0).sum()))]
    rows += [("frame PNGs saved", len(data.frames)), ("detections compared with truth", figs.centroid_count)]
    s.html_body = _table(("what", "count"), rows)
    if data.summary_lines is None:
        s.missing.append("no summary.json: no time-correlation line")
    else:
        corr = [line for line in data.summary_lines if line.startswith("time correlation")]
        s.notes += corr or ["summary.json has no time-correlation line"]
        s.notes += [f"summary: {line}" for line in data.summary_lines if not line.startswith("time correlation")]
    return s


def events_section(data: RunData, ca_obt: float, limit: int = 60) -> Section:
    """The service 5 events, in time order (the first ``limit``)."""
    s = Section("Events", "On-board events (service 5): mode changes, target acquired or lost, faults, saturation.")
    tm = data.telemetry
    if tm is None or not tm.events:
        s.missing.append("no telemetry" if tm is None else "no event reports in the telemetry")
        return s
    rows = []
    for t, ev in sorted(tm.events, key=lambda e: e[0])[:limit]:
        fields = {k: v for k, v in ev.model_dump().items() if k != "severity"}
        detail = ", ".join(f"{k}={MODE_NAMES.get(v, v) if k.endswith('_mode') else v}" for k, v in fields.items())
        rows.append((f"{t - ca_obt:+.1f}", type(ev).__name__, ev.severity.name, detail))
    if len(tm.events) > limit:
        s.notes.append(f"{len(tm.events) - limit} later event(s) not listed")
    s.html_body = _table(("t - C/A, s", "event", "severity", "detail"), rows)
    return s


def write_report(run_dir: Path, cfg: ReportConfig | None = None) -> Path:
    """Write run_dir/report.html (self-contained), its images under run_dir/report/, report/flyby.gif and
    run_dir/figures.json; return the path of report.html.

    ``cfg`` defaults to the scenario's ``analysis.report``. Raises ReportError if the folder has no usable scenario.
    """
    return build_report(Path(run_dir), cfg)[0]


def build_report(run_dir: Path, cfg: ReportConfig | None = None) -> tuple[Path, ReportFigures]:
    """``write_report`` that also returns the figures."""
    from analysis import plots  # matplotlib loads only when a report is drawn

    data = load_run(run_dir)
    cfg = cfg or data.scenario.ground.report
    figs, notes = report_figures(data, cfg)
    out = run_dir / "report"
    out.mkdir(exist_ok=True)
    sections = plots.plot_sections(data, figs, cfg)
    sections.insert(0, counts_section(data, figs))
    sections.append(events_section(data, figs.true_ca_obt_s))
    for s in sections:
        if s.png is not None and s.file_name is not None:
            (out / s.file_name).write_bytes(s.png)
    title = f"Flyby report: {data.scenario.name} (seed {data.scenario.seed})"
    page = report_html(title, requirement_rows(figs, data.scenario, cfg), notes, data.missing, sections)
    path = run_dir / "report.html"
    path.write_text(page, encoding="utf-8")
    (run_dir / "figures.json").write_text(figs.model_dump_json(indent=2))
    return path, figs


def cmd_report(args: argparse.Namespace) -> int:
    """``flyby report RUN_DIR``: regenerate the report of a run; exit 2 if the folder cannot be reported on."""
    try:
        path, figs = build_report(args.run_dir)
    except ReportError as err:
        print(f"flyby report: {err}", file=sys.stderr)
        return EXIT_CONFIG
    verdict = "all requirements PASS" if figs.all_pass else "some requirement FAILS or was not assessed"
    print(f"{path}: {verdict}")
    return 0
