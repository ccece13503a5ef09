"""The mode manager: the flyby sequence, the allowed graph, one report per transition, typed refusals."""

from __future__ import annotations

import math

import pytest
from hypothesis import settings
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, invariant, rule

from contracts.task import Task
from obsw.config import ModesConfig
from obsw.errors import CommandRejected, IllegalTransition, InternalFault, RejectReason
from obsw.executive import Activation, EventKind, Executive, TaskSpec
from obsw.modes import (
    CaEstimate,
    Cause,
    FalseLock,
    Fault,
    Mode,
    ModeManager,
    SetMode,
    TargetDetected,
    Tick,
    WheelSaturation,
    allowed_transitions,
)
from obsw.table import ScheduleTable
from obsw.timing import Work

SAFE, SB, AQ, NT, AT = "SAFE", "STANDBY", "ACQUISITION", "NOMINAL_TRACKING", "AUTONOMOUS_TRACKING"

# The graph written out by hand from the mode design (DESIGN.md, paper): the independent truth of these tests.
COMMANDS = {SAFE: {SB}, SB: {SAFE, AQ}, AQ: {SAFE, SB}, NT: {SAFE, SB, AQ, AT}, AT: {SAFE, SB}}
GRAPH = {(a, b) for a, bs in COMMANDS.items() for b in bs} | {
    (SB, SAFE), (AQ, SAFE), (NT, SAFE), (AT, SAFE),  # fault / wheel saturation
    (AQ, NT),  # target acquired
    (NT, AT),  # C/A-30 s by the on-board estimate, or a false lock
    (NT, AQ),  # target lost
    (AQ, SB), (NT, SB), (AT, SB),  # flyby over
}  # fmt: skip


def test_table_graph_is_the_designed_graph() -> None:
    """The edges the table can produce are exactly the designed graph."""
    assert {(a.name, b.name) for a, b in allowed_transitions()} == GRAPH


def test_nominal_flyby_sequence() -> None:
    """STANDBY -> ACQUISITION (command) -> NOMINAL (detection) -> AUTONOMOUS (C/A-30 s) -> STANDBY (C/A+90 s)."""
    cfg = ModesConfig()
    m = ModeManager(cfg)
    ca = 1000.0
    events = [m.handle(SetMode(Mode.ACQUISITION), ca - 240.0), m.handle(CaEstimate(ca), ca - 200.0)]
    for k in range(2400):  # 10 Hz from C/A-200 s to C/A+40 s, target seen every second
        t = ca - 200.0 + 0.1 * k
        if k % 10 == 0:
            events.append(m.handle(TargetDetected(), t))
        events.append(m.handle(Tick(), t))
    events.append(m.handle(Tick(), ca + 89.9))
    events.append(m.handle(Tick(), ca + 90.0))
    reports = [e for e in events if e is not None]
    assert [(e.from_mode, e.to_mode, e.cause) for e in reports] == [
        (Mode.STANDBY, Mode.ACQUISITION, Cause.COMMANDED),
        (Mode.ACQUISITION, Mode.NOMINAL_TRACKING, Cause.TARGET_ACQUIRED),
        (Mode.NOMINAL_TRACKING, Mode.AUTONOMOUS_TRACKING, Cause.AUTONOMY_TIME),
        (Mode.AUTONOMOUS_TRACKING, Mode.STANDBY, Cause.FLYBY_OVER),
    ]
    assert reports[1].obt_s == ca - 200.0
    assert reports[2].obt_s == pytest.approx(ca - 30.0, abs=0.1 + 1e-9) and reports[2].obt_s >= ca - 30.0
    assert reports[3].obt_s == ca + 90.0 and "1000.000" in reports[3].detail


def test_target_lost_only_in_nominal_tracking() -> None:
    """Unseen past the timeout: NOMINAL goes back to ACQUISITION, AUTONOMOUS keeps tracking on its trajectory."""
    cfg = ModesConfig(target_lost_timeout_s=10.0)
    m = ModeManager(cfg, initial=Mode.ACQUISITION)
    m.handle(TargetDetected(), 0.0)
    assert m.handle(Tick(), 10.0) is None  # exactly the timeout: not yet lost
    lost = m.handle(Tick(), 10.01)
    assert lost is not None and (lost.to_mode, lost.cause) == (Mode.ACQUISITION, Cause.TARGET_LOST)
    m.handle(TargetDetected(), 20.0)
    m.handle(SetMode(Mode.AUTONOMOUS_TRACKING), 21.0)
    assert all(m.handle(Tick(), 21.0 + k) is None for k in range(100))
    assert m.mode == Mode.AUTONOMOUS_TRACKING


def test_a_false_lock_hands_nominal_tracking_over_to_autonomous_tracking_only() -> None:
    """A false lock in NOMINAL_TRACKING gives AUTONOMOUS_TRACKING (cause FALSE_LOCK, naming the frame) at once; in
    any other mode it changes nothing."""
    m = ModeManager(ModesConfig(), initial=Mode.NOMINAL_TRACKING)
    e = m.handle(FalseLock(128), 5.0)
    assert e is not None and (e.from_mode, e.to_mode, e.cause, e.obt_s) == (
        Mode.NOMINAL_TRACKING, Mode.AUTONOMOUS_TRACKING, Cause.FALSE_LOCK, 5.0)
    assert e.detail == "frame 128 refused"
    for start in (Mode.SAFE, Mode.STANDBY, Mode.ACQUISITION, Mode.AUTONOMOUS_TRACKING):
        m = ModeManager(ModesConfig(), initial=start)
        assert m.handle(FalseLock(1), 5.0) is None and m.mode == start


def test_faults_go_safe_and_only_a_command_leaves_safe() -> None:
    """Fault or saturation from any non-SAFE mode gives SAFE; in SAFE events do nothing; only STANDBY is commandable."""
    for start in (Mode.STANDBY, Mode.ACQUISITION, Mode.NOMINAL_TRACKING, Mode.AUTONOMOUS_TRACKING):
        for trig, cause in ((Fault("star tracker lost"), Cause.FAULT), (WheelSaturation(2), Cause.WHEEL_SATURATION)):
            m = ModeManager(ModesConfig(), initial=start)
            e = m.handle(trig, 5.0)
            assert e is not None and (e.from_mode, e.to_mode, e.cause) == (start, Mode.SAFE, cause)
            assert e.detail in ("star tracker lost", "wheel 2")
    m = ModeManager(ModesConfig(), initial=Mode.SAFE)
    m.handle(CaEstimate(0.0), 0.0)
    for trig in (TargetDetected(), Tick(), Fault("x"), WheelSaturation()):
        assert m.handle(trig, 100.0) is None
    with pytest.raises(IllegalTransition) as err:
        m.handle(SetMode(Mode.ACQUISITION), 101.0)
    assert isinstance(err.value, CommandRejected) and err.value.reason == RejectReason.ILLEGAL_TRANSITION
    assert "cannot command ACQUISITION from SAFE; allowed from SAFE: STANDBY" in str(err.value)
    assert m.mode == Mode.SAFE
    assert m.handle(SetMode(Mode.STANDBY), 102.0) is not None and m.mode == Mode.STANDBY


def test_reasserting_the_mode_is_accepted_silently() -> None:
    """Commanding the current mode is not an error and reports no transition."""
    m = ModeManager(ModesConfig(), initial=Mode.ACQUISITION)
    assert m.handle(SetMode(Mode.ACQUISITION), 1.0) is None and m.mode == Mode.ACQUISITION


def test_bad_internal_inputs_are_internal_faults() -> None:
    """A non-finite OBT or C/A, or an unknown trigger, is the flight software's own fault."""
    m = ModeManager(ModesConfig())
    with pytest.raises(InternalFault, match="obt_s"):
        m.handle(Tick(), math.nan)
    with pytest.raises(InternalFault, match="ca_obt_s"):
        m.handle(CaEstimate(math.inf), 0.0)
    with pytest.raises(InternalFault, match="unknown trigger"):
        m.handle("go", 0.0)  # type: ignore[arg-type]


def reference_next(mode: str, trigger: object, obt: float, ca: float | None, seen: float | None,
                   cfg: ModesConfig) -> str | None:
    """The hand-written reference: the mode after ``trigger`` at ``obt``, or None when the command must be refused."""
    if isinstance(trigger, SetMode):
        t = trigger.mode.name
        return t if (t == mode or t in COMMANDS[mode]) else None
    if isinstance(trigger, (Fault, WheelSaturation)):
        return SAFE
    if isinstance(trigger, TargetDetected):
        return NT if mode == AQ else mode
    if isinstance(trigger, FalseLock):
        return AT if mode == NT else mode
    if isinstance(trigger, Tick):
        if mode in (AQ, NT, AT) and ca is not None and obt >= ca + cfg.standby_after_ca_s:
            return SB
        if mode == NT and ca is not None and obt >= ca - cfg.autonomous_before_ca_s:
            return AT
        if mode == NT and seen is not None and obt - seen > cfg.target_lost_timeout_s:
            return AQ
    return mode


def reference_seen(mode: str, trigger: object, obt: float, seen: float | None) -> float | None:
    """The reference's last detection time after ``trigger`` left the manager in ``mode``."""
    if mode not in (NT, AT):
        return None
    return obt if isinstance(trigger, TargetDetected) else seen


def draw_trigger(kind: str, mode: str, data: st.DataObject) -> object:
    """A command (onwards, legal or any), a detection or a failure, weighted to reach the tracking modes."""
    onwards = sorted(COMMANDS[mode] - {SAFE, SB}) or sorted(COMMANDS[mode])
    if kind == "forward_command":
        return SetMode(Mode[data.draw(st.sampled_from(onwards))])
    if kind == "legal_command":
        return SetMode(Mode[data.draw(st.sampled_from(sorted(COMMANDS[mode])))])
    if kind == "any_command":
        return SetMode(data.draw(st.sampled_from(list(Mode))))
    if kind == "detection":
        return TargetDetected()
    if kind == "false_lock":
        return FalseLock(data.draw(st.integers(0, 1000)))
    return data.draw(st.sampled_from([Fault("injected"), WheelSaturation(0)]))


class ModesVersusReference(RuleBasedStateMachine):
    """Any sequence of commands, events, estimates and time (jumps back included) against a hand-written reference."""

    def __init__(self) -> None:
        super().__init__()
        self.cfg = ModesConfig()
        self.m = ModeManager(self.cfg)
        self.mode = SB
        self.obt = 0.0
        self.ca: float | None = None
        self.seen: float | None = None

    def _apply(self, trigger: object) -> None:
        expected = reference_next(self.mode, trigger, self.obt, self.ca, self.seen, self.cfg)
        before = self.mode
        if expected is None:
            with pytest.raises(IllegalTransition):
                self.m.handle(trigger, self.obt)  # type: ignore[arg-type]
            assert self.m.mode.name == before
            return
        event = self.m.handle(trigger, self.obt)  # type: ignore[arg-type]
        assert self.m.mode.name == expected
        if expected == before:
            assert event is None
        else:
            assert event is not None
            assert (event.from_mode.name, event.to_mode.name, event.obt_s) == (before, expected, self.obt)
            assert (before, expected) in GRAPH
        self.mode = expected
        self.seen = reference_seen(self.mode, trigger, self.obt, self.seen)

    # one rule with weighted kinds, so that the walk leaves SAFE and reaches the tracking modes often
    @rule(
        kind=st.sampled_from(
            ["tick"] * 4
            + ["forward_command"] * 3
            + ["detection"] * 3
            + ["ca"] * 2
            + ["legal_command", "any_command", "failure", "false_lock"]
        ),
        data=st.data(),
    )
    def step(self, kind: str, data: st.DataObject) -> None:
        """A command (onwards, legal or any), a detection, a failure, a C/A estimate, or time moving (back too)."""
        if kind == "ca":
            self.ca = self.obt + data.draw(st.floats(-150.0, 150.0))
            self._apply(CaEstimate(self.ca))
        elif kind == "tick":
            self.obt += data.draw(st.floats(0.0, 12.0) | st.floats(0.0, 60.0) | st.floats(-20.0, 0.0))
            self._apply(Tick())
        else:
            self._apply(draw_trigger(kind, self.mode, data))

    @invariant()
    def mode_is_legal(self) -> None:
        """The mode is always one of the five, and the reference's."""
        assert isinstance(self.m.mode, Mode)
        assert self.m.mode.name == self.mode


ModesVersusReference.TestCase.settings = settings(max_examples=80, stateful_step_count=30, deadline=None)
test_modes_match_reference = ModesVersusReference.TestCase


# --- the mode manager as a task of the executive ----------------------------------------------------------------

PERIOD = 0.1
QUICK = ModesConfig(autonomous_before_ca_s=0.5, standby_after_ca_s=1.0, target_lost_timeout_s=0.35)
EVENT_OF = {SetMode: EventKind.TC_ARRIVED, TargetDetected: EventKind.MEASUREMENT, Fault: EventKind.PARAM_CHECK_FAILED,
            WheelSaturation: EventKind.PARAM_CHECK_FAILED}


class ModesInTheExecutive(RuleBasedStateMachine):
    """Triggers posted at random on-board times, C/A estimates and minor frames whose mode task starts anywhere in
    the frame (a TIME task of random length before it): every transition is made in the first minor frame whose
    mode task starts at or after its trigger (an event's time, or the time a guard becomes true), at that start,
    as the reference says; a refused command changes nothing."""

    def __init__(self) -> None:
        super().__init__()
        self.m = ModeManager(QUICK)
        self.made: list[tuple[float, str, str]] = []
        self.time_cost = 0.0
        specs = {t: TaskSpec(lambda act: Work()) for t in Task}
        specs[Task.MODES] = TaskSpec(self._modes_task, frozenset(EVENT_OF.values()))
        self.ex = Executive(ScheduleTable(), PERIOD, specs,
                            lambda task, work: self.time_cost if task == Task.TIME else 0.0)
        self.frame = 0
        self.pending: list[tuple[float, int, object]] = []  # the reference's queue: (time, order posted, trigger)
        self.posted = 0
        self.mode, self.ca, self.seen = SB, None, None

    def _modes_task(self, act: Activation) -> Work:
        for ev in act.events:
            try:
                e = self.m.handle(ev.payload, act.now_s)  # type: ignore[arg-type]
            except IllegalTransition:
                continue
            if e is not None:
                self.made.append((e.obt_s, e.from_mode.name, e.to_mode.name))
        e = self.m.handle(Tick(), act.now_s)
        if e is not None:
            self.made.append((e.obt_s, e.from_mode.name, e.to_mode.name))
        return Work()

    @property
    def tick(self) -> float:
        return 1000.0 + self.frame * PERIOD

    @rule(kind=st.sampled_from(["forward_command"] * 6 + ["detection"] * 6 + ["legal_command", "any_command",
                                                                            "failure"]),
          after_s=st.floats(0.0, 0.35), data=st.data())
    def post(self, kind: str, after_s: float, data: st.DataObject) -> None:
        """A trigger that exists on board from a random time in this or one of the next minor frames."""
        trigger = draw_trigger(kind, self.mode, data)
        self.ex.post(EVENT_OF[type(trigger)], self.tick + after_s, trigger)
        self.pending.append((self.tick + after_s, self.posted, trigger))
        self.posted += 1

    @rule(offset_s=st.floats(-1.5, 2.0))
    def ca_estimate(self, offset_s: float) -> None:
        """A new C/A estimate, a little before or after now, so the time-driven rows come true within frames."""
        self.ca = self.tick + offset_s
        self.m.handle(CaEstimate(self.ca), self.tick)

    @rule(time_cost_s=st.floats(0.0, 0.075))
    def minor_frame(self, time_cost_s: float) -> None:
        """One minor frame; the mode task starts after TIME (the tasks between cost nothing) before its deadline."""
        self.time_cost = time_cost_s
        start = self.tick + time_cost_s
        made_before = len(self.made)
        self.ex.minor_frame(self.tick)
        expected = []
        due = sorted(p for p in self.pending if p[0] <= start)
        self.pending = [p for p in self.pending if p[0] > start]
        for _, _, trigger in [*due, (start, -1, Tick())]:
            after = reference_next(self.mode, trigger, start, self.ca, self.seen, QUICK)
            if after is None:
                continue
            if after != self.mode:
                expected.append((start, self.mode, after))
            self.mode = after
            self.seen = reference_seen(after, trigger, start, self.seen)
        assert self.made[made_before:] == expected
        assert self.m.mode.name == self.mode
        self.frame += 1


ModesInTheExecutive.TestCase.settings = settings(max_examples=80, stateful_step_count=60, deadline=None)
test_modes_in_the_executive_match_reference = ModesInTheExecutive.TestCase
