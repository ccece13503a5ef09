"""The report's charts (matplotlib, Agg): pointing, rate, wheels, line-of-sight angle, C/A estimates, centroids,
modes, and the mosaic of frames.

Each ``*_section`` function takes the loaded run and its figures and returns a report Section holding its PNG, or
saying what it is missing. Times are OBT relative to the true C/A (to Dimorphos), s.
"""

from __future__ import annotations

import io
from collections.abc import Sequence

import matplotlib

matplotlib.use("Agg")

import numpy as np  # noqa: E402
from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: E402
from matplotlib.collections import LineCollection  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from contracts import pus  # noqa: E402
from contracts.task import Task  # noqa: E402
from ground.config import ReportConfig  # noqa: E402
from obsw.recognition import measured_theta_rad  # noqa: E402
from analysis.candidates import candidate_axes, uploaded_nominal  # noqa: E402
from analysis.frames import frame_marks, frame_obt_s, load_gray, spread_ids  # noqa: E402
from analysis.page import Section  # noqa: E402
from analysis.runfolder import RunData  # noqa: E402
from analysis.scoring import RunFigures, centroid_errors_px, estimate_at  # noqa: E402
from analysis.report_columns import ReportColumns  # noqa: E402
from analysis.telemetry import MODE_NAMES, Telemetry  # noqa: E402

TRUTH_COLOUR, TM_COLOUR, LIMIT_COLOUR, CHOSEN_COLOUR = "tab:blue", "tab:orange", "tab:red", "tab:green"


def _figure(rows: int = 1, height_in: float = 3.2) -> tuple[Figure, list]:
    fig = Figure(figsize=(10, height_in * rows), layout="constrained")
    FigureCanvasAgg(fig)
    axes = [fig.add_subplot(rows, 1, i + 1) for i in range(rows)]
    return fig, axes


def png_bytes(fig: Figure, dpi: int) -> bytes:
    """The figure as PNG octets."""
    buf = io.BytesIO()
    # zlib level 1, not 6: the report's processor time 7.2 -> 6.1 s on the nominal run, the page 1.7 -> 1.9 MB
    fig.savefig(buf, format="png", dpi=dpi, pil_kwargs={"compress_level": 1})
    return buf.getvalue()


def _ca_lines(ax, cfg: ReportConfig, window: tuple[float, float] | None = None, ca_obt: float = 0.0) -> None:
    """C/A and C/A-30 s markers, and the scoring window shaded."""
    ax.axvline(0.0, color="k", lw=0.8, ls=":", label="true C/A")
    ax.axvline(-cfg.estimate_before_ca_s, color="grey", lw=0.8, ls=":", label=f"C/A-{cfg.estimate_before_ca_s:g} s")
    if window is not None:
        ax.axvspan(window[0] - ca_obt, window[1] - ca_obt, color="0.92", zorder=0, label="scoring window")
    ax.grid(alpha=0.3)
    ax.set_xlabel("OBT - true C/A, s")


def _housekeeping(tm: Telemetry | None) -> ReportColumns[pus.Housekeeping]:
    """The run's housekeeping columns; none (empty columns) without telemetry."""
    return tm.housekeeping if tm is not None else ReportColumns(pus.Housekeeping)


def pointing_section(data: RunData, figs: RunFigures, cfg: ReportConfig) -> Section:
    """True (and on-board estimated) pointing error against time, with the half-FOV line."""
    limit = data.scenario.universe.camera.fov_deg * cfg.max_pointing_error_fov_fraction
    s = Section("Pointing error", f"Angle between the camera boresight and Dimorphos; it must stay under {limit:g} deg "
                "(half the field of view) in the shaded window.", file_name="pointing_error.png")
    truth, tm, ca = data.truth, data.telemetry, figs.true_ca_obt_s
    hk_t, (hk_e,) = _housekeeping(tm).present("pointing_error_rad")
    hk = hk_t.size > 0
    if truth is None:
        s.missing.append("no truth: the true pointing error is missing")
    if not hk:
        s.missing.append("no on-board pointing-error estimate in the housekeeping")
    if truth is None and not hk:
        return s
    fig, (ax,) = _figure()
    peak = limit
    if truth is not None:
        err = np.degrees(truth.pointing_error_rad)
        ax.plot(truth.obt_s - ca, err, color=TRUTH_COLOUR, lw=1, label="truth")
        if figs.max_pointing_error_deg is not None:
            peak = max(peak, figs.max_pointing_error_deg)
    if hk:
        ax.plot(hk_t - ca, np.degrees(hk_e), ".", color=TM_COLOUR, ms=3, label="on-board estimate (HK)")
    ax.axhline(limit, color=LIMIT_COLOUR, lw=1.2, ls="--", label=f"half FOV {limit:g} deg")
    top = 1.4 * peak
    ax.set_ylim(0, top)
    if truth is not None and np.nanmax(np.degrees(truth.pointing_error_rad)) > top:
        s.notes.append(f"off scale outside the window: up to {np.nanmax(np.degrees(truth.pointing_error_rad)):.2f} deg")
    _ca_lines(ax, cfg, figs.window_obt_s, ca)
    ax.set_ylabel("pointing error, deg")
    ax.legend(loc="upper left", fontsize=8)
    s.png = png_bytes(fig, cfg.plot_dpi)
    return s


def rate_section(data: RunData, figs: RunFigures, cfg: ReportConfig) -> Section:
    """True and on-board body rate against time, with the required peak."""
    need = cfg.peak_rate_required_deg_s
    s = Section("Body rate", f"Norm of the body rate; the flyby must reach {need:g} deg/s.", file_name="body_rate.png")
    truth, tm, ca = data.truth, data.telemetry, figs.true_ca_obt_s
    hk = _housekeeping(tm)
    if truth is None:
        s.missing.append("no truth: the true body rate is missing")
    if not hk:
        s.missing.append("no housekeeping: the on-board rate is missing")
    if truth is None and not hk:
        return s
    fig, (ax,) = _figure()
    if truth is not None:
        ax.plot(truth.obt_s - ca, np.degrees(np.linalg.norm(truth.omega_rad_s, axis=1)), color=TRUTH_COLOUR, lw=1,
                label="truth |omega|")
    if hk:
        rate = hk.column("rate_rad_s")
        ax.plot(hk.t_s - ca, np.degrees(np.linalg.norm(rate, axis=1)), ".", color=TM_COLOUR, ms=3,
                label="on-board |omega| (HK)")
    ax.axhline(need, color=LIMIT_COLOUR, lw=1.2, ls="--", label=f"required peak {need:g} deg/s")
    _ca_lines(ax, cfg)
    ax.set_ylabel("body rate, deg/s")
    ax.legend(loc="upper left", fontsize=8)
    s.png = png_bytes(fig, cfg.plot_dpi)
    return s


def wheels_section(data: RunData, figs: RunFigures, cfg: ReportConfig) -> Section:
    """Wheel momentum and torque command per wheel, against their limits."""
    w = data.scenario.universe.spacecraft.wheels
    s = Section("Reaction wheels", f"Momentum (limit {w.max_momentum_nms:g} N m s) and torque command (limit "
                f"{w.max_torque_nm:g} N m) of each wheel.", file_name="wheels.png")
    truth, tm, ca = data.truth, data.telemetry, figs.true_ca_obt_s
    if truth is None or truth.wheel_momentum_nms.shape[1] == 0:
        s.missing.append("no truth wheel columns: true momentum and torque are missing")
        if tm is None or not tm.housekeeping:
            s.missing.append("no housekeeping: on-board wheel momentum is missing")
            return s
    fig, (ax_h, ax_u) = _figure(2, 2.8)
    if truth is not None and truth.wheel_momentum_nms.shape[1]:
        for i in range(truth.wheel_momentum_nms.shape[1]):
            ax_h.plot(truth.obt_s - ca, truth.wheel_momentum_nms[:, i], lw=1, label=f"wheel {i}")
            ax_u.plot(truth.obt_s - ca, truth.wheel_torque_nm[:, i] * 1e3, lw=1, label=f"wheel {i}")
    elif tm is not None:
        t = tm.housekeeping.t_s
        h = tm.housekeeping.column("wheel_momentum_nms")
        for i in np.flatnonzero(np.isfinite(h).any(axis=0)):  # the slots some report used
            ax_h.plot(t - ca, h[:, i], ".", ms=3, label=f"wheel {i} (HK)")
        ax_u.text(0.5, 0.5, "torque missing (no truth)", transform=ax_u.transAxes, ha="center")
    for ax, lim in ((ax_h, w.max_momentum_nms), (ax_u, w.max_torque_nm * 1e3)):
        ax.axhline(lim, color=LIMIT_COLOUR, ls="--", lw=1.2, label="limit")
        ax.axhline(-lim, color=LIMIT_COLOUR, ls="--", lw=1.2)
        ax.set_ylim(-1.5 * lim, 1.5 * lim)  # limits in view, room for the legend above them
        _ca_lines(ax, cfg)
        ax.legend(loc="upper left", fontsize=7, ncol=6)
    ax_h.set_ylabel("momentum, N m s")
    ax_u.set_ylabel("torque command, mN m")
    s.png = png_bytes(fig, cfg.plot_dpi)
    return s


def theta_section(data: RunData, figs: RunFigures, cfg: ReportConfig) -> Section:
    """Measured LOS angle against every candidate's prediction and the chosen candidate's."""
    s = Section("Line-of-sight angle and trajectory candidates",
                "theta = angle between the relative velocity and the measured line of sight (NavigationReport). "
                "Bottom: everything minus the chosen candidate's prediction; grey lines are the other candidates.",
                file_name="los_angle.png")
    tm, truth, ca = data.telemetry, data.truth, figs.true_ca_obt_s
    # a line of sight without a Dimorphos centroid is Didymos's, standing in for it: not Dimorphos's trajectory
    with_los = [(t, n) for t, n in (tm.navigation if tm else []) if n.los_inertial is not None]
    meas = [(t, n.los_inertial) for t, n in with_los if n.dimorphos_col_row is not None]
    stand_ins = len(with_los) - len(meas)
    if stand_ins:
        s.notes.append(f"{stand_ins} lines of sight of Didymos standing in for Dimorphos's (not shown)")
    if not meas:
        s.missing.append("no NavigationReport with a measured line of sight" if tm else "no telemetry")
        return s
    nominal = uploaded_nominal(data.scenario)
    times_c, dists_c = candidate_axes(data.scenario)
    t_m = np.array([t for t, _ in meas])
    th_m = np.array([measured_theta_rad(nominal, los) for _, los in meas])
    est, hk_best = estimate_at(tm, ca - cfg.estimate_before_ca_s)
    if est is not None and est.grid_ca_obt_s is not None and est.grid_ca_distance_km is not None:
        chosen, how = (est.grid_ca_obt_s, est.grid_ca_distance_km), f"grid choice at C/A-{cfg.estimate_before_ca_s:g} s"
    elif hk_best is not None:
        chosen, how = hk_best, f"grid choice at C/A-{cfg.estimate_before_ca_s:g} s (housekeeping)"
    elif tm is not None and tm.estimates and tm.estimates[-1][1].grid_ca_obt_s is not None:
        last = tm.estimates[-1][1]
        chosen, how = (last.grid_ca_obt_s, last.grid_ca_distance_km), "last grid choice (none before C/A-30 s)"
    else:
        chosen, how = (nominal.ca_time_obt_s, nominal.ca_distance_km), "the nominal (no grid choice in the telemetry)"
    s.notes.append(f"chosen: {how}: C/A {chosen[0] - ca:+.2f} s from the truth, {chosen[1]:.2f} km; grid of "
                   f"{times_c.size} x {dists_c.size} candidates around the uploaded nominal (C/A "
                   f"{nominal.ca_time_obt_s - ca:+.2f} s, {nominal.ca_distance_km:.2f} km)")
    if data.scenario.ground.upload_nominal_at_s is not None:
        s.notes.append("the grid is rebuilt with ground's a-priori OBT-UTC offset; this scenario uploads the nominal "
                       "later, with a fitted correlation, so the on-board grid may be shifted by the difference")
    grid_t = np.linspace(t_m.min(), t_m.max(), 200)
    chosen_traj = nominal.with_ca(*chosen)
    fig, (ax, ax_r) = _figure(2, 3.0)
    ref_m, ref_g = chosen_traj.theta_rad(t_m), chosen_traj.theta_rad(grid_t)
    tc, dc = np.meshgrid(times_c, dists_c * 1e3, indexing="ij")
    tau = grid_t[None, :] - tc.reshape(-1, 1)
    preds = np.arctan2(dc.reshape(-1, 1), -nominal.speed_m_s * tau)  # theta(t) = atan2(d, -v (t - t_ca))
    ax.fill_between(grid_t - ca, np.degrees(preds.min(axis=0)), np.degrees(preds.max(axis=0)), color="0.85",
                    label=f"{preds.shape[0]} candidates")
    x = np.broadcast_to(grid_t - ca, preds.shape)
    ax_r.add_collection(LineCollection(np.stack([x, 1e3 * (preds - ref_g)], axis=-1), colors="0.8", linewidths=0.4))
    ax.plot(t_m - ca, np.degrees(th_m), ".", color=TM_COLOUR, ms=3, label="measured")
    ax.plot(grid_t - ca, np.degrees(ref_g), color=CHOSEN_COLOUR, lw=1.5, label="chosen candidate")
    resid = 1e3 * (th_m - ref_m)
    ax_r.plot(t_m - ca, resid, ".", color=TM_COLOUR, ms=3, label="measured - chosen")
    ax_r.axhline(0.0, color=CHOSEN_COLOUR, lw=1.5)
    if truth is not None:
        # truth theta is about Dimorphos with its true velocity: drawn for reference only
        ax.plot(truth.obt_s - ca, np.degrees(truth.theta_rad), color=TRUTH_COLOUR, lw=0.8, ls="--", label="truth")
    span = max(3 * float(np.percentile(np.abs(resid), 95)), 1.0)
    ax_r.set_ylim(-span, span)
    for a in (ax, ax_r):
        _ca_lines(a, cfg)
        a.set_xlim(grid_t[0] - ca, grid_t[-1] - ca)
        a.legend(loc="upper left", fontsize=8)
    ax.set_ylabel("theta, deg")
    ax_r.set_ylabel("theta - chosen, mrad")
    s.png = png_bytes(fig, cfg.plot_dpi)
    return s


def estimates_section(data: RunData, figs: RunFigures, cfg: ReportConfig) -> Section:
    """Estimated minus true C/A (to Dimorphos) time and distance over time, grid and continuous (with one sigma),
    and where the Didymos barycentre's C/A lies on the same axes; the line-of-sight offsets solved on board."""
    s = Section("C/A estimates against the truth",
                "On-board estimates of the C/A time and distance minus the true C/A to Dimorphos, as they evolved "
                "(EstimateReport; grid choice also from housekeeping). The dashed line is the C/A to the Didymos "
                "barycentre on the same axes.", file_name="ca_estimates.png")
    tm, ca = data.telemetry, figs.true_ca_obt_s
    d_true = figs.true_ca_distance_km
    hk_t, (hk_ca, hk_d) = _housekeeping(tm).present("best_ca_obt_s", "best_ca_distance_km")
    hk = hk_t.size > 0
    est = tm.estimates if tm else []
    if not est:
        s.missing.append("no EstimateReport in the telemetry" if tm else "no telemetry")
    if not hk and tm is not None:
        s.missing.append("no best trajectory in the housekeeping")
    if not est and not hk:
        return s
    offsets = los_offset_series(est, ca)
    fig, axes = _figure(3 if offsets.size else 2, 2.8)
    ax_t, ax_d = axes[:2]
    if hk:
        ax_t.plot(hk_t - ca, hk_ca - ca, ".", color="0.6", ms=3, label="grid (HK)")
        ax_d.plot(hk_t - ca, hk_d - d_true, ".", color="0.6", ms=3, label="grid (HK)")
    grid = [(t, e.grid_ca_obt_s, e.grid_ca_distance_km) for t, e in est if e.grid_ca_obt_s is not None]
    cont = [(t, e.continuous_ca_obt_s, e.continuous_ca_distance_km, e.continuous_sigma_time_s,
             e.continuous_sigma_distance_km) for t, e in est if e.continuous_ca_obt_s is not None]
    if grid:
        g = np.array(grid, dtype=float)
        ax_t.step(g[:, 0] - ca, g[:, 1] - ca, where="post", color=CHOSEN_COLOUR, label="grid")
        ax_d.step(g[:, 0] - ca, g[:, 2] - d_true, where="post", color=CHOSEN_COLOUR, label="grid")
    if cont:
        c = np.array(cont, dtype=float)
        x = c[:, 0] - ca
        for ax, val, sig in ((ax_t, c[:, 1] - ca, c[:, 3]), (ax_d, c[:, 2] - d_true, c[:, 4])):
            ax.plot(x, val, color=TM_COLOUR, label="continuous")
            ax.fill_between(x, val - sig, val + sig, color=TM_COLOUR, alpha=0.2, label="continuous 1 sigma")
    for ax, bary in ((ax_t, figs.didymos_ca_obt_s - ca), (ax_d, figs.didymos_ca_distance_km - d_true)):
        ax.axhline(0.0, color="k", lw=0.8, label="Dimorphos (truth)")
        ax.axhline(bary, color="k", lw=0.8, ls="--", label="Didymos barycentre")
        _ca_lines(ax, cfg)
        ax.legend(loc="upper right", fontsize=8)
    ax_t.set_ylabel("C/A time error, s")
    ax_d.set_ylabel("C/A distance error, km")
    if offsets.size:
        b = np.asarray(data.scenario.universe.camera.boresight_body, dtype=float)
        b = b / np.linalg.norm(b)
        off_mrad = np.arccos(min(1.0, float(b[2]))) * 1e3
        s.notes.append(f"line-of-sight offset solved on board (last estimate): in plane {offsets[-1, 1]:+.3f} mrad, "
                       f"out of plane {offsets[-1, 2]:+.3f} mrad; the true camera boresight is {off_mrad:.3f} mrad "
                       f"off body +Z (x {b[0] * 1e3:+.3f}, y {b[1] * 1e3:+.3f} mrad)")
        ax_o = axes[2]
        ax_o.plot(offsets[:, 0], offsets[:, 1], color=TM_COLOUR, label="in plane")
        ax_o.plot(offsets[:, 0], offsets[:, 2], color=CHOSEN_COLOUR, label="out of plane")
        # each component of a constant offset lies within its magnitude, whatever the tracking's roll
        for sign in (1.0, -1.0):
            ax_o.axhline(sign * off_mrad, color="k", lw=0.8, ls="--", label="true boresight offset, magnitude"
                         if sign > 0 else None)
        _ca_lines(ax_o, cfg)
        ax_o.set_ylabel("LOS offset solved on board, mrad")
        ax_o.legend(loc="upper right", fontsize=8)
    s.png = png_bytes(fig, cfg.plot_dpi)
    return s


def los_offset_series(estimates: Sequence[tuple[float, pus.EstimateReport]], ca_obt_s: float) -> np.ndarray:
    """(n, 3): OBT minus the true C/A (s), and the in-plane and out-of-plane line-of-sight offsets solved on board
    (mrad), of each EstimateReport that carries them (the dictionary makes the two come together)."""
    rows = [(t - ca_obt_s, e.los_offset_in_plane_rad * 1e3, e.los_offset_out_of_plane_rad * 1e3)
            for t, e in estimates if e.los_offset_in_plane_rad is not None]
    return np.array(rows, dtype=float).reshape(-1, 3)


def centroid_section(data: RunData, figs: RunFigures, cfg: ReportConfig) -> Section:
    """Distance of each detected Dimorphos centroid from its true projection (binned px), with the tolerance."""
    tol = cfg.centroid_tolerance_px
    s = Section("Centroid error", f"Detected Dimorphos centroid (NavigationReport) minus the truth projection at the "
                f"binned scale; the paper's tolerance is {tol:g} px.", file_name="centroid_error.png")
    ids, errs = centroid_errors_px(data)
    if not ids.size:
        s.missing.append("no detection with a true position to compare (needs NavigationReports and the truth)")
        return s
    assert data.truth is not None  # centroid_errors_px found pairs, so the truth is there
    obt_of = {int(f): t for f, t in zip(data.truth.frame_id, data.truth.obt_s, strict=True) if f >= 0}
    t = np.array([obt_of[int(i)] for i in ids]) - figs.true_ca_obt_s
    fig, (ax,) = _figure(1, 2.8)
    ax.semilogy(t, np.maximum(errs, 1e-2), ".", color=TM_COLOUR, ms=4, label="|detected - true|")
    ax.axhline(tol, color=LIMIT_COLOUR, ls="--", lw=1.2, label=f"tolerance {tol:g} px")
    _ca_lines(ax, cfg)
    ax.set_ylabel("centroid error, binned px")
    ax.legend(loc="upper left", fontsize=8)
    over = int((errs > tol).sum())
    s.notes.append(f"{errs.size} detections compared, {over} beyond {tol:g} px, median {np.median(errs):.2f} px")
    s.png = png_bytes(fig, cfg.plot_dpi)
    return s


def mode_intervals(changes: Sequence[tuple[float, pus.ModeChangedEvent]], hk: Sequence[tuple[float, int]],
                   end_obt_s: float) -> list[tuple[float, float, int]]:
    """(start OBT, end OBT, mode) intervals: from the mode-change events, else from housekeeping modes."""
    if changes:
        ch = sorted(changes, key=lambda c: c[0])
        first = hk[0][0] if hk else ch[0][0]
        out = [(min(first, ch[0][0]), ch[0][0], int(ch[0][1].from_mode))] if first < ch[0][0] else []
        for (t, ev), nxt in zip(ch, [*ch[1:], None], strict=True):
            out.append((t, nxt[0] if nxt is not None else max(end_obt_s, t), int(ev.to_mode)))
        return out
    out = []
    for (t, m), nxt in zip(hk, [*hk[1:], None], strict=True):
        stop = nxt[0] if nxt is not None else max(end_obt_s, t)
        if out and out[-1][2] == m:
            out[-1] = (out[-1][0], stop, m)
        else:
            out.append((t, stop, int(m)))
    return out


def modes_section(data: RunData, figs: RunFigures, cfg: ReportConfig) -> Section:
    """The on-board mode against time."""
    s = Section("Mode timeline", "On-board mode from the ModeChangedEvents (housekeeping mode as dots).",
                file_name="modes.png")
    tm, ca = data.telemetry, figs.true_ca_obt_s
    if tm is None or (not tm.mode_changes and not tm.housekeeping):
        s.missing.append("no mode-change event and no housekeeping in the telemetry")
        return s
    hk = list(zip(tm.housekeeping.t_s.tolist(), tm.housekeeping.column("mode").astype(int).tolist(), strict=True))
    if not tm.mode_changes:
        s.missing.append("no ModeChangedEvent: timeline from housekeeping only")
    last = max([t for t, _ in hk] + [t for t, _ in tm.mode_changes])
    fig, (ax,) = _figure(1, 2.4)
    colours = {0: "tab:red", 1: "tab:gray", 2: "tab:orange", 3: "tab:blue", 4: "tab:green"}
    for t0, t1, m in mode_intervals(tm.mode_changes, hk, last):
        ax.broken_barh([(t0 - ca, max(t1 - t0, 0.1))], (m - 0.4, 0.8), color=colours.get(m, "k"))
        s.notes.append(f"{MODE_NAMES.get(m, m)} from C/A{t0 - ca:+.1f} s to C/A{t1 - ca:+.1f} s")
    if hk:
        a = np.array(hk, dtype=float)
        ax.plot(a[:, 0] - ca, a[:, 1], "k.", ms=2)
    ax.set_yticks(list(MODE_NAMES), [MODE_NAMES[m] for m in MODE_NAMES])
    _ca_lines(ax, cfg)
    s.png = png_bytes(fig, cfg.plot_dpi)
    return s


def mosaic_section(data: RunData, figs: RunFigures, cfg: ReportConfig) -> Section:
    """A mosaic of frames spread over the flyby with the detected (+) and true (o) positions drawn."""
    s = Section("Camera frames", "Frames spread over the flyby: red + detected Dimorphos, green o true Dimorphos, "
                "orange x detected Didymos, cyan o true Didymos (NavigationReport vs truth projection).",
                file_name="mosaic.png")
    if not data.frames:
        s.missing.append("no frame PNGs in frames/")
        return s
    if data.telemetry is None or not data.telemetry.navigation:
        s.missing.append("no NavigationReport: detections are not drawn")
    if data.truth is None:
        s.missing.append("no truth: true positions are not drawn")
    ids = spread_ids(list(data.frames), cfg.mosaic_frames)
    cols = int(np.ceil(np.sqrt(len(ids))))
    rows = int(np.ceil(len(ids) / cols))
    fig = Figure(figsize=(2.6 * cols, 2.75 * rows), layout="constrained")
    FigureCanvasAgg(fig)
    for k, fid in enumerate(ids):
        ax = fig.add_subplot(rows, cols, k + 1)
        img = load_gray(data.frames[fid])
        ax.imshow(img, cmap="gray", vmin=0, vmax=255, interpolation="nearest")
        m = frame_marks(data, fid, img.shape[1])
        styles = {"det_dim": ("+", "red", 12), "true_dim": ("o", "lime", 10), "det_did": ("x", "orange", 9),
                  "true_did": ("o", "cyan", 14)}
        for key, (marker, colour, size) in styles.items():
            if m[key] is not None:
                ax.plot(*m[key], marker, color=colour, ms=size, mfc="none", mew=1.2)
        obt = frame_obt_s(data, fid)
        when = "" if obt is None else f"  C/A{obt - figs.true_ca_obt_s:+.0f} s"
        ax.set_title(f"frame {fid}{when}", fontsize=8)
        ax.set_xlim(-0.5, img.shape[1] - 0.5)
        ax.set_ylim(img.shape[0] - 0.5, -0.5)
        ax.set_xticks([])
        ax.set_yticks([])
    s.png = png_bytes(fig, cfg.plot_dpi)
    return s




def timing_section(data: RunData, figs: RunFigures, cfg: ReportConfig) -> Section:
    """The on-board timing from housekeeping: latencies of the line of sight, longest task times, overruns."""
    s = Section("On-board timing", "Housekeeping: exposure to line of sight on board and line of sight to the torques "
                "using it (top); each task's longest execution time so far at the end of the run (bottom).",
                file_name="timing.png")
    hk = None if data.telemetry is None else data.telemetry.housekeeping
    if hk is None or hk.last is None:
        s.missing.append("no housekeeping in the telemetry")
        return s
    ca = figs.true_ca_obt_s
    fig, (ax, bx) = _figure(2, 2.6)
    for name, label in (("exposure_to_centroid_s", "exposure to line of sight"),
                        ("centroid_to_torque_s", "line of sight to torques")):
        t, (v,) = hk.present(name)
        if t.size:
            ax.plot(t - ca, 1e3 * v, ".-", ms=3, lw=0.8, label=label)
    ax.set_ylabel("latency, ms")
    _ca_lines(ax, cfg)
    ax.legend(fontsize=8)
    last = hk.last[1]
    bx.bar([t.name for t in Task], [1e3 * x for x in last.task_time_max_s], color=TM_COLOUR)
    bx.set_ylabel("longest execution, ms")
    bx.tick_params(axis="x", labelsize=7)
    s.notes.append(f"task overruns {last.task_overruns}, minor frame overruns {last.frame_overruns}, skipped "
                   f"releases {last.skipped_releases} (to the last housekeeping)")
    s.png = png_bytes(fig, cfg.plot_dpi)
    return s


def chart_sections(data: RunData, figs: RunFigures, cfg: ReportConfig) -> list[Section]:
    """Every chart section of the report, in reading order (the mosaic last)."""
    makers = (pointing_section, rate_section, wheels_section, theta_section, estimates_section, centroid_section,
              modes_section, timing_section, mosaic_section)
    return [make(data, figs, cfg) for make in makers]
