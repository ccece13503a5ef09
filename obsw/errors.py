"""Errors of the on-board software, split by who is at fault.

- ``CommandRejected``: the ground sent something the spacecraft refuses (unknown command, bad argument, a tag in
  the past, a full schedule, an illegal mode change...). It carries a ``RejectReason`` code, which goes into the
  PUS service 1 failure report (as 0x0100 + the code), and a text naming the field or value at fault. The OBSW
  carries on.
- ``InternalFault``: the flight software itself is inconsistent (a bug or a broken invariant). It is never the
  ground's fault and must be reported as an on-board fault, not as a telecommand failure.
"""

from __future__ import annotations

from enum import IntEnum


class RejectReason(IntEnum):
    """Why a telecommand or a schedule entry was refused; the PUS service 1 failure code is 0x0100 + the value (the
    range ``contracts.pus.FailureCode`` leaves to the OBSW; below it are the codes of undecodable packets)."""

    MALFORMED = 1
    UNKNOWN_COMMAND = 2
    BAD_ARGUMENT = 3
    TAG_IN_PAST = 4
    TAG_WITHIN_MARGIN = 5
    SCHEDULE_FULL = 6
    DUPLICATE_REQUEST = 7
    UNKNOWN_REQUEST = 8
    ALREADY_RELEASED = 9
    ILLEGAL_TRANSITION = 10
    NO_CA_ESTIMATE = 11


class ObswError(Exception):
    """Base of every error raised by the on-board software."""


class CommandRejected(ObswError):
    """The ground's fault: a telecommand (or one of its entries) is refused; ``reason`` and ``text`` say why."""

    def __init__(self, reason: RejectReason, text: str) -> None:
        self.reason = reason
        self.text = text
        super().__init__(f"{reason.name}: {text}")


class InternalFault(ObswError):
    """The flight software's own fault: a broken invariant or an input no caller should ever produce."""


class IllegalTransition(CommandRejected):
    """A commanded mode change that the mode graph does not allow; names the current and requested modes."""

    def __init__(self, from_mode: str, to_mode: str, allowed: tuple[str, ...]) -> None:
        self.from_mode = from_mode
        self.to_mode = to_mode
        self.allowed = allowed
        super().__init__(
            RejectReason.ILLEGAL_TRANSITION,
            f"cannot command {to_mode} from {from_mode}; allowed from {from_mode}: {', '.join(allowed) or 'none'}",
        )
