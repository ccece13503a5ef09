"""On-board event-action (PUS service 19): a telecommand run when an event is reported.

Rules (ECSS-E-ST-70-41C, service 19, as this mission applies them): one definition per event; a definition added by
telecommand is disabled until enabled, one loaded from the scenario is enabled as configured; ``triggered`` gives the
telecommand packet of an enabled definition, which the flight software executes like a released scheduled command.
An action does not trigger itself: the events raised while an action runs start no further action (no loops).
Pure: no time, no I/O.
"""

from __future__ import annotations

from collections.abc import Iterable

from contracts import pus
from obsw.errors import CommandRejected, RejectReason


class EventActions:
    """The event-action definitions and whether each is enabled."""

    def __init__(self) -> None:
        self._packets: dict[pus.EventId, bytes] = {}
        self._enabled: dict[pus.EventId, bool] = {}

    def add(self, definitions: Iterable[tuple[pus.EventId, bytes]], enabled: bool = False) -> None:
        """Add definitions (all or none): an event that already has one, or is given twice, is refused."""
        defs = list(definitions)
        ids = [e for e, _ in defs]
        dup = sorted({e.name for e in ids if ids.count(e) > 1 or e in self._packets})
        if dup:
            raise CommandRejected(RejectReason.BAD_ARGUMENT, f"event-action definition(s) for {dup} already exist")
        for event, packet in defs:
            self._packets[event] = packet
            self._enabled[event] = enabled

    def delete(self, events: Iterable[pus.EventId]) -> None:
        """Delete the definitions of ``events`` (all or none)."""
        events = self._require(events)
        for e in events:
            del self._packets[e], self._enabled[e]

    def set_enabled(self, events: Iterable[pus.EventId], enabled: bool) -> None:
        """Enable or disable the definitions of ``events`` (all or none)."""
        for e in self._require(events):
            self._enabled[e] = enabled

    def enabled(self, event: pus.EventId) -> bool:
        """Whether ``event`` has an enabled definition."""
        return self._enabled.get(event, False)

    def triggered(self, event: pus.EventId) -> bytes | None:
        """The TC packet ``event`` runs, or None (no definition, or disabled)."""
        return self._packets[event] if self._enabled.get(event, False) else None

    def _require(self, events: Iterable[pus.EventId]) -> list[pus.EventId]:
        out = list(events)
        unknown = sorted({e.name for e in out if e not in self._packets})
        if unknown:
            raise CommandRejected(RejectReason.BAD_ARGUMENT, f"no event-action definition for {unknown}")
        return out
