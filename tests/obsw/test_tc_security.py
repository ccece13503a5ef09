"""The flight software refuses uplinked TCs that fail authentication: nothing executes, each refusal is answered by
an acceptance failure naming the TC and a security event, and counted in housekeeping by kind."""

from __future__ import annotations

import pytest

from contracts import pus, sdls
from contracts.messages import SensorData, StepRequest
from obsw.config import ObswConfig
from obsw.software import FlightSoftware

APID = ObswConfig().apid
KEYS = sdls.KeyRing.generate()
SAFE = pus.encode_tc(pus.SetMode(mode=pus.Mode.SAFE), APID, 9)


def _step(fsw: FlightSoftware, k: int, uplink: tuple[bytes, ...]) -> list[tuple[pus.TmHeader, pus.TmReport]]:
    req = StepRequest(step=k, obt_s=1000.0 + 0.1 * k, uplink=uplink,
                      sensors=SensorData(star_tracker_q=(0, 0, 0, 1), gyro_rad_s=(0, 0, 0), wheel_speed_rad_s=(0, 0, 0)))
    return [pus.decode_tm(p) for p in fsw.step(req, None).downlink]


def _forged() -> dict[str, tuple[bytes, pus.FailureCode]]:
    genuine = sdls.secure(SAFE, KEYS.associations[0], 1)
    wrong_mac = genuine[:-1] + bytes([genuine[-1] ^ 1])
    return {"plain": (SAFE, pus.FailureCode.UNAUTHENTICATED),
            "wrong MAC": (wrong_mac, pus.FailureCode.UNAUTHENTICATED),
            "other key": (sdls.secure(SAFE, sdls.SecurityAssociation(KEYS.active_spi, bytes(32)), 5),
                          pus.FailureCode.UNAUTHENTICATED),
            "unknown SPI": (sdls.secure(SAFE, sdls.SecurityAssociation(77, KEYS.associations[0].key), 5),
                            pus.FailureCode.UNKNOWN_SPI)}


@pytest.mark.parametrize("kind", list(_forged()))
def test_forged_tc_is_refused_reported_and_not_executed(kind: str) -> None:
    """A SAFE command that fails the check: TM[1,2] with the security code and the TC's request id, a high-severity
    security event, no mode change, and the housekeeping counter of its kind at 1."""
    unit, code = _forged()[kind]
    fsw = FlightSoftware(ObswConfig(), KEYS)
    tm = _step(fsw, 0, (unit,))
    ver = [r for _, r in tm if isinstance(r, pus.Verification)]
    assert [(v.stage, v.failure_code, v.request_id.seq_count) for v in ver] == [(pus.Stage.ACCEPTANCE, code, 9)]
    events = [r for _, r in tm if isinstance(r, pus.TcSecurityRejectedEvent)]
    assert len(events) == 1 and events[0].failure_code == code and events[0].severity == pus.Severity.HIGH
    assert fsw.mode_name == "STANDBY" and not [r for _, r in tm if isinstance(r, pus.ModeChangedEvent)]
    hk = [r for _, r in tm if isinstance(r, pus.Housekeeping)][0]
    counts = (hk.tc_rejected_auth, hk.tc_rejected_spi, hk.tc_rejected_replay)
    assert counts == ((0, 1, 0) if code == pus.FailureCode.UNKNOWN_SPI else (1, 0, 0))


def test_replayed_tc_executes_once() -> None:
    """A genuine SAFE executes; the same unit uplinked again later is refused as a replay and counted."""
    fsw = FlightSoftware(ObswConfig(), KEYS)
    unit = sdls.Sender(KEYS).secure(pus.encode_tc(pus.SetMode(mode=pus.Mode.ACQUISITION), APID, 3))
    first = _step(fsw, 0, (unit,))
    assert any(isinstance(r, pus.ModeChangedEvent) for _, r in first)
    again = []
    for k in range(1, 12):  # past the next housekeeping period
        again += _step(fsw, k, (unit,) if k == 1 else ())
    ver = [r for _, r in again if isinstance(r, pus.Verification)]
    assert [(v.stage, v.failure_code) for v in ver] == [(pus.Stage.ACCEPTANCE, pus.FailureCode.REPLAYED)]
    assert not any(isinstance(r, pus.ModeChangedEvent) for _, r in again)
    assert [r for _, r in again if isinstance(r, pus.Housekeeping)][-1].tc_rejected_replay == 1


def test_garbage_unit_without_request_id_gets_an_event_only() -> None:
    """Three octets of garbage: no request id to report on, so a security event alone; the next TC still runs."""
    fsw = FlightSoftware(ObswConfig(), KEYS)
    ping = sdls.Sender(KEYS).secure(pus.encode_tc(pus.Ping(), APID, 4))
    tm = _step(fsw, 0, (b"\x01\x02\x03", ping))
    assert [r.failure_code for _, r in tm if isinstance(r, pus.TcSecurityRejectedEvent)] == [
        pus.FailureCode.UNAUTHENTICATED]
    assert not [r for _, r in tm if isinstance(r, pus.Verification) and not r.success]
    assert [r for _, r in tm if isinstance(r, pus.PingReply)]


def test_without_keys_every_uplinked_tc_is_refused() -> None:
    """A flight software holding no security association executes nothing uplinked."""
    fsw = FlightSoftware(ObswConfig(), None)
    tm = _step(fsw, 0, (sdls.Sender(KEYS).secure(SAFE),))
    assert [r.failure_code for _, r in tm if isinstance(r, pus.Verification)] == [pus.FailureCode.UNKNOWN_SPI]
    assert fsw.mode_name == "STANDBY"
