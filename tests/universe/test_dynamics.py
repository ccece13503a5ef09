"""Attitude and reaction-wheel dynamics against closed forms and conservation laws."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import linprog
from scipy.spatial.transform import Rotation

from universe.config import SpacecraftConfig, WheelConfig
from universe.dynamics import AttitudeState, DynamicsError, SpacecraftDynamics

FRICTIONLESS = {"viscous_friction_nms": 0.0, "coulomb_friction_nm": 0.0}
# An asymmetric body with products of inertia, so that every gyroscopic term is exercised.
TUMBLING_INERTIA = ((0.152, 0.004, -0.002), (0.004, 0.117, 0.003), (-0.002, 0.003, 0.058))


def spacecraft(layout: str = "orthogonal", inertia=None, **wheel) -> SpacecraftDynamics:
    """Return dynamics for a spacecraft with the given wheel layout and wheel overrides."""
    kwargs = {"wheels": WheelConfig(layout=layout, **wheel)}
    if inertia is not None:
        kwargs["inertia_kgm2"] = inertia
    return SpacecraftDynamics(SpacecraftConfig(**kwargs))


def run(dyn: SpacecraftDynamics, state: AttitudeState, torque, seconds: float, dt: float = 0.1, **kw) -> AttitudeState:
    """Return the state after stepping `seconds` with a constant command."""
    for _ in range(round(seconds / dt)):
        state = dyn.step(state, np.asarray(torque, dtype=float), dt, **kw)
    return state


@pytest.mark.parametrize("layout", ["orthogonal", "pyramid"])
def test_torque_free_motion_conserves_momentum_and_energy(layout: str) -> None:
    """With no torque and no friction, inertial H and kinetic energy stay constant to 1e-9 over 600 s."""
    dyn = spacecraft(layout, TUMBLING_INERTIA, **FRICTIONLESS)
    rng = np.random.default_rng(1)
    state = AttitudeState(
        q=Rotation.random(random_state=2).as_quat(),
        omega_rad_s=np.array([0.08, -0.05, 0.12]),
        wheel_speed_rad_s=rng.uniform(-300, 300, dyn.n_wheels),
    )
    h0, e0 = dyn.angular_momentum_inertial(state), dyn.kinetic_energy(state)
    state = run(dyn, state, np.zeros(dyn.n_wheels), 600.0)
    assert np.linalg.norm(dyn.angular_momentum_inertial(state) - h0) / np.linalg.norm(h0) < 1e-9
    assert abs(dyn.kinetic_energy(state) - e0) / e0 < 1e-9
    assert abs(np.linalg.norm(state.q) - 1.0) < 1e-12


def test_axisymmetric_nutation_matches_analytic() -> None:
    """An axisymmetric body's transverse rate rotates at lambda = (I3 - I1)/I1 w3 while w3 stays constant."""
    i1, i3 = 0.12, 0.05
    dyn = spacecraft("orthogonal", ((i1, 0, 0), (0, i1, 0), (0, 0, i3)), **FRICTIONLESS)
    w0 = np.array([0.03, 0.0, 0.2])
    # Rotors counter-spun so their absolute momentum is zero: the body is a plain rigid body.
    state = AttitudeState(q=np.array([0, 0, 0, 1.0]), omega_rad_s=w0, wheel_speed_rad_s=-w0)
    lam = (i3 - i1) / i1 * w0[2]
    for k in range(1, 7):
        state = run(dyn, state, np.zeros(3), 10.0)
        t = 10.0 * k
        np.testing.assert_allclose(
            state.omega_rad_s, [0.03 * math.cos(lam * t), 0.03 * math.sin(lam * t), 0.2], atol=1e-10
        )


def test_gyrostat_nutation_includes_wheel_momentum() -> None:
    """With a rotor holding momentum h3 along Z, the nutation rate becomes ((I3 - I1) w3 + h3) / I1."""
    i1, i3 = 0.12, 0.05
    dyn = spacecraft("orthogonal", ((i1, 0, 0), (0, i1, 0), (0, 0, i3)), **FRICTIONLESS)
    w0 = np.array([0.02, 0.0, 0.1])
    spin_z = 400.0
    state = AttitudeState(
        q=np.array([0, 0, 0, 1.0]), omega_rad_s=w0, wheel_speed_rad_s=np.array([-0.02, 0.0, spin_z])
    )
    h3 = 1e-4 * (w0[2] + spin_z)
    lam = ((i3 - i1) * w0[2] + h3) / i1
    state = run(dyn, state, np.zeros(3), 40.0)
    expected = [0.02 * math.cos(lam * 40), 0.02 * math.sin(lam * 40), 0.1]
    np.testing.assert_allclose(state.omega_rad_s, expected, atol=1e-10)


def test_constant_wheel_torque_spin_up_and_saturation() -> None:
    """Torque u on wheel X from rest: w = -u t / I, J Omega = u t (1 + J/I) until J Omega = h_max, then both hold."""
    dyn = spacecraft("orthogonal", **FRICTIONLESS)
    ix, jw, u, hmax = 0.152, 1e-4, 0.005, 0.1
    k = 1 + jw / ix
    t_sat = hmax / (u * k)
    state = AttitudeState(q=np.array([0, 0, 0, 1.0]), omega_rad_s=np.zeros(3), wheel_speed_rad_s=np.zeros(3))
    t = 0.0
    for _ in range(300):
        state = dyn.step(state, np.array([u, 0.0, 0.0]), 0.1)
        t += 0.1
        p = dyn.wheel_momentum_nms(state)[0]
        assert p <= hmax * (1 + 1e-12)
        if t < t_sat - 1e-9:
            assert state.omega_rad_s[0] == pytest.approx(-u * t / ix, rel=1e-9)
            assert p == pytest.approx(u * t * k, rel=1e-9)
        elif t > t_sat + 0.1:
            assert p == pytest.approx(hmax, rel=1e-9)
            assert state.omega_rad_s[0] == pytest.approx(-hmax / (k * ix), rel=1e-9)
        np.testing.assert_allclose(state.omega_rad_s[1:], 0.0, atol=1e-15)
    # A reversed command is not blocked by the limit: the wheel spins down at once.
    state = dyn.step(state, np.array([-u, 0.0, 0.0]), 0.1)
    assert dyn.wheel_momentum_nms(state)[0] == pytest.approx(hmax - 0.1 * u * k, rel=1e-9)


def test_wheel_torque_is_clipped_to_max_torque() -> None:
    """A command above max_torque_nm accelerates the body at max_torque / I, in both directions."""
    dyn = spacecraft("orthogonal", **FRICTIONLESS)
    state = AttitudeState(q=np.array([0, 0, 0, 1.0]), omega_rad_s=np.zeros(3), wheel_speed_rad_s=np.zeros(3))
    after = run(dyn, state, [0.05, -1.0, 0.0], 2.0)
    np.testing.assert_allclose(after.omega_rad_s, [-0.007 * 2 / 0.152, 0.007 * 2 / 0.117, 0.0], rtol=1e-9, atol=1e-15)


def test_friction_spin_down_matches_closed_form_and_conserves_momentum() -> None:
    """Viscous + Coulomb friction: Omega = (W0 + c/b) exp(-b k t / J) - c/b; the body takes J (W0 - Omega)/(I + J)."""
    b, c, jw, ix = 1e-7, 1e-5, 1e-4, 0.152
    dyn = spacecraft("orthogonal", viscous_friction_nms=b, coulomb_friction_nm=c)
    state = AttitudeState(
        q=np.array([0, 0, 0, 1.0]), omega_rad_s=np.zeros(3), wheel_speed_rad_s=np.array([500.0, 0.0, 0.0])
    )
    h0 = dyn.angular_momentum_inertial(state)
    k = 1 + jw / ix
    # A failed wheel ignores its command: same spin-down as with no command.
    after = run(dyn, state, [0.007, 0.0, 0.0], 200.0, failed_wheels=frozenset({0}))
    omega_wheel = (500.0 + c / b) * math.exp(-b * k * 200.0 / jw) - c / b
    assert after.wheel_speed_rad_s[0] == pytest.approx(omega_wheel, rel=1e-7)
    assert after.omega_rad_s[0] == pytest.approx(jw * (500.0 - omega_wheel) / (ix + jw), rel=1e-7)
    np.testing.assert_allclose(dyn.angular_momentum_inertial(after), h0, rtol=1e-10, atol=1e-15)
    assert dyn.kinetic_energy(after) < dyn.kinetic_energy(state)


def test_coulomb_friction_stops_a_failed_wheel_without_chatter() -> None:
    """A slow failed wheel is brought to rest by Coulomb friction and stays there (no sign chatter)."""
    dyn = spacecraft("orthogonal")
    state = AttitudeState(
        q=np.array([0, 0, 0, 1.0]), omega_rad_s=np.zeros(3), wheel_speed_rad_s=np.array([2.0, 0, 0])
    )
    speeds = []
    for _ in range(300):
        state = dyn.step(state, np.zeros(3), 0.1, failed_wheels=frozenset({0}))
        speeds.append(state.wheel_speed_rad_s[0])
    # Coulomb (1e-5 N m) alone stops it after J * 2 / 1e-5 = 20 s; it must never change sign on the way.
    assert speeds[49] == pytest.approx(2.0 - 1e-5 * 5.0 / 1e-4, abs=0.05)
    assert min(speeds) >= 0.0
    assert speeds[-1] < 1e-3


def test_stuck_wheel_hands_momentum_to_body() -> None:
    """A seized spinning rotor stops relative to the body; the body takes J Omega0 / (I + J); H is conserved."""
    dyn = spacecraft("orthogonal", **FRICTIONLESS)
    state = AttitudeState(
        q=np.array([0, 0, 0, 1.0]), omega_rad_s=np.zeros(3), wheel_speed_rad_s=np.array([0.0, 600.0, 0.0])
    )
    h0 = dyn.angular_momentum_inertial(state)
    after = run(dyn, state, [0.0, 0.007, 0.0], 5.0, stuck_wheels=frozenset({1}))
    assert after.wheel_speed_rad_s[1] == 0.0
    assert after.omega_rad_s[1] == pytest.approx(1e-4 * 600.0 / (0.117 + 1e-4), rel=1e-12)
    np.testing.assert_allclose(dyn.angular_momentum_inertial(after), h0, rtol=1e-10, atol=1e-15)
    assert dyn.kinetic_energy(after) < dyn.kinetic_energy(state)


state_strategy = st.builds(
    lambda rv, w, spin, torque, layout, stuck, failed: (rv, w, spin, torque, layout, stuck, failed),
    st.tuples(*[st.floats(-3.0, 3.0)] * 3),
    st.tuples(*[st.floats(-0.2, 0.2)] * 3),
    st.lists(st.floats(-900.0, 900.0), min_size=4, max_size=4),
    st.lists(st.floats(-0.02, 0.02), min_size=4, max_size=4),
    st.sampled_from(["orthogonal", "pyramid"]),
    st.frozensets(st.integers(0, 2), max_size=1),
    st.frozensets(st.integers(0, 2), max_size=2),
)


@settings(max_examples=40, deadline=None)
@given(case=state_strategy)
def test_quaternion_unit_and_momentum_conserved_under_any_internal_torque(case) -> None:
    """Whatever the wheel commands, friction and faults, |q| = 1 and inertial H is conserved (wheels are internal)."""
    rv, w, spin, torque, layout, stuck, failed = case
    dyn = spacecraft(layout, TUMBLING_INERTIA)
    n = dyn.n_wheels
    state = AttitudeState(
        q=Rotation.from_rotvec(rv).as_quat(), omega_rad_s=np.array(w), wheel_speed_rad_s=np.array(spin[:n])
    )
    h0 = dyn.angular_momentum_inertial(state)
    for _ in range(10):
        state = dyn.step(state, np.array(torque[:n]), 0.1, stuck_wheels=stuck, failed_wheels=failed)
        assert abs(np.linalg.norm(state.q) - 1.0) < 1e-12
    assert np.linalg.norm(dyn.angular_momentum_inertial(state) - h0) <= 1e-9 * max(np.linalg.norm(h0), 1e-3)
    assert np.all(np.abs(dyn.wheel_momentum_nms(state)) <= 0.1 + 1e-4)


def test_pyramid_axes_and_envelope_closed_forms() -> None:
    """Pyramid axes are unit at the elevation; max torque is 4 T sin(b) along Z and 2 sqrt2 T cos(b) along X."""
    beta = 54.7356
    dyn = spacecraft("pyramid", pyramid_angle_deg=beta)
    a = dyn.wheel_axes_body
    assert a.shape == (3, 4)
    np.testing.assert_allclose(np.linalg.norm(a, axis=0), 1.0, rtol=1e-12)
    np.testing.assert_allclose(a[2], math.sin(math.radians(beta)), rtol=1e-12)
    np.testing.assert_allclose(np.degrees(np.arctan2(a[1], a[0])) % 360, [45, 135, 225, 315], atol=1e-9)
    assert max_torque_along(a, np.array([0, 0, 1.0])) == pytest.approx(4 * 0.007 * math.sin(math.radians(beta)))
    along_x = 2 * math.sqrt(2) * 0.007 * math.cos(math.radians(beta))
    assert max_torque_along(a, np.array([1.0, 0, 0])) == pytest.approx(along_x)
    np.testing.assert_array_equal(spacecraft("orthogonal").wheel_axes_body, np.eye(3))


def max_torque_along(axes: np.ndarray, d: np.ndarray, t_max: float = 0.007) -> float:
    """Return the largest body torque magnitude along unit d that |u_i| <= t_max realises (LP, independent truth)."""
    n = axes.shape[1]
    # Variables [u, s]: maximise s subject to -A u = s d.
    res = linprog(
        c=np.r_[np.zeros(n), -1.0],
        A_eq=np.hstack([-axes, -d[:, None]]),
        b_eq=np.zeros(3),
        bounds=[(-t_max, t_max)] * n + [(0, None)],
    )
    assert res.success
    return float(res.x[-1])


@settings(max_examples=25, deadline=None)
@given(
    direction=st.tuples(*[st.floats(-1.0, 1.0)] * 3).filter(lambda v: sum(c * c for c in v) > 0.05),
    fraction=st.floats(0.05, 0.99),
)
def test_pyramid_realises_any_body_torque_in_envelope(direction, fraction) -> None:
    """Any body torque inside the pyramid's envelope is produced by admissible wheel torques: I dw/dt = T at rest."""
    dyn = spacecraft("pyramid", **FRICTIONLESS)
    a = dyn.wheel_axes_body
    d = np.array(direction) / np.linalg.norm(direction)
    torque = fraction * max_torque_along(a, d) * d
    # Minimal peak wheel torque realising it: minimise m with -A u = T, |u_i| <= m.
    res = linprog(
        c=np.r_[np.zeros(4), 1.0],
        A_ub=np.vstack([np.hstack([np.eye(4), -np.ones((4, 1))]), np.hstack([-np.eye(4), -np.ones((4, 1))])]),
        b_ub=np.zeros(8),
        A_eq=np.hstack([-a, np.zeros((3, 1))]),
        b_eq=torque,
        bounds=[(None, None)] * 4 + [(0, None)],
    )
    assert res.success and res.x[-1] <= 0.007 * (1 + 1e-9)
    u = np.clip(res.x[:4], -0.007, 0.007)
    state = AttitudeState(q=np.array([0, 0, 0, 1.0]), omega_rad_s=np.zeros(3), wheel_speed_rad_s=np.zeros(4))
    dt = 1e-3
    after = dyn.step(state, u, dt)
    inertia = np.asarray(SpacecraftConfig().inertia_kgm2)
    np.testing.assert_allclose(inertia @ after.omega_rad_s / dt, torque, rtol=1e-5, atol=1e-10)


def test_zero_dt_returns_same_state_and_bad_inputs_raise() -> None:
    """dt = 0 changes nothing; wrong shapes, negative dt and unknown wheel indices raise DynamicsError."""
    dyn = spacecraft("orthogonal")
    state = AttitudeState(
        q=np.array([0, 0, 0, 1.0]), omega_rad_s=np.array([0.01, 0, 0]), wheel_speed_rad_s=np.ones(3)
    )
    same = dyn.step(state, np.zeros(3), 0.0)
    np.testing.assert_allclose(same.omega_rad_s, state.omega_rad_s, rtol=1e-15)
    np.testing.assert_allclose(same.wheel_speed_rad_s, state.wheel_speed_rad_s, rtol=1e-12)
    with pytest.raises(DynamicsError, match="torque_cmd_nm"):
        dyn.step(state, np.zeros(4), 0.1)
    with pytest.raises(DynamicsError, match="dt_s"):
        dyn.step(state, np.zeros(3), -0.1)
    with pytest.raises(DynamicsError, match="stuck_wheels"):
        dyn.step(state, np.zeros(3), 0.1, stuck_wheels=frozenset({3}))
    with pytest.raises(DynamicsError, match="wheel_speed_rad_s"):
        dyn.step(AttitudeState(state.q, state.omega_rad_s, np.ones(4)), np.zeros(3), 0.1)
    with pytest.raises(DynamicsError, match="unit quaternion"):
        dyn.step(AttitudeState(np.array([0, 0, 0, 2.0]), state.omega_rad_s, np.ones(3)), np.zeros(3), 0.1)


@pytest.mark.parametrize("overrides", [
    {"integration_substep_s": 1e-7},
    {"wheels": WheelConfig(coulomb_friction_nm=1.0, coulomb_smoothing_rad_s=1e-6)},
])
def test_an_integration_effort_of_hours_per_period_is_refused_at_load(overrides: dict) -> None:
    """A substep or a friction stiffness needing over 10,000 RK4 substeps per simulated second is refused by name."""
    from pydantic import ValidationError

    with pytest.raises(ValidationError, match="integration_substep_s must be >= 0.0001 s"):
        SpacecraftConfig(**overrides)
    SpacecraftConfig(integration_substep_s=1e-4)  # the bound itself is allowed


@settings(max_examples=60, deadline=None)
@given(before=st.lists(st.floats(-5e-3, 5e-3), min_size=3, max_size=3),
       after=st.lists(st.floats(-5e-3, 5e-3), min_size=3, max_size=3), switch=st.floats(0.0, 1.0),
       rate=st.lists(st.floats(-0.2, 0.2), min_size=3, max_size=3), stuck=st.sampled_from([(), (1,)]),
       failed=st.sampled_from([(), (2,)]))
def test_torques_switched_within_a_period_equal_two_steps(before, after, switch, rate, stuck, failed) -> None:
    """One step with the torques switched at ``switch_s`` gives the state of two steps (the first torques up to the
    switch, the others after), to rounding; the switch at 0 is one step with the new torques."""
    dyn = spacecraft(inertia=TUMBLING_INERTIA)
    state = AttitudeState(q=Rotation.from_rotvec([0.3, -0.2, 0.1]).as_quat(), omega_rad_s=np.asarray(rate),
                          wheel_speed_rad_s=np.array([50.0, -30.0, 10.0]))
    dt, at = 0.1, switch * 0.1
    kw = {"stuck_wheels": frozenset(stuck), "failed_wheels": frozenset(failed)}
    one = dyn.step(state, np.asarray(after), dt, before_nm=np.asarray(before), switch_s=at, **kw)
    two = dyn.step(state, np.asarray(before), at, **kw) if at > 0 else state
    two = dyn.step(two, np.asarray(after), dt - at, **kw) if at < dt else two
    assert np.allclose(one.q, two.q, atol=1e-12) and np.allclose(one.omega_rad_s, two.omega_rad_s, atol=1e-12)
    assert np.allclose(one.wheel_speed_rad_s, two.wheel_speed_rad_s, atol=1e-9)
    if at == 0.0:
        plain = dyn.step(state, np.asarray(after), dt, **kw)
        assert np.array_equal(one.q, plain.q) and np.array_equal(one.wheel_speed_rad_s, plain.wheel_speed_rad_s)


@settings(max_examples=300, deadline=None)
@given(w=st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3), scale=st.integers(-9, 1),
       layout=st.sampled_from(["orthogonal", "pyramid"]))
def test_ndarray_dot_is_matmul_to_the_bit(w: list[float], scale: int, layout: str) -> None:
    """The rotor momenta are computed with ``ndarray.dot`` where matmul was (it skips the generalised ufunc's set-up):
    the same BLAS product, so the same bits, on the spacecraft's axes as on the camera's 3 x 3 matrices."""
    from universe.camera.pinhole import _camera_to_body, quat_matrix

    a = spacecraft(layout).wheel_axes_body
    v = np.array(w) * 10.0 ** scale
    assert np.array_equal(a.T.dot(v), a.T @ v)
    q = np.array([*w, 0.5]) / np.linalg.norm([*w, 0.5])
    for boresight in ((0.0, 0.0, 1.0), (0.0, 0.6, 0.8)):
        c = _camera_to_body(boresight)
        assert np.array_equal(quat_matrix(q).dot(c), quat_matrix(q) @ c)
