"""Scoring a run against the paper's requirements: ONE function, ``score_run``, whose ``RunFigures`` feed the run's
summary lines, figures.json, the report's requirement table and the closed-loop benchmark, so they never disagree.

The requirements (thresholds in ``ground.config.ReportConfig``, each with its source): Dimorphos in the field of
view in enough camera frames, and the pointing error never above half the field of view, from the first camera
frame of the first ACQUISITION (``window_start_obt_s``; the paper: the target kept in the field of view during the
scientific activities, the imaging) to C/A + ``in_view_after_ca_s``; the peak body rate reached; every detected
Dimorphos centroid near its true projection. The on-board C/A estimates standing at C/A - ``estimate_before_ca_s`` are scored against
the true C/A to Dimorphos (``analysis.closest_approach``), the body the camera measures.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from pydantic import Field

from contracts import pus
from contracts.model import Frozen
from ground.config import ReportConfig
from analysis.closest_approach import didymos_barycentre_ca, dimorphos_ca
from analysis.runfolder import RunData
from analysis.telemetry import Telemetry
from analysis.truth import Truth

PAPER = "the LICIACube navigation paper"


def _fmt(x: float | None, spec: str) -> str:
    return "-" if x is None else format(x, spec)


def _sub(a: float | None, b: float) -> float | None:
    return None if a is None else a - b


@dataclass(frozen=True)
class RequirementRow:
    """One line of the requirements table: the requirement, its threshold, this run's figure, the verdict."""

    requirement: str
    threshold: str
    figure: str
    passed: bool | None  # None: not assessed (the run lacks the data)
    source: str


@dataclass(frozen=True)
class EstimateRow:
    """One line of the C/A estimates table: an on-board estimate minus a true C/A, time (s) and distance (km)."""

    estimate: str
    reference: str
    time_error_s: float | None
    distance_error_km: float | None

    def time_text(self) -> str:
        """The time error as the summary and the report print it, s ("-" if missing)."""
        return _fmt(self.time_error_s, "+.3f")

    def distance_text(self) -> str:
        """The distance error as the summary and the report print it, km ("-" if missing)."""
        return _fmt(self.distance_error_km, "+.3f")

    def text(self) -> str:
        """Both errors with their units."""
        return f"{self.time_text()} s, {self.distance_text()} km"


class RunFigures(Frozen):
    """The run's figures against the paper's requirements, with the thresholds used; None where data is missing."""

    in_view_fraction: float | None = Field(description="fraction of frames with Dimorphos in the FOV in the window")
    in_view_basis: str = Field(description="what the fraction counts (camera frames, or control periods)")
    window_obt_s: tuple[float, float] = Field(description="OBT window of the in-view and pointing figures, s")
    max_pointing_error_deg: float | None = Field(description="largest true pointing error in the window, deg")
    peak_rate_deg_s: float | None = Field(description="largest true body rate of the run, deg/s")
    max_centroid_error_px: float | None = Field(description="largest Dimorphos centroid error, binned px")
    centroid_count: int = Field(description="detections compared with the truth, count")
    in_view_required: float = Field(description="in-view fraction required, fraction")
    pointing_limit_deg: float = Field(description="largest pointing error allowed in the window, deg")
    peak_rate_required_deg_s: float = Field(description="body rate the run must reach, deg/s")
    centroid_tolerance_px: float = Field(description="largest centroid error allowed, binned px")
    estimate_before_ca_s: float = Field(description="the C/A estimates are those standing this long before C/A, s")
    true_ca_obt_s: float = Field(description="true C/A to Dimorphos (the measured body) in OBT, s")
    true_ca_distance_km: float = Field(description="true C/A distance to Dimorphos, km")
    didymos_ca_obt_s: float = Field(description="C/A to the Didymos barycentre (the scenario's flyby) in OBT, s")
    didymos_ca_distance_km: float = Field(description="C/A distance to the Didymos barycentre, km")
    ca_time_error_grid_s: float | None = Field(description="grid C/A time minus the Dimorphos truth, s")
    ca_distance_error_grid_km: float | None = Field(description="grid C/A distance minus the Dimorphos truth, km")
    ca_time_error_continuous_s: float | None = Field(description="continuous C/A time minus the Dimorphos truth, s")
    ca_distance_error_continuous_km: float | None = Field(
        description="continuous C/A distance minus the Dimorphos truth, km")
    in_view_pass: bool | None
    pointing_pass: bool | None
    rate_pass: bool | None
    centroid_pass: bool | None

    @property
    def all_pass(self) -> bool:
        """Every requirement was assessed and passed."""
        return all(r.passed is True for r in self.requirement_rows())

    def window_end_after_ca_s(self) -> float:
        """How long after the true C/A the scoring window ends, s."""
        return self.window_obt_s[1] - self.true_ca_obt_s

    def requirement_rows(self) -> list[RequirementRow]:
        """The requirements table: each paper requirement, this run's figure, PASS/FAIL (None: not assessed)."""
        def num(text: str, value: float | None, why: str) -> str:
            return f"missing: {why}" if value is None else text

        in_view = None if self.in_view_fraction is None else 100 * self.in_view_fraction
        return [
            RequirementRow(
                f"target in view from the first frame of ACQUISITION to C/A+{self.window_end_after_ca_s():g} s",
                f">= {100 * self.in_view_required:g}%",
                num(f"{_fmt(in_view, '.2f')}% of {self.in_view_basis}", in_view, "no truth in the window"),
                self.in_view_pass, f"{PAPER}: asteroid in the FoV 98% of the time (nominal), > 90% (worst cases)"),
            RequirementRow(
                "pointing error never above half the field of view (same window)",
                f"<= {self.pointing_limit_deg:g} deg",
                num(f"{_fmt(self.max_pointing_error_deg, '.3f')} deg max", self.max_pointing_error_deg,
                    "no truth in the window"),
                self.pointing_pass, f"{PAPER}: pointing error less than half the camera FoV"),
            RequirementRow(
                "peak body rate reached",
                f">= {self.peak_rate_required_deg_s:g} deg/s",
                num(f"{_fmt(self.peak_rate_deg_s, '.2f')} deg/s", self.peak_rate_deg_s, "no truth"),
                self.rate_pass, f"{PAPER}: the satellite reaches the requested body rate of 7 deg/s"),
            RequirementRow(
                "Dimorphos centroids near the truth projection (binned image)",
                f"<= {self.centroid_tolerance_px:g} px",
                num(f"{_fmt(self.max_centroid_error_px, '.2f')} px max over {self.centroid_count} frames",
                    self.max_centroid_error_px, "no detection matched to a true position"),
                self.centroid_pass, f"{PAPER}: centroids less than 15 pixels from the reference (OpenCV) pass"),
        ]

    def estimate_rows(self) -> list[EstimateRow]:
        """The C/A estimates standing at C/A - estimate_before_ca_s minus the true C/A to Dimorphos (scored) and to
        the Didymos barycentre (for comparison)."""
        dt = self.true_ca_obt_s - self.didymos_ca_obt_s
        dd = self.true_ca_distance_km - self.didymos_ca_distance_km

        def shift(x: float | None, by: float) -> float | None:
            return None if x is None else x + by

        rows = []
        for name, t, d in (("grid", self.ca_time_error_grid_s, self.ca_distance_error_grid_km),
                           ("continuous", self.ca_time_error_continuous_s, self.ca_distance_error_continuous_km)):
            rows.append(EstimateRow(name, "Dimorphos", t, d))
            rows.append(EstimateRow(name, "Didymos barycentre", shift(t, dt), shift(d, dd)))
        return rows

    def summary_lines(self) -> list[str]:
        """The figures as the run's summary prints them: the same numbers and texts as figures.json and the report."""
        req = self.requirement_rows()
        est = {(r.estimate, r.reference): r.text() for r in self.estimate_rows()}
        verdicts = ", ".join(f"{name} {_verdict(r.passed)}"
                             for name, r in zip(("in view", "pointing", "rate", "centroids"), req, strict=True))
        return [
            f"target in field of view: {req[0].figure}; pointing error {req[1].figure}; "
            f"peak body rate {req[2].figure}; centroid error {req[3].figure}",
            f"C/A estimates at C/A-{self.estimate_before_ca_s:g} s minus the true C/A to Dimorphos "
            f"(OBT {self.true_ca_obt_s:.3f} s, {self.true_ca_distance_km:.3f} km): grid {est['grid', 'Dimorphos']}; "
            f"continuous {est['continuous', 'Dimorphos']}",
            f"requirements: {'all PASS' if self.all_pass else 'some FAIL or were not assessed'} ({verdicts})",
        ]


def _verdict(passed: bool | None) -> str:
    return "NOT ASSESSED" if passed is None else "PASS" if passed else "FAIL"


def binned_px(full_px: NDArray[np.float64], factor: float) -> NDArray[np.float64]:
    """Binned coordinate of a full-resolution pixel coordinate for a binning factor: (x - (b - 1) / 2) / b."""
    return (full_px - (factor - 1.0) / 2.0) / factor


def acquisition_start_obt_s(tm: Telemetry | None) -> float | None:
    """OBT of the first ModeChangedEvent into ACQUISITION, s; None if there is none."""
    if tm is None:
        return None
    starts = [t for t, ev in tm.mode_changes if ev.to_mode == pus.Mode.ACQUISITION]
    return min(starts) if starts else None


def window_start_obt_s(tm: Telemetry | None, truth: Truth | None) -> float | None:
    """OBT the requirement window opens, s: the first camera frame (truth row with a frame) at or after the first
    ACQUISITION; the first ACQUISITION when no frame follows it, or no truth is kept; None without an ACQUISITION.
    The attitude at ACQUISITION's entry is STANDBY's, wherever the target has drifted since: the paper asks for the
    target in the field of view during the imaging, which the timeline starts once the slew onto it is done."""
    start = acquisition_start_obt_s(tm)
    if start is None or truth is None:
        return start
    frames = truth.obt_s[(truth.frame_id >= 0) & (truth.obt_s >= start)]
    return float(frames.min()) if frames.size else start


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
    t, (best_t, best_d) = tm.housekeeping.present("best_ca_obt_s", "best_ca_distance_km")
    before = np.flatnonzero(t <= obt_s)
    hk_best = None if not before.size else (float(best_t[before[-1]]), float(best_d[before[-1]]))
    return est, hk_best


def score_run(data: RunData, cfg: ReportConfig) -> tuple[RunFigures, list[str]]:
    """Score a run against ``cfg``'s thresholds; return the figures and notes on how each was obtained."""
    sc = data.scenario
    truth, tm = data.truth, data.telemetry
    ca = dimorphos_ca(sc, truth)
    bary = didymos_barycentre_ca(sc, truth)
    notes = [
        f"true C/A: the closest approach to Dimorphos, the body the camera measures, at OBT {ca.obt_s:.3f} s "
        f"({ca.t_s:.3f} s after the epoch), {ca.distance_km:.3f} km ({ca.how}); every time in this report is "
        "relative to it and the scored C/A errors are against it",
        f"Didymos barycentre C/A (the scenario's universe.flyby, what ground's nominal trajectory describes): "
        f"C/A{bary.obt_s - ca.obt_s:+.3f} s, {bary.distance_km:.3f} km; the estimates against it are shown beside",
    ]
    start = window_start_obt_s(tm, truth)
    if start is None:
        start = ca.obt_s - sc.obsw.modes.acquisition_before_ca_s
        notes.append(f"no ModeChangedEvent into ACQUISITION in the telemetry: the window starts at C/A-"
                     f"{sc.obsw.modes.acquisition_before_ca_s:g} s (obsw.modes.acquisition_before_ca_s)")
    end = ca.obt_s + cfg.in_view_after_ca_s
    notes.append(f"window: C/A{start - ca.obt_s:+.1f} s (the first frame of the first ACQUISITION) to "
                 f"C/A+{cfg.in_view_after_ca_s:g} s")
    in_view = max_err = peak = None
    basis = "camera frames"
    if truth is not None:
        peak = float(np.degrees(np.max(np.linalg.norm(truth.omega_rad_s, axis=1))))
        win = (truth.obt_s >= start) & (truth.obt_s <= end)
        if truth.obt_s[-1] < end:
            notes.append(f"the truth ends at C/A{truth.obt_s[-1] - ca.obt_s:+.1f} s, before the window ends")
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
    est, hk_best = estimate_at(tm, ca.obt_s - cfg.estimate_before_ca_s)
    grid: tuple[float | None, float | None] = (None, None)
    cont: tuple[float | None, float | None] = (None, None)
    if est is not None and est.grid_ca_obt_s is not None and est.grid_ca_distance_km is not None:
        grid = (est.grid_ca_obt_s, est.grid_ca_distance_km)
    elif hk_best is not None:
        grid = hk_best
        notes.append(f"grid C/A error from housekeeping (no EstimateReport before C/A-{cfg.estimate_before_ca_s:g} s)")
    if est is not None and est.continuous_ca_obt_s is not None and est.continuous_ca_distance_km is not None:
        cont = (est.continuous_ca_obt_s, est.continuous_ca_distance_km)
    limit_deg = sc.universe.camera.fov_deg * cfg.max_pointing_error_fov_fraction
    figs = RunFigures(
        in_view_fraction=in_view,
        in_view_basis=basis,
        window_obt_s=(start, end),
        max_pointing_error_deg=max_err,
        peak_rate_deg_s=peak,
        max_centroid_error_px=max_centroid,
        centroid_count=int(errs.size),
        in_view_required=cfg.in_view_required,
        pointing_limit_deg=limit_deg,
        peak_rate_required_deg_s=cfg.peak_rate_required_deg_s,
        centroid_tolerance_px=cfg.centroid_tolerance_px,
        estimate_before_ca_s=cfg.estimate_before_ca_s,
        true_ca_obt_s=ca.obt_s,
        true_ca_distance_km=ca.distance_km,
        didymos_ca_obt_s=bary.obt_s,
        didymos_ca_distance_km=bary.distance_km,
        ca_time_error_grid_s=_sub(grid[0], ca.obt_s),
        ca_distance_error_grid_km=_sub(grid[1], ca.distance_km),
        ca_time_error_continuous_s=_sub(cont[0], ca.obt_s),
        ca_distance_error_continuous_km=_sub(cont[1], ca.distance_km),
        in_view_pass=None if in_view is None else in_view >= cfg.in_view_required,
        pointing_pass=None if max_err is None else max_err <= limit_deg,
        rate_pass=None if peak is None else peak >= cfg.peak_rate_required_deg_s,
        centroid_pass=None if max_centroid is None else max_centroid <= cfg.centroid_tolerance_px,
    )
    return figs, notes
