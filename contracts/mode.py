"""The spacecraft's navigation modes: one enum for the mode manager, the packets, the timeline and ground.

The value is the mode's wire code (one octet in housekeeping, mode events and the set-mode telecommand); the name
is how the timeline and the logs spell it.
"""

from __future__ import annotations

from enum import IntEnum
from typing import Annotated, Any

from pydantic import BeforeValidator, PlainSerializer


class Mode(IntEnum):
    """On-board modes and their wire codes."""

    SAFE = 0
    STANDBY = 1
    ACQUISITION = 2
    NOMINAL_TRACKING = 3
    AUTONOMOUS_TRACKING = 4


def mode_of(value: Any) -> Any:
    """Let a mode be given by name ('STANDBY') as well as by code; an unknown name is refused naming the choices."""
    if isinstance(value, str) and not isinstance(value, Mode):
        if value in Mode.__members__:
            return Mode[value]
        names = [f"'{m.name}'" for m in Mode]
        raise ValueError(f"Input should be {', '.join(names[:-1])} or {names[-1]}")
    return value


ModeValue = Annotated[Mode, BeforeValidator(mode_of), PlainSerializer(lambda m: m.name, when_used="json")]
"""A mode field: accepts a name or a code, holds a ``Mode``, serialises to its name in JSON (timeline files)."""
