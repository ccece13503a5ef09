"""The universe core: true time, flyby geometry, attitude dynamics, sensors, camera, link and faults, step by step.

Pure with respect to the outside world: it takes the OBSW's ``StepReply`` and ground's ``GroundReply`` and returns
the next ``StepRequest`` and ``GroundStep``. All randomness comes from one ``SeedSequence`` of the scenario seed,
spawned into one independent stream per subsystem, so adding draws to one never changes another's.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from contracts import pus
from contracts.messages import (
    FrameMeta,
    GroundReply,
    GroundStep,
    StepReply,
    StepRequest,
    TruthRecord,
)
from contracts.seeding import rng_streams
from universe.camera import dark_frame
from universe.config import FaultConfig, UniverseConfig
from universe.dynamics import AttitudeState, SpacecraftDynamics
from universe.geometry import FlybyGeometry
from universe.link import SpaceLink
from universe.measurement import MeasurementState, measure_at
from universe.oscillator import Oscillator, clock_jumps_s
from universe.scene import body_shapes, render_at
from universe.sensors import Sensors

def pointing_attitude(los_inertial: np.ndarray, roll_ref_inertial: np.ndarray) -> Rotation:
    """The attitude that puts the body +Z boresight on ``los`` with body +X as close as possible to ``roll_ref``."""
    z = los_inertial / np.linalg.norm(los_inertial)
    x = roll_ref_inertial - (roll_ref_inertial @ z) * z
    if np.linalg.norm(x) < 1e-9:  # reference along the boresight: any perpendicular will do
        x = np.cross(z, [0.0, 0.0, 1.0] if abs(z[2]) < 0.9 else [1.0, 0.0, 0.0])
    x /= np.linalg.norm(x)
    # a reference nearly along the boresight leaves x with a relative error of 1e-16 / |x|: projecting once more
    # makes it perpendicular to working precision (Gram-Schmidt twice)
    x -= (x @ z) * z
    x /= np.linalg.norm(x)
    return Rotation.from_matrix(np.column_stack([x, np.cross(z, x), z]))


_NO_WHEELS: frozenset[int] = frozenset()


@dataclass(slots=True)
class _Period:
    """The state of one control period, kept until the next ground step turns it into a TruthRecord: the geometry
    of all the periods since the last one is computed at once (one vectorised call instead of one per period)."""

    t_s: float
    obt_s: float
    q: tuple[float, ...]
    omega_rad_s: tuple[float, ...]
    wheel_momentum_nms: tuple[float, ...]
    wheel_torque_nm: tuple[float, ...]
    frame: dict[str, object] | None = None  # the frame exposed at this period: its id and true target positions


class FaultBook:
    """The scenario's faults: which are active at a time, and a log line at each start and end."""

    def __init__(self, faults: list[FaultConfig]) -> None:
        self.faults = list(faults)
        self._started: set[int] = set()
        self._ended: set[int] = set()
        self._first_call = True
        # the faults of each kind, in scenario order: asked for several kinds a period, most of which have none
        self._by_kind: dict[str, list[FaultConfig]] = {}
        for f in self.faults:
            self._by_kind.setdefault(f.kind, []).append(f)

    def active(self, kind: str, t_s: float) -> list[FaultConfig]:
        """Faults of ``kind`` whose window contains ``t_s``."""
        of_kind = self._by_kind.get(kind)
        if of_kind is None:
            return []
        return [f for f in of_kind if f.start_s <= t_s < f.end_s]

    def still_active(self, t_s: float) -> Iterator[str]:
        """Log lines for the faults still active when the run ends at ``t_s`` (they never got an end line)."""
        for i in sorted(self._started - self._ended):
            f = self.faults[i]
            yield f"fault still active at the end of the run t={t_s:.2f} s: {f.kind} (window {f.start_s:g}..{f.end_s:g} s)"

    def transitions(self, t_s: float) -> Iterator[str]:
        """Log lines for the faults that started or ended by ``t_s`` since the last call (non-decreasing times).

        A window that falls wholly between two calls (an instantaneous clock jump, say) logs its start and its end
        at the same call: it still acted (the oscillator steps at ``start_s`` whatever the control period). Windows
        that ended before the first call (before the run) are not logged.
        """
        if self._first_call:
            self._first_call = False
            for i, f in enumerate(self.faults):
                if f.end_s < t_s:
                    self._started.add(i)
                    self._ended.add(i)
        for i, f in enumerate(self.faults):
            if i not in self._started and t_s >= f.start_s:
                self._started.add(i)
                yield f"fault start t={t_s:.2f} s: {self._what(f)} (window {f.start_s:g}..{f.end_s:g} s)"
            if i in self._started and i not in self._ended and t_s >= f.end_s:
                self._ended.add(i)
                yield f"fault end   t={t_s:.2f} s: {self._what(f)}"

    @staticmethod
    def _what(f: FaultConfig) -> str:
        """The fault's kind, wheel and magnitude, for its log lines."""
        return f.kind + (f" wheel {f.wheel}" if f.wheel is not None else "") + (
            f" magnitude {f.magnitude:g}" if f.magnitude is not None else "")


class Universe:
    """The whole truth of one run, advanced one control period at a time."""

    def __init__(self, cfg: UniverseConfig, seed: int, *, apid: int, ground_period_s: float) -> None:
        """``apid``: the spacecraft's APID (its approach telemetry); ``ground_period_s``: true s between ground steps."""
        u = cfg
        self.cfg = u
        self.seed = seed
        self.apid = apid
        self.rng = rng_streams(seed)
        self.geometry = FlybyGeometry(u.flyby, u.bodies)
        self.dynamics = SpacecraftDynamics(u.spacecraft)
        self.sensors = Sensors(u.sensors, self.dynamics.n_wheels, self.rng["sensors"])
        self.oscillator = Oscillator(u.oscillator, self.rng["oscillator"], clock_jumps_s(u.faults))
        self.link = SpaceLink(u.link)
        self.faults = FaultBook(u.faults)
        self.dt_s = u.control_period_s
        self.n_steps = int(round((u.end_s - u.start_s) / self.dt_s))
        self.step = 0
        self.t_s = u.start_s
        self.state = self._initial_state()
        self.torque_nm = np.zeros(self.dynamics.n_wheels)
        self.frame_count = 0
        self.last_frame: np.ndarray | None = None
        self.ground_period_s = ground_period_s
        self._next_ground_s = u.start_s
        self._ground_step = 0
        self._truth: list[_Period] = []
        self._log: list[str] = []
        self._boresight = np.asarray(u.camera.boresight_body, dtype=float)
        self._history = self._approach_history()
        self._obt_s = self.oscillator.obt_s(self.t_s)
        self.shapes = body_shapes(seed)
        self.measurement = MeasurementState()  # centroid-level fidelity: a misidentification episode under way
        self._dark_frames: dict[float, np.ndarray] = {}
        self._rotor_inertia_kgm2 = float(self.dynamics.rotor_inertia_kgm2)
        self._no_bias = np.zeros(3)  # the gyro's fault step when none is active (added all the same: the same bits)

    def _approach_history(self) -> list[tuple[float, bytes]]:
        """The service 9 time reports of the approach before the run, with the true time each reached ground.

        They stand for the telemetry of the days before the flyby (the OBSW of this run starts at ``start_s``), so
        they are read from the same oscillator and sent through the same link model; their sequence counts end
        just before the run's first packet so ground sees one gapless stream.
        """
        h = self.cfg.approach_history
        if h.duration_s <= 0:
            return []
        n = int(h.duration_s // h.report_period_s)
        times = [self.t_s - (n - k) * h.report_period_s for k in range(n)]
        link = self.cfg.link
        out = []
        for k, t in enumerate(times):
            obt = self.oscillator.obt_s(t)
            seq = (k - n) % pus.SEQ_COUNT_MODULO
            raw = pus.encode_tm(pus.TimeReport(obt_s=obt), self.apid, seq, obt, seq % 0x10000)
            out.append((t + len(raw) * 8.0 / link.downlink_rate_bps + link.one_way_light_time_s, raw))
        return out

    def _initial_state(self) -> AttitudeState:
        sc = self.cfg.spacecraft
        rng = self.rng["initial"]
        los = self.geometry.truth_sample(self.t_s, np.array([0, 0, 0, 1.0]), np.array([0, 0, 1.0]), 90.0)
        # body +X against the velocity puts body +Y on the flyby-plane normal e_ca x e_v, the attitude the on-board
        # tracking loop holds, so a run starts without a 180 deg roll slew
        att = pointing_attitude(los.los_dimorphos_inertial, -self.geometry.e_v)
        axis = rng.standard_normal(3)
        axis /= np.linalg.norm(axis)
        error = Rotation.from_rotvec(np.radians(sc.initial_attitude_error_deg) * axis)
        q = (att * error).as_quat()
        return AttitudeState(
            q=q,
            omega_rad_s=np.radians(np.asarray(sc.initial_rate_deg_s, dtype=float)),
            wheel_speed_rad_s=np.zeros(self.dynamics.n_wheels),
        )

    # -- OBSW side -----------------------------------------------------------------------------------------
    def begin(self) -> tuple[StepRequest, bytes | memoryview]:
        """The request of step 0: sensors at the start time, no frame yet."""
        self._log.extend(self.faults.transitions(self.t_s))
        self._record_truth()
        return self._request(frame_requested=False)

    def advance(self, reply: StepReply) -> tuple[StepRequest, bytes | memoryview] | None:
        """Apply the OBSW's reply over one control period; return the next request, or None at the end."""
        if len(reply.wheel_torque_nm) != self.dynamics.n_wheels:
            raise ValueError(
                f"StepReply {reply.step}: wheel_torque_nm has {len(reply.wheel_torque_nm)} values, "
                f"expected {self.dynamics.n_wheels}"
            )
        self.link.downlink.send(self.t_s, reply.downlink, outage=bool(self.faults.active("link_outage", self.t_s)))
        previous_nm, self.torque_nm = self.torque_nm, np.asarray(reply.wheel_torque_nm, dtype=float)
        stuck, failed = self._wheels("wheel_stuck"), self._wheels("wheel_failed")
        # the wheels keep the previous torques until the control task's modelled finish, then take the new ones
        delay = min(reply.actuation_delay_s, self.dt_s)
        self.state = self.dynamics.step(self.state, self.torque_nm, self.dt_s, stuck, failed, before_nm=previous_nm,
                                        switch_s=max(delay, 0.0))
        self.step += 1
        self.t_s = self.cfg.start_s + self.step * self.dt_s
        if reply.clock_adjust_s:  # the OBSW commanded its oscillator to step, from this period on
            self.oscillator.jump(self.t_s, reply.clock_adjust_s)
            self._log.append(f"commanded clock step t={self.t_s:.2f} s: OBT {reply.clock_adjust_s:+.6f} s")
        if self.faults.faults:  # a scenario without faults has no transitions to look for
            self._log.extend(self.faults.transitions(self.t_s))
        self._obt_s = self.oscillator.obt_s(self.t_s)
        self._record_truth()
        if self.step >= self.n_steps:
            return None
        return self._request(frame_requested=reply.frame_request is not None,
                             exposure_s=reply.frame_request.exposure_s if reply.frame_request else None)

    def _request(self, frame_requested: bool,
                 exposure_s: float | None = None) -> tuple[StepRequest, bytes | memoryview]:
        outage = bool(self.faults.active("star_tracker_outage", self.t_s))
        steps = self.faults.active("gyro_bias_step", self.t_s)
        bias = (sum((np.radians(f.magnitude or 0.0) * np.ones(3) for f in steps), np.zeros(3)) if steps
                else self._no_bias)
        r = self.sensors.measure(self.t_s, self.state, self.dt_s, star_tracker_out=outage, gyro_bias_step_rad_s=bias)
        # the readings' arrays as Python floats (tolist: float() of each, at once), validated with the request
        sensors = dict(star_tracker_q=None if r.star_tracker_q is None else r.star_tracker_q.tolist(),
                       gyro_rad_s=r.gyro_rad_s.tolist(), wheel_speed_rad_s=r.wheel_speed_rad_s.tolist())
        uplink = tuple(self.link.uplink.arrived(self.t_s))
        meta, blob = (None, b"")
        if frame_requested:
            meta, blob = self._frame(exposure_s or self.cfg.camera.exposure_s)
        # the processor's speed and the camera interface's delay, as the OBSW node's processor model reads them
        overload = self.faults.active("cpu_overload", self.t_s)
        slowdown = float(math.prod(f.magnitude or 1.0 for f in overload)) if overload else 1.0
        latency = self.faults.active("imaging_latency", self.t_s) if meta else None
        delay = sum(f.magnitude or 0.0 for f in latency) if latency else 0.0
        # one validation of the request and its nested readings: pydantic-core's validation of this small model is
        # quicker than Frozen.trusted of it and its readings (3.1 against 5.3 us)
        return StepRequest.model_validate(dict(step=self.step, obt_s=self._obt_s, sensors=sensors, uplink=uplink,
                                               frame=meta, cpu_slowdown=slowdown, imaging_delay_s=delay)), blob

    def _wheels(self, kind: str) -> frozenset[int]:
        """The wheels of the faults of ``kind`` active now."""
        active = self.faults.active(kind, self.t_s)
        return frozenset(f.wheel for f in active if f.wheel is not None) if active else _NO_WHEELS

    def _frame(self, exposure_s: float) -> tuple[FrameMeta | None, bytes | memoryview]:
        if self.faults.active("frame_lost", self.t_s):
            self._log.append(f"frame lost at t={self.t_s:.2f} s (fault)")
            return None, b""
        if self.cfg.fidelity == "centroid":  # the imaging chain's output modelled, no pixels
            measurement, dim, did = measure_at(self, exposure_s)
            pixels = None
        else:
            pixels, dim, did = render_at(self, exposure_s)
            measurement = None
        self.last_frame = pixels
        # the truth record of this period (already appended) gets the frame's true target positions
        self._truth[-1].frame = {"frame_id": self.frame_count, "dimorphos_px": dim, "didymos_px": did}
        side = self.cfg.camera.resolution_px
        meta = FrameMeta(frame_id=self.frame_count, obt_s=self._obt_s, width=side, height=side,
                         bit_depth=self.cfg.camera.bit_depth, exposure_s=exposure_s, measurement=measurement)
        self.frame_count += 1
        if pixels is None:
            return meta, b""
        # the frame's own octets, read-only, not a 2 MB copy (every frame is a new array, never written again)
        return meta, memoryview(np.ascontiguousarray(pixels.astype("<u2", copy=False))).cast("B").toreadonly()

    def frame_at(self, t_s: float, q: tuple[float, ...], omega_rad_s: tuple[float, ...],
                 exposure_s: float) -> np.ndarray:
        """The pixels of a frame exposed at true time ``t_s`` in attitude ``q`` turning at ``omega_rad_s``, rendered
        as the run renders its frames, the noise being the camera streams' next draws; the universe's own time and
        state are left as they are. A new universe of a run's scenario, asked in frame order for the time and state
        its truth records at each frame, gives the run's frames again, bit for bit (a replay of a record that keeps
        frames by reference)."""
        state = AttitudeState(q=np.asarray(q, dtype=float), omega_rad_s=np.asarray(omega_rad_s, dtype=float),
                              wheel_speed_rad_s=self.state.wheel_speed_rad_s)
        return render_at(self, exposure_s, t_s, state)[0]

    def _record_truth(self) -> None:
        self._truth.append(_Period(
            # tolist: the same Python floats as float() of each element, without a generator a period
            t_s=self.t_s, obt_s=self._obt_s, q=tuple(np.asarray(self.state.q, dtype=float).tolist()),
            omega_rad_s=tuple(np.asarray(self.state.omega_rad_s, dtype=float).tolist()),
            # dynamics.wheel_momentum_nms in floats (one product each, the same bits), without a NumPy call
            wheel_momentum_nms=tuple([self._rotor_inertia_kgm2 * w
                                      for w in np.asarray(self.state.wheel_speed_rad_s, dtype=float).tolist()]),
            wheel_torque_nm=tuple(np.asarray(self.torque_nm, dtype=float).tolist())))

    def _truth_records(self) -> list[TruthRecord]:
        """The TruthRecords of the periods kept since the last ground step, their geometry computed at once."""
        periods, self._truth = self._truth, []
        if not periods:
            return []
        ts = self.geometry.truth_samples(np.array([p.t_s for p in periods]), np.array([p.q for p in periods]),
                                         self._boresight, self.cfg.camera.fov_deg)
        # whole columns to Python floats at once: per element, the conversions cost more than the geometry
        err, fov, rng, theta, phase, rng_did = (a.tolist() for a in (
            ts.pointing_error_rad, ts.target_in_fov, ts.range_to_dimorphos_m, ts.theta_rad, ts.phase_angle_deg,
            ts.range_to_didymos_m))
        # each vector column as 3 lists of components zipped into tuples (not one list per vector, then a tuple)
        los_dim, los_did, cam = (list(zip(*a.T.tolist())) for a in (
            ts.los_dimorphos_inertial, ts.los_didymos_inertial, ts.los_dimorphos_camera))
        out = []
        # trusted, not validated: every value is a Python float, bool, int or tuple of floats of the field's length,
        # made above or by _record_truth and _frame, as validation would leave them (2.6 us a record against 3.8)
        for k, p in enumerate(periods):
            out.append(TruthRecord.trusted(
                t_s=p.t_s, obt_s=p.obt_s, q=p.q, omega_rad_s=p.omega_rad_s,
                wheel_momentum_nms=p.wheel_momentum_nms, wheel_torque_nm=p.wheel_torque_nm,
                pointing_error_rad=err[k], target_in_fov=fov[k], range_m=rng[k], theta_rad=theta[k],
                phase_angle_deg=phase[k], los_dimorphos_inertial=los_dim[k], los_didymos_inertial=los_did[k],
                dimorphos_camera=cam[k], range_didymos_m=rng_did[k], **(p.frame or {})))
        return out

    def dark_frame(self, exposure_s: float | None = None) -> np.ndarray:
        """The run's dark frame: one frame with the shutter closed (``exposure_s``, default the camera's), uint16 DN,
        drawn from its own random stream on the first call for that exposure and the same array on every later one.
        What the flight software would subtract to remove bias, dark current and warm pixels."""
        t = self.cfg.camera.exposure_s if exposure_s is None else float(exposure_s)
        if t not in self._dark_frames:
            frame = dark_frame(self.cfg.camera, t, self.rng["dark_frame"])
            frame.setflags(write=False)
            self._dark_frames[t] = frame
        return self._dark_frames[t]

    def take_log(self) -> list[str]:
        """Log lines produced since the last call (fault starts and ends, lost frames)."""
        out, self._log = self._log, []
        return out

    # -- ground side ---------------------------------------------------------------------------------------
    def ground_due(self) -> bool:
        """Whether a ground exchange is due at the current true time."""
        return self.t_s >= self._next_ground_s - 1e-9

    def ground_step(self) -> GroundStep:
        """The telemetry that reached the antenna and the truth recorded since the last ground step."""
        arrived = self.link.downlink.arrived_timed(self.t_s)
        if self._history:  # the approach's time reports come first, in the order they arrived
            arrived = [(t, p) for t, p in self._history if t <= self.t_s] + arrived
            self._history = [(t, p) for t, p in self._history if t > self.t_s]
        msg = GroundStep(step=self._ground_step, utc_s=self.t_s, downlink=tuple(p for _, p in arrived),
                         downlink_utc_s=tuple(t for t, _ in arrived), truth=tuple(self._truth_records()))
        self._ground_step += 1
        self._next_ground_s += self.ground_period_s
        return msg

    def drain(self) -> GroundStep | None:
        """After the last control period: the next ground step while telemetry is still in flight, else None."""
        if not self.link.downlink.in_flight and not self._truth:
            return None
        t = max(self.t_s, self._next_ground_s)  # true time runs on while the last packets travel
        if t > self.cfg.end_s + self.cfg.drain_limit_s and not self._truth:
            dropped = len(self.link.downlink.in_flight)
            self.link.downlink.in_flight.clear()
            self.link.downlink.lost += dropped
            self._log.append(f"{dropped} telemetry packet(s) still in flight {self.cfg.drain_limit_s:g} s after the "
                             "run's end (universe.drain_limit_s): dropped")
            return None
        self.t_s = t
        return self.ground_step()

    def accept_ground(self, reply: GroundReply) -> None:
        """Radiate ground's telecommands into the uplink."""
        self.link.uplink.send(self.t_s, reply.uplink, outage=bool(self.faults.active("link_outage", self.t_s)))
