"""The on-board oscillator against closed forms, the integral of its frequency, and its ordering rules."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import quad
from scipy.stats import norm

from universe.config import FaultConfig, OscillatorConfig
from universe.oscillator import ClockModelError, Oscillator, clock_jumps_s

DAY_S = 86400.0


def _osc(seed: int = 0, jumps: tuple[tuple[float, float], ...] = (), **kw: float) -> Oscillator:
    kw.setdefault("initial_offset_s", 0.0)  # closed forms below count from a zero offset
    return Oscillator(OscillatorConfig(**kw), np.random.default_rng(seed), jumps=jumps)


def test_offset_and_drift_closed_form() -> None:
    """10 ppm over one day gains 0.864 s on top of the initial offset."""
    osc = _osc(initial_offset_s=2.5, drift_ppm=10.0)
    assert osc.obt_mean_s(0.0) == 2.5
    assert osc.obt_mean_s(DAY_S) == pytest.approx(DAY_S + 2.5 + 0.864, abs=1e-9)


def test_drift_rate_closed_form() -> None:
    """1 ppm/day of ageing over one day gains half of 1 ppm x 1 day = 0.0432 s."""
    osc = _osc(drift_rate_ppm_per_day=1.0)
    assert osc.obt_mean_s(DAY_S) - DAY_S == pytest.approx(0.0432, abs=1e-9)
    assert osc.rate(DAY_S) == pytest.approx(1.0 + 1e-6, abs=1e-15)


envelope = dict(
    initial_offset_s=st.floats(-1e5, 1e5),
    drift_ppm=st.floats(-200.0, 200.0),
    drift_rate_ppm_per_day=st.floats(-10.0, 10.0),
)


@settings(max_examples=60, deadline=None)
@given(t=st.floats(-3 * DAY_S, 3 * DAY_S), **envelope)
def test_model_is_integral_of_frequency(
    t: float, initial_offset_s: float, drift_ppm: float, drift_rate_ppm_per_day: float
) -> None:
    """OBT(t) equals the offset plus the integral of the oscillator's frequency ratio 1 + d + r s."""
    osc = _osc(initial_offset_s=initial_offset_s, drift_ppm=drift_ppm, drift_rate_ppm_per_day=drift_rate_ppm_per_day)
    d, r = drift_ppm * 1e-6, drift_rate_ppm_per_day * 1e-6 / DAY_S
    integral, _ = quad(lambda s: 1.0 + d + r * s, 0.0, t)
    assert osc.obt_mean_s(t) == pytest.approx(initial_offset_s + integral, abs=1e-6)


@settings(max_examples=80, deadline=None)
@given(t=st.floats(-3 * DAY_S, 3 * DAY_S), **envelope)
def test_true_time_inverts_the_model(
    t: float, initial_offset_s: float, drift_ppm: float, drift_rate_ppm_per_day: float
) -> None:
    """Without jumps, true_s(obt_mean_s(t)) gives back t."""
    osc = _osc(initial_offset_s=initial_offset_s, drift_ppm=drift_ppm, drift_rate_ppm_per_day=drift_rate_ppm_per_day)
    assert osc.true_s(osc.obt_mean_s(t)) == pytest.approx(t, abs=1e-6)


jump_list = st.lists(
    st.tuples(st.floats(-500.0, 500.0), st.floats(-20.0, 20.0).filter(lambda x: abs(x) > 1e-3)),
    max_size=4,
    unique_by=lambda j: j[0],
)


@settings(max_examples=80, deadline=None)
@given(obt=st.floats(-700.0, 700.0), jumps=jump_list, drift_ppm=st.floats(-200.0, 200.0))
def test_true_time_is_first_time_reading_at_least(
    obt: float, jumps: list[tuple[float, float]], drift_ppm: float
) -> None:
    """With jumps, true_s(y) is the first true time the model reads >= y: it does there and not just before."""
    osc = _osc(drift_ppm=drift_ppm, jumps=tuple(jumps))
    t = osc.true_s(obt)
    assert osc.obt_mean_s(t) >= obt - 1e-9
    # scan a fine grid before t (plus the instants just before each jump): the clock never reached obt there
    grid = list(np.linspace(-1000.0, t, 2001)[:-1]) + [a - 1e-7 for a, _ in jumps if a - 1e-7 < t]
    assert all(osc.obt_mean_s(s) < obt + 1e-9 for s in grid if s < t - 1e-6)


@settings(max_examples=80, deadline=None)
@given(
    steps=st.lists(st.floats(0.0, 2.0), min_size=2, max_size=60),
    jumps=jump_list,
    jitter_s=st.floats(0.0, 0.05),
    seed=st.integers(0, 2**32 - 1),
    **envelope,
)
def test_readings_bounded_and_monotonic_between_jumps(
    steps: list[float],
    jumps: list[tuple[float, float]],
    jitter_s: float,
    seed: int,
    initial_offset_s: float,
    drift_ppm: float,
    drift_rate_ppm_per_day: float,
) -> None:
    """Each reading is within the jitter bound of the model and moves by at least the jumps crossed since the last."""
    cfg = OscillatorConfig(
        initial_offset_s=initial_offset_s,
        drift_ppm=drift_ppm,
        drift_rate_ppm_per_day=drift_rate_ppm_per_day,
        jitter_s=jitter_s,
    )
    times = list(np.cumsum(steps) - 50.0)
    jumps = [(a / 5.0, dlt) for a, dlt in jumps if a / 5.0 > times[0]]  # jumps strictly after the first reading
    osc = Oscillator(cfg, np.random.default_rng(seed))
    bound = cfg.jitter_bound_sigma * jitter_s + 1e-9
    previous: tuple[float, float] | None = None
    pending = sorted(jumps)
    for t in times:
        while pending and (previous is None or pending[0][0] > previous[0]) and pending[0][0] <= t:
            osc.jump(*pending.pop(0))
        reading = osc.obt_s(t)
        assert abs(reading - osc.obt_mean_s(t)) <= bound
        if previous is not None:
            crossed = sum(dlt for a, dlt in osc.jumps if previous[0] < a <= t)
            assert reading - previous[1] >= crossed - 1e-9
        previous = (t, reading)


def test_jitter_has_the_configured_spread() -> None:
    """Readings 1 s apart scatter about the model with the spread of a Gaussian clipped at 3 sigma."""
    osc = _osc(seed=7, jitter_s=1e-3, drift_ppm=30.0)
    t = np.arange(4000.0)
    residual = np.array([osc.obt_s(float(x)) - osc.obt_mean_s(float(x)) for x in t])
    # variance of N(0,1) clipped at +-3: the mass inside plus 9 times the mass outside
    clipped_var = (norm.cdf(3) - norm.cdf(-3)) - 6 * norm.pdf(3) + 9 * 2 * norm.sf(3)
    assert abs(residual.mean()) < 1e-4
    assert residual.std() == pytest.approx(1e-3 * math.sqrt(clipped_var), rel=0.04)
    assert np.abs(residual).max() <= 3e-3 + 1e-9


def test_same_seed_same_readings() -> None:
    """Two clocks with the same seed read identically; another seed reads differently."""
    a, b, c = (_osc(seed=s, jitter_s=1e-3) for s in (1, 1, 2))
    ra = [a.obt_s(float(t)) for t in range(10)]
    assert ra == [b.obt_s(float(t)) for t in range(10)]
    assert ra != [c.obt_s(float(t)) for t in range(10)]


def test_backward_jump_steps_obt_back() -> None:
    """A -5 s jump at 100 s makes the next reading 5 s behind the jump-free clock, then it rises again."""
    osc = _osc(jumps=((100.0, -5.0),))
    assert osc.obt_s(99.9) == pytest.approx(99.9)
    assert osc.obt_s(100.0) == pytest.approx(95.0)
    assert osc.obt_s(101.0) == pytest.approx(96.0)
    assert osc.true_s(97.0) == pytest.approx(97.0)  # first reached before the jump


def test_readings_out_of_order_are_refused() -> None:
    """Reading OBT earlier than the last reading is a ClockModelError naming both times."""
    osc = _osc()
    osc.obt_s(10.0)
    with pytest.raises(ClockModelError, match="9.0 s is before the last reading at 10.0 s"):
        osc.obt_s(9.0)


def test_jump_into_the_past_is_refused() -> None:
    """A jump at or before the last reading would rewrite it: ClockModelError."""
    osc = _osc()
    osc.obt_s(10.0)
    with pytest.raises(ClockModelError, match="rewrite the reading"):
        osc.jump(10.0, 1.0)
    osc.jump(10.1, 1.0)
    assert osc.obt_s(10.1) == pytest.approx(11.1)


def test_clock_jumps_come_from_faults() -> None:
    """clock_jump faults become (start_s, magnitude) jumps; other faults are ignored; no magnitude is an error."""
    faults = [
        FaultConfig(kind="frame_lost", start_s=0.0, end_s=1.0),
        FaultConfig(kind="clock_jump", start_s=50.0, end_s=50.0, magnitude=0.25),
    ]
    assert clock_jumps_s(faults) == [(50.0, 0.25)]
    with pytest.raises(ClockModelError, match="faults\\[0\\].*no magnitude"):
        clock_jumps_s([FaultConfig(kind="clock_jump", start_s=1.0, end_s=1.0)])


def test_model_outside_its_domain_is_refused() -> None:
    """A clock that would stop (rate <= 0) or an unreachable OBT raises instead of returning nonsense."""
    with pytest.raises(ClockModelError, match="drift_ppm"):
        _osc(drift_ppm=-1e6)
    osc = _osc(drift_rate_ppm_per_day=-1e6)  # stops after one day
    with pytest.raises(ClockModelError, match="rate"):
        osc.obt_mean_s(2 * DAY_S)
    with pytest.raises(ClockModelError, match="never reached"):
        osc.true_s(DAY_S)
    assert math.isfinite(osc.true_s(0.4 * DAY_S))
