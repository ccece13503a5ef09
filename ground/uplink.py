"""Turning a validated timeline into PUS telecommands: each command becomes its TC, wrapped in one
service 11 insert with its release OBT (and its C/A offset, so the spacecraft can re-anchor it on board)."""

from __future__ import annotations

from collections.abc import Callable

from contracts import pus
from contracts.dictionary import DICTIONARY
from timeline.convert import ResolvedCommand
from timeline.model import Command


class UplinkError(ValueError):
    """A timeline command has no telecommand, or ground cannot complete it."""


def telecommand_of(command: Command, nominal: pus.UploadNominalTrajectory | None = None) -> pus.TcCommand:
    """The telecommand that carries out one timeline command (the dictionary's command of that name).

    The fields the dictionary says ground fills come from ``nominal``, ground's own telecommand of that type.
    """
    cls = DICTIONARY.commands.get(command.name)
    if cls is None:
        raise UplinkError(f"timeline command '{command.name}' has no telecommand mapping")
    fills = cls.COMMAND.ground_fills  # type: ignore[union-attr]
    known = {}
    if fills:
        if not isinstance(nominal, cls):
            raise UplinkError(f"{command.name}: ground has no {cls.__name__} to complete it from")
        known = {name: getattr(nominal, name) for name in fills}
    return cls.model_validate({**known, **command.args})  # type: ignore[return-value]


def schedule_insert(resolved: list[ResolvedCommand], apid: int, next_seq: Callable[[], int],
                    nominal: pus.UploadNominalTrajectory | None = None) -> pus.InsertActivities:
    """One TC[11,4] inserting every resolved command, each as a complete TC with its own sequence count."""
    activities = tuple(
        pus.ScheduledActivity(release_obt_s=r.obt_s, ca_offset_s=r.ca_offset_s,
                              tc_packet=pus.encode_tc(telecommand_of(r.command, nominal=nominal), apid, next_seq()))
        for r in resolved
    )
    return pus.InsertActivities(activities=activities)
