"""Configuration of the ground segment and of the space link it talks through.

"paper" in a description is the LICIACube navigation paper.
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from contracts.link import LinkConfig
from contracts.model import Config


class ReportConfig(Config):
    """The flyby report: the paper's requirement thresholds (each with its source) and how much imagery it shows."""

    in_view_required: float = Field(
        0.98,
        gt=0,
        le=1,
        description="fraction of camera frames with Dimorphos in the field of view required from the first "
        "frame of the first ACQUISITION to C/A + in_view_after_ca_s, fraction (paper: 98% nominal; worst-case "
        "scenarios set 0.90, paper: more than 90%)",
    )
    in_view_after_ca_s: float = Field(
        60.0, ge=0, description="the in-view and pointing windows end this long after the true C/A, s (the "
        "window holds the fast part of the flyby: 60 s after C/A the line-of-sight rate is below 2 % of its peak at "
        "the nominal 55 km and 7 km/s)",
    )
    max_pointing_error_fov_fraction: float = Field(
        0.5,
        gt=0,
        description="largest pointing error allowed, as a fraction of the field of view (paper: half the FOV)",
    )
    peak_rate_required_deg_s: float = Field(
        7.0, gt=0, description="body rate the spacecraft must reach, deg/s (paper: a peak of 7 deg/s)"
    )
    centroid_tolerance_px: float = Field(
        15.0,
        gt=0,
        description="largest distance of a Dimorphos centroid from the reference at the binned 512x512 scale, px "
        "(paper: an image test passes when the centroids are less than 15 pixels apart)",
    )
    estimate_before_ca_s: float = Field(
        30.0,
        gt=0,
        description="the C/A estimates are scored as they stood this long before the true C/A, s "
        "(the LICIACube navigation paper: autonomous tracking on the recognised trajectory starts at C/A-30 s)",
    )
    mosaic_frames: int = Field(
        16, ge=1, le=64, description="camera frames shown in the mosaic, count (a 4x4 grid: "
        "one frame every ~25 s of a 420 s flyby, each still legible at a quarter of the page width)"
    )
    gif_max_frames: int = Field(
        140, ge=1, description="frames at most in the animated GIF, count (a 512-px frame is ~40-70 kB as GIF: "
        "140 keep a 420-frame flyby under ~10 MB)"
    )
    gif_max_bytes: int = Field(
        10_000_000, gt=0, description="largest animated GIF, octets (10 MB: the usual attachment limit of "
        "mail and issue trackers); frames are thinned to fit"
    )
    gif_frame_ms: int = Field(
        100, ge=20, description="display time of each GIF frame, ms (10 frames per second: ~14 s for 140 frames)"
    )
    plot_dpi: int = Field(100, ge=50, le=300, description="resolution of the PNG plots, dots per inch (screen class)")


Vec3 = tuple[float, float, float]


class FlybyBelief(Config):
    """What ground believes of the flyby before the pass (its navigation's nominal trajectory and uncertainty).

    In a scenario it is the truth plus a knowledge error drawn with the seed (``universe.uncertainty``); the
    composition of a run computes it, the ground segment only uses it.
    """

    ca_utc_s: float = Field(description="nominal time of closest approach, s after the scenario epoch")
    ca_distance_km: float = Field(gt=0, description="nominal distance at closest approach, km")
    speed_km_s: float = Field(gt=0, description="relative speed, km/s")
    approach_direction: Vec3 = Field(description="unit vector of the relative velocity, inertial frame")
    ca_direction: Vec3 = Field(description="unit vector target -> spacecraft at closest approach, inertial frame")
    ca_time_sigma_s: float = Field(ge=0, description="one-sigma uncertainty of the C/A time, s")
    ca_distance_sigma_km: float = Field(ge=0, description="one-sigma uncertainty of the C/A distance, km")


class GroundConfig(Config):
    """What the ground segment does during a run."""

    step_period_s: float = Field(1.0, gt=0, description="how often ground exchanges with the link, s of UTC")
    apid: int = Field(0x0C1, ge=0, lt=2048, description="APID the ground addresses its telecommands to")
    source_id: int = Field(1, ge=0, le=0xFFFF, description="PUS source id of the ground's telecommands, the id "
                           "its verification reports come back to (ECSS-E-ST-70-41C)")
    upload_nominal_at_s: float | None = Field(
        None,
        description="true time at which ground uploads the nominal trajectory, s after the epoch "
        "(default: at the start of the run)",
    )
    link: LinkConfig = Field(
        LinkConfig(),
        description="ground's knowledge of the link (light time for upload margins and time reports); defaults to "
        "the true link, universe.link",
    )
    upload_bad_pixel_map: bool = Field(
        True,
        description="upload the camera's bad-pixel map (pus.LoadBadPixelMap) with the nominal trajectory, from ground's "
        "calibration: the pixels of a dark frame at the planned exposure more than bad_pixel_k_sigma above its median "
        "(hot and warm pixels), and the dead pixels and columns of the sensor (found in flat fields); "
        "scenario/compose.py",
    )
    bad_pixel_k_sigma: float = Field(
        5.0, gt=0, description="a dark-frame pixel this many robust sigmas above the frame's median is bad, sigma "
        "(five sigma: about one false pixel per 3.5 million of Gaussian read noise)"
    )
    timeline_file: str | None = Field(
        None, description="command timeline (YAML or CSV) uploaded after the nominal trajectory; a relative path is "
        "taken from the scenario file's folder"
    )
    upload_margin_s: float = Field(
        5.0, ge=0, description="ground refuses timeline commands tagged earlier than now + light time + this, s"
    )
    a_priori_obt_offset_s: float = Field(
        26_499_202.0,
        description="OBT minus UTC (s from the epoch) that ground assumes before any time report, s "
        "(default: the oscillator's default, a clock counting from launch)",
    )
    verification_margin_s: float = Field(
        10.0, ge=0, description="a radiated telecommand's acceptance report is awaited for the round-trip light time, "
        "its transmission and this margin, s; then the TC is re-sent (a new sequence count) or, after max_resends, an "
        "alarm is raised (10 s: a few ground steps and the on-board processing, far below a light time)")
    max_resends: int = Field(2, ge=0, description="times a telecommand without acceptance is re-sent before the alarm")
    alarm_severity: Literal["LOW", "MEDIUM", "HIGH"] = Field(
        "MEDIUM", description="an on-board event report of at least this severity raises an alarm (ECSS-E-ST-70-41C "
        "service 5: medium and high severity are anomaly reports)")
    time_report_rate_exponent: int = Field(
        2, ge=0, le=16, description="ask for a service 9 time report every 2^n OBT s (PUS 9,1)"
    )
    correlation_window: int = Field(
        200, ge=3, description="number of most recent time reports the OBT-UTC fit uses"
    )
    report: ReportConfig = ReportConfig()
