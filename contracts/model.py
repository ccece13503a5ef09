"""Base classes of every message and config: immutable, typed, no unknown fields.

``Config`` is stricter than ``Frozen``, for what people write by hand (scenarios, timelines): a number must be
written as a number (``true`` or ``'2.9'`` is refused, not read as 1.0 or 2.9) and must be finite unless the field
says otherwise, so a typo is refused before a run starts instead of failing, or silently doing nothing, in flight.
"""

from __future__ import annotations

import types
import typing
from enum import IntEnum
from typing import Annotated, Any, Self, get_args, get_origin

from pydantic import BaseModel, BeforeValidator, ConfigDict, PlainSerializer, Strict


class Frozen(BaseModel):
    """An immutable pydantic model that forbids fields it does not declare."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    @classmethod
    def trusted(cls, **values: Any) -> Self:
        """``cls(**values)`` without validation, for values a program made itself, each already of its field's type
        as validation would leave it (a float field a float, a tuple field a tuple of them): never for input.

        ``model_construct`` without its Python loop over the fields, which costs more than pydantic-core's validation:
        this is a dictionary copy, quicker than validation for a model of many fields (a TruthRecord 2.6 us against
        3.8, model_construct 4.7; not for a few fields); unknown or missing fields still raise TypeError. The models
        trusted with the same fields share one set of them (``model_fields_set``, never changed in place: a frozen
        model refuses assignment and ``model_copy`` copies it), one object fewer per model for the garbage collector.
        """
        defaults, required = _TEMPLATES.get(cls) or _template(cls)
        fields = defaults.copy()  # every field in declaration order, as validation makes the model's __dict__
        fields.update(values)
        if len(fields) != len(defaults) or not required <= values.keys():  # an unknown field adds a key
            unknown, missing = sorted(values.keys() - defaults.keys()), sorted(required - values.keys())
            raise TypeError(f"{cls.__name__}.trusted: unknown fields {unknown}, missing fields {missing}")
        model = cls.__new__(cls)
        _setattr(model, "__dict__", fields)
        given = _FIELDS_SETS.get(tuple(values))
        if given is None:
            given = _FIELDS_SETS[tuple(values)] = set(values)
        _setattr(model, "__pydantic_fields_set__", given)
        _setattr(model, "__pydantic_extra__", None)
        _setattr(model, "__pydantic_private__", None)
        return model


_setattr = object.__setattr__  # a frozen model's attributes are set as pydantic's model_construct sets them
# per class that ``Frozen.trusted`` made: each field's default (None for a required field) in declaration order, and
# the required fields
_TEMPLATES: dict[type[Frozen], tuple[dict[str, Any], frozenset[str]]] = {}
_FIELDS_SETS: dict[tuple[str, ...], set[str]] = {}  # the fields given to Frozen.trusted, in the order given
_IMMUTABLE = (type(None), bool, int, float, str, bytes, tuple, frozenset, IntEnum)


def _template(cls: type[Frozen]) -> tuple[dict[str, Any], frozenset[str]]:
    """The defaults and required fields of ``cls`` for ``Frozen.trusted`` (TypeError if it cannot make it)."""
    if cls.__private_attributes__ or cls.__pydantic_post_init__ is not None:
        raise TypeError(f"{cls.__name__}.trusted: a model with private attributes or a post-init hook is not supported")
    defaults: dict[str, Any] = {}
    required = set()
    for name, info in cls.model_fields.items():
        if info.is_required():
            required.add(name)
            defaults[name] = None
        elif info.default_factory is not None or not isinstance(info.default, _IMMUTABLE):
            raise TypeError(f"{cls.__name__}.trusted: the default of {name} is not an immutable value")
        else:
            defaults[name] = info.default
    _TEMPLATES[cls] = defaults, frozenset(required)
    return _TEMPLATES[cls]


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
