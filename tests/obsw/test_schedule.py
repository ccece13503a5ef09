"""The PUS 11 time-based schedule: rejections, order, re-anchoring, and exactly-once release under any clock."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, invariant, precondition, rule

from obsw.errors import CommandRejected, InternalFault, RejectReason
from obsw.schedule import ScheduledCommand, ScheduleRequest, Selection, TimeBasedSchedule
from universe.config import OscillatorConfig
from universe.oscillator import Oscillator

# --- rejections and basic rules -------------------------------------------------------------------


def _req(
    rid: int, tag: float, priority: int = 0, ca_offset_s: float | None = None, payload: object = b""
) -> ScheduleRequest:
    return ScheduleRequest(request_id=rid, tag_obt_s=tag, payload=payload, priority=priority, ca_offset_s=ca_offset_s)


def _known_commands(payload: object) -> None:
    """A two-command dictionary: b'IMG' takes no argument, b'MODE' one digit 0-4."""
    if not isinstance(payload, bytes) or not payload:
        raise CommandRejected(RejectReason.MALFORMED, "payload must be non-empty bytes")
    name, _, arg = payload.partition(b" ")
    if name == b"IMG" and not arg:
        return
    if name == b"MODE":
        if arg.isdigit() and int(arg) <= 4:
            return
        raise CommandRejected(RejectReason.BAD_ARGUMENT, f"MODE argument {arg!r} is not a mode 0-4")
    raise CommandRejected(RejectReason.UNKNOWN_COMMAND, f"unknown command {name!r}")


def test_each_rejection_names_entry_and_reason() -> None:
    """Every refused request comes back once, with its index, id, reason code and a text naming the fault."""
    s = TimeBasedSchedule(capacity=3, margin_s=2.0, payload_check=_known_commands)
    rej = s.insert(
        100.0,
        [
            _req(1, 110.0, payload=b"IMG"),  # accepted
            _req(2, 99.0, payload=b"IMG"),  # past
            _req(3, 101.0, payload=b"IMG"),  # within margin
            _req(1, 120.0, payload=b"IMG"),  # duplicate of 1
            _req(4, float("nan"), payload=b"IMG"),  # malformed
            _req(5, 130.0, payload=b"FIRE"),  # unknown
            _req(6, 130.0, payload=b"MODE 9"),  # bad argument
            _req(7, 102.0, payload=b"MODE 2"),  # accepted: exactly at the margin
            _req(8, 140.0, payload=b"IMG"),  # accepted (third)
            _req(9, 150.0, payload=b"IMG"),  # full
        ],
    )
    got = [(r.index, r.request_id, r.reason) for r in rej]
    assert got == [
        (1, 2, RejectReason.TAG_IN_PAST),
        (2, 3, RejectReason.TAG_WITHIN_MARGIN),
        (3, 1, RejectReason.DUPLICATE_REQUEST),
        (4, 4, RejectReason.MALFORMED),
        (5, 5, RejectReason.UNKNOWN_COMMAND),
        (6, 6, RejectReason.BAD_ARGUMENT),
        (9, 9, RejectReason.SCHEDULE_FULL),
    ]
    assert all(f"request {r.request_id}" in r.text for r in rej)
    assert "2.0 s margin" in rej[1].text and "full (3 entries)" in rej[6].text
    assert [e.request_id for e in s.listing()] == [7, 1, 8]


def test_non_request_entry_is_malformed() -> None:
    """An entry that is not a ScheduleRequest is refused as MALFORMED with no request id."""
    s = TimeBasedSchedule(capacity=4, margin_s=0.0)
    (r,) = s.insert(0.0, [("not", "a", "request")])  # type: ignore[list-item]
    assert (r.index, r.request_id, r.reason) == (0, None, RejectReason.MALFORMED)
    assert len(s) == 0


def test_ties_break_on_priority_then_insertion() -> None:
    """Equal tags release by ascending priority, then in the order they were accepted."""
    s = TimeBasedSchedule(capacity=10, margin_s=0.0)
    s.insert(0.0, [_req(1, 5.0, priority=1), _req(2, 5.0, priority=0), _req(3, 5.0, priority=1), _req(4, 4.0, 9)])
    s.insert(0.0, [_req(5, 5.0, priority=0)])
    assert [e.request_id for e in s.release_due(4.99)] == [4]
    assert [e.request_id for e in s.release_due(5.0)] == [2, 5, 1, 3]
    assert s.release_due(1e9) == []


def test_time_shift_is_atomic_and_checked() -> None:
    """A shift bringing any selected tag within the margin changes nothing; a legal one moves only the selection."""
    s = TimeBasedSchedule(capacity=10, margin_s=1.0)
    s.insert(0.0, [_req(1, 10.0), _req(2, 20.0), _req(3, 30.0)])
    with pytest.raises(CommandRejected) as err:
        s.time_shift(0.0, -9.5)
    assert err.value.reason == RejectReason.TAG_WITHIN_MARGIN and "request 1 shifted by -9.5 s" in err.value.text
    assert [e.tag_obt_s for e in s.listing()] == [10.0, 20.0, 30.0]
    moved = s.time_shift(0.0, -15.0, Selection(from_obt_s=15.0))
    assert [(e.request_id, e.tag_obt_s) for e in moved] == [(2, 5.0), (3, 15.0)]
    assert [e.request_id for e in s.listing()] == [2, 1, 3]
    with pytest.raises(CommandRejected) as err:
        s.time_shift(0.0, float("inf"))
    assert err.value.reason == RejectReason.MALFORMED


def test_delete_refuses_unknown_and_released_ids() -> None:
    """Deleting a released or unknown request is refused with its own reason and deletes nothing."""
    s = TimeBasedSchedule(capacity=10, margin_s=0.0)
    s.insert(0.0, [_req(1, 1.0), _req(2, 2.0), _req(3, 3.0)])
    s.release_due(1.0)
    with pytest.raises(CommandRejected) as err:
        s.delete(Selection(request_ids=frozenset({1, 2})))
    assert err.value.reason == RejectReason.ALREADY_RELEASED and "request 1" in err.value.text
    with pytest.raises(CommandRejected) as err:
        s.delete(Selection(request_ids=frozenset({2, 7})))
    assert err.value.reason == RejectReason.UNKNOWN_REQUEST and "request 7" in err.value.text
    assert len(s) == 2
    assert [e.request_id for e in s.delete(Selection(request_ids=frozenset({3})))] == [3]
    assert s.summary().pending == 1 and s.summary().released == 1


def test_ca_relative_entries_follow_the_anchor() -> None:
    """Before an estimate the ground's tag holds; after, tag = C/A + offset, shifts move the offset too."""
    s = TimeBasedSchedule(capacity=10, margin_s=0.0)
    s.insert(0.0, [_req(1, 100.0, ca_offset_s=-10.0), _req(2, 95.0)])
    assert [(e.request_id, e.tag_obt_s) for e in s.listing()] == [(2, 95.0), (1, 100.0)]
    s.reanchor_ca(120.0)
    assert [(e.request_id, e.tag_obt_s) for e in s.listing()] == [(2, 95.0), (1, 110.0)]
    s.time_shift(0.0, 2.0, Selection(ca_relative=True))
    s.reanchor_ca(130.0)
    assert s.listing()[1].tag_obt_s == 122.0 and s.listing()[1].ca_offset_s == -8.0
    s.insert(0.0, [_req(3, 1.0, ca_offset_s=5.0)])  # the ground's tag is superseded by the board's C/A
    assert s.listing()[-1].tag_obt_s == 135.0
    summary = s.summary()
    assert (summary.ca_anchor_obt_s, summary.ca_relative_pending, summary.first_tag_obt_s) == (130.0, 2, 95.0)


def test_reanchor_into_the_past_releases_late_not_twice() -> None:
    """An entry re-anchored before now is released at the next tick, once; released ones never come back."""
    s = TimeBasedSchedule(capacity=10, margin_s=0.0)
    s.insert(0.0, [_req(1, 50.0, ca_offset_s=-10.0), _req(2, 55.0, ca_offset_s=-5.0)])
    assert s.release_due(50.0)[0].request_id == 1
    s.reanchor_ca(40.0)  # both now in the past
    assert [e.request_id for e in s.release_due(51.0)] == [2]
    s.time_shift(51.0, 0.0)
    s.reanchor_ca(100.0)
    assert s.release_due(1e6) == []


def test_a_ca_relative_entry_already_past_is_taken_and_released_at_the_next_tick() -> None:
    """A C/A-relative entry arriving after its tag (or within the margin) was meant for before now: it is accepted
    and released at the next tick with its tag; an absolute tag in the past is still refused."""
    s = TimeBasedSchedule(capacity=10, margin_s=1.0)
    rejected = s.insert(100.0, [_req(1, 90.0, ca_offset_s=-240.0), _req(2, 100.5, ca_offset_s=-229.5), _req(3, 90.0)])
    assert [(r.index, r.reason) for r in rejected] == [(2, RejectReason.TAG_IN_PAST)]
    assert [(e.request_id, e.tag_obt_s) for e in s.release_due(100.1)] == [(1, 90.0)]
    assert [e.request_id for e in s.release_due(100.5)] == [2]


def test_internal_times_must_be_finite() -> None:
    """A non-finite on-board time or C/A estimate is an InternalFault, not a ground rejection."""
    s = TimeBasedSchedule(capacity=1, margin_s=0.0)
    with pytest.raises(InternalFault, match="now_obt_s"):
        s.release_due(math.nan)
    with pytest.raises(InternalFault, match="new_ca_obt_s"):
        s.reanchor_ca(math.inf)
    with pytest.raises(ValueError, match="capacity"):
        TimeBasedSchedule(capacity=0, margin_s=0.0)


# --- the schedule driven by an imperfect clock ----------------------------------------------------

TICK_S = 0.1
MARGIN_S = 1.0


@settings(max_examples=60, deadline=None)
@given(
    offset_s=st.floats(-1e4, 1e4),
    drift_ppm=st.floats(-100.0, 100.0),
    drift_rate_ppm_per_day=st.floats(-10.0, 10.0),
    jitter_s=st.floats(0.0, 1e-3),
    seed=st.integers(0, 2**32 - 1),
    timeline=st.lists(st.tuples(st.floats(0.0, 30.0), st.integers(0, 3)), min_size=1, max_size=40),
)
def test_every_command_released_once_in_order_within_one_tick(
    offset_s: float,
    drift_ppm: float,
    drift_rate_ppm_per_day: float,
    jitter_s: float,
    seed: int,
    timeline: list[tuple[float, int]],
) -> None:
    """Offset<=1e4 s, drift<=100 ppm, ageing<=10 ppm/day, jitter<=1 ms: once, in order, not early, <=1 tick late."""
    cfg = OscillatorConfig(
        initial_offset_s=offset_s, drift_ppm=drift_ppm, drift_rate_ppm_per_day=drift_rate_ppm_per_day, jitter_s=jitter_s
    )
    osc = Oscillator(cfg, np.random.default_rng(seed))
    sched = TimeBasedSchedule(capacity=64, margin_s=MARGIN_S)
    t0 = -50.0
    now = osc.obt_s(t0)
    requests = [_req(i, now + MARGIN_S + dt, priority=p) for i, (dt, p) in enumerate(timeline)]
    assert sched.insert(now, requests) == []
    released: list[tuple[int, float, float, float, ScheduledCommand]] = []  # (tick, t, obt, previous obt, entry)
    previous_obt = now
    for k in range(1, int(40.0 / TICK_S)):
        t = t0 + k * TICK_S
        obt = osc.obt_s(t)
        released += [(k, t, obt, previous_obt, e) for e in sched.release_due(obt)]
        previous_obt = obt
    assert sorted(r[4].request_id for r in released) == list(range(len(timeline)))
    keys = [r[4].key for r in released]
    assert keys == sorted(keys)
    bound_s = cfg.jitter_bound_sigma * jitter_s / (1.0 - 1e-4) + 1e-6  # jitter as true time, slowest clock
    for _, t, obt, prev, e in released:
        assert prev < e.tag_obt_s <= obt  # first tick at or after the tag: not early, not a tick late
        t_tag = osc.true_s(e.tag_obt_s)
        assert -bound_s <= t - t_tag <= TICK_S + bound_s


def test_burst_stays_centred_on_true_ca_after_reanchor() -> None:
    """An 11-frame burst at C/A-5..+5 s, tagged on a C/A 7 s wrong, is re-centred on the true C/A by one estimate."""
    cfg = OscillatorConfig(initial_offset_s=1234.5, drift_ppm=40.0, jitter_s=2e-4)
    osc = Oscillator(cfg, np.random.default_rng(3))
    true_ca_s = 168.0
    ground_ca_obt = osc.obt_mean_s(true_ca_s) + 7.0
    sched = TimeBasedSchedule(capacity=32, margin_s=MARGIN_S)
    t = -100.0
    burst = [_req(i, ground_ca_obt + off, ca_offset_s=float(off)) for i, off in enumerate(range(-5, 6))]
    assert sched.insert(osc.obt_s(t), burst) == []
    frames_at: list[float] = []
    while t < 200.0:
        t = round(t + TICK_S, 10)
        if t == 130.0:  # the on-board trajectory recognition converges on the true C/A
            sched.reanchor_ca(osc.obt_mean_s(true_ca_s))
        frames_at += [t for _ in sched.release_due(osc.obt_s(t))]
    assert len(frames_at) == 11
    assert np.mean(frames_at) == pytest.approx(true_ca_s, abs=TICK_S)
    assert np.diff(frames_at) == pytest.approx(np.ones(10), abs=TICK_S + 1e-6)


# --- stateful: the schedule against a plain sorted-list model --------------------------------------


class ScheduleVersusModel(RuleBasedStateMachine):
    """Random inserts, deletes, shifts, re-anchors, clock jumps and ticks; the model is a list sorted on each use."""

    CAPACITY = 8
    MARGIN = 1.0

    def __init__(self) -> None:
        super().__init__()
        self.sched = TimeBasedSchedule(capacity=self.CAPACITY, margin_s=self.MARGIN)
        self.now = 0.0
        self.model: list[dict] = []  # {"id", "tag", "prio", "seq", "off"}
        self.anchor: float | None = None
        self.seq = 0
        self.next_id = 0
        self.released_seqs: set[int] = set()
        self.released_ids: set[int] = set()

    def _sorted_model(self) -> list[dict]:
        return sorted(self.model, key=lambda m: (m["tag"], m["prio"], m["seq"]))

    @rule(
        batch=st.lists(
            st.tuples(
                st.integers(-5, 60).map(float) | st.floats(-5.0, 60.0),  # whole seconds make tag ties
                st.integers(0, 2),
                st.none() | st.floats(-20.0, 20.0),
                st.sampled_from(["new"] * 6 + ["duplicate", "nan"]),
            ),
            max_size=5,
        )
    )
    def insert(self, batch: list[tuple[float, int, float | None, str]]) -> None:
        """Insert a batch: the rejections and the accepted entries match the model's verdict."""
        requests, expected = [], []
        pending = {m["id"] for m in self.model}
        for index, (dt, prio, off, kind) in enumerate(batch):
            if kind == "duplicate" and pending:
                rid = min(pending)
            else:
                rid, self.next_id = self.next_id, self.next_id + 1
            tag = math.nan if kind == "nan" else self.now + dt
            requests.append(_req(rid, tag, prio, off))
            if kind == "nan":
                expected.append((index, RejectReason.MALFORMED))
                continue
            if rid in pending:
                expected.append((index, RejectReason.DUPLICATE_REQUEST))
                continue
            eff = self.anchor + off if (off is not None and self.anchor is not None) else tag
            if off is None and eff < self.now:  # a C/A-relative tag already past is taken and released late
                expected.append((index, RejectReason.TAG_IN_PAST))
            elif off is None and eff < self.now + self.MARGIN:
                expected.append((index, RejectReason.TAG_WITHIN_MARGIN))
            elif len(self.model) >= self.CAPACITY:
                expected.append((index, RejectReason.SCHEDULE_FULL))
            else:
                self.model.append({"id": rid, "tag": eff, "prio": prio, "seq": self.seq, "off": off})
                self.seq += 1
                pending.add(rid)
        got = [(r.index, r.reason) for r in self.sched.insert(self.now, requests)]
        assert got == expected

    @precondition(lambda self: self.model)
    @rule(data=st.data())
    def delete_some(self, data: st.DataObject) -> None:
        """Delete a random subset of pending ids: exactly those leave."""
        ids = data.draw(st.sets(st.sampled_from(sorted(m["id"] for m in self.model))))
        gone = self.sched.delete(Selection(request_ids=frozenset(ids)))
        assert sorted(e.request_id for e in gone) == sorted(ids)
        self.model = [m for m in self.model if m["id"] not in ids]

    @precondition(lambda self: self.released_ids)
    @rule(data=st.data())
    def delete_released(self, data: st.DataObject) -> None:
        """Deleting a released (and not re-used) id is refused and changes nothing."""
        rid = data.draw(st.sampled_from(sorted(self.released_ids)))
        if rid in {m["id"] for m in self.model}:
            return
        with pytest.raises(CommandRejected) as err:
            self.sched.delete(Selection(request_ids=frozenset({rid})))
        assert err.value.reason == RejectReason.ALREADY_RELEASED

    @rule(delta=st.floats(-30.0, 30.0), lo=st.none() | st.floats(-10.0, 70.0), ca=st.none() | st.booleans())
    def time_shift(self, delta: float, lo: float | None, ca: bool | None) -> None:
        """Shift a window: either all selected move (offsets too) or, if any would land early, none and a refusal."""
        lo_abs = None if lo is None else self.now + lo
        sel = Selection(from_obt_s=lo_abs, ca_relative=ca)
        chosen = [
            m
            for m in self.model
            if (lo_abs is None or m["tag"] >= lo_abs) and (ca is None or (m["off"] is not None) == ca)
        ]
        if any(m["tag"] + delta < self.now + self.MARGIN for m in chosen):
            with pytest.raises(CommandRejected):
                self.sched.time_shift(self.now, delta, sel)
            return
        self.sched.time_shift(self.now, delta, sel)
        for m in chosen:
            m["tag"] += delta
            if m["off"] is not None:
                m["off"] += delta

    @rule(x=st.floats(-10.0, 60.0))
    def reanchor(self, x: float) -> None:
        """A new C/A estimate moves every C/A-relative entry to anchor + offset."""
        self.anchor = self.now + x
        self.sched.reanchor_ca(self.anchor)
        for m in self.model:
            if m["off"] is not None:
                m["tag"] = self.anchor + m["off"]

    @rule(delta=st.floats(-30.0, 30.0))
    def clock_jump(self, delta: float) -> None:
        """OBT steps (backwards too) without a scheduler tick."""
        self.now += delta

    @rule(delta=st.floats(-30.0, 30.0))
    def clock_jump_followed(self, delta: float) -> None:
        """OBT steps and the schedule is told: every tag and the anchor move with it, so nothing falls due."""
        self.now += delta
        assert self.sched.shift_clock(delta) == len(self.model)
        for m in self.model:
            m["tag"] += delta
        if self.anchor is not None:
            self.anchor += delta

    @rule(enabled=st.booleans(), dt=st.floats(0.0, 10.0))
    def disabled_tick(self, enabled: bool, dt: float) -> None:
        """A disabled schedule releases nothing and names no next tag; enabled again, it releases what is due."""
        self.sched.enabled = False
        self.now += dt
        assert self.sched.release_due(self.now) == [] and self.sched.next_tag_obt_s is None
        self.sched.enabled = True
        if enabled:
            self._tick(0.0)

    @rule(dt=st.floats(0.0, 3.0))
    def tick(self, dt: float) -> None:
        """A scheduler tick releases exactly the model's due entries, in key order, none early, none twice."""
        self._tick(dt)

    @rule(dt=st.floats(5.0, 60.0))
    def long_tick(self, dt: float) -> None:
        """A tick after a long wait (or a forward clock jump) releases many entries at once, in order."""
        self._tick(dt)

    def _tick(self, dt: float) -> None:
        self.now += dt
        due = [m for m in self._sorted_model() if m["tag"] <= self.now]
        got = self.sched.release_due(self.now)
        assert [(e.request_id, e.tag_obt_s, e.sequence) for e in got] == [(m["id"], m["tag"], m["seq"]) for m in due]
        assert all(e.tag_obt_s <= self.now for e in got)
        assert [e.key for e in got] == sorted(e.key for e in got)
        assert not self.released_seqs & {e.sequence for e in got}
        self.released_seqs |= {e.sequence for e in got}
        self.released_ids |= {e.request_id for e in got}
        self.model = [m for m in self.model if m["tag"] > self.now]

    @invariant()
    def listing_matches_model(self) -> None:
        """The listing is the model in release order and never exceeds the capacity."""
        listing = self.sched.listing()
        assert [(e.request_id, e.tag_obt_s, e.priority, e.sequence) for e in listing] == [
            (m["id"], m["tag"], m["prio"], m["seq"]) for m in self._sorted_model()
        ]
        assert len(listing) <= self.CAPACITY
        assert self.sched.summary().ca_anchor_obt_s == self.anchor


ScheduleVersusModel.TestCase.settings = settings(max_examples=60, stateful_step_count=30, deadline=None)
test_schedule_matches_sorted_list_model = ScheduleVersusModel.TestCase
