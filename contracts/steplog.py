"""The record of the flight software's inputs and outputs, control period by control period (``flyby replay``).

One file per run, ``obsw_steps.rec``: a gzip stream (RFC 1952) of records ``[kind: 1 octet][length: u32 BE][payload]``:

- ``H`` once, first: a JSON object: ``format`` (this module's ``FORMAT``), ``frames`` (how camera frames are kept:
  ``reference`` or ``raw``), ``obsw`` (the on-board configuration the recorded software ran with), and whatever else
  the recorder adds (``scenario``: the run's scenario, which a replay by reference renders the frames from);
- ``Q``: a ``StepRequest`` exactly as on the bus (``contracts.messages.encode``: OBT, sensors, telecommands, frame
  metadata with the frame id that names ``frames/frame_NNNNN.png``), without its blob;
- ``D``: the camera frame of the preceding request by reference: the BLAKE2b-64 digest (RFC 7693, 8 octets) of its
  pixels as they travelled (16-bit little-endian, row-major). The replay renders the frame again from the scenario
  and the truth at its exposure, and checks it against this digest;
- ``T``: the truth at that frame's exposure, for a recorder that has it (a run in one process; a run over the bus
  has it in ``truth.csv``): true time, attitude quaternion and body rate, eight big-endian IEEE 754 doubles
  ``t_s, q_x, q_y, q_z, q_w, omega_x, omega_y, omega_z`` (rad/s), the exact numbers the universe rendered with;
- ``F``: the camera frame of the preceding request by value (``frames: raw``, and every frame of format 1): its
  16-bit little-endian pixels as two byte planes, every low octet then every high octet (the high plane of a 12-bit
  frame is nearly constant, so deflate packs the planes about 20 % smaller than interleaved pixels);
- ``A``: the outcomes of the telecommand authentication checks the software made in the period, in order, as JSON:
  ``{"tc": HEX}`` for a TC packet that passed, ``{"rejected": {code, why, spi, arsn, request_id}}`` for a refusal.
  The keys are not kept (not in the run folder, by design), so a replay without them takes these outcomes;
- ``R``: the ``StepReply`` to the preceding request, as on the bus (torques, frame request, telemetry packets).

A frame without pixels (centroid-level fidelity: the request's frame metadata carries the measurement) has neither
``D`` nor ``F``. A file cut short (a node killed mid-run) reads up to its last complete step. Writing compresses in
a thread of its own (``StepLogWriter(threaded=True)``), so a control loop only hands over references.
"""

from __future__ import annotations

import gzip
import hashlib
import json
import queue
import struct
import threading
import zlib
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np

from contracts.errors import DecodeError, FlybyError
from contracts.messages import StepReply, StepRequest, decode, encode
from contracts.packet_errors import FailureCode, RequestId
from contracts.sdls import SecurityRejection

FORMAT = 2
READABLE_FORMATS = (1, 2)
"""Formats this build reads: 1 kept every frame's pixels (``F``); 2 adds frames by reference (``D``, ``T``)."""
STEP_RECORD = "obsw_steps.rec"
"""Name of the record in a run folder."""
FrameKeeping = Literal["reference", "raw"]
FRAME_KEEPING: tuple[FrameKeeping, ...] = ("reference", "raw")
"""How a record keeps camera frames: by reference (a digest; the replay renders them again) or raw (the pixels)."""
_RECORD = struct.Struct(">cI")
_TRUTH = struct.Struct(">8d")
_DIGEST_OCTETS = 8  # BLAKE2b-64: a changed frame among a run's few hundred goes unnoticed with probability 2^-64
_QUEUE_STEPS = 32  # steps waiting for the writer thread at most: ~64 MB of raw frames, then the loop waits
# deflate level: raw, 20 ms a 1024x1024 frame (level 6 packs 6 % smaller at 7x the time); by reference the stream
# is messages only, which level 9 packs 12 % smaller than level 1 for 0.2 s of processor time a nominal flyby
_COMPRESS_LEVEL: dict[FrameKeeping, int] = {"raw": 1, "reference": 9}


class StepLogError(FlybyError):
    """A step record cannot be read; the message names the file and what was wrong."""


def frame_planes(blob: bytes) -> bytes:
    """The little-endian 16-bit pixels of ``blob`` as byte planes: every low octet, then every high octet."""
    return np.frombuffer(blob, dtype=np.uint8).reshape(-1, 2).T.tobytes()


def frame_from_planes(planes: bytes, height: int, width: int) -> np.ndarray:
    """The uint16 frame (height x width) whose byte planes are ``planes``."""
    if len(planes) != 2 * height * width:
        raise ValueError(f"{len(planes)} octets of byte planes for a {width}x{height} frame, expected "
                         f"{2 * height * width}")
    b = np.frombuffer(planes, dtype=np.uint8).reshape(2, -1)
    return (b[0].astype(np.uint16) | (b[1].astype(np.uint16) << 8)).reshape(height, width)


def frame_digest(blob: bytes) -> bytes:
    """The BLAKE2b-64 digest of a frame's pixels as they travel (16-bit little-endian, row-major)."""
    return hashlib.blake2b(blob, digest_size=_DIGEST_OCTETS).digest()


@dataclass(frozen=True)
class FrameTruth:
    """The truth a frame was rendered with: true time (s), attitude quaternion body -> inertial (x, y, z, w) and
    body rate (rad/s, body axes) at its exposure."""

    t_s: float
    q: tuple[float, float, float, float]
    omega_rad_s: tuple[float, float, float]

    @classmethod
    def of(cls, t_s: float, q: Sequence[float], omega_rad_s: Sequence[float]) -> FrameTruth:
        """The truth of numbers as the universe holds them (numpy arrays), as exact Python floats."""
        if len(q) != 4 or len(omega_rad_s) != 3:
            raise ValueError(f"a quaternion of {len(q)} and a rate of {len(omega_rad_s)} components, expected 4 and 3")
        return cls(t_s=float(t_s), q=(float(q[0]), float(q[1]), float(q[2]), float(q[3])),
                   omega_rad_s=(float(omega_rad_s[0]), float(omega_rad_s[1]), float(omega_rad_s[2])))

    def pack(self) -> bytes:
        """The ``T`` record payload: eight big-endian doubles."""
        return _TRUTH.pack(self.t_s, *self.q, *self.omega_rad_s)

    @classmethod
    def unpack(cls, payload: bytes) -> FrameTruth:
        """The truth of a ``T`` record payload; ValueError if it is not eight doubles."""
        if len(payload) != _TRUTH.size:
            raise ValueError(f"a truth record of {len(payload)} octets, expected {_TRUTH.size}")
        v = _TRUTH.unpack(payload)
        return cls(t_s=v[0], q=(v[1], v[2], v[3], v[4]), omega_rad_s=(v[5], v[6], v[7]))


def _record(kind: bytes, payload: bytes) -> bytes:
    return _RECORD.pack(kind, len(payload)) + payload


_Step = tuple[StepRequest, bytes, StepReply, FrameTruth | None]


class StepLogWriter:
    """Writes a step record; ``step`` hands over one period, ``close`` finishes the file.

    A write that fails (a full disk) stops the recording, never the caller: ``error`` then says why.
    """

    def __init__(self, path: Path, header: dict[str, Any], threaded: bool = True,
                 frames: FrameKeeping = "reference") -> None:
        """``header``: JSON-able facts of the recording (``obsw``: the configuration; ``scenario``: the run's
        scenario, which a replay by reference needs); ``frames``: keep camera frames by reference or raw."""
        if frames not in FRAME_KEEPING:
            raise ValueError(f"frames: {frames!r}, expected one of {', '.join(FRAME_KEEPING)}")
        self.path = Path(path)
        self.frames = frames
        self.error: str | None = None
        self.steps = 0
        self._file: gzip.GzipFile | None = None
        try:
            self._file = gzip.GzipFile(self.path, "wb", compresslevel=_COMPRESS_LEVEL[frames], mtime=0)
        except OSError as exc:
            self.error = f"{self.path}: not recording: {exc}"
        self._write(_record(b"H", json.dumps({"format": FORMAT, "frames": frames, **header}).encode()))
        self._queue: queue.Queue[_Step | None] | None = None
        self._thread: threading.Thread | None = None
        if threaded:
            self._queue = queue.Queue(maxsize=_QUEUE_STEPS)
            self._thread = threading.Thread(target=self._drain, name="step-record", daemon=True)
            self._thread.start()

    def step(self, request: StepRequest, blob: bytes, reply: StepReply, truth: FrameTruth | None = None,
             verdicts: Sequence[bytes | SecurityRejection] = ()) -> None:
        """Record one control period: the request as the software got it, the frame's pixels (kept by reference or
        raw), its reply, the truth the frame was rendered with if the recorder knows it (kept by reference), and the
        outcomes of the telecommand authentication checks made in the period (a replay without the keys uses them)."""
        self.steps += 1
        if self._queue is not None:
            self._queue.put((request, blob, reply, truth, tuple(verdicts)))
        else:
            self._write_step(request, blob, reply, truth, tuple(verdicts))

    def close(self) -> None:
        """Write what is waiting and finish the gzip stream."""
        if self._queue is not None and self._thread is not None:
            self._queue.put(None)
            self._thread.join()
            self._queue = None
        if self._file is not None:
            try:
                self._file.close()
            except OSError as exc:
                self.error = self.error or f"{self.path}: {exc}"
            self._file = None

    def __enter__(self) -> StepLogWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _drain(self) -> None:
        assert self._queue is not None
        while (item := self._queue.get()) is not None:
            self._write_step(*item)

    def _write_step(self, request: StepRequest, blob: bytes, reply: StepReply, truth: FrameTruth | None,
                    verdicts: tuple[bytes | SecurityRejection, ...] = ()) -> None:
        parts = [_record(b"Q", encode(request))]
        if verdicts:
            parts.append(_record(b"A", json.dumps([verdict_json(v) for v in verdicts]).encode()))
        if request.frame is not None and blob:
            if self.frames == "raw":
                parts.append(_record(b"F", frame_planes(blob)))
            else:
                parts.append(_record(b"D", frame_digest(blob)))
                if truth is not None:
                    parts.append(_record(b"T", truth.pack()))
        parts.append(_record(b"R", encode(reply)))
        self._write(b"".join(parts))

    def _write(self, data: bytes) -> None:
        if self.error is not None or self._file is None:
            return
        try:
            self._file.write(data)
        except OSError as exc:
            self.error = f"{self.path}: recording stopped after {self.steps} steps: {exc}"


def verdict_json(v: bytes | SecurityRejection) -> dict[str, Any]:
    """One authentication outcome as JSON: the TC packet that passed, or the rejection's fields."""
    if isinstance(v, bytes):
        return {"tc": v.hex()}
    rid = None if v.request_id is None else [v.request_id.apid, v.request_id.seq_count]
    return {"rejected": {"code": int(v.failure_code), "why": v.why, "spi": v.spi, "arsn": v.arsn, "request_id": rid}}


def verdict_from_json(d: dict[str, Any]) -> bytes | SecurityRejection:
    """The authentication outcome ``verdict_json`` wrote; ValueError if it is not one."""
    if "tc" in d:
        return bytes.fromhex(d["tc"])
    r = d["rejected"]
    rid = None if r["request_id"] is None else RequestId(apid=r["request_id"][0], seq_count=r["request_id"][1])
    return SecurityRejection(FailureCode(r["code"]), r["why"], r["spi"], r["arsn"], rid)


@dataclass(frozen=True)
class RecordedStep:
    """One control period as recorded: the request, its frame's pixels (None without a raw frame), its frame's
    digest and truth (kept by reference; None otherwise, the truth also when the recorder did not have it) and the
    reply (None if the recording stopped before it)."""

    request: StepRequest
    frame: np.ndarray | None = None
    reply: StepReply | None = None
    frame_digest: bytes | None = None
    verdicts: tuple[bytes | SecurityRejection, ...] = ()  # the authentication outcomes of the period, in order
    frame_truth: FrameTruth | None = None


class StepLog:
    """A step record opened for reading: ``header``, then ``steps()`` in order; ``truncated`` says whether the
    file ended inside a record (read once ``steps()`` is exhausted)."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        if not self.path.is_file():
            raise StepLogError(f"{self.path}: no step record (the flight software's inputs and outputs); a run "
                               "records one since the replay was added")
        self.truncated = False
        self._records = self._read_records()
        first = next(self._records, None)
        if first is None or first[0] != b"H":
            raise StepLogError(f"{self.path}: not a step record (no header record)")
        try:
            header = json.loads(first[1])
        except ValueError as exc:
            raise StepLogError(f"{self.path}: header record is not JSON: {exc}") from None
        if not isinstance(header, dict) or header.get("format") not in READABLE_FORMATS:
            raise StepLogError(f"{self.path}: format {header.get('format') if isinstance(header, dict) else '?'}, "
                               f"this build reads formats {', '.join(map(str, READABLE_FORMATS))}")
        header.setdefault("frames", "raw")  # format 1 kept every frame's pixels
        self.header: dict[str, Any] = header

    def steps(self) -> Iterator[RecordedStep]:
        """The recorded periods in order."""
        pending: StepRequest | None = None
        frame: dict[str, Any] = {}
        for kind, payload in self._records:
            try:
                if kind == b"Q":
                    if pending is not None:
                        yield RecordedStep(pending, reply=None, **frame)
                    pending, frame = decode(StepRequest, payload)[0], {}
                elif kind == b"A":
                    if pending is None:
                        raise StepLogError(f"{self.path}: an authentication record follows no request")
                    frame["verdicts"] = tuple(verdict_from_json(v) for v in json.loads(payload))
                elif kind in (b"F", b"D", b"T"):
                    meta = pending.frame if pending is not None else None
                    if meta is None:
                        raise StepLogError(f"{self.path}: a frame record follows no request with a frame")
                    if kind == b"F":
                        frame["frame"] = frame_from_planes(payload, meta.height, meta.width)
                    elif kind == b"D":
                        if len(payload) != _DIGEST_OCTETS:
                            raise ValueError(f"frame {meta.frame_id}: a digest of {len(payload)} octets, expected "
                                             f"{_DIGEST_OCTETS}")
                        frame["frame_digest"] = payload
                    else:
                        frame["frame_truth"] = FrameTruth.unpack(payload)
                elif kind == b"R":
                    if pending is None:
                        raise StepLogError(f"{self.path}: a reply record follows no request")
                    yield RecordedStep(pending, reply=decode(StepReply, payload)[0], **frame)
                    pending, frame = None, {}
                else:
                    raise StepLogError(f"{self.path}: unknown record kind {kind!r}")
            except (DecodeError, ValueError) as exc:
                raise StepLogError(f"{self.path}: {exc}") from None
        if pending is not None:
            yield RecordedStep(pending, reply=None, **frame)

    def _read_records(self) -> Iterator[tuple[bytes, bytes]]:
        buf = bytearray()
        for chunk in self._inflated():
            buf += chunk
            pos = 0
            while len(buf) - pos >= _RECORD.size:
                kind, n = _RECORD.unpack_from(buf, pos)
                if len(buf) - pos - _RECORD.size < n:
                    break
                yield kind, bytes(buf[pos + _RECORD.size: pos + _RECORD.size + n])
                pos += _RECORD.size + n
            del buf[:pos]
        if buf:
            self.truncated = True

    def _inflated(self) -> Iterator[bytes]:
        """The decompressed stream in chunks; a stream cut short just ends (``truncated`` is set)."""
        inflater = zlib.decompressobj(wbits=31)  # gzip container
        try:
            with open(self.path, "rb") as f:
                while chunk := f.read(1 << 20):
                    yield inflater.decompress(chunk)
                    while inflater.eof and inflater.unused_data:  # concatenated gzip members
                        rest = inflater.unused_data
                        inflater = zlib.decompressobj(wbits=31)
                        yield inflater.decompress(rest)
        except zlib.error as exc:
            raise StepLogError(f"{self.path}: not a gzip stream: {exc}") from None
        if not inflater.eof:
            self.truncated = True
