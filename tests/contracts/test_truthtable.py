"""The truth table: columns derived from TruthRecord with units in their names, exact round trip, clear errors."""

from __future__ import annotations

import csv
import io

import pytest
from hypothesis import given
from hypothesis import strategies as st

from contracts.messages import TruthRecord
from contracts.truthtable import TruthTable, TruthTableError

num = st.floats(allow_nan=False, width=64)  # infinities too: the text form must carry them back


def vec(n: int) -> st.SearchStrategy[tuple[float, ...]]:
    """A tuple of n floats."""
    return st.tuples(*([num] * n))


@st.composite
def records(draw: st.DrawFn, wheels: int) -> TruthRecord:
    """A TruthRecord with ``wheels`` wheels, each optional field present or None."""
    def maybe(s: st.SearchStrategy) -> object:
        return draw(st.one_of(st.none(), s))

    return TruthRecord(
        t_s=draw(num), obt_s=draw(num), q=draw(vec(4)), omega_rad_s=draw(vec(3)),
        wheel_momentum_nms=draw(vec(wheels)), wheel_torque_nm=draw(vec(wheels)),
        pointing_error_rad=draw(num), target_in_fov=draw(st.booleans()), range_m=draw(num), theta_rad=draw(num),
        phase_angle_deg=draw(num), los_dimorphos_inertial=maybe(vec(3)), los_didymos_inertial=maybe(vec(3)),
        dimorphos_camera=maybe(vec(3)), range_didymos_m=maybe(num), frame_id=maybe(st.integers(0, 2**40)),
        dimorphos_px=maybe(vec(2)), didymos_px=maybe(vec(2)),
    )


def through_csv(table: TruthTable, recs: list[TruthRecord]) -> list[TruthRecord]:
    """Write records as CSV text with the table, read them back by header name."""
    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow(table.columns)
    for r in recs:
        w.writerow(table.cells(r))
    rows = list(csv.reader(io.StringIO(buf.getvalue())))
    back = TruthTable.for_header(rows[0])
    return [back.record(dict(zip(rows[0], row, strict=True))) for row in rows[1:]]


@given(data=st.data(), wheels=st.integers(0, 6))
def test_every_field_round_trips(data: st.DataObject, wheels: int) -> None:
    """A record written as a CSV row and read back by its header equals the record, None fields included."""
    recs = data.draw(st.lists(records(wheels), min_size=1, max_size=4))
    assert through_csv(TruthTable(wheels), recs) == recs


def test_a_full_record_fills_a_column_of_every_field() -> None:
    """Every TruthRecord field has at least one column, and a record with every field set fills every cell."""
    rec = TruthRecord(
        t_s=1.5, obt_s=2.25, q=(0.1, 0.2, 0.3, 0.9), omega_rad_s=(1e-3, -2e-3, 3e-3), wheel_momentum_nms=(0.1, 0.2),
        wheel_torque_nm=(-0.001, 0.002), pointing_error_rad=0.01, target_in_fov=True, range_m=55e3, theta_rad=1.2,
        phase_angle_deg=60.0, los_dimorphos_inertial=(0.0, 1.0, 0.0), los_didymos_inertial=(0.0, 0.0, 1.0),
        dimorphos_camera=(0.01, 0.02, 0.99), range_didymos_m=56e3, frame_id=7, dimorphos_px=(512.5, 300.25),
        didymos_px=(600.0, 310.0),
    )
    table = TruthTable.for_record(rec)
    assert {f.field for f in table.fields} == set(TruthRecord.model_fields)
    cells = table.cells(rec)
    assert len(cells) == len(table.columns) and all(cells)
    assert through_csv(table, [rec]) == [rec]


def test_header_names_carry_units() -> None:
    """The header of a two-wheel table, written out by hand: component labels before the unit suffix."""
    assert TruthTable(2).columns == (
        "t_s", "obt_s", "q_x", "q_y", "q_z", "q_w", "omega_x_rad_s", "omega_y_rad_s", "omega_z_rad_s",
        "wheel_momentum_0_nms", "wheel_momentum_1_nms", "wheel_torque_0_nm", "wheel_torque_1_nm",
        "pointing_error_rad", "target_in_fov", "range_m", "theta_rad", "phase_angle_deg",
        "los_dimorphos_inertial_x", "los_dimorphos_inertial_y", "los_dimorphos_inertial_z",
        "los_didymos_inertial_x", "los_didymos_inertial_y", "los_didymos_inertial_z",
        "dimorphos_camera_x", "dimorphos_camera_y", "dimorphos_camera_z", "range_didymos_m", "frame_id",
        "dimorphos_col_px", "dimorphos_row_px", "didymos_col_px", "didymos_row_px",
    )


def test_wheel_count_is_read_from_the_header() -> None:
    """for_header finds the wheel count from the wheel_momentum_i_nms columns, in any column order."""
    header = list(reversed(TruthTable(4).columns))
    assert TruthTable.for_header(header).wheels == 4


def test_missing_required_column_is_named() -> None:
    """A header without range_m is refused naming range_m; a missing optional column reads as None."""
    header = [c for c in TruthTable(1).columns if c not in ("range_m", "range_didymos_m")]
    with pytest.raises(TruthTableError, match="lacks column.*range_m"):
        TruthTable.for_header(header)
    no_optional = [c for c in TruthTable(1).columns if c != "range_didymos_m"]
    assert TruthTable.for_header(no_optional).wheels == 1


def test_bad_cells_name_their_column() -> None:
    """A non-number, a boolean other than 0/1 and half a pixel pair are refused naming the column or field."""
    table = TruthTable(1)
    rec = TruthRecord(t_s=0.0, obt_s=1.0, q=(0.0, 0.0, 0.0, 1.0), omega_rad_s=(0.0, 0.0, 0.0),
                      wheel_momentum_nms=(0.0,), wheel_torque_nm=(0.0,), pointing_error_rad=0.0, target_in_fov=False,
                      range_m=1.0, theta_rad=0.0, phase_angle_deg=0.0)
    row = dict(zip(table.columns, table.cells(rec), strict=True))
    assert table.record(row) == rec
    with pytest.raises(TruthTableError, match="range_m: 'far' is not a float"):
        table.record({**row, "range_m": "far"})
    with pytest.raises(TruthTableError, match="target_in_fov: 'yes' is not a bool"):
        table.record({**row, "target_in_fov": "yes"})
    with pytest.raises(TruthTableError, match="dimorphos_row_px of TruthRecord.dimorphos_px"):
        table.record({**row, "dimorphos_col_px": "3.0"})
    with pytest.raises(TruthTableError, match="TruthRecord.t_s"):
        table.record({**row, "t_s": ""})


def test_a_record_with_another_wheel_count_is_refused() -> None:
    """A table holds one wheel count: a three-wheel record in a two-wheel table is refused naming the field."""
    rec = TruthRecord(t_s=0.0, obt_s=1.0, q=(0.0, 0.0, 0.0, 1.0), omega_rad_s=(0.0, 0.0, 0.0),
                      wheel_momentum_nms=(0.0, 0.0, 0.0), wheel_torque_nm=(0.0, 0.0, 0.0), pointing_error_rad=0.0,
                      target_in_fov=False, range_m=1.0, theta_rad=0.0, phase_angle_deg=0.0)
    with pytest.raises(TruthTableError, match="wheel_momentum_nms has 3 component"):
        TruthTable(2).cells(rec)
