"""The step record: what is written reads back the same (frames by reference as the digest of their pixels and the
truth they were rendered with, raw frames as their pixels), a file cut short reads up to its last complete step,
and a record of format 1 still reads."""

from __future__ import annotations

import gzip
import hashlib
import json
import math
import struct
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from contracts import pus
from contracts.messages import CentroidMeasurement, FrameMeta, FrameRequest, SensorData, StepReply, StepRequest
from contracts.messages import encode
from contracts.steplog import (
    FrameTruth,
    StepLog,
    StepLogError,
    StepLogWriter,
    frame_digest,
    frame_from_planes,
    frame_planes,
)

Step = tuple[StepRequest, bytes, StepReply, FrameTruth | None]


def _steps(n: int, every_frame: int = 3) -> list[Step]:
    rng = np.random.default_rng(5)
    out = []
    for k in range(n):
        meta, blob, truth = None, b"", None
        if k % every_frame == 2:  # centroid-level fidelity: a measurement, no pixels
            m = CentroidMeasurement(dimorphos_col_row=(500.25, 511.5), dimorphos_area_px=30.0, didymos_col_row=None,
                                    didymos_area_px=0.0)
            meta = FrameMeta(frame_id=k, obt_s=100.0 + 0.1 * k, width=1024, height=1024, bit_depth=12,
                             exposure_s=0.01, measurement=m)
        if k % every_frame == 1:
            px = rng.integers(0, 4096, size=(16, 24), dtype=np.uint16)
            meta = FrameMeta(frame_id=k, obt_s=100.0 + 0.1 * k, width=24, height=16, bit_depth=12, exposure_s=0.01)
            blob = px.astype("<u2").tobytes()
            truth = FrameTruth(t_s=0.1 * k - 1e-17, q=(0.5, -0.5, 0.5, 0.5), omega_rad_s=(1e-3 * k, math.pi, -0.0))
        req = StepRequest(step=k, obt_s=100.0 + 0.1 * k, frame=meta,
                          uplink=(pus.encode_tc(pus.Ping(), 0x0C1, k),) if k == 2 else (),
                          sensors=SensorData(star_tracker_q=None if k == 4 else (0.0, 0.0, 0.1 * k, 1.0),
                                             gyro_rad_s=(1e-3 * k, -2e-17, 3.0), wheel_speed_rad_s=(1.0, 2.0, k / 3)))
        rep = StepReply(step=k, wheel_torque_nm=(1e-4 / (k + 1), -0.0, 7e-3),
                        frame_request=FrameRequest(exposure_s=0.01) if k % 2 else None,
                        downlink=(pus.encode_tm(pus.TimeReport(obt_s=req.obt_s), 0x0C1, k, req.obt_s, k),))
        out.append((req, blob, rep, truth))
    return out


@pytest.mark.parametrize("threaded", [True, False])
@pytest.mark.parametrize("frames", ["reference", "raw"])
def test_round_trip(tmp_path: Path, threaded: bool, frames: str) -> None:
    """Every request and reply reads back equal to what was written, in order, with the header; a frame with pixels
    reads back as its pixels (raw) or as the BLAKE2b-64 of its pixels and its truth, exactly (by reference); a frame
    without pixels (a centroid-level measurement) reads back as its metadata alone."""
    steps = _steps(20)
    path = tmp_path / "r.rec"
    with StepLogWriter(path, {"obsw": {"apid": 193}, "scenario": {"name": "s"}}, threaded=threaded,
                       frames=frames) as w:  # type: ignore[arg-type]
        for req, blob, rep, truth in steps:
            w.step(req, blob, rep, truth)
    log = StepLog(path)
    assert log.header == {"format": 2, "frames": frames, "obsw": {"apid": 193}, "scenario": {"name": "s"}}
    got = list(log.steps())
    assert not log.truncated and len(got) == len(steps)
    for rec, (req, blob, rep, truth) in zip(got, steps, strict=True):
        assert rec.request == req and rec.reply == rep
        if blob and frames == "raw":
            assert rec.frame is not None and rec.frame.dtype == np.uint16
            assert rec.frame.tobytes() == np.frombuffer(blob, dtype="<u2").tobytes()
            assert rec.frame_digest is None and rec.frame_truth is None
        elif blob:
            assert rec.frame is None and rec.frame_truth == truth
            assert rec.frame_digest == hashlib.blake2b(blob, digest_size=8).digest()
        else:
            assert rec.frame is None and rec.frame_digest is None and rec.frame_truth is None


def test_frames_by_reference_keep_no_pixels(tmp_path: Path) -> None:
    """By reference a frame costs its digest and truth, 8 + 64 octets and their record heads, whatever its size:
    the record of 1024x1024 frames is about as large as their messages, a hundredth of the pixels kept raw."""
    rng = np.random.default_rng(1)
    sizes = {}
    for frames in ("reference", "raw"):
        path = tmp_path / f"{frames}.rec"
        messages = 0
        with StepLogWriter(path, {"obsw": {}}, threaded=False, frames=frames) as w:  # type: ignore[arg-type]
            for k in range(6):
                px = rng.integers(0, 4096, size=(1024, 1024), dtype=np.uint16)
                req = StepRequest(step=k, obt_s=float(k), sensors=SensorData(star_tracker_q=None, gyro_rad_s=(0, 0, 0),
                                                                             wheel_speed_rad_s=(0, 0, 0)),
                                  frame=FrameMeta(frame_id=k, obt_s=float(k), width=1024, height=1024, bit_depth=12,
                                                  exposure_s=0.01))
                rep = StepReply(step=k, wheel_torque_nm=(0.0, 0.0, 0.0))
                messages += len(encode(req)) + len(encode(rep))
                w.step(req, px.astype("<u2").tobytes(), rep, FrameTruth(float(k), (0, 0, 0, 1.0), (0, 0, 0)))
        sizes[frames] = path.stat().st_size
    # uncompressed: the messages, 8 + 64 octets a frame, a 5-octet head a record, the header, the gzip container
    assert sizes["reference"] <= messages + 6 * (8 + 64 + 4 * 5) + 200
    assert sizes["reference"] < sizes["raw"] / 100


def _format1(path: Path, steps: list[Step]) -> None:
    """A record as format 1 wrote it, built from the format's description: the header, then per step Q, F (the
    pixels as byte planes, for frames with pixels) and R."""
    def rec(kind: bytes, payload: bytes) -> bytes:
        return struct.pack(">cI", kind, len(payload)) + payload

    data = rec(b"H", json.dumps({"format": 1, "obsw": {}, "scenario": "s", "seed": 3}).encode())
    for req, blob, rep, _ in steps:
        low_high = np.frombuffer(blob, dtype="<u2")
        planes = (low_high & 0xFF).astype(np.uint8).tobytes() + (low_high >> 8).astype(np.uint8).tobytes()
        data += rec(b"Q", encode(req)) + (rec(b"F", planes) if blob else b"") + rec(b"R", encode(rep))
    path.write_bytes(gzip.compress(data))


def test_format_1_still_reads(tmp_path: Path) -> None:
    """A record of format 1 (every frame's pixels) reads as one keeping frames raw: the same requests, pixels and
    replies."""
    steps = _steps(9)
    _format1(tmp_path / "old.rec", steps)
    log = StepLog(tmp_path / "old.rec")
    assert log.header["frames"] == "raw" and log.header["format"] == 1
    got = list(log.steps())
    assert [g.request for g in got] == [s[0] for s in steps] and [g.reply for g in got] == [s[2] for s in steps]
    for g, (_, blob, _, _) in zip(got, steps, strict=True):
        assert (g.frame is None) == (not blob)
        assert g.frame is None or g.frame.astype("<u2").tobytes() == blob


@settings(max_examples=50, deadline=None)
@given(st.floats(allow_nan=False), st.lists(st.floats(allow_nan=False), min_size=7, max_size=7))
def test_frame_truth_reads_back_exactly(t_s: float, v: list[float]) -> None:
    """The truth of a frame reads back bit for bit (the frame is rendered from these very numbers), from numpy
    values as from floats."""
    truth = FrameTruth.of(np.float64(t_s), np.array(v[:4]), np.array(v[4:]))
    back = FrameTruth.unpack(truth.pack())
    assert back == truth and isinstance(back.q[0], float)
    assert struct.pack(">8d", t_s, *v) == truth.pack()


def test_digest_is_blake2b_64() -> None:
    """A frame's digest is BLAKE2b with an 8-octet output (RFC 7693), over the pixels as they travel."""
    blob = np.arange(12, dtype="<u2").tobytes()
    assert frame_digest(blob) == hashlib.new("blake2b", blob, digest_size=8).digest() and len(frame_digest(blob)) == 8


def test_cut_file_reads_complete_steps(tmp_path: Path) -> None:
    """A record cut inside its stream yields the steps before the cut (the last perhaps without its reply) and says
    it was truncated."""
    steps = _steps(30)
    path = tmp_path / "r.rec"
    with StepLogWriter(path, {"obsw": {}}, threaded=False, frames="raw") as w:
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
    (tmp_path / "future.rec").write_bytes(gzip.compress(struct.pack(">cI", b"H", 13) + b'{"format": 3}'))
    with pytest.raises(StepLogError, match="format 3, this build reads formats 1, 2"):
        StepLog(tmp_path / "future.rec")


def test_bad_frame_records_are_named(tmp_path: Path) -> None:
    """A digest of the wrong length names the frame; a truth record of the wrong length says so."""
    (req, blob, rep, _), = [s for s in _steps(3) if s[1]]
    for kind, payload, message in [(b"D", b"1234", "frame 1: a digest of 4 octets, expected 8"),
                                   (b"T", b"\0" * 63, "a truth record of 63 octets, expected 64")]:
        path = tmp_path / f"{kind.decode()}.rec"
        body = b"".join(struct.pack(">cI", k, len(p)) + p for k, p in [
            (b"H", b'{"format": 2}'), (b"Q", encode(req)), (kind, payload), (b"R", encode(rep))])
        path.write_bytes(gzip.compress(body))
        with pytest.raises(StepLogError, match=message):
            list(StepLog(path).steps())


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
    with pytest.raises(ValueError, match="frames: 'pixels'"):
        StepLogWriter(tmp_path / "r.rec", {}, frames="pixels")  # type: ignore[arg-type]
    assert w.error is not None and "no-such-dir" in w.error
