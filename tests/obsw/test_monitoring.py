"""Service 12 on-board monitoring: limit, expected-value and delta checks confirmed by their repetition count,
against a plain reference scan of the samples; definitions managed by telecommand."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from contracts import pus
from obsw.errors import CommandRejected
from obsw.monitoring import ParameterMonitor

S = pus.CheckStatus
P = pus.Parameter.BODY_RATE


def _limit(pmon_id: int = 1, low: float = 0.0, high: float = 1.0, rep: int = 1,
           kind: pus.CheckType = pus.CheckType.LIMIT) -> pus.MonitoringDefinition:
    return pus.MonitoringDefinition(pmon_id=pmon_id, parameter=P, check_type=kind, repetition=rep, low=low,
                                    high=high, severity=pus.Severity.MEDIUM)


def _reference(values: list[float], low: float, high: float, rep: int) -> list[tuple[int, S, S]]:
    """(sample index, from, to) of each confirmed transition, by the rules of the module docstring, scanned plainly."""
    out, status, run_status, run = [], S.UNCHECKED, None, 0
    for i, v in enumerate(values):
        found = S.BELOW_LOW if v < low else S.ABOVE_HIGH if v > high else S.WITHIN
        if found == status:
            run_status, run = None, 0
            continue
        run = run + 1 if found == run_status else 1
        run_status = found
        if run >= rep:
            if not (status == S.UNCHECKED and found == S.WITHIN):
                out.append((i, status, found))
            status, run_status, run = found, None, 0
    return out


@settings(max_examples=200, deadline=None)
@given(values=st.lists(st.sampled_from([-1.0, 0.5, 2.0]), max_size=40), rep=st.integers(1, 4))
def test_limit_check_transitions_are_confirmed_by_the_repetition_count(values: list[float], rep: int) -> None:
    """A new status is confirmed after `rep` samples in a row; each confirmed change is one transition."""
    mon = ParameterMonitor([_limit(rep=rep)])
    got = []
    for i, v in enumerate(values):
        got += [(i, t.previous, t.status) for t in mon.check({P: v})]
    assert got == _reference(values, 0.0, 1.0, rep)


def test_transition_carries_the_value_and_the_limit_crossed() -> None:
    """Out above: the high limit; back within: the limit left; an unknown value (None) leaves the check alone."""
    mon = ParameterMonitor([_limit(low=0.0, high=1.0)])
    (up,) = mon.check({P: 3.0})
    assert (up.status, up.value, up.limit) == (S.ABOVE_HIGH, 3.0, 1.0)
    assert mon.check({P: None}) == [] and mon.check({}) == []
    (back,) = mon.check({P: 0.5})
    assert (back.previous, back.status, back.limit) == (S.ABOVE_HIGH, S.WITHIN, 1.0)
    (down,) = mon.check({P: -2.0})
    assert (down.status, down.limit) == (S.BELOW_LOW, 0.0)


def test_expected_value_and_delta_checks() -> None:
    """Expected value: any other value is UNEXPECTED; delta: the change since the previous sample is checked, the
    first sample only sets the reference."""
    ev = ParameterMonitor([_limit(kind=pus.CheckType.EXPECTED_VALUE, low=4.0, high=4.0)])
    assert ev.check({P: 4.0}) == []
    assert [t.status for t in ev.check({P: 3.0})] == [S.UNEXPECTED]
    delta = ParameterMonitor([_limit(kind=pus.CheckType.DELTA, low=-0.5, high=0.5)])
    assert delta.check({P: 10.0}) == [] and delta.check({P: 10.4}) == []
    (t,) = delta.check({P: 11.4})
    assert (t.status, t.value) == (S.ABOVE_HIGH, pytest.approx(1.0))


def test_definitions_are_managed_all_or_none() -> None:
    """Add refuses a known identifier, delete and modify an unknown one, with nothing changed; a disabled definition
    is not checked and starts again from UNCHECKED when enabled."""
    mon = ParameterMonitor([_limit(1)])
    with pytest.raises(CommandRejected, match=r"\[1\] already defined"):
        mon.add((_limit(2), _limit(1)))
    assert [d.pmon_id for d in mon.definitions] == [1]
    with pytest.raises(CommandRejected, match=r"no monitoring definition \[7\]"):
        mon.delete((1, 7))
    mon.check({P: 5.0})
    assert mon.status(1) == S.ABOVE_HIGH
    mon.set_enabled((1,), False)
    assert mon.check({P: 0.5}) == [] and mon.status(1) == S.ABOVE_HIGH
    mon.set_enabled((1,), True)
    assert mon.status(1) == S.UNCHECKED
    mon.modify((_limit(1, high=10.0),))
    assert mon.check({P: 5.0}) == [] and mon.status(1) == S.WITHIN
    mon.delete((1,))
    assert mon.definitions == ()
