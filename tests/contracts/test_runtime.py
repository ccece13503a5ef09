"""A node's bus attachment over real Zenoh sessions on loopback: several requests answered in any order."""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager

import pytest
import zenoh

from contracts.bus import Keys, free_tcp_port, session_config
from contracts.clock import WallClock
from contracts.errors import NodeFailure
from contracts.messages import GroundReply, GroundStep, SensorData, StepReply, StepRequest, decode, encode
from contracts.runtime import Attachment

KEYS = Keys("test-runtime")
LOG = logging.getLogger("test-runtime")


def request(step: int) -> StepRequest:
    """A step request without a frame."""
    return StepRequest(step=step, obt_s=100.0 + 0.1 * step,
                       sensors=SensorData(star_tracker_q=(0.0, 0.0, 0.0, 1.0), gyro_rad_s=(0.0, 0.0, 0.0),
                                          wheel_speed_rad_s=(0.0, 0.0, 0.0)))


@pytest.fixture
def sessions() -> Iterator[tuple[zenoh.Session, zenoh.Session, zenoh.Session]]:
    """Three peers: the asking node listens, the two responders connect to it."""
    ep = f"tcp/127.0.0.1:{free_tcp_port()}"
    asker = zenoh.open(session_config(listen=[ep]))
    obsw = zenoh.open(session_config(connect=[ep]))
    ground = zenoh.open(session_config(connect=[ep]))
    try:
        yield asker, obsw, ground
    finally:
        for s in (ground, obsw, asker):
            s.close()


def _connected(bus: Attachment, session: zenoh.Session, key: str) -> None:
    """Wait (the event: a message through) until ``session`` hears ``key`` from ``bus``'s session."""
    heard = threading.Event()
    sub = session.declare_subscriber(key + "/probe", lambda _s: heard.set())
    try:
        for _ in range(200):
            bus.session.put(key + "/probe", b"")
            if heard.wait(0.1):
                return
        raise AssertionError(f"{key}: the peers never connected")
    finally:
        sub.undeclare()


@contextmanager
def responders(bus: Attachment, obsw: zenoh.Session, ground: zenoh.Session,
               on_step: Callable[[zenoh.Sample], None], on_ground: Callable[[zenoh.Sample], None]) -> Iterator[None]:
    """The flight software and ground answering (or not) from their sessions' callbacks, once connected."""
    subs = [obsw.declare_subscriber(KEYS.step, on_step), ground.declare_subscriber(KEYS.ground_step, on_ground)]
    try:
        _connected(bus, obsw, KEYS.step)
        _connected(bus, ground, KEYS.ground_step)
        yield
    finally:
        for s in subs:
            s.undeclare()


def test_collect_returns_every_answer_in_the_order_asked_whichever_arrives_first(sessions) -> None:
    """Two requests in flight: the answers come back in the order asked, the later one answered first; a reply to
    another step is dropped."""
    asker, obsw, ground = sessions
    bus = Attachment(asker, KEYS, "universe", WallClock(), LOG)
    bus.subscribe(KEYS.reply, StepReply)
    bus.subscribe(KEYS.ground_reply, GroundReply)
    ground_answered = threading.Event()

    def on_step(sample: zenoh.Sample) -> None:
        req, _ = decode(StepRequest, sample.payload.to_bytes())
        ground_answered.wait(30.0)  # ground's answer first, though asked second
        obsw.put(KEYS.reply, encode(StepReply(step=req.step - 1, wheel_torque_nm=(9.0, 9.0, 9.0))))  # stale
        obsw.put(KEYS.reply, encode(StepReply(step=req.step, wheel_torque_nm=(1.0, 2.0, 3.0))))

    def on_ground(sample: zenoh.Sample) -> None:
        gs, _ = decode(GroundStep, sample.payload.to_bytes())
        ground.put(KEYS.ground_reply, encode(GroundReply(step=gs.step, uplink=(b"\x18\x01",))))
        ground_answered.set()

    with responders(bus, obsw, ground, on_step, on_ground):
        pending = [bus.ask(KEYS.step, request(7), b"", StepReply, "obsw"),
                   bus.ask(KEYS.ground_step, GroundStep(step=3, utc_s=1.0), b"", GroundReply, "ground")]
        reply, ground_reply = bus.collect(pending, timeout_s=60.0, resend_s=30.0)
    assert isinstance(reply.msg, StepReply) and reply.msg.step == 7 and reply.msg.wheel_torque_nm == (1.0, 2.0, 3.0)
    assert isinstance(ground_reply.msg, GroundReply) and ground_reply.msg.step == 3
    assert ground_reply.msg.uplink == (b"\x18\x01",)


def test_an_unanswered_request_is_resent_and_then_its_peer_failure(sessions) -> None:
    """The answered request is not resent; the silent peer gets its request again, then is named as failed."""
    asker, obsw, ground = sessions
    bus = Attachment(asker, KEYS, "universe", WallClock(), LOG)
    bus.subscribe(KEYS.reply, StepReply)
    bus.subscribe(KEYS.ground_reply, GroundReply)
    seen = {"obsw": 0, "ground": 0}
    lock = threading.Lock()

    def on_step(sample: zenoh.Sample) -> None:
        req, _ = decode(StepRequest, sample.payload.to_bytes())
        with lock:
            seen["obsw"] += 1
        obsw.put(KEYS.reply, encode(StepReply(step=req.step, wheel_torque_nm=(0.0, 0.0, 0.0))))

    def on_ground(_sample: zenoh.Sample) -> None:
        with lock:
            seen["ground"] += 1  # never answers

    with responders(bus, obsw, ground, on_step, on_ground):
        pending = [bus.ask(KEYS.step, request(1), b"", StepReply, "obsw"),
                   bus.ask(KEYS.ground_step, GroundStep(step=1, utc_s=1.0), b"", GroundReply, "ground")]
        with pytest.raises(NodeFailure) as failure:
            bus.collect(pending, timeout_s=2.0, resend_s=0.25)
    assert failure.value.node == "ground" and "no reply to step 1" in str(failure.value)
    assert seen["ground"] >= 3 and seen["obsw"] < seen["ground"]  # ground resent some 7 times, obsw not after its answer
