"""Rekeying by telecommand (CCSDS 355.0-B over-the-air rekeying): ground sends a new key wrapped under the current
one, switches to it when the spacecraft reports the TC completed, and the spacecraft then retires the old key."""

from __future__ import annotations

from contracts import pus, sdls
from contracts.messages import SensorData, StepRequest
from scenario import compose
from scenario.model import scenario_from_dict


def test_rekey_switches_both_ends_and_retires_the_old_key() -> None:
    """After the rekeying TC completes, ground's TCs carry the new SPI and execute; once one has, a TC under the
    old key is refused as an unknown SPI; a rekey wrapped under a key the board does not hold is refused."""
    sc = scenario_from_dict({"name": "x", "ground": {"upload_nominal_at_s": 0.0}})
    keys = sdls.KeyRing.generate()
    seg, fsw = compose.ground_segment(sc, keys=keys), compose.flight_software(sc, keys)
    downlink: tuple[bytes, ...] = ()
    sent: list[bytes] = []
    log: list[str] = []
    tm: list[pus.TmReport] = []

    def period(k: int, extra: tuple[bytes, ...] = ()) -> None:
        nonlocal downlink
        units, _, lines = seg.step(float(k), downlink, (float(k),) * len(downlink))
        sent.extend(units)
        log.extend(lines)
        req = StepRequest(step=k, obt_s=1000.0 + 0.1 * k, uplink=(*units, *extra),
                          sensors=SensorData(star_tracker_q=(0, 0, 0, 1), gyro_rad_s=(0, 0, 0),
                                             wheel_speed_rad_s=(0, 0, 0)))
        downlink = fsw.step(req, None).downlink
        tm.extend(pus.decode_tm(p)[1] for p in downlink)

    period(0)
    cmd = seg.rekey()
    assert cmd.spi == 3 and len(cmd.wrapped_key) == pus.WRAPPED_KEY_LEN
    period(1)
    # the nominal trajectory, the bad-pixel map and the rekey itself: still the old key until confirmed
    assert len(sent) >= 3 and {int.from_bytes(u[:2], "big") for u in sent} == {1}
    seg.queue(pus.Ping())
    period(2)  # ground hears the completion of the rekey, then sends the ping under the new key
    assert any("security association 3" in line for line in log)
    assert int.from_bytes(sent[-1][:2], "big") == 3
    assert [r for r in tm if isinstance(r, pus.PingReply)], "the TC under the new key did not execute"
    old = sdls.secure(pus.encode_tc(pus.Ping(), sc.obsw.apid, 77), keys.get(1), 10**6)
    period(3, (old,))
    refused = [r for r in tm if isinstance(r, pus.TcSecurityRejectedEvent)]
    assert [(r.spi, r.failure_code) for r in refused] == [(1, pus.FailureCode.UNKNOWN_SPI)]
    # a key wrapped under an association the board never held does not unwrap: refused at completion
    rogue = sdls.SecurityAssociation(3, bytes(32)).wrap(bytes(32))
    seg.queue(pus.RekeySecurityAssociation(spi=9, wrapped_key=rogue))
    period(4)
    failures = [r for r in tm if isinstance(r, pus.Verification) and not r.success]
    assert failures[-1].stage == pus.Stage.COMPLETION and "not wrapped under SPI 3" in failures[-1].reason
