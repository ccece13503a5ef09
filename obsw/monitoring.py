"""On-board parameter monitoring (PUS service 12): limit, expected-value and delta checks with repetition counts.

Rules (ECSS-E-ST-70-41C, service 12, as this mission applies them):

- a definition checks one parameter (``contracts.dictionary.Parameter``) every time ``check`` is called (each
  control period); a parameter without a value (``None``: not known yet) leaves the check alone;
- a limit check finds the value BELOW_LOW, ABOVE_HIGH or WITHIN; an expected-value check UNEXPECTED or WITHIN; a
  delta check compares the change since the previous sample with the low and high thresholds (its first sample only
  gives the reference);
- a new status must be found ``repetition`` times in a row before it is confirmed; every confirmed change of status
  (out of limits, back within, from one limit to the other) is a check transition, reported as an event with the
  definition's severity. The first confirmed status after UNCHECKED is a transition only when it is not WITHIN;
- definitions are loaded from the scenario and added, modified, deleted, enabled or disabled by telecommand; a
  modified or re-enabled definition starts again from UNCHECKED. Pure: values come in as arguments.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

from contracts import pus
from obsw.errors import CommandRejected, RejectReason

Status = pus.CheckStatus


@dataclass(frozen=True, slots=True)
class Transition:
    """A confirmed change of checking status of one definition."""

    definition: pus.MonitoringDefinition
    previous: Status
    status: Status
    value: float  # the parameter (its change, for a delta check)
    limit: float  # the limit crossed (left, for a return within)


@dataclass
class _State:
    status: Status = Status.UNCHECKED
    candidate: Status = Status.UNCHECKED
    count: int = 0
    previous_value: float | None = None


class ParameterMonitor:
    """The monitoring definitions, whether each is enabled, and their checking state."""

    def __init__(self, definitions: Iterable[pus.MonitoringDefinition] = ()) -> None:
        self._defs: dict[int, pus.MonitoringDefinition] = {}
        self._enabled: dict[int, bool] = {}
        self._state: dict[int, _State] = {}
        self.add(tuple(definitions))

    @property
    def definitions(self) -> tuple[pus.MonitoringDefinition, ...]:
        """The definitions, by identifier."""
        return tuple(self._defs[k] for k in sorted(self._defs))

    def status(self, pmon_id: int) -> Status:
        """The confirmed checking status of a definition."""
        return self._state[pmon_id].status

    def enabled(self, pmon_id: int) -> bool:
        """Whether a definition is checked."""
        return self._enabled[pmon_id]

    # -- telecommands --------------------------------------------------------------------------------------
    def add(self, definitions: tuple[pus.MonitoringDefinition, ...]) -> None:
        """Add definitions, enabled; all or none (an identifier already defined, or given twice, is refused)."""
        ids = [d.pmon_id for d in definitions]
        dup = sorted({i for i in ids if ids.count(i) > 1 or i in self._defs})
        if dup:
            raise CommandRejected(RejectReason.BAD_ARGUMENT, f"monitoring definition(s) {dup} already defined")
        for d in definitions:
            self._defs[d.pmon_id] = d
            self._enabled[d.pmon_id] = True
            self._state[d.pmon_id] = _State()

    def modify(self, definitions: tuple[pus.MonitoringDefinition, ...]) -> None:
        """Replace existing definitions (all or none); their checks start again."""
        self._require([d.pmon_id for d in definitions])
        for d in definitions:
            self._defs[d.pmon_id] = d
            self._state[d.pmon_id] = _State()

    def delete(self, pmon_ids: tuple[int, ...]) -> None:
        """Delete definitions (all or none)."""
        self._require(pmon_ids)
        for i in pmon_ids:
            del self._defs[i], self._enabled[i], self._state[i]

    def set_enabled(self, pmon_ids: tuple[int, ...], enabled: bool) -> None:
        """Enable or disable definitions (all or none); an enabled one starts again from UNCHECKED."""
        self._require(pmon_ids)
        for i in pmon_ids:
            if enabled and not self._enabled[i]:
                self._state[i] = _State()
            self._enabled[i] = enabled

    def _require(self, pmon_ids: Iterable[int]) -> None:
        unknown = sorted({i for i in pmon_ids if i not in self._defs})
        if unknown:
            raise CommandRejected(RejectReason.BAD_ARGUMENT, f"no monitoring definition {unknown}")

    # -- checking ------------------------------------------------------------------------------------------
    def check(self, values: Mapping[pus.Parameter, float | None]) -> list[Transition]:
        """Check every enabled definition against this sample; return the confirmed transitions."""
        out = []
        for pmon_id, d in self._defs.items():
            if not self._enabled[pmon_id]:
                continue
            value = values.get(d.parameter)
            if value is None or not math.isfinite(value):
                continue
            t = self._sample(d, self._state[pmon_id], float(value))
            if t is not None:
                out.append(t)
        return out

    def _sample(self, d: pus.MonitoringDefinition, s: _State, value: float) -> Transition | None:
        checked = value
        if d.check_type == pus.CheckType.DELTA:
            if s.previous_value is None:
                s.previous_value = value
                return None
            checked, s.previous_value = value - s.previous_value, value
        found, limit = _status(d, checked)
        if found == s.status:
            s.candidate, s.count = found, 0
            return None
        s.count = s.count + 1 if found == s.candidate else 1
        s.candidate = found
        if s.count < d.repetition:
            return None
        previous, s.status, s.count = s.status, found, 0
        if previous == Status.UNCHECKED and found == Status.WITHIN:
            return None
        if found == Status.WITHIN:  # back within: the limit left is the one of the previous status
            limit = d.low if previous in (Status.BELOW_LOW, Status.UNEXPECTED) else d.high
        return Transition(d, previous, found, checked, limit)


def _status(d: pus.MonitoringDefinition, x: float) -> tuple[Status, float]:
    """The status of one checked value and the limit that decided it."""
    if d.check_type == pus.CheckType.EXPECTED_VALUE:
        return (Status.WITHIN, d.low) if x == d.low else (Status.UNEXPECTED, d.low)
    if x < d.low:
        return Status.BELOW_LOW, d.low
    if x > d.high:
        return Status.ABOVE_HIGH, d.high
    return Status.WITHIN, d.low
