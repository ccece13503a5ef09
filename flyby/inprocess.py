"""The three cores in one process, exchanging exactly the messages the nodes exchange over Zenoh.

Same order of work as the nodes (ground step when due, then the OBSW step, then the universe advances), same
messages, same seeds: a run here gives the same telemetry as a run over the bus. It exists for tests of the
closed loop, for debugging with a plain debugger, and for Monte Carlo sweeps where process start-up would dominate.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from contracts.messages import GroundReply, StepReply, StepRequest, TruthRecord, decode, encode
from contracts.sdls import KeyRing
from contracts.steplog import FrameKeeping, FrameTruth, StepLogWriter
from ground.segment import GroundSegment, ReceivedPacket, TimelineUpload
from obsw.software import FlightSoftware
from scenario import compose
from scenario.model import Scenario
from timeline.model import Timeline
from universe.simulator import Universe


@dataclass
class InProcessRun:
    """Everything a run produced."""

    truth: list[TruthRecord] = field(default_factory=list)
    received: list[ReceivedPacket] = field(default_factory=list)
    log: list[str] = field(default_factory=list)
    frames: int = 0
    record_error: str | None = None  # why the step record stopped, if it did
    uploads: list[TimelineUpload] = field(default_factory=list)  # what ground did with each timeline row
    alarms: list[tuple[float, str]] = field(default_factory=list)  # ground's alarms raised by no packet (UTC s, text)


def run_in_process(scenario: Scenario, timeline: Timeline | None = None, through_codec: bool = False,
                   on_step: Callable[[StepRequest, StepReply, np.ndarray | None], None] | None = None,
                   max_steps: int | None = None, record: Path | None = None,
                   record_frames: FrameKeeping = "reference") -> InProcessRun:
    """Run the scenario to its end (or its first ``max_steps`` control periods); ``through_codec`` also encodes and
    decodes every message, as the bus does; ``record``: a file to record the flight software's inputs and outputs
    into, as the OBSW node does (``contracts.steplog``; ``flyby replay`` reads it), with the scenario and, for each
    frame kept by reference (``record_frames``), the truth it was rendered with: the record replays on its own."""
    sim = compose.universe(scenario)
    keys = KeyRing.derived(scenario.seed)  # fixed by the seed: an in-process uplink is reproduced byte for byte
    fsw = compose.flight_software(scenario, keys)
    ground = compose.ground_segment(scenario, timeline, keys)
    out = InProcessRun()
    writer = None if record is None else StepLogWriter(
        record, {"scenario": scenario.model_dump(mode="json"), "obsw": fsw.cfg.model_dump(mode="json"),
                 "tc_keys": "derived from the seed"}, frames=record_frames)
    fsw.security.keep_verdicts = writer is not None
    try:
        _loop(sim, fsw, ground, out, through_codec, on_step, max_steps, writer)
        out.uploads = list(ground.uploads)
    finally:
        if writer is not None:
            writer.close()
            out.record_error = writer.error
    return out


def _loop(sim: Universe, fsw: FlightSoftware, ground: GroundSegment, out: InProcessRun, through_codec: bool,
          on_step: Callable[[StepRequest, StepReply, np.ndarray | None], None] | None, max_steps: int | None,
          writer: StepLogWriter | None) -> None:

    def ground_exchange() -> None:
        gs = sim.ground_step()
        uplink, received, lines = ground.step(gs.utc_s, gs.downlink, gs.downlink_utc_s)
        out.received += received
        out.truth += gs.truth
        out.log += [f"ground: {x}" for x in lines]
        out.alarms += ground.take_alarms()
        sim.accept_ground(GroundReply(step=gs.step, uplink=tuple(uplink)))

    request, blob = sim.begin()
    while True:
        if sim.ground_due():
            ground_exchange()
        if through_codec:
            request, blob = decode(StepRequest, encode(request, blob))
        frame = None
        if request.frame is not None:
            if request.frame.measurement is None:
                frame = np.frombuffer(blob, dtype="<u2").reshape(request.frame.height, request.frame.width)
            out.frames += 1
        reply = fsw.step(request, frame)
        if through_codec:
            reply, _ = decode(StepReply, encode(reply))
        if writer is not None:
            # the universe has not advanced yet: its time and state are those the frame was rendered with
            truth = None if frame is None else FrameTruth.of(sim.t_s, sim.state.q, sim.state.omega_rad_s)
            writer.step(request, blob if frame is not None else b"", reply, truth, fsw.security.take_verdicts())
        if on_step is not None:
            on_step(request, reply, frame)
        universe_log, obsw_log = sim.take_log(), fsw.take_log()
        if universe_log or obsw_log:  # most periods log nothing
            out.log += [f"universe: {x}" for x in universe_log] + [f"obsw: {x}" for x in obsw_log]
        nxt = sim.advance(reply)
        if nxt is None or (max_steps is not None and sim.step >= max_steps):
            break
        request, blob = nxt
    while (gs := sim.drain()) is not None:
        uplink, received, lines = ground.step(gs.utc_s, gs.downlink, gs.downlink_utc_s)
        out.received += received
        out.truth += gs.truth
        out.log += [f"ground: {x}" for x in lines]
        out.alarms += ground.take_alarms()
    out.log += [f"universe: {x}" for x in sim.take_log()]
