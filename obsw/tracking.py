"""Tracking loop: the desired attitude from the trajectory model, corrected by the image feedback.

Paper ("Tracking and Trajectory Recognition Module"): a second-order loop on the image feedback and the
trajectory's angle gives the desired pointing quaternion; it "fully corrects any initial pointing error" and
compensates a constant rate error.

The trajectory predicts the line of sight ``l_pred(t)``; the camera and the attitude give the measured one. Their
difference, the rotation vector ``y`` taking ``l_pred`` to ``l_meas`` (inertial), is the offset to correct. A
type-2 loop (proportional + integral on the error ``e = y - c``) drives the correction ``c``:

    c' = i + kp e,    i' = ki e,    kp = 2 zeta wn,    ki = wn^2,

so ``e'' + kp e' + ki e = y''``: a step offset decays as a second-order system of natural frequency ``wn`` and
damping ``zeta``, a ramp (constant rate error) leaves no steady-state error, a parabola leaves ``a / wn^2``.
Between frames the input ``y`` is the last measurement extrapolated along the slope of the last two (for at most
``extrapolation_limit_s``, then held), and the loop is integrated exactly (matrix exponential) over each step, so
the response does not depend on the control period or the frame cadence.

The commanded attitude is ``R_des = R(c) R_pred`` where ``R_pred`` puts the boresight on ``l_pred`` and the
``plane_normal_axis_body`` on the flyby-plane normal: the slew is a rotation about that one body axis.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from obsw import tracking_kernels as kernels
from obsw.config import TrackingConfig
from obsw.trajectory import NominalTrajectory


@dataclass(frozen=True)
class Reference:
    """Desired attitude (body->inertial, scalar-last), body rate (rad/s) and angular acceleration (rad/s^2),
    both in the desired body frame, and the commanded line of sight (inertial unit vector)."""

    q_des: NDArray[np.float64]
    omega_des_body: NDArray[np.float64]
    alpha_des_body: NDArray[np.float64]
    los_commanded_inertial: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))


def offset_rotvec(los_from: ArrayLike, los_to: ArrayLike) -> NDArray[np.float64]:
    """Rotation vector (rad) of the smallest rotation taking unit vector ``los_from`` onto ``los_to``."""
    a = np.asarray(los_from, dtype=float)
    b = np.asarray(los_to, dtype=float)
    axis = _cross(a, b)
    s = float(np.linalg.norm(axis))
    if s < 1e-15:
        if float(a @ b) < 0:
            raise ValueError(f"line of sight {b} is opposite to {a}: the rotation between them is undefined")
        return np.zeros(3)
    return axis / s * np.arctan2(s, float(a @ b))


def _cross(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """Cross product of two 3-vectors (numpy.cross is ten times slower on single vectors)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


@lru_cache(maxsize=64)
def loop_transition(kp: float, ki: float, h_s: float) -> NDArray[np.float64]:
    """exp(M h) for M = [[-kp, -1], [ki, 0]] in closed form (M = a I + N with N^2 = delta I); read-only (cached:
    the loop steps by the same control period almost every time)."""
    out = np.array(kernels.transition(float(kp), float(ki), float(h_s))).reshape(2, 2)
    out.setflags(write=False)
    return out


def _body_triad(cfg: TrackingConfig, boresight_body: tuple[float, float, float]) -> NDArray[np.float64]:
    """Columns: unit boresight, unit plane-normal axis (made exactly orthogonal), and their cross product."""
    b = np.asarray(boresight_body, dtype=float)
    b = b / np.linalg.norm(b)
    p = np.asarray(cfg.plane_normal_axis_body, dtype=float)
    p = p - float(p @ b) * b
    p = p / np.linalg.norm(p)
    return np.column_stack([b, p, _cross(b, p)])


def quaternion_of_matrix(m: NDArray[np.float64]) -> NDArray[np.float64]:
    """Scalar-last unit quaternion of a rotation matrix: ``Rotation.from_matrix(m).as_quat()`` to the last bit, at a
    twentieth of its cost.

    Markley's method (F. L. Markley, "Unit Quaternion from Rotation Matrix", Journal of Guidance, Control, and
    Dynamics 31(2), 2008) in the operations and order of SciPy's implementation; a matrix SciPy would first
    orthogonalise (its Gram matrix off the identity by 1e-12 or more) or refuse (not a rotation) goes to SciPy.
    """
    arr = np.asarray(m, dtype=float)
    if arr.shape == (3, 3):
        q, valid = kernels.quaternion_of_matrix(arr)
        if valid:
            return q
    return Rotation.from_matrix(m).as_quat()


def _geometry(trajectory: NominalTrajectory) -> NDArray[np.float64]:
    """The kernels' form of a trajectory: ``[t_ca (OBT s), d (m), v (m/s), e_ca (3), e_v (3)]``."""
    return np.array([trajectory.ca_time_obt_s, trajectory.ca_distance_m, trajectory.speed_m_s,
                     *trajectory.ca_direction, *trajectory.approach_direction])


def predicted_attitude(trajectory: NominalTrajectory, obt_s: float, cfg: TrackingConfig,
                       boresight_body: tuple[float, float, float] = (0.0, 0.0, 1.0)) -> Rotation:
    """Attitude putting the boresight on the predicted LOS and the plane-normal body axis on the plane normal."""
    geometry = _geometry(trajectory)
    los = kernels.los_inertial(geometry, float(obt_s))
    return Rotation.from_matrix(kernels.predicted_matrix(geometry, los, _body_triad(cfg, boresight_body)))


_Line = tuple[float, NDArray[np.float64], NDArray[np.float64]]
_NO_LINE: _Line = (0.0, np.zeros(3), np.zeros(3))  # the kernels' placeholder for "no measurement yet"


class TrackingLoop:
    """Second-order tracking loop; one ``update`` per control period. Pure: time and inputs come as arguments."""

    def __init__(self, cfg: TrackingConfig, boresight_body: tuple[float, float, float] = (0.0, 0.0, 1.0)) -> None:
        self.cfg = cfg
        self._kp = 2.0 * cfg.damping * cfg.natural_frequency_rad_s
        self._ki = cfg.natural_frequency_rad_s**2
        self._triad = _body_triad(cfg, boresight_body)
        self.reset()

    def reset(self) -> None:
        """Forget the correction, the measurements and the trajectory (e.g. on leaving the pointing modes)."""
        self._c = np.zeros(3)  # correction rotation vector, inertial, rad
        self._i = np.zeros(3)  # integral state: the loop's estimate of the offset rate, rad/s
        self._t: float | None = None  # loop time (advanced by dt_s), s
        self._obt: float | None = None
        self._trajectory: NominalTrajectory | None = None
        self._geometry_of: NominalTrajectory | None = None  # the trajectory whose kernel form is held
        self._geometry = np.zeros(9)
        # last two measurements: (loop time, OBT, measured LOS inertial)
        self._meas: list[tuple[float, float, NDArray[np.float64]]] = []
        self._line: _Line | None = None  # the input, from the measurements and the current trajectory
        self._extrapolate = True
        self.rejected_count = 0  # measurements ignored by the gate since the last reset
        self._rejected_run = 0  # consecutive measurements ignored by the gate

    def shift_time(self, step_s: float) -> None:
        """On-board time stepped by ``step_s``: the OBTs held (the loop's, the measurements', the trajectory's C/A)
        move with it, so the loop goes on as if nothing happened (its own time runs on the control period)."""
        if self._obt is not None:
            self._obt += step_s
        self._meas = [(t, obt + step_s, los) for t, obt, los in self._meas]
        if self._trajectory is not None:
            self._trajectory = self._trajectory.with_ca(self._trajectory.ca_time_obt_s + step_s,
                                                        self._trajectory.ca_distance_km)

    @property
    def last_measurement_obt_s(self) -> float | None:
        """OBT the last measurement taken by the loop refers to (its exposure, as given), or None."""
        return self._meas[-1][1] if self._meas else None

    @property
    def correction_rotvec(self) -> NDArray[np.float64]:
        """Current correction applied to the predicted LOS, inertial rotation vector, rad."""
        return self._c.copy()

    # --- input model ---------------------------------------------------------------------------------------------

    def _input_line(self, trajectory: NominalTrajectory) -> _Line | None:
        """(loop time of the last measurement, offset there, slope) of the extrapolated input, or None before any.

        Offsets are taken against ``trajectory``, so a new trajectory model re-expresses the same measurements.
        """
        if not self._meas:
            return None
        t_k, obt_k, los_k = self._meas[-1]
        y_k = offset_rotvec(trajectory.los_inertial(obt_k), los_k)
        slope = np.zeros(3)
        if len(self._meas) == 2 and self._extrapolate:
            t_j, obt_j, los_j = self._meas[0]
            gap = t_k - t_j
            if 0 < gap <= self.cfg.extrapolation_limit_s:
                slope = (y_k - offset_rotvec(trajectory.los_inertial(obt_j), los_j)) / gap
        return t_k, y_k, slope

    def _input_at(self, line: _Line, t: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Input offset and its rate at loop time ``t``."""
        t_k, y_k, slope = line
        return kernels.input_at(t_k, y_k, slope, self.cfg.extrapolation_limit_s, float(t))

    def _line_args(self) -> tuple[bool, float, NDArray[np.float64], NDArray[np.float64]]:
        """The input line as the kernels take it: (there is one, its loop time, offset, slope)."""
        line = self._line
        return (False, *_NO_LINE) if line is None else (True, *line)

    def _geometry_array(self, trajectory: NominalTrajectory) -> NDArray[np.float64]:
        """The kernels' form of ``trajectory``, built once per trajectory."""
        if trajectory is not self._geometry_of:
            self._geometry, self._geometry_of = _geometry(trajectory), trajectory
        return self._geometry

    # --- loop ----------------------------------------------------------------------------------------------------

    def _propagate(self, dt_s: float) -> None:
        """Advance (c, i) exactly over dt_s: with e = y - c and a linear input, (e, i - y') obeys z' = M z."""
        assert self._t is not None
        state = kernels.propagate(self._c, self._i, self._t, float(dt_s), *self._line_args(),
                                  self.cfg.extrapolation_limit_s, self._kp, self._ki)
        self._c, self._i = state[:3], state[3:]
        self._t += dt_s

    def _correction_rate(self) -> NDArray[np.float64]:
        """c' = i + kp (y - c) at the current loop time."""
        assert self._t is not None
        return kernels.correction_rate(self._c, self._i, self._kp, *self._line_args(),
                                       self.cfg.extrapolation_limit_s, self._t)

    def _rebase(self, old: NominalTrajectory, new: NominalTrajectory) -> None:
        """Keep the commanded attitude and rate continuous when the trajectory model is replaced."""
        assert self._obt is not None and self._t is not None
        rate_before = self._correction_rate()
        shift = offset_rotvec(new.los_inertial(self._obt), old.los_inertial(self._obt))
        self._c = kernels.compose_rotvec(self._c, shift)
        self._line = self._input_line(new)
        # commanded LOS rate ~ theta' n + c': move the difference of the trajectories' rates into c'
        wanted_rate = rate_before + (old.los_rate_rad_s(self._obt) - new.los_rate_rad_s(self._obt)) * new.plane_normal
        self._i = self._i + wanted_rate - self._correction_rate()

    def update(
        self,
        obt_s: float,
        dt_s: float,
        trajectory: NominalTrajectory,
        los_measured_inertial: ArrayLike | None,
        measured_obt_s: float | None = None,
        extrapolate: bool = True,
        gate_rad: float | None = None,
    ) -> Reference:
        """Advance the loop by ``dt_s`` to ``obt_s``, take the measured LOS (inertial unit vector, or None when the
        target was not seen), and return the reference at ``obt_s``.

        ``measured_obt_s`` is when the frame was exposed (default ``obt_s``): the offset is taken against the
        trajectory at that time, since near C/A the LOS turns 1 deg in one 0.1 s control period.

        ``dt_s`` (the control period) drives the loop, ``obt_s`` the trajectory, so an OBT jump does not make the
        loop integrate over the jump. The first call starts the loop at ``obt_s`` and ignores ``dt_s``. A change
        of ``trajectory`` (e.g. to the recognised one) keeps the commanded attitude and rate continuous.

        ``extrapolate=False`` holds the last measured offset instead of extending its slope: when the trajectory
        model already carries the LOS motion (the recognised trajectory), the offset is a slowly varying bias and
        a slope between two measurements is mostly their noise, or one misidentified blob, amplified.
        ``gate_rad`` ignores a measurement whose offset is farther than this from the loop's prediction of it
        (counted in ``rejected_count``), unless the ``cfg.gate_release_count`` before it were all ignored.
        """
        if not math.isfinite(obt_s):
            raise ValueError(f"obt_s must be finite, got {obt_s}")
        los = None
        if los_measured_inertial is not None:
            los = np.asarray(los_measured_inertial, dtype=float)
            x, y, z = los.tolist() if los.shape == (3,) else (0.0, 0.0, 0.0)
            norm = math.sqrt(x * x + y * y + z * z)
            if los.shape != (3,) or not np.isfinite(norm) or abs(norm - 1.0) > 1e-6:
                raise ValueError(f"los_measured_inertial must be a unit 3-vector, got {los_measured_inertial}")
            if measured_obt_s is not None and not (math.isfinite(measured_obt_s) and measured_obt_s <= obt_s):
                raise ValueError(f"measured_obt_s {measured_obt_s} must be finite and not after obt_s {obt_s}")
        if gate_rad is not None and not gate_rad > 0:
            raise ValueError(f"gate_rad must be > 0 or None, got {gate_rad}")
        switched = extrapolate != self._extrapolate
        self._extrapolate = bool(extrapolate)
        if self._t is None:
            self._t = 0.0
        else:
            if not (math.isfinite(dt_s) and dt_s >= 0):
                raise ValueError(f"dt_s must be finite and >= 0, got {dt_s}")
            if self._trajectory is not None and trajectory is not self._trajectory and trajectory != self._trajectory:
                self._rebase(self._trajectory, trajectory)
            self._propagate(dt_s)
        self._obt = float(obt_s)
        if los is not None:
            taken = self._obt if measured_obt_s is None else float(measured_obt_s)
            t_taken = self._t - (self._obt - taken)
            # a run of rejections means the scene, not one blob, has moved: take the measurement again
            if gate_rad is not None and self._line is not None and self._rejected_run < self.cfg.gate_release_count \
                    and self._innovation_rad(trajectory, t_taken, taken, los) > gate_rad:
                self.rejected_count += 1
                self._rejected_run += 1
                los = None
            else:
                self._rejected_run = 0
                self._meas = [*self._meas[-1:], (t_taken, taken, los)]
        if los is not None or switched or (trajectory is not self._trajectory and trajectory != self._trajectory):
            self._line = self._input_line(trajectory)
        self._trajectory = trajectory
        return self._reference(trajectory)

    def _innovation_rad(self, trajectory: NominalTrajectory, t_taken: float, obt_taken: float,
                        los: NDArray[np.float64]) -> float:
        """Distance of a measured offset from the loop's prediction of it (the input line, else the correction)."""
        y = offset_rotvec(trajectory.los_inertial(obt_taken), los)
        line = self._input_line(trajectory) if self._line is not None else None
        predicted = self._c if line is None else self._input_at(line, t_taken)[0]
        return float(np.linalg.norm(y - predicted))

    def _reference(self, trajectory: NominalTrajectory) -> Reference:
        """R_des = R(c) R_pred; omega and alpha from theta', theta'' about the normal plus the correction's motion."""
        assert self._obt is not None and self._t is not None
        out, valid = kernels.reference(self._c, self._i, self._kp, self._ki, self._t, *self._line_args(),
                                       self.cfg.extrapolation_limit_s, self._geometry_array(trajectory), self._obt,
                                       self._triad)
        return Reference(
            q_des=out[:4] if valid else Rotation.from_matrix(out[13:].reshape(3, 3)).as_quat(),
            omega_des_body=out[4:7],
            alpha_des_body=out[7:10],
            los_commanded_inertial=out[10:13],
        )


def warm_up() -> None:
    """Compile (or load from the cache) the loop's kernels now, as a run calls them: periods with and without a
    measurement, a gated one and a change of trajectory."""
    trajectory = NominalTrajectory(ca_time_obt_s=100.0, ca_distance_km=50.0, speed_km_s=7.0,
                                   approach_direction=(1.0, 0.0, 0.0), ca_direction=(0.0, 1.0, 0.0))
    loop = TrackingLoop(TrackingConfig())
    loop.update(0.0, 0.1, trajectory, None)
    loop.update(0.1, 0.1, trajectory, trajectory.los_inertial(0.1))
    loop.update(0.2, 0.1, trajectory, trajectory.los_inertial(0.2), measured_obt_s=0.15, gate_rad=0.1)
    loop.update(0.3, 0.1, trajectory.with_ca(101.0, 50.0), None, extrapolate=False)
    predicted_attitude(trajectory, 0.3, loop.cfg)
