"""The universe node: the simulator core on the bus. It owns true time and drives the lock-step.

Each control period it publishes a ``StepRequest`` to the OBSW and waits for the ``StepReply``; every ground
period it publishes a ``GroundStep`` to ground and waits for the ``GroundReply``. With ``realtime`` it also
waits for the wall clock, for hardware in the loop.
"""

from __future__ import annotations

import logging
import queue
import threading
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
import zenoh

from contracts.bus import BusConfig, Keys
from contracts.clock import Clock, WallClock
from contracts.hoptrace import WORK_END, WORK_START, HopTrace
from contracts.messages import GroundReply, StepReply
from contracts.runtime import Attachment
from contracts.shared_blobs import run_folder
from universe import kernels
from universe.camera import display_png8
from universe.simulator import Universe

log = logging.getLogger("universe")
_FRAMES_QUEUED = 8  # frames waiting for their PNG at most (16 MB): the loop waits rather than hold more



class FrameWriter:
    """Writes the frames the camera took as 8-bit 512x512 PNGs, for the report and for people to look at, in a
    thread of its own: the stretch, resampling and compression stay off the control loop (OpenCV and numpy release
    the interpreter while they work). A write that fails (a full disk) stops the PNGs, never the run: ``error``
    then says why."""

    def __init__(self, folder: Path, every: int, bit_depth: int) -> None:
        self.folder, self.every, self.bit_depth = folder, every, bit_depth
        self.error: str | None = None
        self._last = -1
        self._queue: queue.Queue[tuple[int, np.ndarray] | None] = queue.Queue(maxsize=_FRAMES_QUEUED)
        self._thread: threading.Thread | None = None
        if every:
            folder.mkdir(parents=True, exist_ok=True)
            self._thread = threading.Thread(target=self._drain, name="frame-png", daemon=True)
            self._thread.start()

    def maybe_write(self, sim: Universe) -> None:
        """Queue the latest frame if it is new and one of every n-th (waits while the queue is full)."""
        fid = sim.frame_count - 1
        if not self.every or sim.last_frame is None or fid == self._last:
            return
        self._last = fid
        if fid % self.every or self.error is not None:
            return
        self._queue.put((fid, sim.last_frame))  # the universe makes a new array for every frame: no copy

    def close(self) -> None:
        """Write what is queued and stop the thread."""
        if self._thread is not None:
            self._queue.put(None)
            self._thread.join()
            self._thread = None

    def _drain(self) -> None:
        while (item := self._queue.get()) is not None:
            if self.error is not None:
                continue
            fid, frame = item
            path = self.folder / f"frame_{fid:05d}.png"
            try:
                img = display_png8(frame, self.bit_depth, 512)
                if not cv2.imwrite(str(path), img):
                    raise OSError("OpenCV could not write it")
            except (OSError, cv2.error) as exc:
                self.error = f"{path}: {exc}; no more frame PNGs"
                log.error("%s", self.error)


def run(bus: Attachment, sim: Universe, bus_cfg: BusConfig, realtime: bool, clock: Clock,
        frames: FrameWriter | None = None) -> None:
    """Drive the simulation to its end over the bus."""
    timeout = bus_cfg.reply_timeout_s
    bus.wait_for_peers(["obsw", "ground"], bus_cfg.startup_timeout_s)
    log.info("peers up; running from t=%.1f s to %.1f s", sim.t_s, sim.cfg.end_s)
    wall0, sim0 = clock.now(), sim.t_s
    last_status = -1.0
    request, blob = sim.begin()
    while True:
        bus.sim_time_s = sim.t_s
        if realtime:
            clock.sleep_until(wall0 + (sim.t_s - sim0))
        pending = [bus.ask(bus.keys.step, request, blob, StepReply, "obsw")]
        # ground's step runs while the flight software steps: the request is built already, so the telecommands
        # ground radiates now reach a later one, whichever answers first (the in-process order, the same results)
        if sim.ground_due():
            pending.append(bus.ask(bus.keys.ground_step, sim.ground_step(), b"", GroundReply, "ground"))
        reply, *ground = bus.collect(pending, timeout)
        if ground:
            sim.accept_ground(ground[0].msg)  # type: ignore[arg-type]
        for line in sim.take_log():
            log.info("%s", line)
        bus.mark(WORK_START, request.step)
        nxt = sim.advance(reply.msg)  # type: ignore[arg-type]
        bus.mark(WORK_END, request.step)
        if frames is not None:
            frames.maybe_write(sim)
        now = clock.now()
        if now - last_status >= 0.5 or nxt is None:
            rtf = (sim.t_s - sim0) / max(now - wall0, 1e-9)
            bus.status(sim.t_s, rtf, None, text=f"step {sim.step}")
            last_status = now
        if nxt is None:
            break
        request, blob = nxt
    for line in sim.faults.still_active(sim.t_s):
        log.info("%s", line)
    # hand ground the last truth, and the telemetry still travelling down, before stopping
    while (gs := sim.drain()) is not None:
        bus.sim_time_s = sim.t_s
        bus.exchange(bus.keys.ground_step, gs, b"", GroundReply, "ground", timeout)
    for line in sim.take_log():
        log.warning("%s", line)


def main(conf: zenoh.Config, build: Callable[[], Universe], bus_cfg: BusConfig, run_id: str, out: Path,
         realtime: bool = False, shared_memory: bool = False, trace: Path | None = None) -> int:
    """Run the universe node until the scenario ends or a peer fails; return the process exit code.

    ``build`` makes the simulator inside the node's failure handling, so a geometry it refuses is announced to
    the other nodes like any error. ``shared_memory``: camera frames go to the OBSW through shared memory
    (``contracts.shared_blobs``: the OBSW must run on this host). ``trace``: a file for the time marks of the
    lock-step (``contracts.hoptrace``).
    """
    keys = Keys(run_id)
    with zenoh.open(conf) as session:
        bus = Attachment(session, keys, "universe", WallClock(), log, share_blobs=shared_memory,
                         trace=None if trace is None else HopTrace("universe", trace))
        if shared_memory:
            log.info("camera frames go to the OBSW through shared memory (%s)", run_folder(run_id))
        bus.subscribe(keys.reply, StepReply)
        bus.subscribe(keys.ground_reply, GroundReply)
        bus.watch_peers()
        bus.declare_alive()
        made: list[Universe] = []

        def body() -> None:  # building the simulator is inside: a bad geometry is reported like any error
            made.append(build())
            wall = WallClock()
            t0 = wall.now()
            cfg = made[0].cfg
            # compiled code: seconds on the first run after an install, before any frame is due (no camera at
            # centroid level: nothing is rendered)
            kernels.warm_up(camera=cfg.fidelity == "image")
            log.info("%sdynamics, sensor and geometry kernels ready in %.1f s",
                     "camera, " if cfg.fidelity == "image" else "", wall.now() - t0)
            frames = FrameWriter(out / "frames", cfg.save_frames_every, cfg.camera.bit_depth)
            try:
                run(bus, made[0], bus_cfg, realtime, WallClock(), frames)
            finally:
                frames.close()  # every PNG on disk before the run is declared over (the report reads them)

        try:
            code, finished = bus.guarded(body)
            if finished:
                sim = made[0]
                log.info("run complete at t=%.1f s (%d steps); %d undecodable messages", sim.t_s, sim.step,
                         bus.decode_errors)
                bus.shutdown("run complete", failed=False)
                bus.wait_until_gone(["obsw", "ground"], timeout_s=bus_cfg.reply_timeout_s * 6)
            return code
        finally:
            bus.close()
