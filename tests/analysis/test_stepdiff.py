"""The step diff names each differing packet type and parameter with its first divergence and largest difference."""

from __future__ import annotations

import math

from analysis.stepdiff import ABSENT, COMMANDS, StepDiff, flatten
from contracts import pus
from contracts.messages import FrameRequest, StepReply


def _hk(obt: float, rate_z: float, mode: pus.Mode = pus.Mode.STANDBY, seq: int = 0) -> bytes:
    hk = pus.Housekeeping(mode=mode, q=(0.0, 0.0, 0.0, 1.0), rate_rad_s=(0.0, 0.0, rate_z),
                          wheel_speed_rad_s=(0.0, 0.0, 0.0), wheel_momentum_nms=(0.0, 0.0, 0.0),
                          pointing_error_rad=None, best_ca_obt_s=None, best_ca_distance_km=None, best_mse_rad2=None)
    return pus.encode_tm(hk, 0x0C1, seq, obt, seq)


def _reply(step: int, torque: tuple[float, ...], downlink: tuple[bytes, ...] = (),
           frame: bool = False) -> StepReply:
    return StepReply(step=step, wheel_torque_nm=torque, downlink=downlink,
                     frame_request=FrameRequest(exposure_s=0.01) if frame else None)


def test_flatten_names_parameters() -> None:
    """Nested models and tuples become dotted, indexed names; an absent sub-model is one None leaf."""
    flat = flatten(_reply(3, (1.0, 2.0)).model_copy(update={"downlink": ()}))
    assert flat["wheel_torque_nm[1]"] == 2.0 and flat["frame_request"] is None and flat["step"] == 3
    assert flatten(_reply(3, (1.0,), frame=True))["frame_request.exposure_s"] == 0.01


def test_identical_replies() -> None:
    """Equal replies are identical and leave no row."""
    d = StepDiff()
    for k in range(5):
        assert d.compare(k, 10.0 + k, _reply(k, (1e-3, -0.0), (_hk(10.0 + k, 0.1),)),
                         _reply(k, (1e-3, -0.0), (_hk(10.0 + k, 0.1),)))
    assert d.identical and d.steps == 5 and d.rows() == []


def test_rows_count_first_and_largest() -> None:
    """A torque differing by 1, 3, 2 at steps 2, 3, 4 reports 3 samples, first at step 2, largest 3 at step 3;
    a housekeeping rate and mode differing at step 4 are named under the housekeeping packet; an extra event is a
    packet the recording lacks."""
    d = StepDiff()
    extra = pus.encode_tm(pus.TargetLostEvent(unseen_s=12.0), 0x0C1, 9, 14.0, 9)
    for k, delta in enumerate([0.0, 0.0, 1.0, 3.0, 2.0]):
        rec = _reply(k, (5.0, 1.0), (_hk(10.0 + k, 0.1),))
        rate, mode, down = 0.1, pus.Mode.STANDBY, ()
        if k == 4:
            rate, mode, down = 0.25, pus.Mode.SAFE, (extra,)
        rep = _reply(k, (5.0 + delta, 1.0), (_hk(10.0 + k, rate, mode), *down))
        assert d.compare(k, 10.0 + k, rec, rep) == (delta == 0.0)
    assert not d.identical and d.differing_steps == 3
    rows = {(p.packet, p.parameter): p for p in d.rows()}
    t = rows[(COMMANDS, "wheel_torque_nm[0]")]
    assert (t.count, t.first_step, t.first_obt_s) == (3, 2, 12.0)
    assert math.isclose(t.largest or 0, 3.0) and t.largest_step == 3
    assert (COMMANDS, "wheel_torque_nm[1]") not in rows
    hk = "Housekeeping [3,25]"
    rate = rows[(hk, "rate_rad_s[2]")]
    assert rate.first_step == 4 and math.isclose(rate.largest or 0, 0.15, abs_tol=1e-6)
    assert rows[(hk, "mode")].largest is None and rows[(hk, "mode")].first_replayed == pus.Mode.SAFE
    ev = next(p for (pk, par), p in rows.items() if pk.startswith("TargetLostEvent") and par == "(packet)")
    assert (ev.first_recorded, ev.first_replayed) == (ABSENT, "sent")
    assert d.first() is t
