"""Reports as columns: every field of every report reads back from its column, absent values and unused slots NaN."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from analysis.report_columns import ReportColumns
from analysis.telemetry import decoded_telemetry
from contracts import pus
from contracts.dictionary import DICTIONARY
from tests.contracts.strategies import packet_strategy

APID = 0x0C1


def _expected(value: object, width: int) -> list[float]:
    """A field's value as the row of a plain reference: NaN for None, a sequence padded with NaN."""
    if value is None:
        return [math.nan] * width
    if isinstance(value, tuple):
        return [float(v) for v in value] + [math.nan] * (width - len(value))
    return [float(value)]  # type: ignore[arg-type]


@settings(max_examples=40, deadline=None)
@given(reports=st.lists(packet_strategy(pus.Housekeeping), max_size=30),
       times=st.lists(st.floats(0, 2**32, allow_nan=False), min_size=30, max_size=30),
       first_rows=st.integers(1, 4))
def test_every_field_reads_back_from_its_column(reports: list[pus.Housekeeping], times: list[float],
                                                first_rows: int) -> None:
    """Column k of field f holds report k's f (NaN where absent or past the used slots), across the growth and the
    trim of the rows; the last report is kept whole."""
    import analysis.report_columns as module

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(module, "_FIRST_ROWS", first_rows)  # rows grown several times over a few reports
        cols = ReportColumns(pus.Housekeeping)
        for t, r in zip(times, reports, strict=False):
            cols.append(t, r)
    if len(reports) % 2:
        cols.trim()
    assert len(cols) == len(reports) and bool(cols) == bool(reports)
    np.testing.assert_array_equal(cols.t_s, np.array(times[: len(reports)]))
    assert cols.last == ((times[len(reports) - 1], reports[-1]) if reports else None)
    for name in pus.Housekeeping.model_fields:
        got = cols.column(name)
        width = 1 if got.ndim == 1 else got.shape[1]
        want = np.array([_expected(getattr(r, name), width) for r in reports]).reshape(len(reports), width)
        np.testing.assert_array_equal(got.reshape(len(reports), width), want, err_msg=name)


@settings(max_examples=20, deadline=None)
@given(reports=st.lists(packet_strategy(pus.Housekeeping), min_size=1, max_size=20))
def test_present_rows_are_those_holding_every_named_field(reports: list[pus.Housekeeping]) -> None:
    """present() keeps the reports where each named field is there, in order, with their values."""
    cols = ReportColumns(pus.Housekeeping)
    for k, r in enumerate(reports):
        cols.append(float(k), r)
    t, (err, best) = cols.present("pointing_error_rad", "best_ca_obt_s")
    keep = [k for k, r in enumerate(reports) if r.pointing_error_rad is not None and r.best_ca_obt_s is not None]
    assert t.tolist() == [float(k) for k in keep]
    assert err.tolist() == [reports[k].pointing_error_rad for k in keep]
    assert best.tolist() == [reports[k].best_ca_obt_s for k in keep]


def test_decoded_housekeeping_lands_in_its_columns_and_a_wrong_field_is_named() -> None:
    """Housekeeping decoded from packets fills the columns with the decoded values; an unknown field name is
    refused naming the fields there are."""
    hk = [pus.Housekeeping(mode=pus.Mode.NOMINAL_TRACKING, q=(0.0, 0.0, 0.6, 0.8), rate_rad_s=(0.01, -0.02, 0.5),
                           wheel_speed_rad_s=(1.0, 2.0, 3.0), wheel_momentum_nms=(0.25, -0.5, 0.75),
                           pointing_error_rad=None if k % 2 else 0.125 * k) for k in range(4)]
    tm = decoded_telemetry([pus.encode_tm(h, APID, k, 100.0 + k, k) for k, h in enumerate(hk)], "test")
    assert tm.housekeeping.t_s.tolist() == [100.0, 101.0, 102.0, 103.0]
    assert tm.housekeeping.column("mode").tolist() == [float(pus.Mode.NOMINAL_TRACKING)] * 4
    np.testing.assert_array_equal(tm.housekeeping.column("wheel_momentum_nms")[:, :3], [[0.25, -0.5, 0.75]] * 4)
    assert np.isnan(tm.housekeeping.column("wheel_momentum_nms")[:, 3:]).all()
    np.testing.assert_array_equal(tm.housekeeping.column("pointing_error_rad"), [0.0, np.nan, 0.25, np.nan])
    with pytest.raises(KeyError, match="no field 'pointing_error'"):
        tm.housekeeping.column("pointing_error")


def test_a_report_with_a_counted_list_is_refused_naming_the_field() -> None:
    """A report kind whose field has no fixed number of numbers cannot be held as columns: the error names it."""
    for kind in DICTIONARY.packets:
        if kind.KIND != "TM":
            continue
        try:
            ReportColumns(kind)
        except TypeError as exc:
            assert str(exc).startswith(f"{kind.__name__}.") and "no fixed number of columns" in str(exc)
            return
    pytest.fail("every report of the dictionary has fixed-width fields: this test needs one that has not")
