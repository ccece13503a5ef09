"""Lock-step throughput between two processes over Zenoh, against the raw Zenoh round trips in the same run.

Starts a responder process, then measures, each as the median of several rounds:
  raw get        session.get on a queryable that echoes (Zenoh's request/reply)
  raw pub/sub    express publisher ping -> echo -> pong (no encoding)
  lock-step      the emulator's own exchange: a StepRequest (typical sensors, no frame) encoded, published,
                 decoded by the responder, answered with a StepReply, decoded, matched by step number
Prints control periods per second and the ratio of each to the raw get round trip.

    python bench/lockstep.py [--n 3000] [--rounds 5]
"""

from __future__ import annotations

import argparse
import logging
import queue
import statistics
import subprocess
import sys
import time

import zenoh

from contracts.bus import Keys, free_tcp_port, session_config
from contracts.clock import WallClock
from contracts.messages import SensorData, StepReply, StepRequest, decode, encode
from contracts.runtime import Attachment

KEYS = Keys("bench")
RAW_Q, RAW_PING, RAW_PONG = "bench/raw/q", "bench/raw/ping", "bench/raw/pong"


def request(step: int) -> StepRequest:
    """A step request of typical size: full sensor set, no frame, no telecommand."""
    return StepRequest(step=step, obt_s=26_499_070.0 + 0.1 * step,
                       sensors=SensorData(star_tracker_q=(0.01, 0.02, 0.7, 0.71), gyro_rad_s=(1e-3, 2e-3, 3e-3),
                                          wheel_speed_rad_s=(10.0, 20.0, 30.0)))


def serve(port: int, seconds: float) -> None:
    """The responder: echo raw queries and pings, answer StepRequests with StepReplies."""
    conf = session_config(listen=[f"tcp/127.0.0.1:{port}"])
    with zenoh.open(conf) as s:
        q = s.declare_queryable(RAW_Q, lambda query: query.reply(query.key_expr, query.payload.to_bytes()))
        pong = s.declare_publisher(RAW_PONG, express=True)
        sub = s.declare_subscriber(RAW_PING, lambda sample: pong.put(sample.payload.to_bytes()))
        reply_pub = s.declare_publisher(KEYS.reply, express=True, congestion_control=zenoh.CongestionControl.BLOCK)

        def on_step(sample: zenoh.Sample) -> None:
            req, _ = decode(StepRequest, sample.payload.to_bytes())
            reply_pub.put(encode(StepReply(step=req.step, wheel_torque_nm=(1e-4, -2e-4, 3e-4))))

        sub2 = s.declare_subscriber(KEYS.step, on_step)
        token = s.liveliness().declare_token(KEYS.alive("obsw"))
        time.sleep(seconds)
        del q, sub, sub2, token


def rate_raw_get(s: zenoh.Session, n: int, payload: bytes) -> float:
    """Round trips per second of session.get."""
    t0 = time.perf_counter()
    for _ in range(n):
        for r in s.get(RAW_Q, payload=payload):
            r.ok.payload.to_bytes()
    return n / (time.perf_counter() - t0)


def rate_raw_pubsub(s: zenoh.Session, n: int, payload: bytes) -> float:
    """Round trips per second of an express publish and its echo."""
    got: queue.SimpleQueue[bytes] = queue.SimpleQueue()
    sub = s.declare_subscriber(RAW_PONG, lambda sample: got.put(sample.payload.to_bytes()))
    pub = s.declare_publisher(RAW_PING, express=True)
    time.sleep(0.3)
    t0 = time.perf_counter()
    for _ in range(n):
        pub.put(payload)
        got.get(timeout=5)
    rate = n / (time.perf_counter() - t0)
    sub.undeclare()
    return rate


def rate_lockstep(bus: Attachment, n: int, start: int) -> float:
    """Control periods per second through the emulator's exchange."""
    t0 = time.perf_counter()
    for k in range(start, start + n):
        bus.exchange(KEYS.step, request(k), b"", StepReply, "obsw", timeout_s=5.0)
    return n / (time.perf_counter() - t0)


def main() -> None:
    """Run the benchmark and print its figures."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=3000, help="round trips per measurement")
    ap.add_argument("--rounds", type=int, default=5, help="measurements per method (median reported)")
    args = ap.parse_args()
    port = free_tcp_port()
    child = subprocess.Popen([sys.executable, __file__, "--serve", str(port)])
    try:
        time.sleep(1.0)
        with zenoh.open(session_config(connect=[f"tcp/127.0.0.1:{port}"])) as s:
            bus = Attachment(s, KEYS, "universe", WallClock(), logging.getLogger("bench"))
            bus.subscribe(KEYS.reply, StepReply)
            bus.watch_peers()
            bus.wait_for_peers(["obsw"], 10.0)
            payload = encode(request(0))
            rates: dict[str, list[float]] = {"raw get": [], "raw pub/sub": [], "lock-step": []}
            rate_lockstep(bus, 200, 0)  # warm-up
            step = 1000
            for r in range(args.rounds):
                rates["raw get"].append(rate_raw_get(s, args.n, payload))
                rates["raw pub/sub"].append(rate_raw_pubsub(s, args.n, payload))
                rates["lock-step"].append(rate_lockstep(bus, args.n, step))
                step += args.n
                print(f"round {r + 1}/{args.rounds}: " + ", ".join(f"{k} {v[-1]:,.0f}/s" for k, v in rates.items()),
                      flush=True)
            med = {k: statistics.median(v) for k, v in rates.items()}
            print(f"\nmedians over {args.rounds} rounds of {args.n} round trips ({len(payload)}-byte step request):")
            for k, v in med.items():
                print(f"  {k:12s} {v:8,.0f} per s   {1e6 / v:6.0f} us per round trip   "
                      f"time ratio to raw get {med['raw get'] / v:4.2f}x")
            print(f"target: lock-step >= 2,000 periods/s and within 1.5x of the raw get round trip: "
                  f"{'MET' if med['lock-step'] >= 2000 and med['raw get'] / med['lock-step'] <= 1.5 else 'NOT MET'}")
            bus.close()
    finally:
        child.terminate()
        child.wait()


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "--serve":
        serve(int(sys.argv[2]), seconds=600.0)
    else:
        main()
