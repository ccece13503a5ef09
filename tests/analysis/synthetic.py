"""A synthetic run folder whose figures are set by construction, for the analysis tests.

Dimorphos passes at 54 km at t = 168 s (the true C/A, on a straight line at 7 km/s), while the scenario puts the
Didymos barycentre's C/A at 167.75 s and 55 km, so figures against the one and the other tell them apart.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import cv2
import numpy as np
import yaml

from contracts import pus
from contracts.messages import TruthRecord
from ground.archive import Archive
from ground.config import GroundConfig, ReportConfig
from ground.node import TruthLog
from scenario.model import Scenario, scenario_from_dict

OFF = 26_499_202.0  # OBT at the epoch (oscillator default): OBT = t + OFF exactly, no drift
CA_T = 168.0  # true C/A to Dimorphos, s after the epoch
CA_OBT = CA_T + OFF
CA_D_KM = 54.0  # true C/A distance to Dimorphos, km
SPEED_M_S = 7000.0
BARY_T = 167.75  # C/A to the Didymos barycentre (the scenario's universe.flyby), s after the epoch
BARY_D_KM = 55.0
APID = 0x0C1
OUT_OF_VIEW_KS = range(-200, -191)  # 9 of the 300 frames in the window see no target
IN_VIEW_EXPECTED = 291 / 300
MAX_ERR_IN_WINDOW_DEG = 1.2
PEAK_RATE_DEG_S = 7.3
LOS_OFFSET_RAD = (2.5e-4, -1.0e-4)  # the on-board LOS offsets every EstimateReport carries
CENTROID_OFFSET_PX = (3.0, 4.0)  # detection minus truth: 5 px
SAVED_FRAME_KS = list(range(-240, 120, 18))  # 20 saved PNGs


def frame_k(j: int) -> int | None:
    """Frame k (exposed at C/A + k + 0.5 s) of truth row j, or None: frames are rows j = 3005 + 10 k."""
    return (j - 3005) // 10 if j % 10 == 5 else None


def true_binned(k: int) -> tuple[float, float]:
    """Dimorphos' true position in frame k at the binned 512 scale."""
    return 200.0 + 0.25 * k / 3, 300.0 - 0.125 * k / 3


def scenario() -> Scenario:
    """The synthetic scenario: defaults (55 km, 7 km/s, 2.9 deg FOV, 1024 px, 3 wheels) but barycentre C/A at BARY_T."""
    return scenario_from_dict({"name": "synthetic", "seed": 3, "universe": {"flyby": {"ca_time_s": BARY_T}}})


def dimorphos_from_spacecraft_m(t_s: float) -> np.ndarray:
    """Spacecraft-to-Dimorphos vector at true time t_s: a straight line passing CA_D_KM away at CA_T."""
    return np.array([-SPEED_M_S * (t_s - CA_T), -CA_D_KM * 1e3, 0.0])


def truth_record(j: int, max_err_deg: float, entry_err_deg: float = 0.5) -> TruthRecord:
    """Truth row j (t = j / 10 - 132): pointing, view and rate series set so their figures are known;
    ``entry_err_deg`` on the rows between ACQUISITION's entry (C/A-240.25 s) and its first frame (C/A-239.5 s)."""
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
    if -240.25 <= tau < -239.5:
        err_deg = entry_err_deg  # the slew onto the target, before the first frame
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
    rel = dimorphos_from_spacecraft_m(t)
    rng = float(np.linalg.norm(rel))
    return TruthRecord(
        t_s=t, obt_s=t + OFF, q=(0.0, 0.0, 0.0, 1.0), omega_rad_s=(0.6 * rate, 0.0, 0.8 * rate),
        wheel_momentum_nms=(0.01, -0.02, 0.03), wheel_torque_nm=(0.001, 0.0, -0.001),
        pointing_error_rad=math.radians(err_deg), target_in_fov=in_fov, range_m=rng, theta_rad=0.5,
        phase_angle_deg=50.0, frame_id=None if k is None else k + 300, dimorphos_px=dim,
        didymos_px=None if dim is None else (dim[0] + 40.0, dim[1]),
        los_dimorphos_inertial=tuple(float(c) for c in rel / rng),
        range_didymos_m=math.hypot(BARY_D_KM * 1e3, SPEED_M_S * (t - BARY_T)),
    )


def los(obt_s: float) -> tuple[float, float, float]:
    """Measured line of sight to Dimorphos (e_v = x, e_ca = y), unit vector."""
    tau = obt_s - CA_OBT
    r = np.array([SPEED_M_S * tau, CA_D_KM * 1e3, 0.0])
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
            grid_ca_distance_km=CA_D_KM + (1.5 if before else 9.0), grid_mse_rad2=1e-8,
            continuous_ca_obt_s=CA_OBT + (-1.5 if before else 77.0), continuous_ca_distance_km=CA_D_KM - 0.75,
            continuous_sigma_time_s=0.5, continuous_sigma_distance_km=0.2,
            los_offset_in_plane_rad=LOS_OFFSET_RAD[0], los_offset_out_of_plane_rad=LOS_OFFSET_RAD[1])))
    return sorted(out, key=lambda p: p[0])


def make_run(run: Path, *, max_err_deg: float = MAX_ERR_IN_WINDOW_DEG, outlier_px: float | None = None,
             telemetry: bool = True, frames: bool = True, truth_rows: int = 4200, cfg: ReportConfig | None = None,
             entry_err_deg: float = 0.5) -> Path:
    """Write a synthetic run folder: scenario.yaml, truth.csv, and optionally tm.bin + archive.sqlite and PNGs."""
    run.mkdir(parents=True, exist_ok=True)
    sc = scenario()
    if cfg is not None:
        sc = sc.model_copy(update={"ground": GroundConfig(report=cfg)})
    (run / "scenario.yaml").write_text(yaml.safe_dump(sc.model_dump(mode="json")))
    log = TruthLog(run / "truth.csv")
    for j in range(truth_rows):
        log.add(truth_record(j, max_err_deg, entry_err_deg))
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
