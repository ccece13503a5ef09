"""Configuration of the on-board software: rates, gains and mode thresholds, all in on-board time.

"paper" in a description is the LICIACube navigation paper.
"""

from __future__ import annotations

from typing import Any, Literal

from pydantic import Field, ValidationError, field_validator, model_validator

from contracts.checks import inertia_problem
from contracts.dictionary import DICTIONARY, CheckType, EventId, MonitoringDefinition, Parameter, Severity
from contracts.model import Config
from obsw.table import ScheduleTable
from obsw.timing import TimingConfig


class ControlConfig(Config):
    """PD attitude control on quaternion error and body rate (paper: PD baseline, no integral term)."""

    # Worst case (paper: one gain set, tuned on the nearest C/A): 40 km at 7 km/s, peak LOS rate v/d = 0.175 rad/s
    # (10 deg/s), peak LOS acceleration 0.65 (v/d)^2 = 0.020 rad/s^2, a slew about body Y (0.117 kg m^2): peak
    # feedforward torque 0.117 x 0.020 = 0.0023 N m (33 % of one wheel's 0.007 N m), peak momentum 0.117 x 0.175 =
    # 0.020 N m s (20 % of 0.1 N m s): feasible with margin for the PD's correction torques.
    kp_nm_per_rad: float = Field(
        0.26,
        gt=0,
        description="proportional gain, N m per rad of attitude error (wn = 1.5 rad/s about body Y, 0.117 kg m^2; "
        "without feedforward the worst-case lag I alpha / kp would be 0.5 deg, with it < 0.02 deg)",
    )
    kd_nms_per_rad: float = Field(
        0.32,
        gt=0,
        description="derivative gain, N m per rad/s of rate error (damping 0.9 about body Y, 0.8 about X, 1.3 "
        "about Z; kd dt / I_z = 0.55 keeps the 10 Hz loop far from its sampling limit of 2)",
    )
    feedforward: bool = Field(True, description="add the reference angular acceleration times inertia")


class RecognitionConfig(Config):
    """Trajectory recognition: the candidate grid of (C/A time, C/A distance) and the continuous estimate beside it."""

    grid_span_sigma: float = Field(
        3.0, gt=0, description="the grid spans +- this many one-sigma uncertainties, sigma (paper: 3-sigma interval)"
    )
    grid_time_points: int = Field(
        13, ge=1, description="candidates along C/A time, odd so the nominal is the centre (13: half-sigma cells)"
    )
    grid_distance_points: int = Field(
        13, ge=1, description="candidates along C/A distance, odd so the nominal is the centre (13: half-sigma cells)"
    )
    angle_noise_rad: float = Field(
        1.0e-4,
        gt=0,
        description="one-sigma noise of a measured LOS angle, rad (one 512-px centroid pixel over 2.9 deg is "
        "9.9e-5 rad; the star tracker's 6 arcsec cross-boresight is 2.9e-5 rad)",
    )
    residual_cap_rad: float = Field(
        0.01,
        gt=0,
        description="grid residuals are capped here, rad: a false detection (anywhere in the 2.9 deg FOV, up to "
        "0.035 rad off the target) then adds the same cost to every far candidate and cannot flip the choice",
    )
    outlier_gate_sigma: float = Field(
        5.0, gt=0, description="the continuous estimate ignores residuals beyond this many angle_noise_rad, sigma"
    )
    max_iterations: int = Field(
        30, ge=1, description="Gauss-Newton iterations per solve of the continuous estimate (converges in < 10)"
    )
    los_offset_sigma_rad: float = Field(
        3.5e-4,
        ge=0,
        description="one-sigma prior of a constant offset of the measured LOS, rad, solved in the continuous "
        "estimate in plane and out of it (3.5e-4: 0.02 deg, a CubeSat camera's alignment to its star tracker after "
        "launch, mechanical and thermoelastic; an assumption of this emulator, as in configs/dispersions/flyby.yaml); "
        "0 holds it at zero, the paper's estimate",
    )

    @field_validator("grid_time_points", "grid_distance_points")
    @classmethod
    def _odd(cls, v: int) -> int:
        if v % 2 == 0:
            raise ValueError(f"must be odd so the nominal trajectory is the centre of the grid, got {v}")
        return v


class TrackingConfig(Config):
    """Second-order (type-2) tracking loop on the image feedback (paper: 'Tracking and Trajectory Recognition')."""

    natural_frequency_rad_s: float = Field(
        0.3,
        gt=0,
        description="natural frequency of the correction loop, rad/s: five times below the 1.5 rad/s attitude "
        "loop so the PD follows it, and settling (4/(zeta wn) = 17 s) well inside the 240 s acquisition phase",
    )
    damping: float = Field(
        0.8,
        gt=0,
        description="damping ratio of the correction loop (paper: tuned on the overshoot; 0.8 gives the type-2 "
        "loop's step an 18 % overshoot, 13.5 % being the least, at critical damping, for a slower settling)",
    )
    extrapolation_limit_s: float = Field(
        3.0,
        gt=0,
        description="the last measured offset is extrapolated along its last slope for at most this long, then "
        "held, s (three frame periods at the 1 s default camera cadence)",
    )
    gate_release_count: int = Field(
        4,
        ge=0,
        description="after this many consecutive measurements ignored by the innovation gate the next is taken "
        "whatever its offset, count (4: two seconds at the 0.5 s cadence around C/A, longer than one "
        "misidentified blob lasts, shorter than the loop's 17 s settling)",
    )
    autonomous_gate_deg: float = Field(
        0.12,
        gt=0,
        description="in AUTONOMOUS_TRACKING, a measured LOS whose offset from the recognised trajectory is this "
        "far from the loop's prediction is not fed back, deg (21 px at 512: twice the largest innovation of a "
        "valid detection, 0.06 deg, in the bench/closedloop.py flybys; a part of the crescent taken for Dimorphos "
        "at C/A+48 s in worst-early-far was 0.17 deg off)",
    )
    autonomous_extrapolation: bool = Field(
        False,
        description="in AUTONOMOUS_TRACKING, extend the measured offset along its slope between frames (False: "
        "hold it; the recognised trajectory carries the LOS motion, so a slope is noise or a misidentified "
        "blob, and one at C/A+48 s drove the pointing 1.2 deg off in 3 s of extrapolation)",
    )
    recognised_when_unseen_s: float | None = Field(
        3.0,
        gt=0,
        description="in NOMINAL_TRACKING, and in ACQUISITION after the target was lost, once Dimorphos has not been "
        "seen for this long and its trajectory is recognised on board, the camera points on the recognised "
        "trajectory until it is seen again, s (None: on ground's nominal, as the paper). Dimorphos hidden behind "
        "Didymos after its trajectory was recognised (bench/envelope.py roll 0 phase 150, roll 180 phase 30) drifted "
        "0.5-1.5 deg on a nominal 6 s off in C/A time and was lost; 3 s: the loop's extrapolation_limit_s",
    )
    didymos_cross_check: bool = Field(
        True,
        description="Didymos's line of sight from every frame that finds it is recognised apart, and Dimorphos's "
        "recognised trajectory is trusted only while the two agree: C/A times within the largest distance between "
        "the two centroids (the orbit's radius plus both bodies' largest apparent radii, targets) over the speed, "
        "C/A distances within that distance, each plus cross_check_sigma of their uncertainties combined; while it "
        "is not trusted, Didymos stands in, pointed on and predicting the frames with its own trajectory. A "
        "recognition 0.4 s off at C/A-159 s was dragged 14 s off by the next lines of sight, of Dimorphos beside "
        "Didymos, trusted by their count, and pointed on: the target was lost (60 % in view; bench/envelope.py "
        "configs/scenarios/worst-late-near.yaml roll 315 phase 330)",
    )
    cross_check_sigma: float = Field(
        3.0, gt=0, description="the cross-check's allowance beyond the largest distance between the centroids, in "
        "combined one-sigma uncertainties of the two recognised trajectories, sigma",
    )
    cross_check_recent: int = Field(
        20, ge=1, description="Didymos's lines of sight, the most recent, whose fit judges whether its recognition "
        "may contradict Dimorphos's (cross_check_fit_sigma)",
    )
    cross_check_fit_sigma: float = Field(
        3.0, gt=0, description="Didymos's recognition contradicts Dimorphos's only while the median absolute residual "
        "of its last cross_check_recent lines of sight is under this many recognition.angle_noise_rad, sigma (a "
        "Gaussian's is 0.67): with the plume taken for Didymos in some frames (configs/scenarios/faults/"
        "plume-x100.yaml) it was 6-10 where Didymos's and a right Dimorphos's disagreed, 0.1-0.7 where a Dimorphos "
        "dragged off disagreed (bench/envelope.py worst-late-near); 1 lost the latter's target again",
    )
    stand_in_pointed_on: bool = Field(
        True,
        description="in NOMINAL_TRACKING and ACQUISITION, while Dimorphos's trajectory is not trusted and Didymos's "
        "stands in for it (didymos_stands_in), the camera points on Didymos's rather than ground's nominal (as in "
        "AUTONOMOUS_TRACKING). Dimorphos hidden behind Didymos through the whole approach with ground's nominal 3 "
        "sigma late (bench/envelope.py configs/scenarios/worst-late-far.yaml roll 0 phase 150): the loop, fed "
        "Didymos's lines of sight against a nominal 30 s off, lagged 1.5 deg behind them by C/A-12 s and lost the "
        "target (60 % in view)",
    )
    didymos_when_unseen_s: float | None = Field(
        10.0,
        gt=0,
        description="in NOMINAL_TRACKING and ACQUISITION, once Dimorphos has not been seen for this long (since it "
        "was last seen, or since ACQUISITION began) and its trajectory is not yet trusted, Didymos's trajectory, "
        "recognised on its own lines of sight "
        "(when they fit it within cross_check_fit_sigma), stands in for Dimorphos's: pointed on (with "
        "stand_in_pointed_on) and predicting the frames, its uncertainty widened by the orbit's radius, s (None: "
        "ground's nominal). Dimorphos a point at the root of its plume, seen a few frames, with ground's nominal 3 "
        "sigma late and near (worst-late-near, campaign seed 2026, run 39): the pointing drifted to 1.6 deg on the "
        "nominal and the target was lost three times; run 0 of that campaign, Dimorphos not found for 80 s of "
        "ACQUISITION, drifted to 1.40 deg before it was. 10 s: a few frames' dropout keeps the nominal",
    )
    didymos_stands_in: bool = Field(
        True,
        description="while Dimorphos is not found and its trajectory not yet recognised, Didymos is found, and the "
        "trajectory's uncertainty on Dimorphos's place in the frame is wider than Dimorphos can be from Didymos (the "
        "orbit's apparent radius), Didymos's line of sight stands in for Dimorphos's: the loop points on it, and a "
        "recognition of its own gives the trajectory pointed on and predicted, its uncertainty widened by the "
        "orbit's radius, until Dimorphos's is recognised. Dimorphos hidden behind or in front of Didymos through "
        "the approach (orbital phase 180 or 0 deg) lost the target without it: 0 of 16 such geometries of "
        "bench/envelope.py kept every requirement, 15 with it",
    )
    propagate_late_measurements: bool = Field(
        True,
        description="a line of sight that reaches the loop after its exposure is taken against the trajectory at "
        "its exposure time, so the trajectory carries it to the present (False: as if exposed when it reached the "
        "loop, the stale direction against the present prediction; for comparing the two in bench/latency.py)",
    )
    plane_normal_axis_body: tuple[float, float, float] = Field(
        (0.0, 1.0, 0.0),
        description="body axis held along the flyby-plane normal, so the slew is about it alone (body Y: the "
        "smaller transverse inertia, 0.117 vs 0.152 kg m^2); must be orthogonal to camera.boresight_body",
    )


class AttitudeConfig(Config):
    """Attitude determination: a multiplicative EKF on the star tracker and the gyro that estimates the gyro bias."""

    star_tracker_noise_arcsec: tuple[float, float, float] = Field(
        (6.0, 6.0, 40.0), description="one-sigma noise of a star tracker solution per body axis, arcsec (knowledge of "
        "universe.sensors.star_tracker.noise_arcsec)")
    gyro_arw_deg_sqrt_h: float = Field(0.15, ge=0, description="gyro angle random walk, deg/sqrt(h) (knowledge of "
                                       "universe.sensors.gyro.arw_deg_sqrt_h)")
    gyro_bias_walk_deg_s_sqrt_s: float = Field(
        1.0e-3, ge=0, description="rate random walk the filter allows for the gyro bias, deg/s per sqrt(s): far above "
        "the gyro's own (1 deg/h over an hour, 4.6e-6 deg/s/sqrt(s)) so that a bias step is followed within seconds "
        "instead of hours; a 0.05 deg/s step is estimated to 10 % in about 20 s (tests/obsw/test_attitude.py)")
    initial_attitude_sigma_deg: float = Field(1.0, gt=0, description="one-sigma attitude uncertainty before the first "
                                              "star tracker solution is folded in, deg")
    initial_bias_sigma_deg_s: float = Field(0.1, gt=0, description="one-sigma gyro bias uncertainty at start, deg/s "
                                            "(twice the largest bias step of configs/scenarios/faults)")
    bias_known_sigma_deg_s: float = Field(
        0.0025, gt=0, description="the bias estimate is taken as known (its parameter monitored) while its one-sigma "
        "uncertainty is below this, deg/s (the filter's steady state with the default noises is 0.0019 deg/s, reached "
        "in about 2 s; a long star tracker outage makes it unknown again)")
    outage_after_s: float = Field(0.5, gt=0, description="a star tracker outage is declared after this long without "
                                  "a reading, s (five updates of a 10 Hz tracker)")


class FdirConfig(Config):
    """Failure detection thresholds of the detectors that are not service 12 parameter checks."""

    wheel_window_s: float = Field(1.0, gt=0, description="wheel failure detection window: commanded impulse against "
                                  "measured momentum change, s (ten control periods)")
    wheel_min_impulse_nms: float = Field(
        1.0e-4, gt=0, description="a wheel is judged over a window only if its commanded impulse is at least this, "
        "N m s: three times the friction of a healthy wheel at the nominal flyby's largest speed (Coulomb 1e-5 N m plus "
        "viscous 1e-7 N m s x 200 rad/s over 1 s, universe.spacecraft.wheels), so friction stays below the "
        "missed fraction")
    wheel_missed_fraction: float = Field(
        0.5, gt=0, lt=1, description="a wheel whose measured momentum change differs from the commanded impulse by "
        "more than this fraction of it in a window fails that window (a failed or stuck wheel misses nearly all)")
    wheel_confirmations: int = Field(2, ge=1, description="consecutive failed windows that confirm a wheel failure")
    wheel_limit_fraction: float = Field(
        0.9, gt=0, le=1, description="a wheel whose momentum reached this fraction of max_momentum_nms in a window is "
        "not judged over it (the hardware cuts its torque at the limit)")
    frame_saturated_fraction: float = Field(
        0.5, gt=0, le=1, description="a frame with at least this fraction of sampled pixels at full scale is "
        "saturated (bodies are at most ~6 % of the frame at C/A, below 90 % of full scale)")
    frame_sample_stride: int = Field(4, ge=1, description="the saturation statistic samples every n-th row and "
                                     "column of the raw frame (65,536 of a 1024x1024 frame)")
    frame_timeout_s: float = Field(0.3, gt=0, description="a requested frame not delivered this long after the "
                                   "request is missing, s (it is exposed one control period after the request)")
    false_lock_gate_deg: float = Field(
        0.25, gt=0, description="a line of sight whose offset from the recognised trajectory moved more than this since "
        "the last accepted one is refused as a false lock, deg (44 px at 512: twice the tracking loop's autonomous "
        "gate, which the five closed-loop flybys never exceed with a valid detection)")
    false_lock_gate_growth_deg_s: float = Field(
        0.02, ge=0, description="the gate grows by this per second since the last accepted line of sight, deg/s (the "
        "Dimorphos offset from the barycentre turns with the line of sight; after 100 s the gate spans the field of "
        "view and anything is taken again)")
    false_lock_residual_sigma: float = Field(
        5.0, gt=0, description="a line of sight farther from the continuous C/A estimate's prediction than the "
        "apparent radius of Dimorphos plus this many one-sigma (centroid, attitude and estimate noise combined) is "
        "refused as a false lock, sigma (a normal deviate beyond 5 sigma has a probability of 5.7e-7: below 1e-3 over "
        "the ~500 lines of sight of a flyby)")
    false_lock_reference_lag_s: float = Field(
        30.0, ge=0, description="the residual is taken from the continuous C/A estimate as it stood this long before "
        "the exposure (during a run of refusals, before the run's first), s: a creep reaching the bound within the "
        "lag is refused against an estimate from before it began (at C/A-100 s of the nominal: 0.002 deg/s over the "
        "0.061 deg bound, 0.0013 deg/s over 0.039 deg with the LOS offset held at zero; the plume of "
        "configs/scenarios/faults/plume-x100.yaml moves 0.15 deg in 3 s)")
    uplink_first_seq_count: int = Field(0, ge=0, description="sequence count of the first telecommand ground "
                                        "radiates (ground.segment counts from 0 at the start of a run)")
    uplink_seq_modulo: int = Field(
        0x2000, ge=2, description="ground's radiated telecommands count modulo this (ground.segment: the counts from "
        "0x2000 up are those of the TCs it schedules)")


class EventActionConfig(Config):
    """An event-action definition loaded with the software (service 19): when ``event`` is reported, run
    ``command`` (a timeline command of the dictionary) with ``args``."""

    event: str = Field(description="event identifier name (contracts.dictionary.EventId)")
    command: str = Field(description="timeline command name of the telecommand to run")
    args: dict[str, Any] = Field(default_factory=dict, description="its arguments")
    enabled: bool = Field(True, description="enabled at start")

    @model_validator(mode="after")
    def _known(self) -> EventActionConfig:
        if self.event not in EventId.__members__:
            raise ValueError(f"event: {self.event!r} is not one of {', '.join(EventId.__members__)}")
        cls = DICTIONARY.commands.get(self.command)
        if cls is None:
            raise ValueError(f"command: {self.command!r} is not one of {', '.join(sorted(DICTIONARY.commands))}")
        try:
            cls.model_validate(self.args)
        except ValidationError as exc:
            raise ValueError("args: " + "; ".join(f"{'.'.join(str(p) for p in e['loc'])}: {e['msg']}"
                                                  for e in exc.errors())) from None
        return self

    def telecommand(self) -> Any:
        """The telecommand this action runs."""
        return DICTIONARY.commands[self.command].model_validate(self.args)


DEFAULT_MONITORING = (
    MonitoringDefinition(pmon_id=1, parameter=Parameter.GYRO_BIAS, check_type=CheckType.LIMIT, repetition=5,
                         low=0.0, high=1.7453292519943295e-04, severity=Severity.MEDIUM),
    MonitoringDefinition(pmon_id=2, parameter=Parameter.EXPOSURE_TO_CENTROID, check_type=CheckType.LIMIT,
                         repetition=3, low=0.0, high=0.6, severity=Severity.MEDIUM),
)
"""Default service 12 definitions: the estimated gyro bias within 0.01 deg/s (five times the estimate's noise with
the default filter, tests/obsw/test_attitude.py; the gyro's own bias instability is 1 deg/h), five samples in a
row; a frame's line of sight on board within 0.6 s of its exposure (three times the 0.2 s of the default timing
model: readout, FPGA stages and software), three samples in a row."""

DEFAULT_EVENT_ACTIONS = (EventActionConfig(event="WHEEL_FAILED", command="set_wheel_set", args={"wheels": 0}),)
"""Default service 19 definitions: a wheel found failed switches the control to the wheels not found failed."""


class ModesConfig(Config):
    """Mode manager thresholds (paper: acquisition from C/A-240 s, autonomous from C/A-30 s)."""

    acquisition_before_ca_s: float = Field(240.0, gt=0, description="enter ACQUISITION this long before C/A, s")
    autonomous_before_ca_s: float = Field(30.0, gt=0, description="enter AUTONOMOUS_TRACKING this long before C/A, s")
    standby_after_ca_s: float = Field(90.0, gt=0, description="return to STANDBY this long after C/A, s")
    target_lost_timeout_s: float = Field(10.0, gt=0, description="declare the target lost after this long unseen, s")
    acquisition_settle_deg: float = Field(
        0.3,
        ge=0,
        description="ACQUISITION entered from STANDBY or SAFE exposes its first frame once the estimated boresight is "
        "within this of the reference's, deg: the slew onto the target done. STANDBY holds its attitude while the "
        "target drifts, and the Monte Carlo late corners entered ACQUISITION up to 1.56 deg off, past half the "
        "field of view, where a frame at once is taken mid-slew; the ground's nominal line of sight is itself up "
        "to 0.8 deg off at a 3-sigma corner's C/A-210 s, and 0.3 deg more stays within the 1.45 deg half field",
    )
    acquisition_settle_timeout_s: float = Field(
        20.0,
        gt=0,
        description="... or this long after the entry, whichever comes first, s (a slew of 1.6 deg settles within "
        "6 s; a slower one, a failed wheel, still gets its frames)",
    )


class ImagingConfig(Config):
    """Imaging subsystem: binning, 12->8 bit compression, binarisation, labelling and target identification.

    Pixel quantities are at the binned (512x512) scale; brightness is in 8-bit compressed DN.
    """

    binned_size_px: int = Field(512, gt=0, description="side of the binned image, px (paper: 512x512)")
    compression_law: Literal["sqrt", "shift"] = Field(
        "sqrt",
        description="12->8 bit law: 'sqrt' = round(255 sqrt(v / vmax)), the square-root companding LUT of "
        "planetary cameras (MER/MSL), which keeps the shot-noise-limited faint signal; "
        "'shift' = v >> (bit_depth - 8), a plain linear truncation",
    )
    otsu_threshold: bool = Field(
        False,
        description="threshold at max(Otsu, noise floor) instead of the noise floor alone: Otsu's split cuts the "
        "diffuse plume off the bodies when they fill the frame, but with a few pixels of bodies it lands between "
        "the background and Didymos and loses a faint Dimorphos (the ejecta merged with a body are trimmed off by "
        "identification instead)",
    )
    noise_k_sigma: float = Field(
        5.0,
        gt=0,
        description="threshold floor = background median + this many robust sigmas (8-bit DN); 5 sigma gives "
        "about 0.1 Gaussian false pixel per 512x512 frame",
    )
    min_threshold_margin_dn8: int = Field(
        3,
        ge=1,
        le=254,
        description="threshold floor is at least this far above the background median, 8-bit DN (3 DN: about ten "
        "times the 0.29 DN quantisation noise, for frames whose noise is below one DN)",
    )
    outlier_filter: bool = Field(
        True, description="replace outliers (hot pixels, cosmic-ray streaks) before binning (obsw/imaging_filtering.py)"
    )
    outlier_k_sigma: float = Field(
        5.0,
        gt=0,
        description="noise margin of the outlier filter, in per-pixel noise sigmas (5: about one false candidate "
        "block in 10^6 of Gaussian noise); a block is examined when its brightest pixel exceeds the mean of the others "
        "by this much, a pixel replaced when it also exceeds outlier_ratio times its 3x3 median (above background) by "
        "this much",
    )
    outlier_ratio: float = Field(
        2.0,
        ge=1,
        description="a pixel more than this many times brighter (above background) than the median of its 3x3 "
        "neighbourhood is sharper than the optics can make it: a defect (the point-spread function keeps a lit "
        "pixel's median neighbour at more than half its level; a limb pixel has half its neighbourhood lit)",
    )
    min_body_area_px: int = Field(
        2,
        ge=1,
        description="smallest blob, px at 512 scale, that may be a body: a hot pixel or cosmic-ray hit binned "
        "is one pixel",
    )
    max_body_elongation: float = Field(
        8.0,
        ge=1,
        description="largest major/minor axis ratio (second moments) of a body; a lit crescent at 135 deg "
        "phase is about 5, a thin plume ray or a smeared star more",
    )
    dimorphos_max_separation_didymos_diameters: float = Field(
        2.0,
        gt=0,
        description="without a trajectory on board (no predicted geometry): largest Didymos-Dimorphos centroid "
        "distance in apparent Didymos diameters (orbit radius 1.19 km / diameter 0.78 km = 1.53, plus margin for the "
        "lit-extent bias); with one, the gate is the predicted orbit radius (obsw/imaging_identification.py)",
    )
    dimorphos_max_area_fraction: float = Field(
        0.3,
        gt=0,
        le=1,
        description="largest Dimorphos/Didymos blob area ratio when Dimorphos is first found (diameters 164/780 m "
        "give 0.044; margin for phase, a Didymos partly out of the frame and plume dust merged with Dimorphos; "
        "two pieces of Didymos's thin crescent after C/A are 0.4 or more: 0.3, from the five closed-loop flybys)",
    )
    deblend_levels: int = Field(
        32,
        ge=2,
        description="levels (8-bit, evenly spaced from the threshold to the peak) at which Didymos's region is split "
        "when Dimorphos was not found in it: SExtractor's DEBLEND_NTHRESH default (Bertin & Arnouts 1996, A&AS 117, "
        "393; obsw/imaging_identification.py, Regions.deblended)",
    )
    deblend_min_flux_fraction: float = Field(
        0.005,
        gt=0,
        lt=1,
        description="least share of a region's light (linear, above the threshold) a part must hold to be an object of "
        "its own when the region is deblended: SExtractor's DEBLEND_MINCONT default (Bertin & Arnouts 1996)",
    )
    dimorphos_min_peak_fraction: float = Field(
        0.3,
        ge=0,
        le=1,
        description="smallest Dimorphos/Didymos brightness ratio in 8-bit DN above the threshold (same albedo; "
        "rejects faint stars, the diffuse plume and small clumps of it; sqrt compression maps a 10x dimmer surface to "
        "0.32): of their peaks without a prediction, and with one, of the light each holds in the best-lit quarter "
        "of Dimorphos's expected area, the part of each disc nearest normal incidence whatever the phase and the "
        "shading law (obsw/imaging_identification.py, aperture_dn8), times what the blur leaves of the peak of "
        "Dimorphos's narrower crescent against Didymos's (_peak_kept_by_blur)",
    )
    dimorphos_max_relative_jump_didymos_diameters: float = Field(
        0.5,
        gt=0,
        description="largest change between frames of the Dimorphos offset from Didymos, in Didymos diameters "
        "(at C/A the 1.19 km baseline turns at up to 7/55 rad/s, 0.13 of the 1.5 diameter separation per s)",
    )
    crescent_min_elongation: float = Field(
        3.0,
        ge=1,
        description="a Didymos blob at least this elongated (major/minor axis ratio) is a thin crescent, seen at high "
        "phase after C/A, that the threshold may break into pieces (a disc is 1, a half-lit disc about 2)",
    )
    crescent_gap_px: int = Field(
        3,
        ge=0,
        description="a blob within this many pixels of a crescent Didymos's box, px at 512 scale, may be a piece of "
        "it and is not taken for Dimorphos (the pieces seen in the closed-loop flybys were 1 px apart)",
    )
    pair_memory_frames: int = Field(
        20,
        ge=1,
        description="frames, counted from the last one that saw both bodies, through which their relative offset "
        "still gates the identification while Dimorphos is not seen (merged with Didymos and its ejecta: up to 8 "
        "frames around C/A-150 s in the closed-loop flybys), when Didymos spanned pair_memory_max_didymos_px; a "
        "smaller (farther) Didymos is remembered longer in proportion (the offset changes at the approach speed over "
        "the range, and the range is inversely proportional to Didymos's apparent size: 20 frames at 20 px, 40 at "
        "10 px: a 9 px Didymos forgotten after 20 frames let a brighter fan root be taken for it, held-out run 165 of "
        "worst-late-near); 20 frames span 20 s at the approach cadence of 1 Hz",
    )
    pair_memory_max_didymos_px: float = Field(
        20.0,
        gt=0,
        description="the remembered pair is used only while Didymos spanned at most this many px at 512 scale "
        "(range > ~400 km): the 1.19 km offset then changes by under 2 %/s (7 km/s / 400 km), a third of it in "
        "20 s, inside the jump gate; nearer C/A it turns too fast to be remembered",
    )
    centroid_noise_px: float = Field(
        2.0,
        ge=0,
        description="centroid jitter allowed on top of every continuity gate, px at 512 scale (a few pixels of "
        "binarisation and shape change)",
    )
    prediction_sigma: float = Field(
        3.0,
        gt=0,
        description="the predicted geometry of a frame spans the trajectory's C/A time and distance +- this many "
        "one-sigma uncertainties, sigma (the recognition grid's 3-sigma interval, paper)",
    )
    blur_margin_px: float = Field(
        0.5,
        ge=0,
        description="the point-spread function widens a body's region above the threshold by about this much beyond "
        "its disc, px at 512 scale (a one-pixel Gaussian sigma at full resolution is half a binned pixel)",
    )
    dimorphos_radius_margin_of_didymos: float = Field(
        2.5,
        ge=1,
        description="Dimorphos's apparent radius is at most this many times Didymos's measured radius scaled by "
        "their diameters' ratio (same range): both shapes (apparent radius up to 1.5 times the mean sphere's "
        "for one, 1.5^2 = 2.25 for the pair at worst) and the diameters' knowledge (3 sigma, 10 %)",
    )
    didymos_sizing_min_radius_px: float = Field(
        4.0,
        gt=0,
        description="Didymos's region measures the range (dimorphos_radius_margin_of_didymos) only when its radius "
        "is at least this, px at 512 scale: a smaller one is mostly blurred limb",
    )
    point_source_sigma_max_px: float = Field(
        0.67,
        gt=0,
        description="largest spread of a point source's light, one sigma, px at 512 scale: the camera's "
        "point-spread function of at most 1.2 full-resolution px sigma (ground calibration; the universe camera's is "
        "1.0) is 0.6 binned px, and the 2x2 binning adds a box of 1/12 px^2: sqrt(0.36 + 0.083) = 0.67. A star "
        "spreads no more; a body that must be resolved (radius at least twice this) is not taken for one",
    )
    didymos_min_report_probability: float = Field(
        0.95,
        ge=0,
        le=1,
        description="smallest probability that a point source taken for Didymos (its light spread no more than "
        "point_source_sigma_max_px allows) is Didymos rather than a star, for it to be reported: its light-and-place "
        "likelihood against the frame's stars (obsw/imaging_identification.py, _likeliest) over those of the point "
        "sources it was chosen among and of Didymos being none of them (unresolved_body_detected_prior). Shape "
        "cannot tell such a Didymos from a star; below it Didymos is reported unseen (a wrong line of sight is worse "
        "than none) and still serves the pair's continuity. 0.95: the conventional 95 % confidence. The probabilities "
        "are calibrated (bench/imaging.py seeds 1-6: 97 % of the Didymos given 0.9-0.99 right), so the threshold sets "
        "how many wrong lines of sight are let through: of the 152 reports of bodies under 3 px that 0.95 withholds "
        "and 0.9 let through on seeds 1-6 and 31-39, 9 lay beyond the paper's 15 px (README, imaging chain; bench/imaging.py prints the reports it "
        "withholds)",
    )
    dimorphos_min_report_probability: float = Field(
        0.95,
        ge=0,
        le=1,
        description="smallest probability that a point source taken for an unresolved Dimorphos is Dimorphos rather "
        "than a star, for it to be reported, as didymos_min_report_probability for Didymos; below it Dimorphos is "
        "reported unseen. 0.95: the same conventional confidence",
    )
    unresolved_body_detected_prior: float = Field(
        0.5,
        gt=0,
        le=1,
        description="prior probability that an unresolved body is among the frame's point sources at all (bright "
        "enough to be detected and not merged with another), against which the report probabilities weigh each "
        "point source near the body's place as the body or as one of the frame's stars "
        "(obsw/imaging_identification.py, _StarField). 0.5: even odds, no brightness model of an unresolved body on "
        "board; 1 takes the body to be one of them always",
    )
    phase_correction: bool = Field(
        True,
        description="move each body's centroid from its lit part to its centre by the phase-angle model of "
        "obsw/imaging_geometry.py (beyond the paper)",
    )
    limb_fit: bool = Field(
        True,
        description="when Dimorphos is cut out of a region it shares with Didymos or the plume, check the cut's "
        "centroid against the circle of its limb and take the limb's centre when they disagree "
        "(obsw/imaging_limb.py, beyond the paper)",
    )
    limb_fit_min_radius_px: float = Field(
        6.0,
        gt=0,
        description="the limb is fitted only when Dimorphos's smallest predicted apparent radius is at least this, "
        "px at 512 scale: a smaller body's cut lies within a few px of its centre anyway, and its limb is too short "
        "to fit",
    )
    limb_fit_max_phase_deg: float = Field(
        90.0,
        gt=0,
        le=180,
        description="the limb is fitted only at phase angles up to this, deg: beyond it the terminator, a soft "
        "edge, takes more than the body's radius off the lit disc (on the independent generator's transits at "
        "60-70 deg, cuts a radius off towards Didymos were moved within 4.2 px of the centre; at 70-90 deg the "
        "chain's own reports stayed within 4.9 px where the 70 deg limit left them up to 8.7 px, and beyond 90 deg "
        "the fit moved good cuts up to 8 px off; run 432 of the nominal's Monte Carlo campaign, 63 deg: 15.35 -> "
        "7.9 px; run 22 of a worst-late-near campaign, 73-90 deg, Dimorphos in a plume as bright as its surface: "
        "11.2 -> 1.4 px)",
    )
    limb_fit_pointing_margin_deg: float = Field(
        0.06,
        ge=0,
        description="the circle's centre is searched within the prediction's uncertainty, the centroid noise and "
        "this angle, deg: what the prediction does not model, the camera's misalignment to the star tracker "
        "(3 sigma of the 0.02 deg one-sigma boresight dispersion, configs/dispersions/flyby.yaml)",
    )
    dust_cut_fraction: float = Field(
        0.5,
        gt=0,
        lt=1,
        description="a Didymos region larger than both bodies' expected lit areas is cut to its pixels whose raw "
        "signal above the threshold is at least this fraction of its surface's typical signal (the median of its "
        "brightest Didymos's expected area): a fan of dust merged with it is fainter (the independent generator's "
        "fans, 0.1-0.7 of the surface's radiance at their source, Dimorphos, fading away from it; bench/imaging.py, "
        "seeds 1-5: at 0.25 a fan as bright as 0.35 of the surface near its source stayed merged); the cut is kept "
        "only when it moves the centroid as a dust fan does (dust_shift_tolerance_radii)",
    )
    dust_shift_tolerance_radii: float = Field(
        0.05,
        ge=0,
        description="the cut of dust_cut_fraction is kept when it moves the region's centroid across the Sun's "
        "direction in the image, or away from the Sun, by more than this many predicted radii plus a pixel: cutting "
        "a lit body's own faint pixels (its terminator and blurred limb, symmetric about the Sun's direction through "
        "it) moves it toward the Sun only (bench/imaging.py seeds 1-5: at most 0.01 radii across for every body of "
        "10 px radius and more without dust; 0.08-0.55 radii for the fans that moved Didymos's centre 11-25 px)",
    )
    limb_fit_max_disagreement_radii: float = Field(
        0.5,
        ge=0,
        description="the limb's centre replaces the cut's phase-corrected centroid only when they are more than this "
        "many predicted radii apart, or the centroid is off the predicted place (by more than its uncertainty and "
        "centroid_noise_px) and the circle on it: a cut holding the body's surface alone lies nearer, and is then the "
        "better of the two (the nominal flyby: the cut within 1 px of the centre, the limb up to 0.35 radii off, the "
        "body not a sphere), one holding Didymos's limb or the plume's core does not (the Monte Carlo cases: 0.8-1.3 "
        "radii)",
    )
    limb_fit_circle_error_radii: float = Field(
        0.35,
        ge=0,
        description="how far the fitted circle's centre may lie from the body's centre, in predicted radii (the "
        "nominal flyby: up to 0.35, the body not a sphere): where the cut lies off the predicted place (by more than "
        "its uncertainty and centroid_noise_px) and the circle does too, the circle is taken when it is off the place "
        "by no more than that allowance and this many radii, and nearer the place than the cut (held-out run 272 of "
        "worst-late-near at C/A-3 s: the cut on the plume's root above the body 12.1 px off a place known to 4 px and "
        "13.95 px off the centre, the circle 6.4 px off the place and 3.3 px off the centre)",
    )
    lit_limb_min_disagreement_radii: float = Field(
        1.0,
        ge=0,
        description="where the whole limb is not fitted (beyond limb_fit_max_phase_deg, or a place too loose for "
        "limb_fit_max_search_px), the centre of the circle whose sunward half steps down outward most, the lit "
        "limb, replaces the cut's phase-corrected centroid when they are more than this many predicted radii apart: "
        "a thin crescent's circle sits up to 0.4 of its radius sunward of the centre (it hugs the limb's best-lit "
        "middle), a cut of the root of a fan of ejecta beside it 1.3-2 radii off (bench/imaging.py seeds 31, 35, 37 "
        "at 101-118 deg: 20-25 px off, the circle 4-7 px)",
    )
    unlit_cut_refused: bool = Field(
        True,
        description="a cut off the predicted place (by more than its uncertainty and centroid_noise_px) whose limb is "
        "not found on the place (the lit limb beyond limb_fit_max_phase_deg, the whole limb below) is not reported "
        "as Dimorphos when no lit limb steps clearly (limb_fit_min_contrast) about the place either: at 130-165 deg "
        "of phase a crescent too thin to see leaves the bright root of the ejecta beside its dark disc as the "
        "brightest cut, 15-22 px off (bench/envelope.py's roll-180 row: 22 such reports in 3 cells, lit-limb "
        "contrast 0.7-2.6 at the place against 4-50 where a crescent is seen); an eclipsed Dimorphos beside the "
        "plume's edge likewise (worst-late-near's envelope, roll 0 phase 270: 18.6 px)",
    )
    limb_fit_max_search_px: float = Field(
        24.0,
        gt=0,
        description="the limb is fitted only when the circle's centre is to be searched within at most this radius, "
        "px at 512 scale: a prediction that precise comes from the recognised trajectory (the Monte Carlo cases: "
        "about 16 px with the pointing margin); it bounds the fit's cost, about 1.7 million samples",
    )
    limb_fit_min_contrast: float = Field(
        4.0,
        gt=0,
        description="the fitted circle is taken only when the median step along it is at least this many times the "
        "median step over the searched window: a limb runs round most of it (the Monte Carlo cases: 9.5-21)",
    )


class TargetKnowledge(Config):
    """What the flight software knows of Didymos, Dimorphos and the Sun (the truth is ``universe.bodies``)."""

    didymos_diameter_m: float = Field(780.0, gt=0, description="mean diameter of Didymos, m (paper)")
    dimorphos_diameter_m: float = Field(164.0, gt=0, description="mean diameter of Dimorphos, m (paper)")
    orbit_radius_m: float = Field(1190.0, gt=0, description="Dimorphos orbit radius, m (Naidu et al. 2020)")
    max_axis_ratio: float = Field(
        1.5,
        ge=1,
        description="largest ratio of a body's apparent radius to that of its mean-diameter sphere (Dimorphos's "
        "axes 177 x 174 x 116 m, Daly et al. 2023: 1.3 over the mean; margin for the unseen pre-impact shape)",
    )
    sun_direction_inertial: tuple[float, float, float] = Field(
        (-0.5, 0.5, 0.0),
        description="direction from the asteroids to the Sun, inertial frame (from the ephemerides; constant over "
        "the flyby)",
    )

    @field_validator("sun_direction_inertial")
    @classmethod
    def _nonzero(cls, v: tuple[float, float, float]) -> tuple[float, float, float]:
        if sum(c * c for c in v) < 1e-18:
            raise ValueError("must be a non-zero vector")
        return v

    @property
    def centroids_apart_max_m(self) -> float:
        """The farthest Dimorphos's and Didymos's centroids can be apart, m: the orbit's radius plus both bodies'
        largest apparent radii (a centroid lies within its body's disc)."""
        return self.orbit_radius_m + self.max_axis_ratio * (self.didymos_diameter_m + self.dimorphos_diameter_m) / 2


class CameraKnowledge(Config):
    """What the flight software knows of its camera (the true camera is ``universe.camera``; by default the same)."""

    fov_deg: float = Field(2.9, gt=0, lt=90, description="horizontal field of view, deg (paper)")
    resolution_px: int = Field(1024, gt=0, description="frame side, px (paper: 1024x1024 or 2048x2048)")
    bit_depth: int = Field(12, ge=8, le=16, description="bits per pixel of the raw frames (paper: 12)")
    boresight_body: tuple[float, float, float] = Field(
        (0.0, 0.0, 1.0), description="camera boresight in body axes (a CubeSat camera along the long +Z axis)"
    )
    exposure_s: float = Field(0.01, gt=0, description="exposure time until a command changes it, s")
    frame_period_s: float = Field(1.0, gt=0, description="time between frames until a command changes it, OBT s")

    @field_validator("boresight_body")
    @classmethod
    def _nonzero(cls, v: tuple[float, float, float]) -> tuple[float, float, float]:
        if sum(c * c for c in v) < 1e-18:
            raise ValueError("must be a non-zero vector")
        return v

    @model_validator(mode="after")
    def _exposure_fits_the_period(self) -> CameraKnowledge:
        if self.exposure_s >= self.frame_period_s:
            raise ValueError(f"exposure_s: {self.exposure_s:g} s must be shorter than frame_period_s "
                             f"{self.frame_period_s:g} s")
        return self


class WheelKnowledge(Config):
    """What the flight software knows of its reaction wheels (truth: ``universe.spacecraft.wheels``)."""

    layout: Literal["orthogonal", "pyramid"] = Field("orthogonal", description="three orthogonal or four in a pyramid")
    pyramid_angle_deg: float = Field(54.7356, gt=0, lt=90, description="pyramid wheel-axis elevation, deg")
    max_torque_nm: float = Field(0.007, gt=0, description="torque limit per wheel, N m (paper)")
    max_momentum_nms: float = Field(0.1, gt=0, description="momentum limit per wheel, N m s (paper)")
    inertia_kgm2: float = Field(
        1.0e-4, gt=0, description="wheel rotor inertia about its axis, kg m^2 (a CubeSat RW of 0.1 Nms at ~9500 rpm)"
    )


class ObswConfig(Config):
    """Everything the on-board software is configured with before the flyby."""

    housekeeping_period_s: float = Field(1.0, gt=0, description="PUS service 3 housekeeping period, OBT s")
    control_period_s: float = Field(0.1, gt=0, description="nominal control period, OBT s (10 Hz)")
    clock_jump_threshold_s: float = Field(
        0.05, gt=0, description="an OBT step this far from the control period between two periods is reported as a "
        "clock jump, s (well above oscillator drift and jitter: 20 ppm is 2 us per period)"
    )
    schedule_capacity: int = Field(256, ge=1, description="PUS service 11 time-based schedule capacity, entries")
    schedule_margin_s: float = Field(
        1.0, ge=0, description="a scheduled command must be tagged at least this far after now, OBT s"
    )
    autonomy_estimate: Literal["grid", "continuous"] = Field(
        "continuous",
        description="which on-board C/A estimate autonomous tracking follows, refreshed with every measurement "
        "(paper: the grid; default the continuous MAP estimate: the 13x13 grid's half-sigma cells leave its choice "
        "up to ~2 s off near the 3-sigma corners, 0.7 km of along-track error at C/A, measured in bench/closedloop.py)",
    )
    min_recognition_measurements: int = Field(
        10, ge=1, description="line-of-sight measurements needed before the on-board C/A estimate is trusted"
    )
    apid: int = Field(0x0C1, ge=0, lt=2048, description="APID of the on-board software's packets")
    ground_id: int = Field(1, ge=0, le=0xFFFF, description="PUS destination id of unsolicited telemetry, the "
                           "ground's application id (ECSS-E-ST-70-41C; a TC's reports go to its own source id)")
    inertia_kgm2: tuple[tuple[float, float, float], ...] = Field(
        ((0.152, 0.0, 0.0), (0.0, 0.117, 0.0), (0.0, 0.0, 0.058)),
        description="on-board knowledge of the inertia matrix, kg m^2",
    )
    camera: CameraKnowledge = CameraKnowledge()
    targets: TargetKnowledge = TargetKnowledge()
    wheels: WheelKnowledge = WheelKnowledge()
    attitude: AttitudeConfig = AttitudeConfig()
    fdir: FdirConfig = FdirConfig()
    monitoring: tuple[MonitoringDefinition, ...] = Field(
        DEFAULT_MONITORING, description="service 12 parameter monitoring definitions loaded with the software")
    event_actions: tuple[EventActionConfig, ...] = Field(
        DEFAULT_EVENT_ACTIONS, description="service 19 event-action definitions loaded with the software")
    onboard_source_id: int = Field(0x0C1, ge=0, le=0xFFFF, description="PUS source id of the telecommands the "
                                   "software builds itself (its event actions; default its own APID): their "
                                   "verification reports stay on board")
    control: ControlConfig = ControlConfig()
    modes: ModesConfig = ModesConfig()
    recognition: RecognitionConfig = RecognitionConfig()
    tracking: TrackingConfig = TrackingConfig()
    imaging: ImagingConfig = ImagingConfig()
    executive: ScheduleTable = Field(ScheduleTable(), description="the executive's schedule table (obsw.table)")
    timing: TimingConfig = Field(TimingConfig(), description="execution times on the modelled on-board computer "
                                 "(obsw.timing)")

    @field_validator("inertia_kgm2")
    @classmethod
    def _rigid_body(cls, v: tuple[tuple[float, float, float], ...]) -> tuple[tuple[float, float, float], ...]:
        problem = inertia_problem(v)
        if problem:
            raise ValueError(problem)
        return v

    @model_validator(mode="after")
    def _unique_definitions(self) -> ObswConfig:
        pmon = [d.pmon_id for d in self.monitoring]
        events = [a.event for a in self.event_actions]
        for name, ids in (("monitoring", pmon), ("event_actions", events)):
            dup = sorted({i for i in ids if ids.count(i) > 1}, key=str)
            if dup:
                raise ValueError(f"{name}: {dup} defined twice")
        if self.onboard_source_id == self.ground_id:
            raise ValueError(f"onboard_source_id: {self.onboard_source_id} is the ground's id (ground_id): the "
                             "verification of the software's own telecommands would go to the ground")
        return self

    @model_validator(mode="after")
    def _orthogonal_axes(self) -> ObswConfig:
        b, p = self.camera.boresight_body, self.tracking.plane_normal_axis_body
        nb = sum(x * x for x in b) ** 0.5
        np_ = sum(x * x for x in p) ** 0.5
        if np_ < 1e-9:
            raise ValueError(f"tracking.plane_normal_axis_body: {p} must be non-zero")
        if abs(sum(x * y for x, y in zip(b, p))) > 1e-6 * nb * np_:
            raise ValueError(f"tracking.plane_normal_axis_body: {p} must be orthogonal to camera.boresight_body {b}")
        return self
