"""OBT-UTC correlation: least-squares estimates, their covariance and worst-case bounds."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pydantic import ValidationError
from scipy import stats

from ground.correlation import Correlation, CorrelationError, TimeReport, fitted_correlation


def _reports(
    offset_s: float, drift: float, gen_utc_s: np.ndarray, light_s: np.ndarray, noise_s: np.ndarray
) -> list[TimeReport]:
    """Reports stamped on board at the given generation UTCs (plus noise), received one light time later."""
    obt = offset_s + (1.0 + drift) * gen_utc_s + noise_s
    return [
        TimeReport(obt_s=float(o), received_utc_s=float(u + lt), light_time_s=float(lt))
        for o, u, lt in zip(obt, gen_utc_s, light_s)
    ]


scenario = st.fixed_dictionaries(
    {
        # OBT counts from launch: about 2.65e7 s at the flyby (universe OscillatorConfig.initial_offset_s).
        "offset_s": st.floats(-1e4, 5e7),
        "drift_ppm": st.floats(-200, 200),
        "envelope_s": st.floats(1e-6, 1e-2),
        "n": st.integers(3, 40),
        "start_s": st.floats(-1e5, 1e5),
        "span_s": st.floats(10, 1e5),
        "light_s": st.floats(0, 1500),
        "seed": st.integers(0, 2**32 - 1),
    }
)


def _draw(s: dict, noise: str) -> tuple[list[TimeReport], np.ndarray]:
    """Reports of a hypothesis scenario with uniform (within the envelope) or Gaussian noise; and their UTCs."""
    rng = np.random.default_rng(s["seed"])
    gen = np.sort(s["start_s"] + s["span_s"] * rng.random(s["n"]))
    gen[0], gen[-1] = s["start_s"], s["start_s"] + s["span_s"]  # ensure the full span
    light = s["light_s"] * (0.8 + 0.4 * rng.random(s["n"]))  # light time changes as the range does
    e = s["envelope_s"]
    n = rng.uniform(-e, e, s["n"]) if noise == "uniform" else rng.normal(0.0, e, s["n"])
    return _reports(s["offset_s"], s["drift_ppm"] * 1e-6, gen, light, n), gen


def _rounding_s(s: dict) -> float:
    """A few float roundings of the largest times of this scenario, s (extra error beyond the envelope)."""
    return 8 * np.finfo(float).eps * (abs(s["offset_s"]) + abs(s["start_s"]) + s["span_s"] + 2 * s["light_s"] + 1.0)


@given(scenario)
@settings(max_examples=80, deadline=None)
def test_offset_within_worst_case_bound_for_noise_within_envelope(s: dict) -> None:
    """With every OBT stamp within +-e of truth, |offset error| <= e sqrt(N [(X^T X)^-1]_00), and OBT likewise."""
    reports, gen = _draw(s, "uniform")
    c = fitted_correlation(reports, obt_sigma_s=s["envelope_s"])
    bound = c.offset_error_bound_s(s["envelope_s"])
    # The bound is the covariance's: sqrt(N) times the offset sigma for sigma = e.
    assert bound == pytest.approx(np.sqrt(s["n"]) * c.offset_sigma_s, rel=1e-9)
    # Rounding of the stamps adds to their noise: widen the envelope by it, then allow for the final sums.
    e = s["envelope_s"] + _rounding_s(s)
    assert abs(c.offset_s - s["offset_s"]) <= c.offset_error_bound_s(e) + _rounding_s(s)
    drift = s["drift_ppm"] * 1e-6
    for u in (gen[0], gen[len(gen) // 2], gen[-1]):
        truth = s["offset_s"] + (1 + drift) * u
        assert abs(c.to_obt(u) - truth) <= c.obt_error_bound_s(u, e) + _rounding_s(s)


@given(scenario)
@settings(max_examples=60, deadline=None)
def test_offset_and_drift_within_six_sigma_for_gaussian_noise(s: dict) -> None:
    """With Gaussian stamps of known sigma, offset and drift errors stay within 6 sigma (chance 2e-9 of failing)."""
    reports, _ = _draw(s, "gauss")
    c = fitted_correlation(reports, obt_sigma_s=s["envelope_s"])
    r = _rounding_s(s)
    assert abs(c.offset_s - s["offset_s"]) <= 6 * c.offset_sigma_s + c.offset_error_bound_s(r) + r
    drift_rounding_ppm = 1e6 * r * np.sqrt(s["n"] * c.design_covariance[1, 1])
    assert abs(c.drift_ppm - s["drift_ppm"]) <= 6 * c.drift_sigma_ppm + drift_rounding_ppm


def test_covariance_matches_the_monte_carlo_spread() -> None:
    """Over many noise draws, the spread of offset, drift and extrapolated OBT equals the stated sigmas."""
    rng = np.random.default_rng(20220926)
    offset, drift, sigma = 3.2, 25e-6, 2e-3
    gen = np.linspace(-600.0, 600.0, 15)
    light = np.full(gen.size, 33.4)
    trials = [fitted_correlation(_reports(offset, drift, gen, light, rng.normal(0, sigma, gen.size)), sigma)
              for _ in range(3000)]
    c0 = trials[0]
    est = np.array([[c.offset_s, c.drift, c.to_obt(3600.0)] for c in trials])
    # The standard deviation of a 3000-sample standard deviation is ~1.3 %; 5 % is ~4 of those.
    assert np.std(est[:, 0]) == pytest.approx(c0.offset_sigma_s, rel=0.05)
    assert np.std(est[:, 1]) * 1e6 == pytest.approx(c0.drift_sigma_ppm, rel=0.05)
    assert np.std(est[:, 2]) == pytest.approx(c0.obt_sigma_s(3600.0), rel=0.05)
    assert np.mean(est[:, 0]) == pytest.approx(offset, abs=4 * c0.offset_sigma_s / np.sqrt(3000))


def test_fit_matches_scipy_linregress() -> None:
    """Offset, drift and their residual-based standard errors equal scipy's linear regression."""
    rng = np.random.default_rng(7)
    gen = np.sort(rng.uniform(1000.0, 5000.0, 25))
    light = rng.uniform(30.0, 36.0, gen.size)
    reports = _reports(-12.5, -80e-6, gen, light, rng.normal(0, 5e-3, gen.size))
    obt = np.array([r.obt_s for r in reports])
    # Regress OBT - UTC, not OBT: with OBT, r is so close to 1 that scipy's 1 - r^2 loses digits.
    ref = stats.linregress(gen, obt - gen)
    c = fitted_correlation(reports)
    assert c.offset_s == pytest.approx(ref.intercept, abs=1e-9)
    assert c.drift == pytest.approx(ref.slope, abs=1e-12)
    assert c.offset_sigma_s == pytest.approx(ref.intercept_stderr, rel=1e-6)
    assert np.sqrt(c.covariance[1, 1]) == pytest.approx(ref.stderr, rel=1e-6)
    residuals = obt - gen - ref.intercept - ref.slope * gen
    assert c.residual_rms_s == pytest.approx(np.sqrt(np.mean(residuals**2)), rel=1e-6)


@given(st.floats(-1e4, 1e4), st.floats(-500, 500), st.floats(0, 2000))
@settings(max_examples=50)
def test_noise_free_reports_give_truth_despite_light_time(offset: float, drift_ppm: float, light_s: float) -> None:
    """Noise-free reports received one (varying) light time late give the true offset and drift."""
    gen = np.linspace(0.0, 7200.0, 6)
    light = light_s * np.linspace(1.0, 1.1, gen.size)
    c = fitted_correlation(_reports(offset, drift_ppm * 1e-6, gen, light, np.zeros(gen.size)))
    assert c.offset_s == pytest.approx(offset, abs=1e-8)
    assert c.drift_ppm == pytest.approx(drift_ppm, abs=1e-8)


def test_ignoring_light_time_would_bias_the_offset() -> None:
    """Treating receipt as generation time shifts the offset by about the light time: the fit must not."""
    gen = np.linspace(0.0, 600.0, 5)
    reports = _reports(1.0, 0.0, gen, np.full(5, 33.4), np.zeros(5))
    naive = [TimeReport(obt_s=r.obt_s, received_utc_s=r.received_utc_s, light_time_s=0.0) for r in reports]
    assert fitted_correlation(reports).offset_s == pytest.approx(1.0, abs=1e-9)
    assert fitted_correlation(naive).offset_s == pytest.approx(1.0 - 33.4, abs=1e-9)


@given(st.floats(-1e5, 1e5), st.floats(-1e-3, 1e-3), st.floats(-1e7, 1e7))
@settings(max_examples=100)
def test_to_utc_inverts_to_obt(offset: float, drift: float, utc: float) -> None:
    """to_utc(to_obt(u)) == u to float rounding."""
    c = Correlation.exact(offset, drift)
    assert c.to_utc(c.to_obt(utc)) == pytest.approx(utc, abs=1e-12 * (abs(offset) + abs(utc) + 1) * 4)


def test_bad_inputs_are_refused_with_their_reason() -> None:
    """Too few reports, no time span, bad sigma, negative light time and non-finite values are refused."""
    r = TimeReport(obt_s=1.0, received_utc_s=40.0, light_time_s=33.4)
    with pytest.raises(CorrelationError, match="need at least 3 time reports .*estimated from the residuals.*got 2"):
        fitted_correlation([r, r])
    with pytest.raises(CorrelationError, match="need at least 2 time reports, got 1"):
        fitted_correlation([r], obt_sigma_s=1e-3)
    with pytest.raises(CorrelationError, match="all 3 time reports were generated at one UTC"):
        fitted_correlation([r, r, r])
    with pytest.raises(CorrelationError, match="obt_sigma_s must be a finite number >= 0, got -1"):
        fitted_correlation([r, r, r], obt_sigma_s=-1.0)
    with pytest.raises(ValidationError, match="light_time_s"):
        TimeReport(obt_s=1.0, received_utc_s=40.0, light_time_s=-1.0)
    with pytest.raises(ValidationError, match="obt_s"):
        TimeReport(obt_s=float("nan"), received_utc_s=40.0, light_time_s=1.0)
    with pytest.raises(CorrelationError, match="drift must be > -1"):
        Correlation.exact(0.0, -1.0)
    with pytest.raises(CorrelationError, match="envelope_s must be >= 0"):
        Correlation.exact(0.0, 0.0).offset_error_bound_s(-1.0)


def test_correlation_arrays_are_read_only() -> None:
    """A fitted correlation's covariance cannot be changed in place by a caller."""
    gen = np.linspace(0.0, 100.0, 4)
    c = fitted_correlation(_reports(0.0, 0.0, gen, np.zeros(4), np.array([1e-3, -1e-3, 2e-3, 0.0])))
    with pytest.raises(ValueError, match="read-only"):
        c.covariance[0, 0] = 0.0
