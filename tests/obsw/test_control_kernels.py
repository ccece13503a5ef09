"""The attitude control's compiled steps against the PD law written here from its formula with SciPy's rotations,
and the wheel allocation's pass against its rule in numpy."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from obsw import control_kernels as k
from obsw.config import ControlConfig
from obsw.control import boresight_error_rad, pd_torque_nm, warm_up, wheel_torques_nm

INERTIA = np.array([[0.152, 0.002, -0.001], [0.002, 0.117, 0.003], [-0.001, 0.003, 0.058]])
vectors = st.lists(st.floats(-0.2, 0.2), min_size=3, max_size=3).map(np.array)
seeds = st.integers(0, 2**31)


def _pd_reference(q: np.ndarray, omega: np.ndarray, q_des: np.ndarray, omega_des: np.ndarray, alpha_des: np.ndarray,
                  kp: float, kd: float, feedforward: bool, h: np.ndarray) -> np.ndarray:
    """``-kp e - kd (omega - C omega_des) + I (C alpha_des - omega x C omega_des) + omega x (I omega + h)``, with
    ``e`` the rotation vector of the body relative to the desired frame and ``C`` desired frame -> body."""
    relative = Rotation.from_quat(q_des).inv() * Rotation.from_quat(q)  # body -> desired
    c = relative.as_matrix().T
    torque = -kp * relative.as_rotvec() - kd * (omega - c @ omega_des)
    if feedforward:
        torque += INERTIA @ (c @ alpha_des - np.cross(omega, c @ omega_des)) + np.cross(omega, INERTIA @ omega + h)
    return torque


@settings(max_examples=300, deadline=None)
@given(seed=seeds, turn=st.floats(0.0, 3.0), scale=st.floats(0.1, 10.0), omega=vectors, omega_des=vectors,
       alpha_des=vectors.map(lambda v: v * 0.1), h=vectors.map(lambda v: v * 0.1), feedforward=st.booleans(),
       with_wheels=st.booleans())
def test_pd_torque_is_the_pd_law_with_its_feedforward(seed: int, turn: float, scale: float, omega: np.ndarray,
                                                      omega_des: np.ndarray, alpha_des: np.ndarray, h: np.ndarray,
                                                      feedforward: bool, with_wheels: bool) -> None:
    """The kernel's torque is the docstring's PD law and feedforward evaluated with SciPy's rotations, for any
    scale or sign of the quaternions and errors up to 3 rad."""
    rng = np.random.default_rng(seed)
    q_des = Rotation.random(random_state=seed).as_quat()
    axis = rng.standard_normal(3)
    q = (Rotation.from_quat(q_des) * Rotation.from_rotvec(axis / np.linalg.norm(axis) * turn)).as_quat()
    kp, kd = 0.02, 0.03
    torque, usable = k.pd_torque(q * scale * rng.choice([-1.0, 1.0]), omega, q_des * rng.choice([-1.0, 1.0]),
                                 omega_des, alpha_des, INERTIA, kp, kd, feedforward, h, with_wheels)
    assert usable
    expected = _pd_reference(q, omega, q_des, omega_des, alpha_des, kp, kd, feedforward,
                             h if with_wheels else np.zeros(3))
    np.testing.assert_allclose(torque, expected, rtol=0, atol=1e-13)


@pytest.mark.parametrize("bad", ["q", "omega", "q_des", "omega_des", "alpha_des", "h"])
def test_pd_torque_refuses_non_finite_or_zero_inputs(bad: str) -> None:
    """A non-finite vector, a zero quaternion or non-finite wheel momenta used by the feedforward is reported
    unusable."""
    args = dict(q=np.array([0.0, 0.0, 0.0, 1.0]), omega=np.zeros(3), q_des=np.array([0.0, 0.0, 0.0, 1.0]),
                omega_des=np.zeros(3), alpha_des=np.zeros(3), h=np.zeros(3))
    args[bad] = args[bad] * np.nan
    assert not k.pd_torque(args["q"], args["omega"], args["q_des"], args["omega_des"], args["alpha_des"], INERTIA,
                           0.02, 0.03, True, args["h"], True)[1]
    if bad in ("q", "q_des"):
        args[bad] = np.zeros(4)
        assert not k.pd_torque(args["q"], args["omega"], args["q_des"], args["omega_des"], args["alpha_des"],
                               INERTIA, 0.02, 0.03, True, args["h"], True)[1]


@settings(max_examples=300, deadline=None)
@given(seed=seeds, n=st.integers(1, 6))
def test_split_pass_is_the_allocation_rule(seed: int, n: int) -> None:
    """One pass puts the share on the usable wheels in order, zeros elsewhere, and flags the usable wheels at or
    past the momentum limit that the share would speed up; the peak is the largest |tau|."""
    rng = np.random.default_rng(seed)
    usable = rng.random(n) < 0.7
    share = rng.normal(scale=1e-3, size=int(usable.sum()))
    momentum = rng.choice([0.0, 0.05, 0.1, -0.1, 0.2], size=n)
    tau, pushing, count, peak = k.split_pass(share, usable, momentum, 0.1)
    expected = np.zeros(n)
    expected[usable] = share
    expected_pushing = usable & (np.abs(momentum) >= 0.1) & (expected * momentum > 0)
    assert tau.tolist() == expected.tolist()
    assert pushing.tolist() == expected_pushing.tolist() and count == int(expected_pushing.sum())
    assert peak == float(np.max(np.abs(expected), initial=0.0))


class _Ref:
    """A reference with given quaternion, rate and acceleration."""

    def __init__(self, q_des: object, omega: object, alpha: object) -> None:
        self.q_des, self.omega_des_body, self.alpha_des_body = q_des, omega, alpha


def test_non_finite_and_zero_inputs_are_refused_with_the_field_named() -> None:
    """Through the combined check, a non-finite vector or a zero quaternion still raises ValueError naming it."""
    unit, zero, nan3 = [0.0, 0.0, 0.0, 1.0], np.zeros(3), np.array([0.0, np.nan, 0.0])
    cfg = ControlConfig()
    cases = [("omega_rad_s must be finite", (unit, nan3, _Ref(unit, zero, zero), None)),
             ("ref.omega_des_body must be finite", (unit, zero, _Ref(unit, nan3, zero), None)),
             ("ref.alpha_des_body must be finite", (unit, zero, _Ref(unit, zero, nan3), None)),
             ("q must be a non-zero quaternion", ([0.0] * 4, zero, _Ref(unit, zero, zero), None)),
             ("ref.q_des must be finite", (unit, zero, _Ref([np.inf, 0, 0, 1], zero, zero), None)),
             ("wheel_momentum_body_nms must be finite", (unit, zero, _Ref(unit, zero, zero), nan3))]
    for message, (q, omega, ref, h) in cases:
        with pytest.raises(ValueError, match=message):
            pd_torque_nm(q, omega, ref, INERTIA, cfg, h)
    # without the feedforward the wheel momenta are not used, so not checked
    assert np.isfinite(pd_torque_nm(unit, zero, _Ref(unit, zero, zero), INERTIA, ControlConfig(feedforward=False),
                                    nan3)).all()
    with pytest.raises(ValueError, match="body_torque_nm must be finite"):
        wheel_torques_nm(nan3, np.eye(3), zero, 0.007, 0.1)
    with pytest.raises(ValueError, match="wheel_momentum_nms must be finite"):
        wheel_torques_nm(zero, np.eye(3), nan3, 0.007, 0.1)
    with pytest.raises(ValueError, match="max_momentum_nms"):
        wheel_torques_nm(zero, np.eye(3), zero, 0.007, np.nan)
    with pytest.raises(ValueError, match="in_use must have 3 values"):
        wheel_torques_nm(zero, np.eye(3), zero, 0.007, 0.1, in_use=[True, False])


@settings(max_examples=300, deadline=None)
@given(seed=seeds, scale=st.floats(0.5, 2.0))
def test_boresight_error_is_the_angle_to_scipys_turned_boresight(seed: int, scale: float) -> None:
    """The boresight error is the angle between SciPy's rotation of the body boresight by q and the LOS."""
    rng = np.random.default_rng(seed)
    q = Rotation.random(random_state=seed).as_quat()
    boresight, los = rng.standard_normal(3), rng.standard_normal(3)
    boresight, los = boresight / np.linalg.norm(boresight), los / np.linalg.norm(los)
    turned = Rotation.from_quat(q).apply(boresight)
    expected = np.arctan2(np.linalg.norm(np.cross(turned, los)), turned @ los)  # well-conditioned at 0 and pi
    assert boresight_error_rad(q * scale, boresight, los) == pytest.approx(expected, abs=1e-7)
    # acos of a dot product a few ulp below 1 (as the flight software takes it): sqrt(2 * 4 ulp) = 4.2e-8 rad
    assert boresight_error_rad(q, boresight, turned) == pytest.approx(0.0, abs=1e-7)


def test_warm_up_compiles_every_kernel_a_period_calls() -> None:
    """After warm_up, the PD law, the wheel split and the boresight error of a period compile nothing more."""
    warm_up()
    before = {name: len(f.signatures) for name, f in vars(k).items() if hasattr(f, "signatures")}
    assert all(before[name] >= 1 for name in ("pd_torque", "split_pass", "all_finite", "boresight_error_rad"))
    q = Rotation.from_rotvec([0.1, -0.2, 0.3]).as_quat()
    torque = pd_torque_nm(q, np.array([0.01, 0.0, -0.02]), _Ref(q, np.zeros(3), np.ones(3) * 1e-3), INERTIA,
                          ControlConfig(), np.array([0.01, 0.02, 0.0]))
    wheel_torques_nm(torque, np.eye(3), np.array([0.1, 0.0, -0.1]), 0.007, 0.1, np.array([True, True, False]))
    boresight_error_rad(q, (0.0, 0.0, 1.0), np.array([0.0, 1.0, 0.0]))
    assert {name: len(f.signatures) for name, f in vars(k).items() if hasattr(f, "signatures")} == before
