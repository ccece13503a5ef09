"""The true C/A to Dimorphos against closed forms: a straight line past a point, whether the truth holds the
closest approach or stops before it, and the scenario's own geometry against a numerical minimum."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import minimize_scalar

from analysis.closest_approach import didymos_barycentre_ca, dimorphos_ca, parabola_vertex
from analysis.truth import Truth
from contracts.messages import TruthRecord
from scenario.model import Scenario
from universe.geometry import FlybyGeometry

OFF = 26_499_202.0  # OBT at the epoch of the default oscillator: OBT = t + OFF


def line_truth(p0: np.ndarray, w: np.ndarray, times: np.ndarray) -> Truth:
    """Truth of a spacecraft-to-Dimorphos vector p0 + w t (m, m/s) sampled at ``times`` (the arrays built at once:
    a record per row cost the test seconds)."""
    n = times.size
    rel = p0[None, :] + w[None, :] * times[:, None]
    rng = np.linalg.norm(rel, axis=1)
    nan = np.full(n, np.nan)
    return Truth(
        t_s=times.astype(float), obt_s=times + OFF, omega_rad_s=np.zeros((n, 3)), pointing_error_rad=np.zeros(n),
        target_in_fov=np.ones(n, dtype=bool), theta_rad=np.zeros(n), range_m=rng, range_didymos_m=nan,
        los_dimorphos_inertial=rel / rng[:, None], frame_id=np.full(n, -1, dtype=np.int64),
        dimorphos_px=np.full((n, 2), np.nan), didymos_px=np.full((n, 2), np.nan),
        wheel_momentum_nms=np.zeros((n, 0)), wheel_torque_nm=np.zeros((n, 0)),
    )


def closed_form(p0: np.ndarray, w: np.ndarray) -> tuple[float, float]:
    """(t_ca, d_ca) of p0 + w t: t_ca = -p0.w / |w|^2, d_ca = |p0 + w t_ca|."""
    t = -float(p0 @ w) / float(w @ w)
    return t, float(np.linalg.norm(p0 + w * t))


geometry = dict(
    t_ca=st.floats(100.0, 200.0),
    d_km=st.floats(20.0, 90.0),
    speed=st.floats(3000.0, 12000.0),
    az=st.floats(0.0, 2 * np.pi),
    el=st.floats(-1.4, 1.4),
    roll=st.floats(0.0, 2 * np.pi),
)


def line(t_ca: float, d_km: float, speed: float, az: float, el: float, roll: float) -> tuple[np.ndarray, np.ndarray]:
    """A line passing d_km away at t_ca with the given speed, in a direction set by three angles."""
    w = speed * np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    a = np.cross(w, [0.0, 0.0, 1.0] if abs(np.sin(el)) < 0.9 else [1.0, 0.0, 0.0])
    b = np.cross(w, a)
    n = np.cos(roll) * a / np.linalg.norm(a) + np.sin(roll) * b / np.linalg.norm(b)
    return d_km * 1e3 * n - w * t_ca, w


@settings(max_examples=60, deadline=None)
@given(**geometry)
def test_ca_inside_the_truth_is_the_closed_form(t_ca: float, d_km: float, speed: float, az: float, el: float,
                                                roll: float) -> None:
    """With C/A among 10 Hz truth rows, time within 1 us and distance within 1 mm of the straight line's."""
    p0, w = line(t_ca, d_km, speed, az, el, roll)
    truth = line_truth(p0, w, np.arange(0.0, 300.0, 0.1))
    want_t, want_d = closed_form(p0, w)
    got = dimorphos_ca(Scenario(name="line"), truth)
    assert got.t_s == pytest.approx(want_t, abs=1e-6)
    assert got.distance_km * 1e3 == pytest.approx(want_d, abs=1e-3)
    assert got.obt_s == pytest.approx(want_t + OFF, abs=1e-6)
    assert got.how.startswith("parabola")


@settings(max_examples=40, deadline=None)
@given(**geometry, before=st.booleans())
def test_ca_outside_the_truth_is_the_closed_form(t_ca: float, d_km: float, speed: float, az: float, el: float,
                                                 roll: float, before: bool) -> None:
    """Truth stopping 20 s before C/A (or starting 20 s after): the fitted line gives the same closed form."""
    p0, w = line(t_ca, d_km, speed, az, el, roll)
    times = np.arange(t_ca - 80.0, t_ca - 20.0, 0.1) if before else np.arange(t_ca + 20.0, t_ca + 80.0, 0.1)
    want_t, want_d = closed_form(p0, w)
    got = dimorphos_ca(Scenario(name="line"), line_truth(p0, w, times))
    assert got.t_s == pytest.approx(want_t, abs=1e-6)
    assert got.distance_km * 1e3 == pytest.approx(want_d, abs=1e-3)
    assert got.how.startswith("straight line")


def test_scenario_geometry_without_truth_and_from_its_own_samples() -> None:
    """The default flyby: Dimorphos' C/A from the geometry alone, and from 10 Hz truth of the same geometry, equals
    the numerical minimum of the distance; it differs from the barycentre's (the scenario's 168 s, 55 km)."""
    sc = Scenario(name="default")
    g = FlybyGeometry(sc.universe.flyby, sc.universe.bodies)

    def dist_m(t: float) -> float:
        return float(np.linalg.norm(g.dimorphos_position_m(t) - g.spacecraft_position_m(t)))

    best = minimize_scalar(dist_m, bounds=(150.0, 190.0), method="bounded", options={"xatol": 1e-9})
    times = np.arange(100.0, 240.0, 0.1)
    rel = g.dimorphos_position_m(times) - g.spacecraft_position_m(times)
    recs = [TruthRecord(t_s=float(t), obt_s=float(t) + OFF, q=(0.0, 0.0, 0.0, 1.0), omega_rad_s=(0.0, 0.0, 0.0),
                        wheel_momentum_nms=(), wheel_torque_nm=(), pointing_error_rad=0.0, target_in_fov=True,
                        range_m=float(np.linalg.norm(r)), theta_rad=0.0, phase_angle_deg=0.0)
            for t, r in zip(times, rel, strict=True)]
    for truth in (None, Truth.from_records(recs)):
        got = dimorphos_ca(sc, truth)
        assert got.t_s == pytest.approx(best.x, abs=1e-5)
        assert got.distance_km * 1e3 == pytest.approx(best.fun, abs=1e-3)
    bary = didymos_barycentre_ca(sc, None)
    assert (bary.t_s, bary.distance_km) == (168.0, 55.0)
    assert abs(got.distance_km - 55.0) > 1.0  # Dimorphos sits ~1.18 km from the barycentre in this geometry


@given(a=st.floats(0.1, 10.0), t0=st.floats(-50.0, 50.0), c=st.floats(-5.0, 5.0), dt=st.floats(0.01, 2.0),
       shift=st.floats(-0.99, 0.99))
def test_parabola_vertex_of_three_samples(a: float, t0: float, c: float, dt: float, shift: float) -> None:
    """Three samples of a (t - t0)^2 + c, unevenly spaced, give back the vertex (t0, c)."""
    ts = t0 + dt * np.array([-1.0 - 0.5 * shift, 0.3 * shift, 1.0 + 0.4 * shift])
    got = parabola_vertex(ts, a * (ts - t0) ** 2 + c)
    assert got == pytest.approx((t0, c), abs=1e-7)
    assert parabola_vertex(ts, -(ts - t0) ** 2) is None
