"""Lock-step throughput between two processes over Zenoh, against the raw Zenoh round trips in the same run, on
plain TCP and on the secured bus (TLS with mutual authentication and the run's access control).

Starts a responder process on plain TCP, and measures, each as the median of several rounds:
  raw get        session.get on a queryable that echoes (Zenoh's request/reply)
  raw pub/sub    express publisher ping -> echo -> pong (no encoding)
  lock-step      the emulator's own exchange: a StepRequest (typical sensors, no frame) encoded, published,
                 decoded by the responder, answered with a StepReply, decoded, matched by step number
and the same lock-step against two more responders, as the flight software with a run's credentials:
  lock-step TLS      over TLS with mutual authentication
  lock-step TLS+ACL  and with the run's access control, as ``flyby run`` does (raw get is refused there)
The modes take turns in every round. Prints control periods per second, the ratio of each to the raw get round
trip, and the secured lock-step against plain TCP.

    python bench/lockstep.py [--n 3000] [--rounds 5]
"""

from __future__ import annotations

import argparse
import logging
import queue
import statistics
import subprocess
import sys
import tempfile
import time
from contextlib import ExitStack
from pathlib import Path

import zenoh

from contracts.bus import Keys, TlsIdentity, access_control, free_tcp_port, session_config
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


MODES = ("plain", "TLS", "TLS+ACL")  # plain TCP; TLS with mutual authentication; and with the run's access control


def _conf(role: str, port: int, mode: str, credentials: Path, listen: bool):  # type: ignore[no-untyped-def]
    """The session configuration of ``role`` in ``mode``."""
    ep = [f"{'tcp' if mode == 'plain' else 'tls'}/127.0.0.1:{port}"]
    kw = dict(listen=ep) if listen else dict(connect=ep)
    if mode == "plain":
        return session_config(**kw)
    acl = access_control(KEYS) if mode == "TLS+ACL" else None
    return session_config(**kw, tls=TlsIdentity.in_folder(credentials, role), acl=acl)


def serve(port: int, seconds: float, mode: str, credentials: Path) -> None:
    """The responder: echo raw queries and pings (plain TCP only), answer StepRequests with StepReplies."""
    conf = _conf("obsw", port, mode, credentials, listen=True)
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


def _responder(mode: str, credentials: Path) -> tuple[subprocess.Popen[bytes], int]:
    port = free_tcp_port()
    return subprocess.Popen([sys.executable, __file__, "--serve", str(port), mode, str(credentials)]), port


def main() -> None:
    """Run the benchmark and print its figures; the modes take turns in every round, so load changes hit all."""
    from flyby.credentials import write_credentials

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=3000, help="round trips per measurement")
    ap.add_argument("--rounds", type=int, default=5, help="measurements per method (median reported)")
    args = ap.parse_args()
    payload = encode(request(0))
    rates: dict[str, list[float]] = {"raw get": [], "raw pub/sub": [], **{f"lock-step {m}": [] for m in MODES}}
    with tempfile.TemporaryDirectory() as tmp, ExitStack() as stack:
        creds = Path(tmp) / "credentials"
        write_credentials(creds)
        children = {m: _responder(m, creds) for m in MODES}
        try:
            time.sleep(1.0)
            sessions, buses = {}, {}
            for m, (_, port) in children.items():
                sessions[m] = stack.enter_context(zenoh.open(_conf("universe", port, m, creds, listen=False)))
                bus = buses[m] = Attachment(sessions[m], KEYS, "universe", WallClock(), logging.getLogger("bench"))
                bus.subscribe(KEYS.reply, StepReply)
                bus.watch_peers()
                bus.wait_for_peers(["obsw"], 10.0)
                rate_lockstep(bus, 200, 0)  # warm-up
            step = 1000
            for r in range(args.rounds):
                rates["raw get"].append(rate_raw_get(sessions["plain"], args.n, payload))
                rates["raw pub/sub"].append(rate_raw_pubsub(sessions["plain"], args.n, payload))
                for m in MODES:
                    rates[f"lock-step {m}"].append(rate_lockstep(buses[m], args.n, step))
                step += args.n
                print(f"round {r + 1}/{args.rounds}: " + ", ".join(f"{k} {v[-1]:,.0f}/s" for k, v in rates.items()),
                      flush=True)
            for bus in buses.values():
                bus.close()
        finally:
            for child, _ in children.values():
                child.terminate()
                child.wait()
    med = {k: statistics.median(v) for k, v in rates.items()}
    print(f"\nmedians over {args.rounds} rounds of {args.n} round trips ({len(payload)}-byte step request):")
    for k, v in med.items():
        print(f"  {k:18s} {v:8,.0f} per s   {1e6 / v:6.0f} us per round trip   "
              f"time ratio to raw get {med['raw get'] / v:4.2f}x")
    plain, secured = med["lock-step plain"], med["lock-step TLS+ACL"]
    print(f"  lock-step time ratio to plain TCP: TLS {plain / med['lock-step TLS']:4.2f}x, "
          f"TLS with access control {plain / secured:4.2f}x")
    print(f"target: lock-step >= 2,000 periods/s and within 1.5x of the raw get round trip: "
          f"{'MET' if plain >= 2000 and med['raw get'] / plain <= 1.5 else 'NOT MET'}")
    print(f"target: lock-step over TLS with access control >= 2,000 periods/s: "
          f"{'MET' if secured >= 2000 else 'NOT MET'}")

if __name__ == "__main__":
    if len(sys.argv) == 5 and sys.argv[1] == "--serve":
        serve(int(sys.argv[2]), 600.0, sys.argv[3], Path(sys.argv[4]))
    else:
        main()
