"""A commanded clock adjustment (TC[200,7]) steps the oscillator by exactly its size, and the OBSW reports the jump."""

from __future__ import annotations

import pytest

from contracts import pus, sdls
from scenario.model import scenario_from_dict
from scenario import compose


@pytest.mark.parametrize("delta_s", [-2.5, 0.75])
def test_commanded_step_moves_obt_and_is_reported(delta_s: float) -> None:
    """OBT between the two periods around the command advances by the period plus delta; one ClockJumpEvent of delta."""
    sc = scenario_from_dict({"name": "x", "universe": {"start_s": -50.0, "end_s": -49.0}})
    u = compose.universe(sc)
    keys = sdls.KeyRing.generate()
    fsw = compose.flight_software(sc, keys)
    tc = sdls.Sender(keys).secure(pus.encode_tc(pus.AdjustObt(delta_s=delta_s), sc.obsw.apid, 3))
    req, _ = u.begin()
    req = req.model_copy(update={"uplink": (tc,)})
    obts, tm = [req.obt_s], []
    for _ in range(3):
        reply = fsw.step(req, None)
        tm += [pus.decode_tm(p)[1] for p in reply.downlink]
        nxt = u.advance(reply)
        assert nxt is not None
        req = nxt[0]
        obts.append(req.obt_s)
    dt = sc.universe.control_period_s
    # oscillator defaults: no drift, no jitter, so the model is exact
    assert obts[1] - obts[0] == pytest.approx(dt + delta_s, abs=1e-6)
    assert obts[2] - obts[1] == pytest.approx(dt, abs=1e-6)
    jumps = [r for r in tm if isinstance(r, pus.ClockJumpEvent)]
    assert len(jumps) == 1 and jumps[0].step_s == pytest.approx(delta_s, abs=1e-6)
    done = [r for r in tm if isinstance(r, pus.Verification) and r.stage == pus.Stage.COMPLETION]
    assert done and all(v.success for v in done)
    assert any("commanded clock step" in line for line in u.take_log())
