"""Reading the text files people write (scenarios, timelines, trajectories): UTF-8 only, YAML without surprises.

A file that is not UTF-8 text (a binary file given by mistake) is refused in one line naming the octet, and a YAML
mapping that repeats a key is refused naming the key and both lines, instead of silently keeping the last value.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from contracts.errors import FlybyError


class TextFileError(FlybyError):
    """A text input that cannot be used; ``where`` is '(file)' or 'line L, column C'."""

    def __init__(self, where: str, message: str) -> None:
        self.where = where
        self.message = message
        super().__init__(f"{where}: {message}")


def read_text(path: str | Path) -> str:
    """The file's text; TextFileError if it cannot be read or is not UTF-8 text."""
    p = Path(path)
    try:
        data = p.read_bytes()
    except IsADirectoryError:
        raise TextFileError("(file)", "is a folder, not a file") from None
    except OSError as exc:
        raise TextFileError("(file)", f"cannot read: {exc.strerror}") from None
    return decode_text(data)


def decode_text(data: bytes) -> str:
    """UTF-8 octets as text (a leading byte-order mark dropped); TextFileError naming the first bad octet."""
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise TextFileError("(file)", f"not UTF-8 text (octet 0x{data[exc.start]:02X} at offset {exc.start}): "
                                      "is this a binary file?") from None
    if "\x00" in text:
        raise TextFileError("(file)", f"not text: NUL character at offset {text.index(chr(0))}") from None
    return text.removeprefix("\ufeff")


class _UniqueKeyLoader(yaml.SafeLoader):
    """A safe loader that refuses a mapping repeating a key."""


def _mapping(loader: _UniqueKeyLoader, node: yaml.MappingNode, deep: bool = False) -> dict[Any, Any]:
    loader.flatten_mapping(node)
    seen: dict[Any, yaml.Node] = {}
    for key_node, _ in node.value:
        key = loader.construct_object(key_node, deep=deep)
        try:
            first = seen.get(key)
        except TypeError:
            raise yaml.constructor.ConstructorError(None, None, f"unhashable key {key!r}", key_node.start_mark) from None
        if first is not None:
            raise yaml.constructor.ConstructorError(
                None, None, f"duplicate key {key!r} (first at line {first.start_mark.line + 1})", key_node.start_mark)
        seen[key] = key_node
    return loader.construct_mapping(node, deep=deep)


_UniqueKeyLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _mapping)


def load_yaml(text: str) -> Any:
    """Parse YAML text (safe types only, keys unique); TextFileError with the line and column of the problem."""
    try:
        return yaml.load(text, Loader=_UniqueKeyLoader)  # noqa: S506 - a SafeLoader subclass
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}, column {mark.column + 1}" if mark else "(file)"
        raise TextFileError(where, f"not valid YAML: {getattr(exc, 'problem', None) or exc}") from None
