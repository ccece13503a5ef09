"""Timeline files: YAML for people, CSV for spreadsheets; readers that name the row and field of every fault,
and writers that the readers read back to the same Timeline.

Time tag text (both formats)::

    2022-09-26T23:10:24.5Z   absolute UTC (ISO 8601, zone required)
    OBT 1234.5               absolute on-board time, s (may be negative)
    +12.5s                   delay after the previous command, on-board s
    CA-240s / CA+60s / CA    offset from closest approach, on-board s

YAML::

    description: optional free text
    commands:
      - {time: CA-240s, command: set_mode, args: {mode: ACQUISITION}}

CSV: a header row with ``time``, ``command`` and one column per argument name; an empty cell is an absent argument.
"""

from __future__ import annotations

import csv
import io
import re
from collections.abc import Callable, Mapping
from datetime import date, datetime, timezone
from pathlib import Path
from typing import Any

import yaml
from pydantic import ValidationError

from contracts.textfile import TextFileError, load_yaml, read_text
from timeline.model import (
    AfterPreviousTag,
    CaTag,
    Command,
    CommandError,
    CommandRegistry,
    ObtTag,
    Tag,
    Timeline,
    TimelineEntry,
    TimelineError,
    UtcTag,
    default_registry,
)

_NUM = r"(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?"
# The zone is optional here so that a time without one gets UtcTag's clear refusal, not "cannot read".
_UTC_RE = re.compile(r"^\d{4}-\d{2}-\d{2}T\d{2}:\d{2}:\d{2}(?:\.\d{1,6})?(?:Z|[+-]\d{2}:\d{2})?$")
_OBT_RE = re.compile(rf"^OBT\s*([+-]?{_NUM})\s*s?$", re.IGNORECASE)
_AFTER_RE = re.compile(rf"^\+\s*({_NUM})\s*s?$", re.IGNORECASE)
_CA_RE = re.compile(rf"^CA\s*(?:([+-])\s*({_NUM})\s*s?)?$", re.IGNORECASE)
_TAG_FORMS = "expected UTC like '2022-09-26T23:10:24Z', 'OBT 1234.5', '+12s' or 'CA-240s'"
_ENTRY_KEYS = ("time", "command", "args")


class TagError(ValueError):
    """A time tag cannot be read; the message says why and what is expected."""


def tag_from_text(text: str) -> Tag:
    """Read one time tag from its text form (see the module docstring)."""
    s = text.strip()
    try:
        if _UTC_RE.match(s):
            return UtcTag(utc=datetime.fromisoformat(s))
        if m := _OBT_RE.match(s):
            return ObtTag(obt_s=float(m.group(1)))
        if m := _AFTER_RE.match(s):
            return AfterPreviousTag(delay_s=float(m.group(1)))
        if m := _CA_RE.match(s):
            if m.group(1) is None:
                return CaTag(ca_offset_s=0.0)
            sign = -1.0 if m.group(1) == "-" else 1.0
            return CaTag(ca_offset_s=sign * float(m.group(2)))
    except (ValueError, ValidationError) as exc:
        # A well-formed tag with an impossible value (month 13, an infinite number).
        raise TagError(f"cannot read {text!r} as a time tag: {_first_error(exc)}") from None
    raise TagError(f"cannot read {text!r} as a time tag ({_TAG_FORMS})")


def _first_error(exc: Exception) -> str:
    """The first message of a pydantic or plain ValueError."""
    if isinstance(exc, ValidationError):
        msg = str(exc.errors()[0]["msg"])
        return msg[len("Value error, ") :] if msg.startswith("Value error, ") else msg
    return str(exc)


def tag_text(tag: Tag) -> str:
    """The text form of a tag, which ``tag_from_text`` reads back to an equal tag."""
    if isinstance(tag, UtcTag):
        u = tag.utc.astimezone(timezone.utc)
        frac = f".{u.microsecond:06d}" if u.microsecond else ""
        return u.strftime("%Y-%m-%dT%H:%M:%S") + frac + "Z"
    if isinstance(tag, ObtTag):
        return f"OBT {tag.obt_s!r}"
    if isinstance(tag, AfterPreviousTag):
        return f"+{tag.delay_s!r}s"
    sign = "-" if tag.ca_offset_s < 0 else "+"
    return f"CA{sign}{abs(tag.ca_offset_s)!r}s"


def _tag_from_value(value: Any) -> Tag:
    """Read a tag from a YAML value: text, or a timestamp YAML already parsed."""
    if isinstance(value, datetime):
        try:
            return UtcTag(utc=value)
        except ValidationError as exc:
            raise TagError(f"cannot read {value.isoformat()!r} as a time tag: {_first_error(exc)}") from None
    if isinstance(value, date):
        raise TagError(f"a date alone ({value.isoformat()}) is not a time tag; give the time of day and 'Z'")
    if isinstance(value, bool) or value is None:
        raise TagError(f"cannot read {value!r} as a time tag ({_TAG_FORMS})")
    if isinstance(value, (int, float)):
        raise TagError(
            f"a bare number ({value!r}) is ambiguous: write 'OBT {value}' for on-board time "
            f"or '+{value}s' for a delay after the previous command (quoted in YAML)"
        )
    if not isinstance(value, str):
        raise TagError(f"cannot read a {type(value).__name__} as a time tag ({_TAG_FORMS})")
    return tag_from_text(value)


def _entry(
    row: str,
    tag_value: Any,
    name: Any,
    args: Any,
    is_first: bool,
    registry: CommandRegistry,
    field_of: Callable[[str], str],
    from_text: bool = False,
) -> tuple[TimelineEntry | None, list[str]]:
    """Validate one entry; return it (or None) and the problems found, each naming ``row`` and a field."""
    problems: list[str] = []
    tag: Tag | None = None
    try:
        tag = _tag_from_value(tag_value)
        if is_first and isinstance(tag, AfterPreviousTag):
            problems.append(f"{row}, {field_of('time')}: {tag_value!r} is relative to the previous command, "
                            "but there is none")
            tag = None
    except TagError as exc:
        problems.append(f"{row}, {field_of('time')}: {exc}")
    command: Command | None = None
    if not isinstance(name, str) or not name.strip():
        problems.append(f"{row}, {field_of('command')}: missing command name")
    else:
        try:
            command = registry.command(name.strip(), args, from_text=from_text)
        except CommandError as exc:
            for f, msg in exc.problems:
                key = f if f in ("command", "args") else "args" if f == "(args)" else "args." + f
                problems.append(f"{row}, {field_of(key)}: {msg}")
    if tag is None or command is None:
        return None, problems
    return TimelineEntry(tag=tag, command=command), problems


def _csv_field(key: str) -> str:
    """Name the CSV column of an entry field ('args' alone: the argument columns together)."""
    return "argument columns" if key == "args" else f"column '{key.removeprefix('args.')}'"


def timeline_from_data(data: Any, source: str = "<timeline>", registry: CommandRegistry | None = None) -> Timeline:
    """Validate parsed YAML into a Timeline, or raise TimelineError listing every problem with its row and field."""
    reg = registry or default_registry()
    if not isinstance(data, Mapping):
        raise TimelineError(source, [f"(file): must be a mapping with a 'commands' list, got {type(data).__name__}"])
    problems: list[str] = []
    for key in data:
        if key not in ("description", "commands"):
            problems.append(f"field '{key}': unknown field (expected 'description', 'commands')")
    if "description" in data and not isinstance(data["description"], str):
        problems.append(f"field 'description': must be text, got {type(data['description']).__name__}")
    rows = data.get("commands")
    if not isinstance(rows, list):
        what = "missing" if rows is None else f"must be a list of commands, got {type(rows).__name__}"
        raise TimelineError(source, problems + [f"field 'commands': {what}"])
    entries: list[TimelineEntry] = []
    for i, item in enumerate(rows, start=1):
        row = f"row {i}"
        if not isinstance(item, Mapping):
            problems.append(f"{row}: must be a mapping with 'time' and 'command', got {type(item).__name__}")
            continue
        unknown = [k for k in item if k not in _ENTRY_KEYS]
        for k in unknown:
            problems.append(f"{row}, field '{k}': unknown field (expected {', '.join(_ENTRY_KEYS)})")
        if "time" not in item:
            problems.append(f"{row}, field 'time': missing")
            continue
        entry, found = _entry(row, item["time"], item.get("command"), item.get("args"), i == 1, reg,
                              lambda f: f"field '{f}'")
        problems.extend(found)
        if entry is not None and not unknown:
            entries.append(entry)
    if problems:
        raise TimelineError(source, problems)
    return Timeline(entries=tuple(entries))


def timeline_from_yaml_text(text: str, source: str = "<timeline>", registry: CommandRegistry | None = None) -> Timeline:
    """Parse and validate a YAML timeline."""
    try:
        data = load_yaml(text)
    except TextFileError as exc:
        raise TimelineError(source, [str(exc)]) from None
    return timeline_from_data(data, source, registry)


def timeline_from_csv_text(text: str, source: str = "<timeline>", registry: CommandRegistry | None = None) -> Timeline:
    """Parse and validate a CSV timeline (header: time, command, then argument columns)."""
    reg = registry or default_registry()
    # Spreadsheets often save UTF-8 with a byte-order mark, which would otherwise stick to the first column name.
    reader = csv.reader(io.StringIO(text.removeprefix("\ufeff")))
    try:
        header = next((r for r in reader if any(c.strip() for c in r)), None)
    except csv.Error as exc:
        raise TimelineError(source, [f"line {reader.line_num}: not valid CSV: {exc}"]) from None
    if header is None:
        raise TimelineError(source, ["(file): empty, expected a header row 'time,command,...'"])
    header_line = reader.line_num
    columns = [c.strip() for c in header]
    problems: list[str] = []
    for needed in ("time", "command"):
        if needed not in columns:
            problems.append(f"line {header_line}: missing column '{needed}'")
    known_args = set(reg.argument_names())
    seen: set[str] = set()
    for c in columns:
        if c in seen:
            problems.append(f"line {header_line}, column '{c}': repeated")
        seen.add(c)
        if c not in ("time", "command") and c not in known_args:
            problems.append(f"line {header_line}, column '{c or '(blank)'}': not an argument of any command "
                            f"(known: {', '.join(sorted(known_args))})")
    if problems:
        raise TimelineError(source, problems)
    entries: list[TimelineEntry] = []
    n = 0
    while True:
        try:
            cells = next(reader)
        except StopIteration:
            break
        except csv.Error as exc:
            problems.append(f"line {reader.line_num}: not valid CSV: {exc}")
            break
        if not any(c.strip() for c in cells):
            continue
        n += 1
        row = f"row {n} (line {reader.line_num})"
        if len(cells) != len(columns):
            problems.append(f"{row}: has {len(cells)} cells, the header has {len(columns)}")
            continue
        values = {c: v.strip() for c, v in zip(columns, cells)}
        args = {c: v for c, v in values.items() if c not in ("time", "command") and v != ""}
        if values["time"] == "":
            problems.append(f"{row}, column 'time': missing")
            continue
        entry, found = _entry(row, values["time"], values["command"], args, n == 1, reg,
                              _csv_field, from_text=True)
        problems.extend(found)
        if entry is not None:
            entries.append(entry)
    if problems:
        raise TimelineError(source, problems)
    return Timeline(entries=tuple(entries))


def load_timeline(path: str | Path, registry: CommandRegistry | None = None) -> Timeline:
    """Read a timeline file, YAML (.yaml, .yml) or CSV (.csv) by its suffix."""
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix not in (".yaml", ".yml", ".csv"):
        raise TimelineError(str(p), [f"(file): unknown timeline format '{suffix}', expected .yaml, .yml or .csv"])
    try:
        text = read_text(p)
    except TextFileError as exc:
        raise TimelineError(str(p), [str(exc)]) from None
    if suffix == ".csv":
        return timeline_from_csv_text(text, str(p), registry)
    return timeline_from_yaml_text(text, str(p), registry)


def timeline_yaml_text(timeline: Timeline, description: str = "") -> str:
    """The YAML text of a timeline, which ``timeline_from_yaml_text`` reads back to an equal Timeline."""
    rows: list[dict[str, Any]] = []
    for e in timeline.entries:
        row: dict[str, Any] = {"time": tag_text(e.tag), "command": e.command.name}
        if e.command.args:
            row["args"] = dict(e.command.args)
        rows.append(row)
    data: dict[str, Any] = {"description": description} if description else {}
    data["commands"] = rows
    return yaml.safe_dump(data, sort_keys=False, default_flow_style=False, allow_unicode=True)


def _cell(value: Any) -> str:
    """The CSV cell of one argument value (floats by repr, so they read back exactly)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value)
    return str(value)


def timeline_csv_text(timeline: Timeline) -> str:
    """The CSV text of a timeline, which ``timeline_from_csv_text`` reads back to an equal Timeline."""
    arg_columns: dict[str, None] = {}
    for e in timeline.entries:
        for k in e.command.args:
            arg_columns.setdefault(k, None)
    columns = ["time", "command", *arg_columns]
    out = io.StringIO()
    w = csv.writer(out, lineterminator="\n")
    w.writerow(columns)
    for e in timeline.entries:
        w.writerow([tag_text(e.tag), e.command.name, *(_cell(e.command.args[c]) if c in e.command.args else ""
                                                       for c in arg_columns)])
    return out.getvalue()
