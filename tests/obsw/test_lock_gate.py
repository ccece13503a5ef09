"""False lock: the innovation of a line of sight against the recognised trajectory's prediction, and its residual
from the continuous C/A estimate, against closed-form drifts and a synthetic straight-line flyby."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from obsw.config import FdirConfig, RecognitionConfig
from obsw.lock_gate import Estimate, LockGate, Prediction
from obsw.recognition import ContinuousEstimate, TrajectoryRecognizer
from obsw.trajectory import NominalTrajectory

TRAJ = NominalTrajectory(ca_time_obt_s=1000.0, ca_distance_km=55.0, speed_km_s=7.0, approach_direction=(1, 0, 0),
                         ca_direction=(0, 1, 0))
CFG = FdirConfig(false_lock_gate_deg=0.25, false_lock_gate_growth_deg_s=0.02)


def _off(los: np.ndarray, deg: float) -> np.ndarray:
    """``los`` turned by ``deg`` about the flyby-plane normal."""
    return Rotation.from_rotvec(math.radians(deg) * TRAJ.plane_normal).apply(los)


def test_a_target_following_the_trajectory_with_a_constant_offset_is_accepted() -> None:
    """Dimorphos 1 deg off the barycentre's line of sight, moving with it from C/A-60 s to C/A: never refused."""
    gate = LockGate(CFG)
    for t in np.arange(940.0, 1000.0, 0.5):
        assert gate.check(TRAJ, t, _off(TRAJ.los_inertial(t), 1.0)).accepted
    assert gate.rejected == 0


def test_a_jump_beyond_the_gate_is_refused_and_the_gate_grows_with_time() -> None:
    """A blob 2 deg off the prediction is refused (one run, counted); the gate then grows by 0.02 deg/s, so 0.4 deg
    off is refused 1 s after the last accepted line of sight and taken 10 s after it."""
    gate = LockGate(CFG)
    assert gate.check(TRAJ, 900.0, TRAJ.los_inertial(900.0)).accepted
    r = gate.check(TRAJ, 901.0, _off(TRAJ.los_inertial(901.0), 2.0))
    assert not r.accepted and math.degrees(r.innovation_rad) == pytest.approx(2.0, rel=1e-9)
    assert math.degrees(r.gate_rad) == pytest.approx(0.27, rel=1e-9)
    assert not gate.check(TRAJ, 901.0, _off(TRAJ.los_inertial(901.0), 0.4)).accepted
    assert gate.check(TRAJ, 910.0, _off(TRAJ.los_inertial(910.0), 0.4)).accepted
    assert (gate.rejected, gate.run) == (2, 0)


def test_without_a_trusted_trajectory_everything_is_accepted() -> None:
    """Before the recognition is trusted (trajectory None) the gate takes every line of sight."""
    gate = LockGate(CFG)
    assert gate.check(None, 900.0, TRAJ.los_inertial(900.0)).accepted
    assert gate.check(None, 901.0, _off(TRAJ.los_inertial(901.0), 20.0)).accepted



# --- the residual from the continuous C/A estimate ---------------------------------------------------------------

NOISE_RAD, RADIUS_RAD = 1.0e-4, 0.6e-4
BOUND_RAD = RADIUS_RAD + 5.0 * NOISE_RAD  # the default false_lock_residual_sigma, a prediction of no uncertainty
DRIFT_DEG_S = 0.002  # 0.001 deg a frame at 2 Hz: 250 times under the frame-to-frame gate


def _prediction(t: float, sigma_rad: float = 0.0) -> Prediction:
    """The true trajectory's line of sight at ``t`` as the prediction, uncertain by ``sigma_rad``."""
    return Prediction(theta_rad=float(TRAJ.theta_rad(t)), sigma_rad=sigma_rad, noise_rad=NOISE_RAD,
                      radius_rad=RADIUS_RAD)


def _off_plane(los: np.ndarray, deg: float) -> np.ndarray:
    """``los`` turned by ``deg`` out of the flyby plane (about the in-plane axis normal to it)."""
    return Rotation.from_rotvec(math.radians(deg) * np.cross(TRAJ.plane_normal, los)).apply(los)


@pytest.mark.parametrize("turn", [_off, _off_plane], ids=["in the plane", "out of the plane"])
def test_a_slow_drift_is_refused_from_where_it_exceeds_the_residual_bound(turn: object) -> None:
    """A line of sight creeping off the prediction at 0.002 deg/s from C/A-80 s is accepted while its drift is within
    the radius plus 5 sigma (0.0321 deg) and refused from there on, every frame; without the drift, never refused."""
    times = np.arange(900.0, 990.0, 0.5)
    start = 920.0
    drifting, steady = LockGate(CFG), LockGate(CFG)
    for t in times:
        drift_deg = DRIFT_DEG_S * max(t - start, 0.0)
        los = turn(TRAJ.los_inertial(t), drift_deg)  # type: ignore[operator]
        assert drifting.check(TRAJ, t, los, _prediction(t)).accepted == (math.radians(drift_deg) <= BOUND_RAD)
        assert steady.check(TRAJ, t, TRAJ.los_inertial(t), _prediction(t)).accepted
    first_refused = start + math.degrees(BOUND_RAD) / DRIFT_DEG_S
    assert drifting.rejected == int(np.sum(times > first_refused)) and drifting.run == drifting.rejected
    assert steady.rejected == 0


def test_the_prediction_uncertainty_widens_the_bound() -> None:
    """An offset of 0.05 deg (past the 0.0321 deg of a certain prediction) is refused against a certain prediction and
    accepted against one uncertain by 1.5e-4 rad (bound 0.6e-4 + 5 x 1.8e-4 rad = 0.0551 deg)."""
    t = 950.0
    los = _off(TRAJ.los_inertial(t), 0.05)
    assert not LockGate(CFG).check(TRAJ, t, los, _prediction(t)).accepted
    wide = LockGate(CFG).check(TRAJ, t, los, _prediction(t, sigma_rad=1.5e-4))
    assert wide.accepted
    assert wide.gate_rad == pytest.approx(RADIUS_RAD + 5.0 * math.hypot(NOISE_RAD, 1.5e-4), rel=1e-12)
    assert math.degrees(wide.innovation_rad) == pytest.approx(0.05, rel=1e-9)


# --- the gate and the recognition together, on a synthetic straight-line flyby -----------------------------------

TRUE_FLYBY = TRAJ.with_ca(1003.0, 53.0)  # the truth: 3 s late and 2 km nearer than ground's nominal TRAJ
PRIOR = NominalTrajectory(**{**TRAJ.model_dump(), "ca_time_sigma_s": 10.0, "ca_distance_sigma_km": 5.0})
REC_CFG = RecognitionConfig(angle_noise_rad=NOISE_RAD)
DIMORPHOS_RADIUS_M = 1.5 * 164.0 / 2  # the on-board knowledge: largest axis ratio times the mean radius
CREEP_START = 1003.0 - 120.0


def _los(t: float, drift_rad: float, rng: np.random.Generator) -> np.ndarray:
    """TRUE_FLYBY's line of sight at ``t`` turned ``drift_rad`` in the plane, with 1e-4 rad of noise on each axis."""
    noise = Rotation.from_rotvec(np.array([*rng.normal(0.0, NOISE_RAD, 2), 0.0]))
    return noise.apply(Rotation.from_rotvec(drift_rad * TRAJ.plane_normal).apply(TRUE_FLYBY.los_inertial(t)))


def _misaligned_los(t: float, camera_to_body: Rotation, rng: np.random.Generator) -> np.ndarray:
    """TRUE_FLYBY's line of sight at ``t`` as a camera turned by ``camera_to_body`` from its nominal axes measures it
    (taking camera axes for body axes), on the attitude the tracking holds (boresight +Z on the nominal TRAJ's line of
    sight, body +Y on the plane's normal), with 1e-4 rad of noise on each axis."""
    z, y = TRAJ.los_inertial(t), TRAJ.plane_normal
    body = Rotation.from_matrix(np.column_stack([np.cross(y, z), y, z]))
    in_camera = (body * camera_to_body).inv().apply(TRUE_FLYBY.los_inertial(t))
    noise = Rotation.from_rotvec(np.array([*rng.normal(0.0, NOISE_RAD, 2), 0.0]))
    return body.apply(noise.apply(in_camera))


def _flyby(drift_deg_s: float, seed: int = 3, rec_cfg: RecognitionConfig = REC_CFG,
           camera_to_body: Rotation | None = None,
           times: np.ndarray = np.arange(1003.0 - 240.0, 1003.0 - 30.0, 1.0),
           ) -> tuple[TrajectoryRecognizer, list[tuple[float, float, bool, float]]]:
    """Lines of sight of TRUE_FLYBY at ``times`` (1 Hz from C/A-240 s to C/A-30 s), creeping by ``drift_deg_s`` in
    the plane from C/A-120 s or measured by a misaligned camera, each judged by the gate against the reference
    estimate as on board. The recognition of those accepted and, per line of sight, (time, drift rad, accepted,
    newest line of sight of the reference estimate)."""
    rng = np.random.default_rng(seed)
    rec = TrajectoryRecognizer(PRIOR, rec_cfg)
    gate = LockGate(CFG)
    seen = []
    for t in times:
        drift = math.radians(drift_deg_s * max(t - CREEP_START, 0.0))
        los = _los(t, drift, rng) if camera_to_body is None else _misaligned_los(t, camera_to_body, rng)
        prediction, newest = None, math.nan
        if rec.measurement_count >= 10:
            gate.references.add(Estimate(float(rec.last_measurement_obt_s or 0.0), rec.continuous_estimate()))
            reference = gate.reference(t)
            assert reference is not None
            prediction = reference.prediction(t, TRAJ.speed_m_s, NOISE_RAD, DIMORPHOS_RADIUS_M)
            newest = reference.newest_obt_s
        accepted = gate.check(rec.continuous_trajectory() if prediction else None, t, los, prediction).accepted
        if accepted:
            rec.add_measurement(t, los)
        seen.append((t, drift, accepted, newest))
    return rec, seen


def test_noise_alone_is_never_refused_and_the_flyby_is_recognised() -> None:
    """Without a drift no line of sight of the flyby is refused, and the estimate finds the true C/A time within 3
    sigma."""
    rec, seen = _flyby(0.0)
    assert all(ok for _, _, ok, _ in seen)
    t_ca, _, cov = rec.continuous()
    assert abs(t_ca - TRUE_FLYBY.ca_time_obt_s) < 3.0 * math.sqrt(cov[0, 0])


def _creep(offset_sigma_rad: float) -> tuple[list[tuple[float, float, bool, float]], int]:
    """The creeping flyby judged with an estimate solving for a LOS offset of prior ``offset_sigma_rad`` (0: held),
    and the index of its first refusal, checked to come after every line of sight within the radius plus 5 sigma."""
    _, seen = _flyby(DRIFT_DEG_S, rec_cfg=RecognitionConfig(angle_noise_rad=NOISE_RAD,
                                                            los_offset_sigma_rad=offset_sigma_rad))
    radius = [DIMORPHOS_RADIUS_M / float(TRUE_FLYBY.range_m(t)) for t, *_ in seen]
    assert all(ok for (_, drift, ok, _), r in zip(seen, radius, strict=True) if drift <= r + 5.0 * NOISE_RAD)
    first = next(i for i, (_, _, ok, _) in enumerate(seen) if not ok)
    return seen, first


def test_a_creeping_lock_is_refused_against_an_estimate_from_before_it() -> None:
    """With the LOS offset held at zero (the paper's estimate), a creep of 0.002 deg/s from C/A-120 s is never refused
    inside the radius plus 5 sigma, is refused before it passes the radius plus 10 sigma, and through that run of
    refusals (over 20 s) it is judged against an estimate of lines of sight exposed before it began."""
    seen, first = _creep(0.0)
    assert seen[first][1] <= DIMORPHOS_RADIUS_M / float(TRUE_FLYBY.range_m(seen[first][0])) + 10.0 * NOISE_RAD
    run = seen[first:first + next(i for i, (_, _, ok, _) in enumerate(seen[first:]) if ok)]
    assert len(run) > 20 and all(newest < CREEP_START for *_, newest in run)


def test_a_creeping_lock_is_refused_to_the_end_when_the_offset_is_solved() -> None:
    """With the LOS offset solved (the default), the same creep is refused later, before it passes the radius plus
    20 sigma: the offset's prior leaves the prediction 30 s ahead less certain at C/A-100 s, so the creep reaches the
    bound after the lag and the reference holds part of it. Once refused it is never taken again up to C/A-30 s."""
    seen, first = _creep(RecognitionConfig().los_offset_sigma_rad)
    assert seen[first][1] <= DIMORPHOS_RADIUS_M / float(TRUE_FLYBY.range_m(seen[first][0])) + 20.0 * NOISE_RAD
    assert not any(ok for _, _, ok, _ in seen[first:]) and len(seen) - first > 20


@pytest.mark.parametrize("azimuth_deg", [0.0, 60.0, 135.0, 270.0])
def test_a_misaligned_camera_is_never_refused_through_ca(azimuth_deg: float) -> None:
    """A camera misaligned by 0.04 deg (twice the prior's sigma) about any axis across the boresight: with the LOS
    offset solved, no line of sight from C/A-240 s to C/A+20 s (2 Hz from C/A-30 s) is refused; held at zero, an
    in-plane part biases the C/A estimate and lines of sight near C/A are refused (the failure of dispersed runs)."""
    axis = np.array([math.cos(math.radians(azimuth_deg)), math.sin(math.radians(azimuth_deg)), 0.0])
    camera_to_body = Rotation.from_rotvec(math.radians(0.04) * axis)
    times = np.concatenate([np.arange(1003.0 - 240.0, 1003.0 - 30.0, 1.0), np.arange(1003.0 - 30.0, 1023.0, 0.5)])
    _, seen = _flyby(0.0, camera_to_body=camera_to_body, times=times)
    assert all(ok for _, _, ok, _ in seen)
    if abs(math.sin(math.radians(azimuth_deg))) > 0.5:  # a rotation about body +Y moves the LOS within the plane
        _, held = _flyby(0.0, rec_cfg=RecognitionConfig(angle_noise_rad=NOISE_RAD, los_offset_sigma_rad=0.0),
                         camera_to_body=camera_to_body, times=times)
        assert not all(ok for _, _, ok, _ in held)


def test_the_reference_is_the_estimate_lag_before_and_held_through_a_run_of_refusals() -> None:
    """Estimates from lines of sight up to 0, 10, ..., 100 s with a 30 s lag: at 75 s the reference is the one up to
    40 s; after a refusal at 75 s it stays that one at 95 s, and moves to the one up to 60 s once 90 s is accepted."""
    gate = LockGate(FdirConfig(false_lock_reference_lag_s=30.0))
    for k in range(11):
        gate.references.add(Estimate(10.0 * k, ContinuousEstimate(1000.0, 55.0, 0.0, np.eye(2), 0.0, 0.0)))
    assert gate.reference(75.0).newest_obt_s == 40.0  # type: ignore[union-attr]
    t = 75.0
    refused = gate.check(TRAJ, t, TRAJ.los_inertial(t), Prediction(theta_rad=float(TRAJ.theta_rad(t)) + 0.01,
                                                                      sigma_rad=0.0, noise_rad=1e-4, radius_rad=0.0))
    assert not refused.accepted
    assert gate.reference(95.0).newest_obt_s == 40.0  # type: ignore[union-attr]
    assert gate.check(TRAJ, 90.0, TRAJ.los_inertial(90.0), _prediction(90.0)).accepted
    assert gate.reference(90.0).newest_obt_s == 60.0  # type: ignore[union-attr]
