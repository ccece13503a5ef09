"""The record of the flight software's inputs and outputs, control period by control period (``flyby replay``).

One file per run, ``obsw_steps.rec``: a gzip stream (RFC 1952) of records ``[kind: 1 octet][length: u32 BE][payload]``:

- ``H`` once, first: a JSON object: ``format`` (this module's ``FORMAT``), ``obsw`` (the on-board configuration
  the recorded software ran with), and whatever else the recorder adds (``scenario``, ``seed``);
- ``Q``: a ``StepRequest`` exactly as on the bus (``contracts.messages.encode``: OBT, sensors, telecommands, frame
  metadata), without its blob;
- ``F``: the camera frame of the preceding request: its 16-bit little-endian pixels as two byte planes, every low
  octet then every high octet (the high plane of a 12-bit frame is nearly constant, so deflate packs the planes
  about 20 % smaller than interleaved pixels); absent for a frame without pixels (centroid-level fidelity: the
  request's frame metadata carries the measurement);
- ``R``: the ``StepReply`` to the preceding request, as on the bus (torques, frame request, telemetry packets).

A file cut short (a node killed mid-run) reads up to its last complete step. Writing compresses in a thread of its
own (``StepLogWriter(threaded=True)``), so a control loop only hands over references.
"""

from __future__ import annotations

import gzip
import json
import queue
import struct
import threading
import zlib
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from contracts.errors import DecodeError, FlybyError
from contracts.messages import StepReply, StepRequest, decode, encode

FORMAT = 1
STEP_RECORD = "obsw_steps.rec"
"""Name of the record in a run folder."""
_RECORD = struct.Struct(">cI")
_QUEUE_STEPS = 32  # steps waiting for the writer thread at most: ~64 MB of frames, then the loop waits
_COMPRESS_LEVEL = 1  # deflate level: 20 ms a 1024x1024 frame; level 6 packs 6 % smaller at 7x the time


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


def _record(kind: bytes, payload: bytes) -> bytes:
    return _RECORD.pack(kind, len(payload)) + payload


class StepLogWriter:
    """Writes a step record; ``step`` hands over one period, ``close`` finishes the file.

    A write that fails (a full disk) stops the recording, never the caller: ``error`` then says why.
    """

    def __init__(self, path: Path, header: dict[str, Any], threaded: bool = True) -> None:
        """``header``: JSON-able facts of the recording (``obsw``: the configuration, ``scenario``, ``seed``)."""
        self.path = Path(path)
        self.error: str | None = None
        self.steps = 0
        self._file: gzip.GzipFile | None = None
        try:
            self._file = gzip.GzipFile(self.path, "wb", compresslevel=_COMPRESS_LEVEL, mtime=0)
        except OSError as exc:
            self.error = f"{self.path}: not recording: {exc}"
        self._write(_record(b"H", json.dumps({"format": FORMAT, **header}).encode()))
        self._queue: queue.Queue[tuple[StepRequest, bytes, StepReply] | None] | None = None
        self._thread: threading.Thread | None = None
        if threaded:
            self._queue = queue.Queue(maxsize=_QUEUE_STEPS)
            self._thread = threading.Thread(target=self._drain, name="step-record", daemon=True)
            self._thread.start()

    def step(self, request: StepRequest, blob: bytes, reply: StepReply) -> None:
        """Record one control period: the request as the software got it, the frame's pixels, and its reply."""
        self.steps += 1
        if self._queue is not None:
            self._queue.put((request, blob, reply))
        else:
            self._write_step(request, blob, reply)

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

    def _write_step(self, request: StepRequest, blob: bytes, reply: StepReply) -> None:
        parts = [_record(b"Q", encode(request))]
        if request.frame is not None and blob:
            parts.append(_record(b"F", frame_planes(blob)))
        parts.append(_record(b"R", encode(reply)))
        self._write(b"".join(parts))

    def _write(self, data: bytes) -> None:
        if self.error is not None or self._file is None:
            return
        try:
            self._file.write(data)
        except OSError as exc:
            self.error = f"{self.path}: recording stopped after {self.steps} steps: {exc}"


@dataclass(frozen=True)
class RecordedStep:
    """One control period as recorded: the request, its frame (None without one) and the reply (None if the
    recording stopped before it)."""

    request: StepRequest
    frame: np.ndarray | None
    reply: StepReply | None


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
        if not isinstance(header, dict) or header.get("format") != FORMAT:
            raise StepLogError(f"{self.path}: format {header.get('format') if isinstance(header, dict) else '?'}, "
                               f"this build reads format {FORMAT}")
        self.header: dict[str, Any] = header

    def steps(self) -> Iterator[RecordedStep]:
        """The recorded periods in order."""
        pending: StepRequest | None = None
        frame: np.ndarray | None = None
        for kind, payload in self._records:
            try:
                if kind == b"Q":
                    if pending is not None:
                        yield RecordedStep(pending, frame, None)
                    pending, frame = decode(StepRequest, payload)[0], None
                elif kind == b"F":
                    meta = pending.frame if pending is not None else None
                    if meta is None:
                        raise StepLogError(f"{self.path}: a frame record follows no request with a frame")
                    frame = frame_from_planes(payload, meta.height, meta.width)
                elif kind == b"R":
                    if pending is None:
                        raise StepLogError(f"{self.path}: a reply record follows no request")
                    yield RecordedStep(pending, frame, decode(StepReply, payload)[0])
                    pending, frame = None, None
                else:
                    raise StepLogError(f"{self.path}: unknown record kind {kind!r}")
            except (DecodeError, ValueError) as exc:
                raise StepLogError(f"{self.path}: {exc}") from None
        if pending is not None:
            yield RecordedStep(pending, frame, None)

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
