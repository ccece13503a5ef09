"""Configuration of the universe simulator: the truth the flight software is judged against.

Every number carries its unit in its name or description, a default and the source of that default; "paper" is
the LICIACube navigation paper.
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field, field_validator, model_validator

from contracts.checks import inertia_problem, parallel_problem
from contracts.link import LinkConfig
from contracts.model import Config

Vec3 = tuple[float, float, float]

# 100 times the default effort (0.01 s substeps): a finer substep only spends time, its error being below 1e-9 already
MAX_SUBSTEPS_PER_S = 10_000.0
# 1,000 s of the default dynamics in one lock-step period (the paper's control runs every 0.1 s)
MAX_SUBSTEPS_PER_PERIOD = 100_000.0


class FlybyConfig(Config):
    """True flyby geometry: straight-line relative motion about the Didymos barycentre."""

    ca_time_s: float = Field(
        168.0,
        description="true time of closest approach, s after the scenario epoch "
        "(LICIACube flew by about 168 s after the DART impact)",
    )
    ca_distance_km: float = Field(
        55.0, gt=0, le=1.0e6, description="true C/A distance, km (paper: 55 km; up to a million km, where Didymos is "
        "a fraction of a pixel: farther is outside what this emulator models)"
    )
    speed_km_s: float = Field(
        7.0, gt=0, le=100.0, description="relative speed, km/s (paper: ~7 km/s; at most 100 km/s, faster than any "
        "heliocentric encounter)"
    )
    approach_direction: Vec3 = Field(
        (1.0, 0.0, 0.0),
        description="direction of the spacecraft velocity relative to Didymos, inertial frame (normalised)",
    )
    ca_direction: Vec3 = Field(
        (0.0, 1.0, 0.0),
        description="direction from Didymos to the spacecraft at C/A, inertial frame "
        "(made orthogonal to approach_direction)",
    )

    @field_validator("approach_direction", "ca_direction")
    @classmethod
    def _nonzero(cls, v: Vec3) -> Vec3:
        if sum(c * c for c in v) < 1e-12:
            raise ValueError("must be a non-zero vector")
        return v

    @model_validator(mode="after")
    def _not_parallel(self) -> FlybyConfig:
        # the C/A direction is made orthogonal to the velocity: parallel vectors leave nothing to normalise
        problem = parallel_problem(self.ca_direction, self.approach_direction, "approach_direction")
        if problem:
            raise ValueError(f"ca_direction: {problem}")
        return self


class UncertaintyConfig(Config):
    """One-sigma knowledge errors of the trajectory that ground believes (drawn with the seed)."""

    ca_time_sigma_s: float = Field(10.0, ge=0, description="one-sigma error of the C/A time, s")
    ca_distance_sigma_km: float = Field(5.0, ge=0, description="one-sigma error of the C/A distance, km")
    ca_time_offset_sigma: float | None = Field(
        None,
        description="if set, the ground nominal is truth + this many sigmas in C/A time instead of a random draw",
    )
    ca_distance_offset_sigma: float | None = Field(
        None,
        description="if set, the ground nominal is truth + this many sigmas in C/A distance instead of a random draw",
    )


class BodiesConfig(Config):
    """Didymos and Dimorphos (paper: 780 m and 164 m; Dimorphos orbit 1.19 km, 11.92 h)."""

    didymos_diameter_m: float = Field(780.0, gt=0, description="mean diameter of Didymos, m (paper)")
    dimorphos_diameter_m: float = Field(164.0, gt=0, description="mean diameter of Dimorphos, m (paper)")
    orbit_radius_m: float = Field(1190.0, gt=0, description="Dimorphos orbit radius, m (Naidu et al. 2020)")
    orbit_period_h: float = Field(11.92, gt=0, description="Dimorphos orbital period, h (pre-impact)")
    orbit_phase_deg: float = Field(
        90.0,
        description="Dimorphos orbital phase at the epoch, deg (90: Dimorphos beside Didymos as seen on the approach; "
        "at 0 it hides in front of Didymos until C/A)",
    )
    orbit_normal: Vec3 = Field(
        (0.0, 0.0, 1.0),
        description="normal of the Dimorphos orbit plane, inertial frame (normalised; the orbit is prograde about it); "
        "phase 0 lies along inertial X projected on the plane (inertial Y if X is the normal). "
        "Default: the inertial XY plane (a convention of this emulator)",
    )
    mass_ratio: float = Field(0.0093, ge=0, description="Dimorphos/Didymos mass ratio (Naidu et al. 2020)")
    sun_direction: Vec3 = Field(
        (-0.5, 0.5, 0.0),
        description="direction from the asteroid to the Sun, inertial frame (normalised); sets the phase angle",
    )
    impact_time_s: float = Field(0.0, description="DART impact time, s after the epoch; the plume starts here")

    @field_validator("sun_direction", "orbit_normal")
    @classmethod
    def _nonzero(cls, v: Vec3) -> Vec3:
        if sum(c * c for c in v) < 1e-12:
            raise ValueError("must be a non-zero vector")
        return v


class WheelConfig(Config):
    """Reaction wheels (paper: 0.007 Nm, 0.1 Nms)."""

    layout: Literal["orthogonal", "pyramid"] = Field("orthogonal", description="three orthogonal or four in a pyramid")
    pyramid_angle_deg: float = Field(54.7356, gt=0, lt=90, description="pyramid wheel-axis elevation, deg")
    max_torque_nm: float = Field(0.007, gt=0, description="torque limit per wheel, N m (paper)")
    max_momentum_nms: float = Field(0.1, gt=0, description="momentum limit per wheel, N m s (paper)")
    inertia_kgm2: float = Field(
        1.0e-4, gt=0, description="wheel rotor inertia about its axis, kg m^2 (a CubeSat RW of 0.1 Nms at ~9500 rpm)"
    )
    viscous_friction_nms: float = Field(
        1.0e-7, ge=0, description="viscous friction coefficient, N m per rad/s (typical small RW)"
    )
    coulomb_friction_nm: float = Field(1.0e-5, ge=0, description="Coulomb friction torque, N m (typical small RW)")
    coulomb_smoothing_rad_s: float = Field(
        0.01,
        gt=0,
        description="wheel speed, rad/s, over which Coulomb friction ramps up (tanh) so that RK4 does not chatter "
        "at zero speed (numerical regularisation; default equals the tachometer noise, so it is unobservable)",
    )


class SpacecraftConfig(Config):
    """Rigid 6U CubeSat (paper: about 14 kg)."""

    mass_kg: float = Field(14.0, gt=0, description="mass, kg (paper)")
    inertia_kgm2: tuple[Vec3, Vec3, Vec3] = Field(
        ((0.152, 0.0, 0.0), (0.0, 0.117, 0.0), (0.0, 0.0, 0.058)),
        description="inertia matrix about the centre of mass in body axes, kg m^2 "
        "(uniform 14 kg box of 0.1 x 0.2 x 0.3 m)",
    )
    wheels: WheelConfig = WheelConfig()
    initial_attitude_error_deg: float = Field(
        0.5, ge=0, description="initial pointing error about a seeded random axis, deg"
    )
    initial_rate_deg_s: Vec3 = Field((0.0, 0.0, 0.0), description="initial body rate, deg/s")
    integration_substep_s: float = Field(
        0.01,
        gt=0,
        description="longest fixed RK4 substep of the attitude dynamics, s (0.01 s keeps the relative "
        "kinetic-energy error of torque-free motion below 1e-9 over a 600 s flyby at CubeSat rates, as "
        "tests/universe/test_dynamics.py checks)",
    )

    @field_validator("inertia_kgm2")
    @classmethod
    def _rigid_body(cls, v: tuple[Vec3, Vec3, Vec3]) -> tuple[Vec3, Vec3, Vec3]:
        problem = inertia_problem(v)
        if problem:
            raise ValueError(problem)
        return v

    def friction_rate_s(self) -> float:
        """The wheels' friction stiffness on the rotor speed, 1/s."""
        w = self.wheels
        return (w.viscous_friction_nms + w.coulomb_friction_nm / w.coulomb_smoothing_rad_s) / w.inertia_kgm2

    def substeps_per_s(self) -> float:
        """RK4 substeps per simulated second: the shorter of integration_substep_s and half the friction time."""
        return max(1.0 / self.integration_substep_s, 2.0 * self.friction_rate_s())

    @model_validator(mode="after")
    def _bounded_integration_effort(self) -> SpacecraftConfig:
        # bound it here, or a mutated number makes one control period take hours instead of failing at load
        friction_rate_s = self.friction_rate_s()
        per_s = self.substeps_per_s()
        if per_s > MAX_SUBSTEPS_PER_S:
            raise ValueError(
                f"the attitude dynamics would take {per_s:.3g} RK4 substeps per simulated second (at most "
                f"{MAX_SUBSTEPS_PER_S:.0f}): integration_substep_s must be >= {1 / MAX_SUBSTEPS_PER_S:g} s and "
                "wheels (viscous_friction_nms + coulomb_friction_nm / coulomb_smoothing_rad_s) / inertia_kgm2 "
                f"<= {MAX_SUBSTEPS_PER_S / 2:.0f} /s; got {self.integration_substep_s:g} s and {friction_rate_s:.3g} /s"
            )
        return self


class StarTrackerConfig(Config):
    """Star tracker (defaults: a CubeSat-class unit such as the Blue Canyon NST)."""

    noise_arcsec: Vec3 = Field((6.0, 6.0, 40.0), description="one-sigma white noise per body axis, arcsec")
    bias_arcsec: Vec3 = Field((0.0, 0.0, 0.0), description="constant bias per body axis, arcsec")
    rate_hz: float = Field(10.0, gt=0, description="update rate, Hz")


class GyroConfig(Config):
    """Gyro (defaults: a MEMS CubeSat IMU class)."""

    arw_deg_sqrt_h: float = Field(0.15, ge=0, description="angle random walk, deg/sqrt(h)")
    bias_instability_deg_h: float = Field(1.0, ge=0, description="bias instability, deg/h")
    initial_bias_deg_h: Vec3 = Field((0.0, 0.0, 0.0), description="initial bias per axis, deg/h")
    bias_walk_time_s: float = Field(
        3600.0,
        gt=0,
        description="time, s, over which the bias random walk drifts by one bias instability (one-sigma): "
        "rate random walk = bias_instability / sqrt(this); default one hour, the usual reading of a datasheet "
        "bias instability as the drift over an hour",
    )


class SensorsConfig(Config):
    """Attitude sensors and wheel tachometers."""

    star_tracker: StarTrackerConfig = StarTrackerConfig()
    gyro: GyroConfig = GyroConfig()
    wheel_speed_noise_rad_s: float = Field(0.01, ge=0, description="one-sigma wheel speed reading noise, rad/s")


class CameraConfig(Config):
    """Narrow-angle camera (paper: 2.9 deg horizontal FOV; frames 1024x1024 or 2048x2048, 12-bit)."""

    fov_deg: float = Field(2.9, gt=0, lt=90, description="horizontal field of view, deg (paper)")
    resolution_px: Literal[1024, 2048] = Field(1024, description="frame side, px (paper)")
    bit_depth: int = Field(12, ge=8, le=16, description="bits per pixel (paper: 12)")
    exposure_s: float = Field(0.01, gt=0, description="exposure time, s")
    frame_period_s: float = Field(1.0, gt=0, description="default time between frames, s")
    boresight_body: Vec3 = Field((0.0, 0.0, 1.0), description="camera boresight in body axes")
    psf_sigma_px: float = Field(
        1.0,
        gt=0.3,
        le=10.0,
        description="one-sigma width of the Gaussian point-spread function including pixel integration, px "
        "(about the diffraction spot of a ~f/5.6 optics on ~5.5 um pixels)",
    )
    gain_e_per_dn: float = Field(4.0, gt=0, description="detector gain, electrons per DN (CMOS sensor class)")
    read_noise_e: float = Field(8.0, ge=0, description="one-sigma read noise, electrons (CMOS sensor class)")
    dark_offset_dn: float = Field(
        64.0, ge=0, description="dark (bias) offset added to every pixel, DN (typical ADC pedestal)"
    )
    dark_current_e_s: float = Field(
        50.0, ge=0, description="mean dark current, electrons per second per pixel (CMOS at ~20 C)"
    )
    dark_current_dsnu_e_s: float = Field(
        15.0,
        ge=0,
        description="dark signal non-uniformity: one-sigma pixel-to-pixel spread of the dark current, electrons per "
        "second per pixel; each pixel's dark current is fixed, lognormal with mean dark_current_e_s and this spread "
        "(0: uniform; CMOS image sensor datasheets quote a DSNU of 10-50 % of the mean dark current: 30 %)",
    )
    body_signal_e_s: float = Field(
        1.5e6,
        gt=0,
        description="signal of an asteroid surface seen at normal incidence and emission at zero phase, electrons per "
        "second per pixel (chosen so the zero-phase surface sits near 90 % of the 12-bit range at the 0.01 s default "
        "exposure and gain)",
    )
    lommel_seeliger_weight: float = Field(
        0.8,
        ge=0,
        le=1,
        description="weight L of the Lommel-Seeliger term in the lunar-Lambert law "
        "L*2*mu0/(mu0+mu) + (1-L)*mu0 (McEwen 1991; dark rocky surfaces are Lommel-Seeliger dominated)",
    )
    phase_slope_mag_deg: float = Field(
        0.03,
        ge=0,
        description="linear phase darkening of the surface, magnitudes per degree of phase "
        "(typical S-type asteroid, Belskaya & Shevchenko 2000)",
    )
    star_mag0_e_s: float = Field(
        3.0e6,
        gt=0,
        description="total signal of a visual magnitude 0 star, electrons per second "
        "(about 1e6 photons/s/cm^2 in V through a ~4 cm aperture at 30 % throughput)",
    )
    star_limiting_mag: float = Field(
        9.0,
        le=14.0,
        description="faintest visual magnitude rendered, mag (a mag 9 star gives ~8 e- in 0.01 s, far below noise)",
    )
    hot_pixel_count: int = Field(50, ge=0, description="number of hot pixels, at fixed seeded positions (count)")
    hot_pixel_signal_e: float = Field(
        8000.0, ge=0, description="largest hot-pixel excess per frame, electrons (each a fixed 20-100 % of it)"
    )
    hot_pixel_seed: int = Field(
        7,
        ge=0,
        description="seed of the sensor's fixed maps: hot, warm and dead pixels, dead columns and the dark-current "
        "non-uniformity (fixed per sensor: the same in every frame of every run)",
    )
    warm_pixel_fraction: float = Field(
        0.001,
        ge=0,
        le=0.1,
        description="fraction of the pixels that are warm: a fixed excess dark current, growing with the exposure "
        "(CMOS image sensor datasheets allow of order 1e-4 to 1e-3 of the pixels outside their dark-current "
        "specification and proton damage in space adds more: 1e-3)",
    )
    warm_pixel_dark_current_e_s: float = Field(
        2000.0,
        ge=0,
        description="largest excess dark current of a warm pixel, electrons per second (each a fixed 20-100 % of it; "
        "40x the default mean dark current, the order of the warm-pixel tail of irradiated CMOS sensors)",
    )
    dead_pixel_count: int = Field(
        100,
        ge=0,
        description="number of dead pixels, reading the bias only, at fixed seeded positions (count; CMOS datasheets "
        "allow defects of order 1e-4 of the pixels: 100 of 1024x1024)",
    )
    dead_column_count: int = Field(
        1,
        ge=0,
        description="number of dead columns, reading the bias only, at fixed seeded positions (count; column defects "
        "are the usual readout-chain failure of a CMOS sensor: one)",
    )
    cosmic_ray_flux_cm2_s: float = Field(
        5.0,
        ge=0,
        description="rate of charged particles crossing the sensor, per cm^2 per second over its area "
        "(resolution_px x pixel_pitch_um squared), from every direction (galactic cosmic rays in interplanetary "
        "space near solar minimum are about 5 /cm^2/s; 0: none)",
    )
    pixel_pitch_um: float = Field(
        5.5,
        gt=0,
        description="pixel pitch, micrometres (5.5 um: the pitch of 2048x2048 scientific CMOS sensors such as the "
        "CMOSIS CMV4000, the one psf_sigma_px assumes); sets the sensor area the cosmic rays cross",
    )
    cosmic_ray_depth_um: float = Field(
        10.0,
        gt=0,
        description="depth of silicon that collects a particle's charge, micrometres (the epitaxial layer of a "
        "front-illuminated image sensor, ~10 um); a particle at zenith angle theta draws a streak depth tan(theta) "
        "long on the pixels",
    )
    cosmic_ray_charge_e_per_um: float = Field(
        80.0,
        gt=0,
        description="charge a particle frees along its path in silicon, electrons per micrometre (most probable loss "
        "of a minimum-ionizing particle in thin silicon, ~80 electron-hole pairs per um: Particle Data Group, "
        "Review of Particle Physics, passage of particles through matter)",
    )


    @model_validator(mode="after")
    def _defects_fit(self) -> CameraConfig:
        n = self.resolution_px
        if self.dead_pixel_count > n * n:
            raise ValueError(f"dead_pixel_count: {self.dead_pixel_count} is more than the {n * n} pixels")
        if self.dead_column_count > n:
            raise ValueError(f"dead_column_count: {self.dead_column_count} is more than the {n} columns")
        if self.dark_current_dsnu_e_s > 0 and self.dark_current_e_s <= 0:
            raise ValueError("dark_current_dsnu_e_s: a non-uniformity needs a positive mean dark_current_e_s")
        return self

    @model_validator(mode="after")
    def _exposure_fits_the_period(self) -> CameraConfig:
        if self.exposure_s >= self.frame_period_s:
            raise ValueError(f"exposure_s: {self.exposure_s:g} s must be shorter than frame_period_s "
                             f"{self.frame_period_s:g} s (a frame is read out before the next one starts)")
        return self


class PlumeConfig(Config):
    """DART ejecta plume: a hollow-free cone of dust from Dimorphos expanding after the impact.

    Particles leave the surface at t = 0 with speeds uniform in [0, speed_m_s] inside the cone, so at time t the
    cross-section density is ``A(t) / (Omega * speed * t * r^2)`` within ``r < speed * t``; each pixel shows
    ``1 - exp(-tau)`` of the surface signal, tau being the line-of-sight integral of that density.
    """

    enabled: bool = Field(True, description="render the plume after the impact")
    axis_inertial: Vec3 = Field(
        (0.0, 0.0, 1.0),
        description="cone axis, inertial frame (normalised); the default is normal to the default flyby plane so "
        "the fan is seen side-on",
    )
    half_angle_deg: float = Field(
        70.0, gt=0, lt=90, description="cone half-angle, deg (Deshapriya et al. 2023: aperture 140 +- 4 deg)"
    )
    speed_m_s: float = Field(
        50.0, gt=0, description="speed of the ejecta front, m/s (order of the bulk DART ejecta speeds, tens of m/s)"
    )
    cross_section_m2: float = Field(
        1.0e6,
        ge=0,
        description="total geometric cross-section of the ejecta before fading, m^2 (the system brightened ~3.5 mag, "
        "~25x the ~0.5 km^2 of Didymos; Graykowski et al. 2023)",
    )
    rise_time_s: float = Field(
        2.0, gt=0, description="e-folding time of the cross-section rise after the impact, s (A(t) ~ 1 - exp(-t/rise))"
    )
    fade_time_s: float = Field(
        3600.0, gt=0, description="e-folding fading time of the cross-section, s (A(t) ~ exp(-t/fade); hours observed)"
    )
    reflectance_factor: float = Field(
        1.0, ge=0, description="dust brightness relative to the asteroid surface at the same phase (dimensionless)"
    )

    @field_validator("axis_inertial")
    @classmethod
    def _axis_nonzero(cls, v: Vec3) -> Vec3:
        if sum(c * c for c in v) < 1e-12:
            raise ValueError("must be a non-zero vector")
        return v


class OscillatorConfig(Config):
    """On-board oscillator: maps true time to on-board time (OBT)."""

    initial_offset_s: float = Field(
        26_499_202.0,
        description="OBT at the scenario epoch, s: OBT counts from launch (DART launch 2021-11-24T06:21:02Z to "
        "the impact epoch is 26,499,202 s), so it is positive and CUC-encodable throughout",
    )
    drift_ppm: float = Field(0.0, description="frequency error, parts per million")
    drift_rate_ppm_per_day: float = Field(0.0, description="change of the frequency error, ppm per day")
    jitter_s: float = Field(0.0, ge=0, description="one-sigma white jitter of each OBT reading, s")
    jitter_bound_sigma: float = Field(
        3.0,
        gt=0,
        description="jitter is clipped at this many sigmas, so every reading is within "
        "jitter_bound_sigma * jitter_s of the oscillator model (3: the usual bound quoted for a Gaussian timing error)",
    )


FAULT_RULES: dict[str, tuple[bool, str | None]] = {
    # kind: (needs a wheel index, magnitude: "required", "optional" or None for none)
    "frame_lost": (False, None),
    "frame_blank": (False, None),
    "frame_saturated": (False, None),
    "star_tracker_outage": (False, None),
    "gyro_bias_step": (False, "required"),
    "wheel_stuck": (True, None),
    "wheel_failed": (True, None),
    "plume_brightening": (False, "optional"),
    "clock_jump": (False, "required"),
    "link_outage": (False, None),
    "cpu_overload": (False, "required"),
    "imaging_latency": (False, "required"),
}
"""What each fault kind takes; anything else given is refused (it would be ignored in flight)."""
INSTANTANEOUS_FAULTS = ("clock_jump",)  # acts at start_s: its window may be empty


class FaultConfig(Config):
    """A named, time-bounded fault injected by the universe."""

    kind: Literal[
        "frame_lost",
        "frame_blank",
        "frame_saturated",
        "star_tracker_outage",
        "gyro_bias_step",
        "wheel_stuck",
        "wheel_failed",
        "plume_brightening",
        "clock_jump",
        "link_outage",
        "cpu_overload",
        "imaging_latency",
    ]
    start_s: float = Field(description="true start time, s after the epoch")
    end_s: float = Field(description="true end time, s after the epoch")
    wheel: int | None = Field(None, ge=0, description="wheel index, for wheel faults")
    magnitude: float | None = Field(
        None,
        description="size of the fault in the unit of its kind: gyro_bias_step, deg/s added on every axis; "
        "plume_brightening, brightness factor (default 2); clock_jump, OBT step in s; cpu_overload, factor (>= 1) "
        "by which the on-board processor runs slower; imaging_latency, s added between a frame's exposure and its "
        "arrival at the processor",
    )

    @field_validator("end_s")
    @classmethod
    def _ordered(cls, v: float, info) -> float:  # type: ignore[no-untyped-def]
        start = info.data.get("start_s")
        if start is not None and v < start:
            raise ValueError("must not be before start_s")
        return v

    def problems(self, n_wheels: int) -> list[str]:
        """What is wrong with this fault for a spacecraft of ``n_wheels``, as 'field: message' lines."""
        needs_wheel, magnitude = FAULT_RULES[self.kind]
        out = []
        if needs_wheel and self.wheel is None:
            out.append(f"wheel: a {self.kind} fault needs the wheel index")
        elif needs_wheel and self.wheel is not None and self.wheel >= n_wheels:
            out.append(f"wheel: {self.wheel} is not one of the {n_wheels} wheels (0..{n_wheels - 1})")
        elif not needs_wheel and self.wheel is not None:
            out.append(f"wheel: a {self.kind} fault has no wheel (only wheel_stuck and wheel_failed do)")
        if magnitude == "required" and self.magnitude is None:
            out.append(f"magnitude: a {self.kind} fault needs its magnitude")
        elif magnitude is None and self.magnitude is not None:
            out.append(f"magnitude: a {self.kind} fault takes no magnitude")
        if self.kind == "plume_brightening" and self.magnitude is not None and self.magnitude <= 0:
            out.append(f"magnitude: a brightness factor must be > 0, got {self.magnitude:g}")
        if self.kind == "cpu_overload" and self.magnitude is not None and self.magnitude < 1:
            out.append(f"magnitude: a processor slow-down factor must be >= 1, got {self.magnitude:g}")
        if self.kind == "imaging_latency" and self.magnitude is not None and self.magnitude < 0:
            out.append(f"magnitude: an imaging delay must be >= 0 s, got {self.magnitude:g}")
        if self.end_s == self.start_s and self.kind not in INSTANTANEOUS_FAULTS:
            out.append(f"end_s: the window {self.start_s:g}..{self.end_s:g} s is empty: the fault would never act")
        return out


MAX_HISTORY_REPORTS = 100_000  # a ten-day approach at one report a minute is 14,400


class ApproachHistoryConfig(Config):
    """Time reports the spacecraft sent during the approach before the run (ground's correlation history)."""

    duration_s: float = Field(
        0.0, ge=0, le=31_557_600.0, description="length of the approach before the run start covered by time reports, "
        "s (0: none; the paper's approach is about ten days, 864000 s; at most a year)"
    )
    report_period_s: float = Field(600.0, gt=0, description="time between two time reports of the history, true s")

    @model_validator(mode="after")
    def _reports_held(self) -> ApproachHistoryConfig:
        n = self.duration_s / self.report_period_s
        if n > MAX_HISTORY_REPORTS:
            raise ValueError(f"report_period_s: {n:.3g} time reports over {self.duration_s:g} s; at most "
                             f"{MAX_HISTORY_REPORTS} (ground fits the last few hundred: a longer period loses nothing)")
        return self


class CentroidModelConfig(Config):
    """Centroid-level fidelity: the imaging chain's report of a frame modelled from the truth, instead of rendering
    the frame and running the chain on board (``fidelity: centroid``).

    Per body whose centre projects into the frame: the true pinhole projection of its centre, shifted towards the
    Sun's side of the image by a fraction of its apparent radius that depends on the phase angle, plus Gaussian
    noise. Dimorphos is not reported when the chain cannot tell it from Didymos (a probability that depends on the
    gap between their discs), nor in a dropout (a probability that depends on the phase angle); in a
    misidentification episode (a few frames running) it is reported where the chain puts Didymos. Positions in
    full-resolution camera px.

    Defaults: fitted by ``flyby mc-fit configs/scenarios/nominal.yaml --runs 40 --seed 1000 --dispersions
    configs/dispersions/flyby.yaml`` (17,815 frames of 40 image-level runs, refitted at the stop of 2026-12-02 on the
    imaging chain of issue 14 and the recognition solving the line of sight's offset: one misidentification episode
    of 5 frames, where the previous fit on 30 runs found 0.0013 a frame, 13.7 frames long; README, "Centroid-level
    fidelity").
    """

    phase_deg: tuple[float, ...] = Field(
        (5.129, 15.341, 25.72, 36.105, 42.186, 54.927, 65.003, 75.155, 85.224, 95.275, 105.49, 115.821, 125.929,
         130.589),
        min_length=1,
        description="phase angles of the bias and dropout tables, deg, increasing (linear between, constant beyond)")
    bias_radius_fraction: tuple[float, ...] = Field(
        (0.0257, 0.0722, 0.081, 0.1484, 0.0987, 0.14, 0.1726, 0.149, 0.1362, 0.1122, 0.085, 0.0721, 0.0903, -0.0385),
        min_length=1,
        description="centroid shift towards the Sun's side of the image at each phase_deg, fraction of the apparent "
        "radius")
    dimorphos_dropout: tuple[float, ...] = Field(
        (0.0, 0.0, 0.0, 0.0, 0.0, 0.5316, 0.2692, 0.0506, 0.0044, 0.0, 0.0, 0.0, 0.1948, 0.5446),
        min_length=1,
        description="probability that a visible Dimorphos apart from Didymos is not reported, at each phase_deg")
    noise_px: float = Field(0.5227, ge=0, description="one-sigma centroid noise per axis, full-resolution px")
    noise_radius_fraction: float = Field(
        0.0718, ge=0,
        description="one-sigma centroid noise per axis growing with the body, fraction of its apparent radius")
    merge_gap_px: tuple[float, ...] = Field(
        (-103.21, -34.48, -30.44, -25.74, -22.05, -18.02, -14.29, -10.82, -6.35, -2.17, 2.17, 6.21, 10.1, 13.81,
         17.85, 22.2, 25.92, 29.96, 34.1, 37.94, 41.96, 45.96, 49.99, 53.97, 57.99, 61.98, 66.0, 69.99, 73.97,
         95.68),
        min_length=1,
        description="gaps between Dimorphos's disc and Didymos's of the merge table, full-resolution px, increasing")
    merge_probability: tuple[float, ...] = Field(
        (1.0, 0.9005, 1.0, 0.898, 0.758, 0.6277, 0.7564, 0.6471, 0.5549, 0.3367, 0.4525, 0.3275, 0.2897, 0.041,
         0.0497, 0.1138, 0.2364, 0.1382, 0.0449, 0.0331, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
        min_length=1,
        description="probability that Dimorphos is not told from Didymos at each merge_gap_px (linear between, "
        "constant beyond)")
    didymos_dropout: float = Field(0.0, ge=0, le=1, description="probability that a visible Didymos is not reported")
    misidentification: float = Field(
        8.9e-05, ge=0, le=1,
        description="probability that a misidentification episode starts at a frame reporting Dimorphos: it is "
        "reported where Didymos is reported")
    misidentification_frames: float = Field(
        5.0, ge=1, description="mean length of a misidentification episode, frames reporting Dimorphos (geometric)")

    @model_validator(mode="after")
    def _tables(self) -> CentroidModelConfig:
        n = len(self.phase_deg)
        for name in ("bias_radius_fraction", "dimorphos_dropout"):
            if len(getattr(self, name)) != n:
                raise ValueError(f"{name}: {len(getattr(self, name))} values for {n} phase_deg")
        if len(self.merge_probability) != len(self.merge_gap_px):
            raise ValueError(f"merge_probability: {len(self.merge_probability)} values for {len(self.merge_gap_px)} "
                             "merge_gap_px")
        for name in ("phase_deg", "merge_gap_px"):
            v = getattr(self, name)
            if any(b <= a for a, b in zip(v, v[1:])):
                raise ValueError(f"{name}: must increase")
        for name in ("dimorphos_dropout", "merge_probability"):
            if any(not 0 <= p <= 1 for p in getattr(self, name)):
                raise ValueError(f"{name}: probabilities must be within 0..1")
        return self


class UniverseConfig(Config):
    """Everything the universe simulates."""

    start_s: float = Field(-132.0, description="true time at which the run starts, s after the epoch")
    end_s: float = Field(288.0, description="true time at which the run ends, s after the epoch")
    control_period_s: float = Field(
        0.1,
        gt=0,
        description="lock-step period of true time, s (10 Hz, the on-board control rate: at the 7 deg/s peak body "
        "rate the attitude turns 0.7 deg per period, a quarter of the 2.9 deg field of view)",
    )
    flyby: FlybyConfig = FlybyConfig()
    uncertainty: UncertaintyConfig = UncertaintyConfig()
    bodies: BodiesConfig = BodiesConfig()
    spacecraft: SpacecraftConfig = SpacecraftConfig()
    sensors: SensorsConfig = SensorsConfig()
    camera: CameraConfig = CameraConfig()
    plume: PlumeConfig = PlumeConfig()
    oscillator: OscillatorConfig = OscillatorConfig()
    faults: list[FaultConfig] = Field(default_factory=list, description="faults to inject")
    approach_history: ApproachHistoryConfig = ApproachHistoryConfig()
    link: LinkConfig = Field(LinkConfig(), description="the true deep-space link: light time and data rates")
    fidelity: Literal["image", "centroid"] = Field(
        "image", description="image: render each frame and let the on-board imaging chain process it; centroid: send "
        "the chain's output modelled by centroid_model instead (no pixels, for fast Monte Carlo campaigns)")
    centroid_model: CentroidModelConfig = CentroidModelConfig()
    drain_limit_s: float = Field(
        3600.0, gt=0, description="after the last control period, true time the run waits for the telemetry still in "
        "flight, s; what has not arrived by then is dropped and logged (at the default 1 h, a slow link's backlog "
        "cannot hold a run for days)")
    save_frames_every: int = Field(
        1, ge=0, description="write every n-th camera frame as an 8-bit 512x512 PNG into the run folder (0: none)"
    )

    @field_validator("end_s")
    @classmethod
    def _after_start(cls, v: float, info) -> float:  # type: ignore[no-untyped-def]
        start = info.data.get("start_s")
        if start is not None and v <= start:
            raise ValueError("must be after start_s")
        return v

    @model_validator(mode="after")
    def _bounded_period(self) -> UniverseConfig:
        # one lock-step period is integrated in one call: its substeps are bounded as the rate of them is
        n = self.spacecraft.substeps_per_s() * self.control_period_s
        if n > MAX_SUBSTEPS_PER_PERIOD:
            raise ValueError(f"control_period_s: {self.control_period_s:g} s is {n:.3g} RK4 substeps of the attitude "
                             f"dynamics in one period (at most {MAX_SUBSTEPS_PER_PERIOD:.0f}): the lock-step period "
                             f"must be <= {MAX_SUBSTEPS_PER_PERIOD / self.spacecraft.substeps_per_s():g} s")
        return self

    @model_validator(mode="after")
    def _faults_fit_the_run(self) -> UniverseConfig:
        """Refuse at load time a fault that would do nothing or fail mid-run (lines 'faults[i].field: why')."""
        n_wheels = 3 if self.spacecraft.wheels.layout == "orthogonal" else 4
        problems = []
        for i, f in enumerate(self.faults):
            problems += [f"faults[{i}].{p}" for p in f.problems(n_wheels)]
            acts_at_start = f.kind in INSTANTANEOUS_FAULTS
            if f.start_s >= self.end_s or (f.end_s <= self.start_s and not (acts_at_start and f.start_s >= self.start_s)):
                problems.append(f"faults[{i}].start_s: the window {f.start_s:g}..{f.end_s:g} s is outside the run "
                                f"{self.start_s:g}..{self.end_s:g} s: the fault would never act")
        if problems:
            raise ValueError("\n".join(problems))
        return self

