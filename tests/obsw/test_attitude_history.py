"""The attitude history against a plain reference model: a list and ``min`` by distance in time."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from obsw.attitude_history import AttitudeHistory

# times on a coarse binary grid, queries on one twice as fine: repeats and exact ties between two neighbours happen
_time = st.integers(-24, 24).map(lambda k: k * 0.125)
_midway = st.integers(-48, 48).map(lambda k: k * 0.0625)
_op = st.one_of(
    st.tuples(st.just("append"), _time),
    st.tuples(st.just("forward"), st.integers(1, 3)),  # the common case: the next periods, in order
    st.tuples(st.just("query"), _time),
    st.tuples(st.just("query"), _midway),
    st.tuples(st.just("query"), st.floats(-3.0, 3.0)),
    st.tuples(st.just("shift"), st.sampled_from([-0.5, 0.125, 1e-3, 2.0])),
)


def _reference_nearest(entries: list[tuple[float, np.ndarray]], obt_s: float) -> np.ndarray:
    return min(entries, key=lambda e: abs(e[0] - obt_s))[1]


@settings(max_examples=400, deadline=None)
@given(st.integers(1, 8), st.lists(_op, max_size=60))
def test_the_nearest_attitude_is_mins_choice_through_jumps_repeats_and_shifts(
        periods: int, ops: list[tuple[str, float]]) -> None:
    """nearest() returns the very entry min() by |t - obt| would (the earliest of equals), whatever the order of
    the appended times, their repeats, the window's length and clock shifts."""
    history = AttitudeHistory(periods)
    model: list[tuple[float, np.ndarray]] = []
    serial = 0
    for op, value in ops:
        if op in ("append", "forward"):
            times = [float(value)] if op == "append" else \
                [(model[-1][0] if model else 0.0) + 0.125 * k for k in range(1, int(value) + 1)]
            for t in times:
                serial += 1
                q = np.array([0.0, 0.0, 0.0, float(serial)])  # each entry told apart by identity and value
                history.append(t, q)
                model = (model + [(t, q)])[-periods:]
        elif op == "shift":
            history = history.shifted(value)
            model = [(t + value, q) for t, q in model]
        elif model:
            assert history.nearest(value) is _reference_nearest(model, value)
        else:
            with pytest.raises(ValueError):
                history.nearest(value)
        assert len(history) == len(model)


def test_a_window_of_no_periods_is_refused() -> None:
    """A history must hold at least one period."""
    with pytest.raises(ValueError, match="periods must be >= 1"):
        AttitudeHistory(0)
