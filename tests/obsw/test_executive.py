"""The executive: releases in the slots of the table, events in (time, priority, sequence) order, overruns.

Times are on-board times handed to the executive; nothing here reads a clock.
"""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from contracts.task import Task
from obsw.executive import Activation, EventKind, Executive, FrameReport, TaskSpec
from obsw.table import CRITICAL_TASKS, ScheduleTable, SlotConfig
from obsw.timing import Work

PERIOD = 0.1
T0 = 26_500_000.0


def _table_strategy(feasible: bool) -> st.SearchStrategy:
    """A valid schedule table with every task in one slot, and per-task costs (s on the nominal processor).

    ``feasible``: deadlines non-decreasing in table order and each cost at most its window, the time between the
    later of its release and the previous slot's deadline and its own deadline, so no deadline can be missed."""

    @st.composite
    def build(draw: st.DrawFn) -> tuple[ScheduleTable, dict[Task, float]]:
        minor_frames = draw(st.sampled_from([1, 2, 3, 4, 5, 6, 10]))
        divisors = [d for d in range(1, minor_frames + 1) if minor_frames % d == 0]
        order = draw(st.permutations(list(Task)))
        a, c = order.index(Task.ATTITUDE), order.index(Task.CONTROL)
        if a > c:
            order[a], order[c] = order[c], order[a]
        n = len(order)
        weights = draw(st.lists(st.floats(0.05, 1.0), min_size=n, max_size=n))
        scale = draw(st.floats(0.5, 1.0)) / sum(weights)
        deadlines, offsets, costs = [], [], {}
        prev_deadline = prev_offset = 0.0
        for task, w in zip(order, weights, strict=True):
            deadline = min(prev_deadline + w * scale, 1.0)
            offset = prev_offset + draw(st.floats(0.0, 1.0)) * (deadline - prev_offset) * 0.9
            window = deadline - max(offset, prev_deadline)
            costs[task] = draw(st.floats(0.0, 0.999)) * window * PERIOD if feasible else \
                draw(st.floats(0.0, 0.5)) * PERIOD
            deadlines.append(deadline)
            offsets.append(offset)
            prev_deadline, prev_offset = deadline, offset
        slots = []
        for task, offset, deadline in zip(order, offsets, deadlines, strict=True):
            every = 1 if task in CRITICAL_TASKS else draw(st.sampled_from(divisors))
            phase = draw(st.integers(0, every - 1))
            slots.append(SlotConfig(task=task, offset_fraction=offset, deadline_fraction=deadline, every=every,
                                    phase=phase, critical=task in CRITICAL_TASKS))
        return ScheduleTable(minor_frames=minor_frames, slots=tuple(slots)), costs

    return build()


def _periodic(log: list[tuple[Task, Activation]]) -> dict[Task, TaskSpec]:
    def handler(task: Task):  # noqa: ANN202
        def run(act: Activation) -> Work:
            log.append((task, act))
            return Work()
        return run
    return {t: TaskSpec(handler(t)) for t in Task}


@settings(max_examples=60, deadline=None)
@given(_table_strategy(feasible=True), st.integers(1, 3))
def test_every_task_is_released_in_its_slot_in_table_order_and_meets_its_deadline(table_costs, majors) -> None:
    """In each minor frame exactly the slots of its phase are released, once each, in table order, at their offset
    and never started before it or before the previous one finished; a feasible table misses no deadline."""
    table, costs = table_costs
    log: list[tuple[Task, Activation]] = []
    ex = Executive(table, PERIOD, _periodic(log), lambda task, work: costs[task])
    for k in range(majors * table.minor_frames):
        tick = T0 + k * PERIOD
        report = ex.minor_frame(tick)
        m = k % table.minor_frames
        expected = [s for s in table.slots if (m - s.phase) % s.every == 0]
        assert [r.task for r in report.runs] == [s.task for s in expected]
        free = tick
        for slot, run in zip(expected, report.runs, strict=True):
            assert run.ran and not run.skipped
            assert run.release_s == tick + slot.offset_fraction * PERIOD
            assert run.start_s >= run.release_s and run.start_s >= free
            assert run.finish_s == pytest.approx(run.start_s + costs[slot.task], abs=1e-12)
            assert run.finish_s <= tick + slot.deadline_fraction * PERIOD
            free = run.finish_s
        assert not report.overrun
    assert ex.task_overruns == ex.frame_overruns == ex.skipped == 0
    assert len(log) == sum(len([s for s in table.slots if (k % table.minor_frames) % s.every == s.phase])
                           for k in range(majors * table.minor_frames))


def test_events_are_dispatched_in_time_priority_sequence_order_to_every_subscriber_once() -> None:
    """Each subscriber gets its own copy of each event once, ordered by (time, priority, sequence), only when due."""
    got: dict[Task, list] = {Task.TELECOMMANDS: [], Task.FDIR: []}

    def taker(task: Task):  # noqa: ANN202
        def run(act: Activation) -> Work:
            got[task].append([(e.time_s, e.priority, e.payload) for e in act.events])
            return Work()
        return run

    specs = _periodic([])
    for t in got:
        specs[t] = TaskSpec(taker(t), frozenset({EventKind.PARAM_CHECK_FAILED}), periodic=False)
    ex = Executive(ScheduleTable(), PERIOD, specs, lambda task, work: 0.0)
    ex.post(EventKind.PARAM_CHECK_FAILED, T0 + 0.05, "b", priority=1)
    ex.post(EventKind.PARAM_CHECK_FAILED, T0 + 0.05, "a", priority=0)
    ex.post(EventKind.PARAM_CHECK_FAILED, T0, "first")
    ex.post(EventKind.PARAM_CHECK_FAILED, T0 + 0.05, "c", priority=0)
    ex.post(EventKind.PARAM_CHECK_FAILED, T0 + 0.15, "later")
    ex.minor_frame(T0)
    ex.minor_frame(T0 + PERIOD)
    ex.minor_frame(T0 + 2 * PERIOD)
    for t in got:
        assert got[t] == [[(T0, 0, "first")], [(T0 + 0.05, 0, "a"), (T0 + 0.05, 0, "c"), (T0 + 0.05, 1, "b")],
                          [(T0 + 0.15, 0, "later")]]
        assert ex.pending(t) == ()


def test_an_event_emitted_by_a_task_exists_from_its_finish() -> None:
    """A result posted by a task reaches a later task of the same minor frame only if that one starts after the
    producer's finish, else at its next release."""
    seen: list[tuple[float, float]] = []

    def producer(act: Activation) -> Work:
        act.emit(EventKind.MEASUREMENT, act.now_s)
        return Work()

    def consumer(act: Activation) -> Work:
        seen.extend((act.now_s, e.time_s) for e in act.events)
        return Work()

    specs = _periodic([])
    specs[Task.IMAGING] = TaskSpec(producer)
    specs[Task.CONTROL] = TaskSpec(consumer, frozenset({EventKind.MEASUREMENT}))
    costs = {t: 0.0 for t in Task} | {Task.IMAGING: 0.030}
    slots = ScheduleTable().slots
    after = [s.task for s in slots].index(Task.CONTROL)
    table = ScheduleTable(slots=tuple(s.model_copy(update={"offset_fraction": 0.1}) if i >= after else s
                                      for i, s in enumerate(slots)))
    ex = Executive(table, PERIOD, specs, lambda task, work: costs[task])
    ex.minor_frame(T0)  # IMAGING ends at +30 ms, CONTROL released at +10 ms starts at +30 ms: it gets it
    assert seen == [(T0 + 0.030, T0 + 0.030)]
    costs[Task.IMAGING] = 0.0
    ex.minor_frame(T0 + PERIOD)
    assert seen[-1] == pytest.approx((T0 + PERIOD + 0.01, T0 + PERIOD), abs=1e-9)


@settings(max_examples=40, deadline=None)
@given(_table_strategy(feasible=False), st.lists(st.floats(1.0, 30.0), min_size=5, max_size=40),
       st.lists(st.tuples(st.integers(0, 39), st.floats(0.0, 0.1)), max_size=30))
def test_under_random_overloads_overruns_are_counted_and_control_always_runs(table_costs, slowdowns, posts) -> None:
    """Processor slowed by random factors, random events: every overrun of the trace is counted, the control runs
    in every minor frame, and once the overload is over the backlog drains and every event is dispatched."""
    table, costs = table_costs
    specs = _periodic([])
    specs[Task.IMAGING] = TaskSpec(lambda act: Work(), frozenset({EventKind.FRAME_READY}), periodic=False)
    ex = Executive(table, PERIOD, specs, lambda task, work: costs[task])
    by_frame = {}
    for k, dt in posts:
        by_frame.setdefault(k, []).append(dt)
    reports: list[FrameReport] = []
    for k, slowdown in enumerate(slowdowns):
        tick = T0 + k * PERIOD
        for dt in by_frame.get(k, []):
            ex.post(EventKind.FRAME_READY, tick + dt)
        reports.append(ex.minor_frame(tick, slowdown))
    for rep in reports:
        control = [r for r in rep.runs if r.task == Task.CONTROL]
        assert len(control) == 1 and control[0].ran
    runs = [r for rep in reports for r in rep.runs]
    assert ex.task_overruns == sum(r.ran and r.finish_s > r.deadline_s for r in runs)
    assert ex.frame_overruns == sum(rep.busy_until_s > rep.tick_s + PERIOD for rep in reports)
    assert ex.skipped == sum(r.skipped for r in runs)
    assert all(not r.skipped for r in runs if r.task in CRITICAL_TASKS)
    for r in runs:
        if r.ran:
            k = r.frame
            assert r.finish_s - r.start_s == pytest.approx(costs[r.task] * slowdowns[k], abs=1e-8)  # OBT ulp 4e-9 s
    # the overload ends (the tasks have nothing left to do): the backlog drains and the queue empties
    for t in costs:
        costs[t] = 0.0
    k = len(slowdowns)
    backlog = max(0.0, reports[-1].busy_until_s - (reports[-1].tick_s + PERIOD))
    for j in range(math.ceil(backlog / PERIOD) + 2 * table.minor_frames + 2):
        rep = ex.minor_frame(T0 + (k + j) * PERIOD)
    assert not rep.overrun and all(not r.overrun for r in rep.runs)
    assert ex.pending(Task.IMAGING) == ()


def test_a_critical_task_runs_late_where_others_are_skipped_and_keep_their_events() -> None:
    """Behind past every deadline, the non-critical tasks are skipped (counted, events kept) and CONTROL and
    ATTITUDE run late; the events are dispatched at the next release that can run."""
    costs = {t: 0.0 for t in Task} | {Task.TIME: 0.25}
    specs = _periodic([])
    specs[Task.IMAGING] = TaskSpec(lambda act: Work(frames=len(act.events)), frozenset({EventKind.FRAME_READY}),
                                   periodic=False)
    ex = Executive(ScheduleTable(), PERIOD, specs, lambda task, work: costs[task])
    ex.post(EventKind.FRAME_READY, T0)
    first = ex.minor_frame(T0)
    ran = {r.task for r in first.runs if r.ran}
    assert ran == {Task.TIME, Task.ATTITUDE, Task.CONTROL}
    assert {r.task for r in first.runs if r.skipped} == set(Task) - ran
    assert first.overrun and ex.frame_overruns == 1 and ex.skipped == len(Task) - 3
    assert [e.time_s for e in ex.pending(Task.IMAGING)] == [T0]
    costs[Task.TIME] = 0.0
    ex.minor_frame(T0 + PERIOD)  # still 0.15 s behind: everything but the critical two skipped again
    third = ex.minor_frame(T0 + 2 * PERIOD)  # backlog 0.05 s: the imaging slot (85 ms) can start at +50 ms
    imaging = next(r for r in third.runs if r.task == Task.IMAGING)
    assert imaging.ran and [e.time_s for e in imaging.events] == [T0]
    assert imaging.start_s == pytest.approx(T0 + 2 * PERIOD + 0.05, abs=1e-8)


def test_a_timer_posts_its_event_when_due_and_only_once() -> None:
    """The schedule timer's TAG_DUE reaches its subscriber at the first release at or after the due time."""
    due: list[float | None] = [T0 + 0.25]
    calls: list[tuple[float, tuple[float, ...]]] = []

    def release(act: Activation) -> Work:
        calls.append((act.now_s, tuple(e.time_s for e in act.events)))
        due[0] = None
        return Work()

    specs = _periodic([])
    specs[Task.SCHEDULE] = TaskSpec(release, frozenset({EventKind.TAG_DUE}), periodic=False)
    ex = Executive(ScheduleTable(), PERIOD, specs, lambda task, work: 0.0)
    ex.add_timer(EventKind.TAG_DUE, lambda: due[0])
    for k in range(6):
        ex.minor_frame(T0 + k * PERIOD)
    assert calls == [(T0 + 3 * PERIOD, (T0 + 0.25,))]


def test_bad_tables_are_refused_naming_the_slot() -> None:
    """A table that would not repeat, runs out of order, releases a task twice, misses a task or makes the control
    optional is refused with the slot and the reason."""
    base = list(ScheduleTable().slots)
    control = next(i for i, s in enumerate(base) if s.task == Task.CONTROL)
    cases = {
        "does not divide minor_frames": [s.model_copy(update={"every": 3}) if s.task == Task.FDIR else s
                                         for s in base],
        "before the previous slot's": [s.model_copy(update={"offset_fraction": 0.01 if s.task == Task.TIME else 0.0})
                                       for s in base],
        "released twice": [*base, base[0]],
        "no slot for FDIR": [s for s in base if s.task != Task.FDIR],
        "must be critical": [s.model_copy(update={"critical": False}) if i == control else s
                             for i, s in enumerate(base)],
        "ATTITUDE must come before CONTROL": [s for s in base if s.task != Task.ATTITUDE] +
                                             [next(s for s in base if s.task == Task.ATTITUDE)],
    }
    for text, slots in cases.items():
        with pytest.raises(ValueError, match=text):
            ScheduleTable(slots=tuple(slots))
    with pytest.raises(ValueError, match="deadline_fraction"):
        SlotConfig(task="CAMERA", offset_fraction=0.5, deadline_fraction=0.4)
    with pytest.raises(ValueError, match="phase"):
        SlotConfig(task="CAMERA", deadline_fraction=0.4, every=2, phase=2)
