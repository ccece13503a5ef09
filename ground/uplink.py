"""Turning a validated timeline into PUS telecommands: each command becomes its TC, wrapped with its release OBT
in a service 11 insert, or with its C/A offset too in the mission's C/A-relative insert (so the spacecraft can
re-anchor it on board)."""

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


def schedule_inserts(resolved: list[ResolvedCommand], apid: int, next_seq: Callable[[], int],
                     nominal: pus.UploadNominalTrajectory | None = None,
                     source_id: int = 0) -> list[pus.InsertActivities | pus.InsertCaRelativeActivities]:
    """The inserts of every resolved command, each as a complete TC with its own sequence count: one TC[11,4] for
    the absolute tags, one TC[200,8] for the tags that follow the C/A estimate (either left out when empty)."""
    absolute, relative = [], []
    for r in resolved:
        packet = pus.encode_tc(telecommand_of(r.command, nominal=nominal), apid, next_seq(), source_id=source_id)
        if r.ca_offset_s is None:
            absolute.append(pus.ScheduledActivity(release_obt_s=r.obt_s, tc_packet=packet))
        else:
            relative.append(pus.CaRelativeActivity(ca_offset_s=r.ca_offset_s, release_obt_s=r.obt_s, tc_packet=packet))
    out: list[pus.InsertActivities | pus.InsertCaRelativeActivities] = []
    if absolute:
        out.append(pus.InsertActivities(activities=tuple(absolute)))
    if relative:
        out.append(pus.InsertCaRelativeActivities(activities=tuple(relative)))
    return out
