"""The truth as the analysis reads it: what ground's TruthLog wrote comes back record for record, and as arrays."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from analysis.truth import Truth, load_truth, read_truth_records
from contracts.messages import TruthRecord
from ground.node import TruthLog
from tests.contracts.test_truthtable import records


@settings(max_examples=30, deadline=None)
@given(data=st.data(), wheels=st.integers(1, 4))
def test_truth_log_reads_back_every_record(tmp_path_factory, data: st.DataObject, wheels: int) -> None:
    """Records written by ground's TruthLog are read back equal by the analysis, every field included."""
    recs = data.draw(st.lists(records(wheels), min_size=1, max_size=5))
    path = tmp_path_factory.mktemp("truth") / "truth.csv"
    log = TruthLog(path)
    for r in recs:
        log.add(r)
    log.close()
    assert read_truth_records(path) == (recs, 0, "")


def record(t: float, frame: int | None) -> TruthRecord:
    """A plain record at time t, with or without a frame."""
    return TruthRecord(t_s=t, obt_s=t + 10.0, q=(0.0, 0.0, 0.0, 1.0), omega_rad_s=(0.1, 0.2, 0.2),
                       wheel_momentum_nms=(1.0, 2.0), wheel_torque_nm=(0.5, -0.5), pointing_error_rad=0.01,
                       target_in_fov=frame is not None, range_m=1000.0 - t, theta_rad=0.5, phase_angle_deg=40.0,
                       frame_id=frame, dimorphos_px=None if frame is None else (10.0 + t, 20.0))


def test_arrays_hold_the_records_with_nan_for_none() -> None:
    """Truth.from_records: one row per record, NaN (frame -1) where a field is None."""
    truth = Truth.from_records([record(0.0, None), record(1.0, 4)])
    assert len(truth) == 2
    assert truth.frame_id.tolist() == [-1, 4]
    assert truth.target_in_fov.tolist() == [False, True]
    assert np.isnan(truth.dimorphos_px[0]).all() and truth.dimorphos_px[1].tolist() == [11.0, 20.0]
    assert np.linalg.norm(truth.omega_rad_s, axis=1) == pytest.approx([0.3, 0.3])
    assert truth.wheel_torque_nm.tolist() == [[0.5, -0.5], [0.5, -0.5]]
    assert math.isnan(truth.range_didymos_m[0])


@settings(max_examples=40, deadline=None)
@given(data=st.data(), wheels=st.integers(1, 4))
def test_each_row_is_its_record(data: st.DataObject, wheels: int) -> None:
    """Row i of every array is record i's field, as a plain per-record reading gives it: NaN where a field is None,
    -1 for no frame, the shapes (N, width) even for no record."""
    recs = data.draw(st.lists(records(wheels), min_size=0, max_size=6))
    truth = Truth.from_records(recs)
    widths = {"omega_rad_s": 3, "los_dimorphos_inertial": 3, "dimorphos_px": 2, "didymos_px": 2,
              "wheel_momentum_nms": wheels if recs else 0, "wheel_torque_nm": wheels if recs else 0}
    for name, width in widths.items():
        want = np.array([[math.nan] * width if getattr(r, name) is None else list(getattr(r, name)) for r in recs],
                        dtype=float).reshape(len(recs), width)
        assert np.array_equal(getattr(truth, name), want, equal_nan=True), name
    for name in ("t_s", "obt_s", "pointing_error_rad", "theta_rad", "range_m", "range_didymos_m"):
        want = np.array([math.nan if getattr(r, name) is None else getattr(r, name) for r in recs], dtype=float)
        assert np.array_equal(getattr(truth, name), want, equal_nan=True), name
    assert truth.target_in_fov.tolist() == [r.target_in_fov for r in recs]
    assert truth.frame_id.tolist() == [-1 if r.frame_id is None else r.frame_id for r in recs]


def test_cut_and_bad_rows_are_skipped_and_counted(tmp_path: Path) -> None:
    """A row cut short and a row with a bad cell are skipped; the count and the first reason are kept."""
    path = tmp_path / "truth.csv"
    log = TruthLog(path)
    for i in range(3):
        log.add(record(float(i), i))
    log.close()
    lines = path.read_text().splitlines()
    lines[2] = lines[2].replace("0.01", "oops", 1)  # pointing_error_rad of the second record
    path.write_text("\n".join(lines) + "\n" + lines[3][:20] + "\n")
    truth = load_truth(path)
    assert len(truth) == 2 and truth.t_s.tolist() == [0.0, 2.0]
    assert truth.skipped_rows == 2
    assert truth.skip_reason == "line 3: pointing_error_rad: 'oops' is not a float"


@settings(max_examples=30, deadline=None)
@given(n=st.integers(1, 23), chunk=st.integers(1, 6), bad=st.sets(st.integers(0, 22), max_size=5),
       end=st.sampled_from(["\n", "\r\n", "\r"]), final=st.booleans())
def test_arrays_read_in_chunks_equal_the_arrays_of_every_record(tmp_path_factory, n: int, chunk: int,
                                                                 bad: set[int], end: str, final: bool) -> None:
    """load_truth reading a chunk at a time into arrays sized from the line count gives the arrays of all the
    file's records at once, skips counted, whatever the line ends and whether the last line has one."""
    import analysis.truth as truth_module

    path = tmp_path_factory.mktemp("truth") / "truth.csv"
    log = TruthLog(path)
    for i in range(n):
        log.add(record(float(i), i if i % 3 else None))
    log.close()
    lines = path.read_text().splitlines()
    for i in sorted(b for b in bad if b < n):
        lines[1 + i] = lines[1 + i][:15]  # a row cut short
    path.write_bytes((end.join(lines) + (end if final else "")).encode())
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(truth_module, "_CHUNK_ROWS", chunk)
        got = load_truth(path)
    records, skipped, reason = read_truth_records(path)
    want = Truth.from_records(records, skipped, reason)
    assert (got.skipped_rows, got.skip_reason) == (want.skipped_rows, want.skip_reason)
    for name in ("t_s", "obt_s", "omega_rad_s", "target_in_fov", "frame_id", "dimorphos_px", "wheel_torque_nm"):
        np.testing.assert_array_equal(getattr(got, name), getattr(want, name))
    assert len(got) == n - len({b for b in bad if b < n})
