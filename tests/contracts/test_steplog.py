"""The step record: what is written reads back the same, a file cut short reads up to its last complete step."""

from __future__ import annotations

import gzip
import struct
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from contracts import pus
from contracts.messages import CentroidMeasurement, FrameMeta, FrameRequest, SensorData, StepReply, StepRequest
from contracts.steplog import StepLog, StepLogError, StepLogWriter, frame_from_planes, frame_planes


def _steps(n: int, every_frame: int = 3) -> list[tuple[StepRequest, bytes, StepReply]]:
    rng = np.random.default_rng(5)
    out = []
    for k in range(n):
        meta, blob = None, b""
        if k % every_frame == 2:  # centroid-level fidelity: a measurement, no pixels
            m = CentroidMeasurement(dimorphos_col_row=(500.25, 511.5), dimorphos_area_px=30.0, didymos_col_row=None,
                                    didymos_area_px=0.0)
            meta = FrameMeta(frame_id=k, obt_s=100.0 + 0.1 * k, width=1024, height=1024, bit_depth=12,
                             exposure_s=0.01, measurement=m)
        if k % every_frame == 1:
            px = rng.integers(0, 4096, size=(16, 24), dtype=np.uint16)
            meta = FrameMeta(frame_id=k, obt_s=100.0 + 0.1 * k, width=24, height=16, bit_depth=12, exposure_s=0.01)
            blob = px.astype("<u2").tobytes()
        req = StepRequest(step=k, obt_s=100.0 + 0.1 * k, frame=meta,
                          uplink=(pus.encode_tc(pus.Ping(), 0x0C1, k),) if k == 2 else (),
                          sensors=SensorData(star_tracker_q=None if k == 4 else (0.0, 0.0, 0.1 * k, 1.0),
                                             gyro_rad_s=(1e-3 * k, -2e-17, 3.0), wheel_speed_rad_s=(1.0, 2.0, k / 3)))
        rep = StepReply(step=k, wheel_torque_nm=(1e-4 / (k + 1), -0.0, 7e-3),
                        frame_request=FrameRequest(exposure_s=0.01) if k % 2 else None,
                        downlink=(pus.encode_tm(pus.TimeReport(obt_s=req.obt_s), 0x0C1, k, req.obt_s, k),))
        out.append((req, blob, rep))
    return out


@pytest.mark.parametrize("threaded", [True, False])
def test_round_trip(tmp_path: Path, threaded: bool) -> None:
    """Every request, frame and reply reads back equal to what was written, in order, with the header; a frame
    without pixels (a centroid-level measurement) reads back as its metadata and no pixels."""
    steps = _steps(20)
    path = tmp_path / "r.rec"
    with StepLogWriter(path, {"obsw": {"apid": 193}, "scenario": "s"}, threaded=threaded) as w:
        for req, blob, rep in steps:
            w.step(req, blob, rep)
    log = StepLog(path)
    assert log.header == {"format": 1, "obsw": {"apid": 193}, "scenario": "s"}
    got = list(log.steps())
    assert not log.truncated and len(got) == len(steps)
    for rec, (req, blob, rep) in zip(got, steps, strict=True):
        assert rec.request == req and rec.reply == rep
        if blob:
            assert rec.frame is not None and rec.frame.dtype == np.uint16
            assert rec.frame.tobytes() == np.frombuffer(blob, dtype="<u2").tobytes()
        else:
            assert rec.frame is None


def test_cut_file_reads_complete_steps(tmp_path: Path) -> None:
    """A record cut inside its stream yields the steps before the cut (the last perhaps without its reply) and says
    it was truncated."""
    steps = _steps(30)
    path = tmp_path / "r.rec"
    with StepLogWriter(path, {"obsw": {}}, threaded=False) as w:
        for s in steps:
            w.step(*s)
    data = path.read_bytes()
    cut = tmp_path / "cut.rec"
    cut.write_bytes(data[: len(data) * 2 // 3])
    log = StepLog(cut)
    got = list(log.steps())
    assert log.truncated and 0 < len(got) < len(steps)
    complete = [g for g in got if g.reply is not None]
    assert all(g.request == s[0] and g.reply == s[2] for g, s in zip(complete, steps, strict=False))
    assert all(g.reply is None for g in got[len(complete):])


def test_bad_files_are_named(tmp_path: Path) -> None:
    """A missing file, a file that is not gzip and a gzip without the header record are refused naming the file."""
    with pytest.raises(StepLogError, match="no step record"):
        StepLog(tmp_path / "none.rec")
    (tmp_path / "text.rec").write_text("hello")
    with pytest.raises(StepLogError, match="text.rec"):
        StepLog(tmp_path / "text.rec")
    (tmp_path / "nohead.rec").write_bytes(gzip.compress(struct.pack(">cI", b"Q", 2) + b"{}"))
    with pytest.raises(StepLogError, match="no header"):
        StepLog(tmp_path / "nohead.rec")


@settings(max_examples=50, deadline=None)
@given(hnp.arrays(np.uint16, st.tuples(st.integers(1, 9), st.integers(1, 9))))
def test_byte_planes_invert(px: np.ndarray) -> None:
    """Byte planes hold every low octet then every high octet, and turn back into the same frame."""
    blob = px.astype("<u2").tobytes()
    planes = frame_planes(blob)
    n = px.size
    assert planes[:n] == bytes(int(v) & 0xFF for v in px.ravel())
    assert planes[n:] == bytes(int(v) >> 8 for v in px.ravel())
    assert np.array_equal(frame_from_planes(planes, *px.shape), px)


def test_unwritable_record_does_not_raise(tmp_path: Path) -> None:
    """A record that cannot be created is reported in ``error``; stepping and closing still work."""
    w = StepLogWriter(tmp_path / "no-such-dir" / "r.rec", {"obsw": {}}, threaded=True)
    for s in _steps(3):
        w.step(*s)
    w.close()
    assert w.error is not None and "no-such-dir" in w.error
