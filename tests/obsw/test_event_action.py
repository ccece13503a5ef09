"""Service 19 event-action definitions: one per event, enabled or not, managed all or none."""

from __future__ import annotations

import pytest

from contracts import pus
from obsw.errors import CommandRejected
from obsw.event_action import EventActions

E = pus.EventId


def test_an_enabled_definition_gives_its_packet_and_a_disabled_one_nothing() -> None:
    """Added from ground: disabled until enabled; triggered gives the packet only while enabled."""
    acts = EventActions()
    acts.add([(E.WHEEL_FAILED, b"tc-a"), (E.TARGET_LOST, b"tc-b")])
    assert acts.triggered(E.WHEEL_FAILED) is None
    acts.set_enabled([E.WHEEL_FAILED], True)
    assert acts.triggered(E.WHEEL_FAILED) == b"tc-a" and acts.triggered(E.TARGET_LOST) is None
    assert acts.triggered(E.CLOCK_JUMP) is None


def test_definitions_are_managed_all_or_none() -> None:
    """A second definition for an event is refused, as is naming an event without one; nothing changes."""
    acts = EventActions()
    acts.add([(E.WHEEL_FAILED, b"a")], enabled=True)
    with pytest.raises(CommandRejected, match="WHEEL_FAILED"):
        acts.add([(E.TARGET_LOST, b"b"), (E.WHEEL_FAILED, b"c")])
    assert acts.triggered(E.TARGET_LOST) is None and acts.triggered(E.WHEEL_FAILED) == b"a"
    with pytest.raises(CommandRejected, match="CLOCK_JUMP"):
        acts.delete([E.WHEEL_FAILED, E.CLOCK_JUMP])
    assert acts.enabled(E.WHEEL_FAILED)
    acts.delete([E.WHEEL_FAILED])
    assert acts.triggered(E.WHEEL_FAILED) is None
