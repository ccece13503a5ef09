"""Base classes of every message and config: immutable, typed, no unknown fields.

``Config`` is stricter than ``Frozen``, for what people write by hand (scenarios, timelines): a number must be
written as a number (``true`` or ``'2.9'`` is refused, not read as 1.0 or 2.9) and must be finite unless the field
says otherwise, so a typo is refused before a run starts instead of failing, or silently doing nothing, in flight.
"""

from __future__ import annotations

import types
import typing
from enum import IntEnum
from typing import Annotated, Any, get_args, get_origin

from pydantic import BaseModel, BeforeValidator, ConfigDict, PlainSerializer, Strict


class Frozen(BaseModel):
    """An immutable pydantic model that forbids fields it does not declare."""

    model_config = ConfigDict(frozen=True, extra="forbid")


def strict_numbers(tp: Any) -> Any:
    """``tp`` with every ``float`` and ``int`` in it made strict (no bool, no string), through unions, tuples, lists,
    dicts and ``Annotated``."""
    if tp is float or tp is int:
        return Annotated[tp, Strict()]
    origin = get_origin(tp)
    args = get_args(tp)
    if origin is Annotated:
        return Annotated[(strict_numbers(args[0]), *args[1:])]
    if origin in (typing.Union, types.UnionType):
        return typing.Union[tuple(strict_numbers(a) for a in args)]
    if origin is tuple and args:
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple[strict_numbers(args[0]), ...]
        return tuple[tuple(strict_numbers(a) for a in args)]
    if origin is list and args:
        return list[strict_numbers(args[0])]
    if origin is dict and args:
        return dict[args[0], strict_numbers(args[1])]
    return tp


class Config(Frozen):
    """A configuration people write: numbers strict and finite (see the module docstring)."""

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)

    @classmethod
    def __pydantic_init_subclass__(cls, **kwargs: Any) -> None:
        changed = False
        for field in cls.model_fields.values():
            strict = strict_numbers(field.annotation)
            if strict != field.annotation:
                field.annotation, changed = strict, True
        if changed:
            cls.model_rebuild(force=True)


def named_enum(enum: type[IntEnum]) -> Any:
    """An enum field that accepts a member's name as well as its code (an unknown name refused naming the choices),
    and serialises to the name in JSON."""
    def parse(value: Any) -> Any:
        if isinstance(value, str) and not isinstance(value, enum):
            if value in enum.__members__:
                return enum[value]
            raise ValueError(f"Input should be one of {', '.join(repr(m) for m in enum.__members__)}, got {value!r}")
        return value
    return Annotated[enum, BeforeValidator(parse), PlainSerializer(lambda m: m.name, when_used="json")]
