"""Command timelines as data: time tags, command definitions with argument schemas, and the registry of commands.

A timeline is an ordered list of entries, each a time tag and a validated command. A tag is one of:

- ``UtcTag``: an absolute UTC instant (ground converts it to OBT with its current correlation);
- ``ObtTag``: an absolute on-board time, s;
- ``AfterPreviousTag``: a delay after the previous entry's tag, s (>= 0, so file order is kept);
- ``CaTag``: an offset from closest approach, s (re-anchored on board when a new C/A estimate is accepted).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from copy import copy
from dataclasses import dataclass
from datetime import datetime, timezone
from types import UnionType
from typing import Annotated, Any, Literal, Union, get_args, get_origin

from pydantic import Field, ValidationError, create_model, field_validator, model_validator

from contracts.dictionary import DICTIONARY
from contracts.errors import FlybyError
from contracts.mode import Mode
from contracts.model import Frozen
from contracts.packet import Packet

MODES: tuple[str, ...] = tuple(m.name for m in Mode)
"""On-board modes a command may request, by name."""


class TimelineError(FlybyError):
    """A timeline is invalid or cannot be resolved; ``problems`` lists each fault, naming its row and field."""

    def __init__(self, source: str, problems: list[str]) -> None:
        self.source = source
        self.problems = problems
        super().__init__(f"{source}: " + "; ".join(problems))


class CommandError(FlybyError):
    """A command is unknown or its arguments break its definition; ``problems`` holds (field, message) pairs."""

    def __init__(self, name: str, problems: list[tuple[str, str]]) -> None:
        self.name = name
        self.problems = problems
        super().__init__(f"command '{name}': " + "; ".join(f"{f}: {m}" for f, m in problems))


def _finite(v: float, what: str) -> float:
    """Return v if finite, else raise naming what it is."""
    if not math.isfinite(v):
        raise ValueError(f"{what} must be a finite number, got {v}")
    return v


class UtcTag(Frozen):
    """An absolute UTC instant."""

    kind: Literal["utc"] = "utc"
    utc: datetime = Field(description="UTC instant, timezone-aware (microsecond resolution)")

    @field_validator("utc")
    @classmethod
    def _aware_utc(cls, v: datetime) -> datetime:
        if v.tzinfo is None or v.utcoffset() is None:
            raise ValueError("UTC time must carry its zone (end it in 'Z')")
        return v.astimezone(timezone.utc)


class ObtTag(Frozen):
    """An absolute on-board time."""

    kind: Literal["obt"] = "obt"
    obt_s: float = Field(description="on-board time, s")

    @field_validator("obt_s")
    @classmethod
    def _is_finite(cls, v: float) -> float:
        return _finite(v, "OBT")


class AfterPreviousTag(Frozen):
    """A delay after the previous entry's tag."""

    kind: Literal["after_previous"] = "after_previous"
    delay_s: float = Field(ge=0, description="delay after the previous command, on-board s")

    @field_validator("delay_s")
    @classmethod
    def _is_finite(cls, v: float) -> float:
        return _finite(v, "delay")


class CaTag(Frozen):
    """An offset from the time of closest approach (negative: before C/A)."""

    kind: Literal["ca"] = "ca"
    ca_offset_s: float = Field(description="offset from closest approach, on-board s (negative before C/A)")

    @field_validator("ca_offset_s")
    @classmethod
    def _is_finite(cls, v: float) -> float:
        return _finite(v, "C/A offset")


Tag = Annotated[UtcTag | ObtTag | AfterPreviousTag | CaTag, Field(discriminator="kind")]


class Command(Frozen):
    """A command with arguments already validated against its definition (build it with a registry)."""

    name: str = Field(min_length=1, description="command name, as in the registry")
    args: dict[str, Any] = Field(default_factory=dict, description="validated arguments, by name")


class TimelineEntry(Frozen):
    """One time-tagged command."""

    tag: Tag
    command: Command


class Timeline(Frozen):
    """Time-tagged commands in file order (row n is ``entries[n - 1]``)."""

    entries: tuple[TimelineEntry, ...] = ()

    @model_validator(mode="after")
    def _first_not_relative(self) -> Timeline:
        if self.entries and isinstance(self.entries[0].tag, AfterPreviousTag):
            raise ValueError("row 1: a tag relative to the previous command needs a previous command")
        return self


@dataclass(frozen=True)
class CommandDefinition:
    """A command name, the schema of its arguments and what it does."""

    name: str
    arguments: type[Frozen]
    description: str

    def __post_init__(self) -> None:
        if not self.name or not self.name.replace("_", "").isalnum() or not self.name[0].isalpha():
            raise ValueError(f"command name must be a letter then letters, digits or '_', got {self.name!r}")


def _arg_field(loc: tuple[Any, ...]) -> str:
    """Name the argument a pydantic error location points at ('(args)' for a whole-model rule)."""
    return ".".join(str(p) for p in loc) or "(args)"


def _arg_message(err: Mapping[str, Any]) -> str:
    """A short message for one pydantic argument error."""
    kind = err["type"]
    if kind == "extra_forbidden":
        return "not an argument of this command"
    if kind == "missing":
        return "missing"
    if kind in ("greater_than", "greater_than_equal", "less_than", "less_than_equal"):
        op = {"greater_than": ">", "greater_than_equal": ">=", "less_than": "<", "less_than_equal": "<="}[kind]
        bound = next(iter(err["ctx"].values()))
        return f"must be {op} {bound:g}, got {err['input']!r}"
    msg = str(err["msg"])
    if msg.startswith("Value error, "):
        msg = msg[len("Value error, ") :]
    return f"{msg}, got {err['input']!r}" if kind not in ("value_error", "model_type") else msg


class CommandRegistry:
    """The commands a timeline may contain; extend it with ``register``."""

    def __init__(self, definitions: Iterable[CommandDefinition] = ()) -> None:
        self._definitions: dict[str, CommandDefinition] = {}
        for d in definitions:
            self.register(d)

    def register(self, definition: CommandDefinition) -> None:
        """Add a command definition; a name may be registered once."""
        if definition.name in self._definitions:
            raise ValueError(f"command '{definition.name}' is already registered")
        self._definitions[definition.name] = definition

    def names(self) -> tuple[str, ...]:
        """Registered command names, sorted."""
        return tuple(sorted(self._definitions))

    def definition(self, name: str) -> CommandDefinition:
        """The definition of ``name``, or CommandError if it is not registered."""
        try:
            return self._definitions[name]
        except KeyError:
            raise CommandError(
                name, [("command", f"unknown command '{name}' (known: {', '.join(self.names())})")]
            ) from None

    def argument_names(self) -> tuple[str, ...]:
        """Every argument name of every registered command, in registration order without repeats."""
        seen: dict[str, None] = {}
        for d in self._definitions.values():
            for f in d.arguments.model_fields:
                seen.setdefault(f, None)
        return tuple(seen)

    def command(self, name: str, args: Mapping[str, Any] | None = None, *, from_text: bool = False) -> Command:
        """Validate ``args`` against the definition of ``name`` and return the command, or raise CommandError.

        Values typed by their format (YAML) must be numbers where the argument is a number, and finite (``true``
        or ``'0.5'`` is refused); ``from_text`` values (CSV cells) are text and are converted.
        """
        definition = self.definition(name)
        if args is not None and not isinstance(args, Mapping):
            raise CommandError(name, [("args", f"must be a mapping of argument names, got {type(args).__name__}")])
        if not from_text:
            wrong = [(k, why) for k, v in (args or {}).items()
                     if k in definition.arguments.model_fields
                     and (why := _not_a_number(v, definition.arguments.model_fields[k].annotation))]
            if wrong:
                raise CommandError(name, wrong)
        try:
            parsed = definition.arguments.model_validate(dict(args or {}))
        except ValidationError as exc:
            raise CommandError(name, [(_arg_field(e["loc"]), _arg_message(e)) for e in exc.errors()]) from None
        return Command(name=name, args=parsed.model_dump(mode="json"))


def _numeric(annotation: Any) -> type | None:
    """``int`` or ``float`` if an argument's type is that number (possibly optional or annotated), else None."""
    if annotation in (int, float):
        return annotation  # type: ignore[no-any-return]
    args = get_args(annotation)
    if get_origin(annotation) is Annotated:
        return _numeric(args[0])
    if get_origin(annotation) in (Union, UnionType):
        kinds = {_numeric(a) for a in args if a is not type(None)} - {None}
        return float if float in kinds else int if kinds else None
    return None


def _not_a_number(value: Any, annotation: Any) -> str | None:
    """Why a typed value cannot be a number argument, or None."""
    kind = _numeric(annotation)
    if kind is None or value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return f"must be a number, got {value!r} ({type(value).__name__})"
    if kind is int and isinstance(value, float):
        return f"must be a whole number, got {value!r}"
    if isinstance(value, float) and not math.isfinite(value):
        return f"must be a finite number, got {value!r}"
    return None


def _arguments(packet: type[Packet]) -> type[Frozen]:
    """The argument model of the timeline command that sends ``packet``: the packet's fields with their checks,
    less those ground fills, with the command's defaults. A complete command keeps the packet's cross-field rules
    (a subclass); rules on ground-filled fields are checked when ground completes the telecommand."""
    cmd = packet.COMMAND
    assert cmd is not None
    defaults = dict(cmd.defaults)
    fields: dict[str, Any] = {}
    for name, info in packet.model_fields.items():
        if name in cmd.ground_fills:
            continue
        if name in defaults:
            info = copy(info)
            info.default = defaults[name]
        fields[name] = (info.annotation, info)
    base: type[Frozen] = Frozen if cmd.ground_fills else packet
    title = "".join(part.title() for part in cmd.name.split("_"))
    return create_model(f"{title}Args", __base__=base, __module__=__name__, **fields)


STANDARD_COMMANDS: tuple[CommandDefinition, ...] = tuple(
    CommandDefinition(p.COMMAND.name, _arguments(p), p.COMMAND.description)  # type: ignore[union-attr]
    for p in DICTIONARY.commands.values()
)
"""The commands of the TM/TC dictionary that a timeline may contain, with the telecommands' bounds."""


def default_registry() -> CommandRegistry:
    """A new registry holding the standard commands (a new one each call, so extending it changes no other)."""
    return CommandRegistry(STANDARD_COMMANDS)
