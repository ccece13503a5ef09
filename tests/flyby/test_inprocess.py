"""The in-process runner: the three cores exchanging what the nodes exchange, to the end of the run."""

from __future__ import annotations

from pathlib import Path

from pydantic import BaseModel

from contracts.messages import StepReply, StepRequest
from flyby.inprocess import run_in_process
from scenario.model import load_run_inputs, scenario_from_dict

ROOT = Path(__file__).resolve().parents[2]


def test_a_link_too_slow_to_drain_stops_at_the_drain_limit() -> None:
    """Telemetry still in flight drain_limit_s after the run's end is dropped, counted as lost and logged: a slow
    link's backlog never holds the run for days."""
    sc = scenario_from_dict({"name": "slow", "universe": {"drain_limit_s": 60.0, "link": {"downlink_rate_bps": 1e-3}}})
    out = run_in_process(sc, None, max_steps=20)
    assert any("still in flight 60 s after the run's end (universe.drain_limit_s): dropped" in x for x in out.log)
    assert out.received == []  # one bit per 1000 s: nothing arrived


def _types(m: object) -> object:
    """Each field's type, nested models and tuples' items included."""
    if isinstance(m, BaseModel):
        return {k: _types(v) for k, v in m.__dict__.items()}
    if isinstance(m, tuple):
        return tuple(_types(v) for v in m)
    return type(m)


def test_the_lock_step_messages_are_what_validation_makes_of_them() -> None:
    """The flight software's replies, made without validation, and the universe's step requests equal what
    validating their contents gives, value for value and type for type (no list, array or NumPy scalar), at every
    step of a run with frames, measurements, uplinked commands and a processor overload."""
    sc, tl = load_run_inputs(ROOT / "configs" / "scenarios" / "faults" / "cpu-overload.yaml")
    sc = sc.model_copy(update={"universe": sc.universe.model_copy(update={"fidelity": "centroid"})})
    seen = {"frames": 0, "uplink": 0, "slowed": 0}

    def check(req: StepRequest, reply: StepReply, frame: object) -> None:
        for m in (req, reply):
            again = type(m).model_validate(m.model_dump())
            assert again == m and _types(again) == _types(m), (type(m).__name__, m.step)
        seen["frames"] += req.frame is not None
        seen["uplink"] += bool(req.uplink)
        seen["slowed"] += req.cpu_slowdown > 1.0

    run_in_process(sc, tl, on_step=check)
    assert seen["frames"] > 100 and seen["uplink"] > 0 and seen["slowed"] > 0, seen
