"""The OBSW node: the flight software core on the bus, answering each universe step with actuator commands.

The node only moves messages: a ``StepRequest`` (with the camera frame in its blob) goes into
``FlightSoftware.step`` and the ``StepReply`` comes back out. A repeated step (the universe resent it because
our reply was lost) gets the same reply again, so the core never runs a period twice.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import zenoh

from contracts.bus import BusConfig, Keys
from contracts.clock import WallClock
from contracts.errors import NodeFailure
from contracts.hoptrace import WORK_END, WORK_START, HopTrace
from contracts.messages import StepReply, StepRequest
from contracts.runtime import Attachment
from contracts.steplog import FrameKeeping, StepLogWriter
from obsw import kernels
from obsw.software import FlightSoftware

log = logging.getLogger("obsw")



def frame_pixels(req: StepRequest, blob: bytes) -> np.ndarray | None:
    """The camera frame carried in the blob of ``req``, as a uint16 array, or None (no frame, or a centroid-level
    measurement instead of pixels)."""
    meta = req.frame
    if meta is None:
        return None
    if meta.measurement is not None:  # centroid-level fidelity: no pixels travel
        if blob:
            raise ValueError(f"StepRequest {req.step}: frame {meta.frame_id} carries a measurement and {len(blob)} "
                             "bytes of pixels")
        return None
    expected = meta.width * meta.height * 2
    if len(blob) != expected:
        raise ValueError(f"StepRequest {req.step}: frame {meta.frame_id} has {len(blob)} bytes, expected {expected}")
    return np.frombuffer(blob, dtype="<u2").reshape(meta.height, meta.width)


def run(bus: Attachment, fsw: FlightSoftware, bus_cfg: BusConfig, record: StepLogWriter | None = None) -> None:
    """Answer steps until the universe ends the run; ``record`` gets each period's request, frame and reply."""
    last: tuple[int, StepReply] | None = None
    last_status = -1.0
    clock = bus.clock
    wait = bus_cfg.startup_timeout_s + bus_cfg.reply_timeout_s
    while True:
        got = bus.receive(wait)
        if got is None:
            raise NodeFailure("universe", bus.sim_time_s, f"stopped sending steps (nothing for {wait:g} s)")
        wait = bus_cfg.reply_timeout_s
        req = got.msg
        if not isinstance(req, StepRequest):
            continue
        if last is not None and req.step == last[0]:
            bus.publish(bus.keys.reply, last[1])
            continue
        if last is not None and req.step < last[0]:
            continue  # a stale duplicate of an older step
        try:
            frame = frame_pixels(req, got.blob)
        except ValueError as exc:
            bus.decode_errors += 1
            log.warning("%s; frame dropped", exc)
            frame = None
            req = req.model_copy(update={"frame": None})
        bus.mark(WORK_START, req.step)
        reply = fsw.step(req, frame)
        bus.mark(WORK_END, req.step)
        if record is not None:
            record.step(req, got.blob if frame is not None else b"", reply, verdicts=fsw.security.take_verdicts())
        for line in fsw.take_log():
            log.info("%s", line)
        bus.sim_time_s = req.obt_s
        bus.publish(bus.keys.reply, reply)
        last = (req.step, reply)
        now = clock.now()
        if now - last_status >= 0.5:
            bus.status(req.obt_s, None, fsw.mode_name, text=f"OBT {req.obt_s:.1f} s")
            last_status = now


def main(conf: zenoh.Config, fsw: FlightSoftware, bus_cfg: BusConfig, run_id: str, record: Path | None = None,
         record_header: dict[str, object] | None = None, record_frames: FrameKeeping = "reference",
         trace: Path | None = None) -> int:
    """Run the OBSW node until the run ends or a peer fails; return the process exit code.

    ``record``: the file to record the software's inputs and outputs into (``contracts.steplog``), written by a
    thread of its own, camera frames kept by reference or raw (``record_frames``); ``record_header`` adds facts of
    the run to it (the configuration is always there). ``trace``: a file for the time marks of the lock-step
    (``contracts.hoptrace``).
    """
    keys = Keys(run_id)
    writer = None
    if record is not None:
        writer = StepLogWriter(record, {**(record_header or {}), "obsw": fsw.cfg.model_dump(mode="json")},
                               frames=record_frames)
        fsw.security.keep_verdicts = True
    wall = WallClock()
    t0 = wall.now()
    # compiled code: seconds on the first run after an install, paid before the universe's first step can wait on it
    kernels.warm_up()
    log.info("attitude filter, imaging, tracking and control kernels ready in %.1f s", wall.now() - t0)
    with zenoh.open(conf) as session:
        bus = Attachment(session, keys, "obsw", WallClock(), log,
                         trace=None if trace is None else HopTrace("obsw", trace))
        bus.subscribe(keys.step, StepRequest)
        bus.watch_peers()
        bus.declare_alive()
        try:
            return bus.guarded(lambda: run(bus, fsw, bus_cfg, writer))[0]
        finally:
            bus.close()
            if writer is not None:
                writer.close()
                if writer.error:
                    log.error("step record: %s", writer.error)
