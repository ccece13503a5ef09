"""The truth table (``truth.csv``): one TruthRecord per row, its columns derived from the record's fields.

Each field of ``TruthRecord`` is one column, or one per component for a tuple; a component's label goes before
the field's unit suffix so that every header names its unit (``omega_x_rad_s``, ``wheel_momentum_0_nms``,
``dimorphos_col_px``). An empty cell is None, a boolean is 0 or 1, a float is written as Python's shortest
round-trip text, so a record read back equals the record written. Ground writes the table, the analysis reads it.
"""

from __future__ import annotations

import types
import typing
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from pydantic import ValidationError

from contracts.errors import FlybyError
from contracts.messages import TruthRecord

# the unit suffixes of TruthRecord's field names, longest first so "_rad_s" wins over "_s"
UNIT_SUFFIXES = ("_rad_s", "_nms", "_nm", "_rad", "_deg", "_px", "_m", "_s")
# labels of the components of fixed-length tuple fields; 3-vectors default to x, y, z
COMPONENT_LABELS: dict[str, tuple[str, ...]] = {
    "q": ("x", "y", "z", "w"),
    "dimorphos_px": ("col", "row"),
    "didymos_px": ("col", "row"),
}
# the variable-length tuples have one component per reaction wheel
WHEEL_FIELDS = ("wheel_momentum_nms", "wheel_torque_nm")


class TruthTableError(FlybyError):
    """A truth table cannot be written or read: names the column, field or row and what was wrong."""


@dataclass(frozen=True)
class FieldColumns:
    """The columns of one TruthRecord field: their header names, the cell type, whether the field may be None."""

    field: str
    columns: tuple[str, ...]
    kind: type  # float, int or bool
    is_tuple: bool
    optional: bool


def _shape(annotation: Any) -> tuple[type, bool, int | None, bool]:
    """(cell type, is a tuple, fixed length or None if variable, optional) of a TruthRecord field annotation."""
    args = typing.get_args(annotation)
    optional = (typing.get_origin(annotation) in (typing.Union, types.UnionType)) and type(None) in args
    if optional:
        (annotation,) = [a for a in args if a is not type(None)]
    if typing.get_origin(annotation) is tuple:
        elems = typing.get_args(annotation)
        if len(elems) == 2 and elems[1] is Ellipsis:
            return elems[0], True, None, optional
        return elems[0], True, len(elems), optional
    return annotation, False, 1, optional


def component_column(field: str, label: str) -> str:
    """Header of one component of a tuple field: the label before the field's unit suffix."""
    for unit in UNIT_SUFFIXES:
        if field.endswith(unit):
            return f"{field[: -len(unit)]}_{label}{unit}"
    return f"{field}_{label}"


class TruthTable:
    """The column layout of a truth table for a spacecraft with ``wheels`` reaction wheels."""

    def __init__(self, wheels: int) -> None:
        if wheels < 0:
            raise TruthTableError(f"wheel count must be >= 0, got {wheels}")
        self.wheels = wheels
        fields = []
        for name, info in TruthRecord.model_fields.items():
            kind, is_tuple, length, optional = _shape(info.annotation)
            if not is_tuple:
                cols: tuple[str, ...] = (name,)
            else:
                if length is None:
                    labels = tuple(str(i) for i in range(wheels))
                else:
                    labels = COMPONENT_LABELS.get(name, ("x", "y", "z") if length == 3 else ())
                    if len(labels) != length:
                        raise TruthTableError(f"TruthRecord.{name}: no component labels for its {length} components "
                                              "(add them to contracts.truthtable.COMPONENT_LABELS)")
                cols = tuple(component_column(name, lab) for lab in labels)
            fields.append(FieldColumns(name, cols, kind, is_tuple, optional))
        self.fields: tuple[FieldColumns, ...] = tuple(fields)
        self.columns: tuple[str, ...] = tuple(c for f in self.fields for c in f.columns)

    @classmethod
    def for_record(cls, rec: TruthRecord) -> TruthTable:
        """The layout fitting a record's wheel count."""
        return cls(len(rec.wheel_momentum_nms))

    @classmethod
    def for_header(cls, header: Sequence[str]) -> TruthTable:
        """The layout of a table with this header; raise TruthTableError naming the columns a record needs but
        the header lacks (columns of optional fields may be absent: they read as None)."""
        wheels = 0
        while component_column(WHEEL_FIELDS[0], str(wheels)) in header:
            wheels += 1
        table = cls(wheels)
        have = set(header)
        missing = [c for f in table.fields if not f.optional for c in f.columns if c not in have]
        if missing:
            raise TruthTableError(f"header lacks column(s) {', '.join(missing)}")
        return table

    def cells(self, rec: TruthRecord) -> list[str]:
        """One row of text cells for a record, in the order of ``columns``."""
        out: list[str] = []
        for f in self.fields:
            value = getattr(rec, f.field)
            if value is None:
                out += [""] * len(f.columns)
                continue
            values = value if f.is_tuple else (value,)
            if len(values) != len(f.columns):
                raise TruthTableError(f"TruthRecord.{f.field} has {len(values)} component(s), the table "
                                      f"{len(f.columns)} (a table holds one wheel count)")
            out += [str(int(v)) if f.kind is bool else repr(v) for v in values]
        return out

    def record(self, row: dict[str, str]) -> TruthRecord:
        """The TruthRecord of one row given as {column: cell}; raise TruthTableError naming the column of a bad cell.

        A column absent from the row counts as an empty cell.
        """
        values: dict[str, Any] = {}
        for f in self.fields:
            cells = [row.get(c, "") for c in f.columns]
            filled = [c != "" for c in cells]
            if not any(filled) and (f.optional or not f.columns):
                values[f.field] = None if f.optional else ()
                continue
            if not all(filled):
                empty = [c for c, ok in zip(f.columns, filled, strict=True) if not ok]
                raise TruthTableError(f"empty cell(s) {', '.join(empty)} of TruthRecord.{f.field}")
            parsed = [_parse(cell, f.kind, col) for cell, col in zip(cells, f.columns, strict=True)]
            values[f.field] = tuple(parsed) if f.is_tuple else parsed[0]
        try:
            return TruthRecord(**values)
        except ValidationError as exc:
            first = exc.errors()[0]
            where = ".".join(str(p) for p in first["loc"])
            raise TruthTableError(f"TruthRecord.{where}: {first['msg']}") from None


def _parse(cell: str, kind: type, column: str) -> float | int | bool:
    """One cell as its field's type; TruthTableError naming the column if it is not one."""
    try:
        if kind is bool:
            if cell not in ("0", "1"):
                raise ValueError("expected 0 or 1")
            return cell == "1"
        if kind is int:
            return int(cell)
        return float(cell)
    except ValueError:
        raise TruthTableError(f"{column}: {cell!r} is not a {kind.__name__}") from None
