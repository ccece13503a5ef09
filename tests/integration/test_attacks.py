"""A foreign process attached to a running flyby (loopback, bounded in time) tries to command the spacecraft: a
connection without a certificate, one with a certificate of another CA, the ground's certificate publishing a forged
step on the universe's key and a command request on the operator's key, and, racing the real ground's replies, a
forged TC, a TC under a wrong MAC, a replayed TC and garbage on the uplink. None executes: the first are refused at
the transport, the next by access control, the last by the flight software with a PUS 1 report; ground raises its
security alarms, and the flyby passes every requirement."""

from __future__ import annotations

import json
import queue
import time
from pathlib import Path

import pytest
import zenoh

from contracts import pus, sdls
from contracts.bus import Keys, TlsIdentity, session_config
from contracts.messages import GroundReply, GroundStep, OperatorCommand, SensorData, StepRequest, decode, encode
from flyby.credentials import write_credentials
from tests.integration.conftest import DATA, launch_held, start_nodes, stop_nodes

pytestmark = pytest.mark.integration

APID = 0x0C1
SAFE = pus.SetMode(mode=pus.Mode.SAFE)
FORGED_SEQ, WRONG_MAC_SEQ, STEP_SEQ = 3333, 3334, 3400  # request ids of the attacker's own TCs
WINDOW_S = 60.0  # the longest the attacker keeps trying


def _bare_session(endpoint: str, tls: dict[str, object] | None) -> zenoh.Session:
    """A session of the attacker's own making (no access control of its own)."""
    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("scouting/multicast/enabled", "false")
    conf.insert_json5("connect/endpoints", json.dumps([endpoint]))
    if tls is not None:
        conf.insert_json5("transport/link/tls", json.dumps(tls))
    return zenoh.open(conf)


def _sees_no_node(session: zenoh.Session, keys: Keys) -> bool:
    """Whether, after a while, the session still has no peer and sees no node's liveliness token."""
    # the query is the wait: a session let in would have the nodes' tokens answer it before its timeout
    tokens = list(session.liveliness().get(keys.alive_all, timeout=2.5))
    return not list(session.info.peers_zid()) and not [t for t in tokens if t.ok is not None]


def _foreign_ca(folder: Path) -> Path:
    """A CA of the attacker's own, with a certificate that claims to be the universe."""
    write_credentials(folder, roles=("universe",), ca_name="intruder CA")
    return folder


def test_attacks_on_a_running_flyby_are_refused(tmp_path: Path) -> None:
    """Every attack fails where it should, the spacecraft executes none, and the flyby passes every requirement."""
    creds = tmp_path / "credentials"
    write_credentials(creds)
    out = tmp_path / "run"
    out.mkdir()
    # ground is held back until the attacker listens: the universe starts (and ground uplinks) only once every node
    # is up, so the unpaced run cannot radiate its uplink before the attacker hears it
    procs, ep, run_id = start_nodes(out, DATA / "security.yaml", realtime=False, credentials=creds, hold=("ground",))
    keys = Keys(run_id)
    captured: list[bytes] = []  # units radiated by the real ground, heard on the spacecraft's uplink
    arrived: queue.SimpleQueue[tuple[bytes, ...]] = queue.SimpleQueue()
    ground_steps: queue.SimpleQueue[int] = queue.SimpleQueue()
    ground: zenoh.Session | None = None
    try:
        # as ground (its certificate stolen): listen to the uplink and to the ground steps; this is allowed
        ground = zenoh.open(session_config(connect=list(ep.values()), tls=TlsIdentity.in_folder(creds, "ground")))

        def on_step(sample: zenoh.Sample) -> None:
            req, _ = decode(StepRequest, sample.payload.to_bytes())
            if req.uplink:
                (captured if not captured else []).extend(req.uplink)
                arrived.put(req.uplink)

        def on_ground_step(sample: zenoh.Sample) -> None:
            ground_steps.put(decode(GroundStep, sample.payload.to_bytes())[0].step)

        subs = [ground.declare_subscriber(keys.step, on_step),
                ground.declare_subscriber(keys.ground_step, on_ground_step)]
        # the universe answering a liveliness query proves the link is up and the subscriptions (declared before the
        # query, on the same link) have reached it
        deadline = time.monotonic() + WINDOW_S
        while not [t for t in ground.liveliness().get(keys.alive("universe"), timeout=2.0) if t.ok is not None]:
            assert time.monotonic() < deadline and procs["universe"].poll() is None, "the universe was never seen"
        launch_held(out, run_id, procs)
        while not captured:  # woken by the first uplink heard
            assert time.monotonic() < deadline and procs["universe"].poll() is None, "the uplink was never heard"
            try:
                arrived.get(timeout=1.0)
            except queue.Empty:
                pass

        # 1. no certificate at all: plain TCP, then TLS without a client certificate
        port = ep["universe"].rsplit(":", 1)[1]
        for endpoint, tls in ((f"tcp/127.0.0.1:{port}", None),
                              (ep["universe"], {"root_ca_certificate": str(creds / "ca.pem")})):
            with _bare_session(endpoint, tls) as s:
                s.put(keys.step, encode(StepRequest(step=10**6, obt_s=0.0, uplink=(pus.encode_tc(SAFE, APID, 1),),
                                                    sensors=SensorData(star_tracker_q=None, gyro_rad_s=(0, 0, 0),
                                                                       wheel_speed_rad_s=(0, 0, 0)))))
                assert _sees_no_node(s, keys), f"{endpoint} accepted a connection without a certificate"
        # 2. a certificate of another CA claiming to be the universe
        foreign = _foreign_ca(tmp_path / "intruder")
        with _bare_session(ep["obsw"], {"root_ca_certificate": str(foreign / "ca.pem"), "enable_mtls": True,
                                        "verify_name_on_connect": False,
                                        "connect_certificate": str(foreign / "universe.pem"),
                                        "connect_private_key": str(foreign / "universe.key")}) as s:
            assert _sees_no_node(s, keys), "a certificate of a foreign CA was accepted"

        # 3. the ground's certificate on the universe's keys (a forged step) and on the operator's key
        step = StepRequest(step=10**6, obt_s=0.0, uplink=(pus.encode_tc(pus.Ping(), APID, STEP_SEQ),),
                           sensors=SensorData(star_tracker_q=None, gyro_rad_s=(0, 0, 0), wheel_speed_rad_s=(0, 0, 0)))
        request = OperatorCommand(request=4242, action="send", name="set_mode",
                                  payload=b"{command: set_mode, args: {mode: SAFE}}")
        for _ in range(5):
            ground.put(keys.step, encode(step))
            ground.put(keys.ground_step, encode(GroundStep(step=10**6, utc_s=0.0)))
            ground.put(keys.operator, encode(request))
            ground_steps.get(timeout=WINDOW_S)  # one try per ground step

        # 4. racing the real ground with the units a ground certificate holder can put on the uplink
        genuine = captured[0]
        wrong_mac = sdls.secure(pus.encode_tc(SAFE, APID, WRONG_MAC_SEQ), sdls.SecurityAssociation(
            int.from_bytes(genuine[:2], "big"), bytes(sdls.KEY_LEN)), 10**6)
        forged = (pus.encode_tc(SAFE, APID, FORGED_SEQ), wrong_mac, genuine, b"\x00garbage\xff")
        reply_pub = ground.declare_publisher(keys.ground_reply, express=True)
        landed = False
        while not landed:  # one try at a time: each either lands within a light time or lost its race
            assert time.monotonic() < deadline and procs["universe"].poll() is None, "the forged reply never won"
            while not ground_steps.empty():
                ground_steps.get()
            try:
                k = ground_steps.get(timeout=2.0)
            except queue.Empty:
                continue
            reply_pub.put(encode(GroundReply(step=k, uplink=forged)))
            settle = time.monotonic() + 2.0
            while not landed and time.monotonic() < settle:
                try:
                    landed = forged[0] in arrived.get(timeout=0.1)
                except queue.Empty:
                    pass
        del subs, reply_pub
        ground.close()

        codes = {n: p.wait(timeout=120) for n, p in procs.items()}
        assert codes == {"universe": 0, "obsw": 0, "ground": 0}, codes
    finally:
        if ground is not None:
            ground.close()  # a session left open with live callbacks can hold up the interpreter's exit
        stop_nodes(procs)

    tm = [pus.decode_tm(p) for p in pus.split_packets((out / "tm.bin").read_bytes())]
    failures = {(r.request_id.seq_count, r.failure_code) for _, r in tm if isinstance(r, pus.Verification)
                and not r.success}
    seq_of_genuine = pus.request_id_of(sdls.packet_of(genuine)).seq_count
    assert {(FORGED_SEQ, pus.FailureCode.UNAUTHENTICATED), (WRONG_MAC_SEQ, pus.FailureCode.UNAUTHENTICATED),
            (seq_of_genuine, pus.FailureCode.REPLAYED)} <= failures
    # the forged step never reached the flight software, and no attacker's TC executed
    reported = {r.request_id.seq_count for _, r in tm if isinstance(r, pus.Verification)}
    assert STEP_SEQ not in reported
    assert not any(r.success for _, r in tm if isinstance(r, pus.Verification)
                   and r.request_id.seq_count in (FORGED_SEQ, WRONG_MAC_SEQ, STEP_SEQ))
    assert pus.Mode.SAFE not in {r.to_mode for _, r in tm if isinstance(r, pus.ModeChangedEvent)}
    # each landing of the forged reply: three units unauthenticated (bare, wrong MAC, garbage), one replayed
    rejections = [r.failure_code for _, r in tm if isinstance(r, pus.TcSecurityRejectedEvent)]
    landings = rejections.count(pus.FailureCode.REPLAYED)
    assert landings >= 1 and sorted(rejections) == sorted([pus.FailureCode.UNAUTHENTICATED] * 3 * landings
                                                          + [pus.FailureCode.REPLAYED] * landings)
    hk = [r for _, r in tm if isinstance(r, pus.Housekeeping)][-1]
    assert (hk.tc_rejected_auth, hk.tc_rejected_spi, hk.tc_rejected_replay) == (3 * landings, 0, landings)
    # access control kept the operator request from the ground's certificate away from the ground node
    assert "operator request" not in (out / "ground.log").read_text()
    # ground noticed: alarms for the reports of TCs it never sent and for every refusal
    summary = json.loads((out / "summary.json").read_text())["lines"]
    assert any("alarm(s); the first" in line for line in summary), summary
    assert any(f"sequence {FORGED_SEQ}, which ground never sent" in line for line in summary)
    assert "SECURITY ALARM" in (out / "ground.log").read_text()
    assert any(line.startswith("requirements: all PASS") for line in summary), summary
