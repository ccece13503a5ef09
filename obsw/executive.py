"""The on-board executive: tasks released in the slots of the schedule table at each OBT tick, events dispatched.

One call of ``minor_frame`` is one minor frame, started by the on-board time tick. The slots the table releases in
it run in table order on one processor core, without preemption: a task is released at its slot's offset into the
minor frame, starts when it is released and the core is free (never earlier), and finishes after its execution
time (the timing model's, times the processor's slow-down factor). A finish after the slot's deadline is a task overrun;
work of a minor frame still running at the next tick is a minor frame overrun, and the core's backlog is carried
into the next minor frame (as a time after its tick, so an OBT jump does not stretch it). When the core is still
busy at a slot's deadline, a task that is not critical is skipped (its events wait for its next release); a
critical one (the control) runs late, so the executive never skips it.

Events have a kind, a time (when they exist on board: a telecommand's arrival, the end of a frame's FPGA stages,
a tag, the finish of the task that produced them), a priority and a sequence number. Each task that subscribes
to a kind gets its own copy, queued by (time, priority, sequence); at its release a task gets the events of its
queue due by its start. A task that only reacts to events does not run, and takes no time, when none is due; a
periodic task runs at every release. A timer (the schedule's next tag) is asked at each release of its subscriber
whether it is due, and if so posts its event at the due time.

Pure: time comes in with each tick; tasks are handlers returning the work they did (``obsw.timing.Work``).
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from enum import IntEnum
from typing import NamedTuple

from contracts.task import Task
from obsw.errors import InternalFault
from obsw.table import ScheduleTable
from obsw.timing import Work


class EventKind(IntEnum):
    """What an event says has happened."""

    TC_ARRIVED = 1  # a telecommand packet was received
    FRAME_READY = 2  # a frame's FPGA stages are done: its regions wait for the software
    TAG_DUE = 3  # the schedule's next time tag has come
    MEASUREMENT = 4  # a frame's Dimorphos line of sight is available
    PARAM_CHECK_FAILED = 5  # a monitored parameter is out of its limits
    DIDYMOS_SIGHTED = 6  # a frame's Didymos line of sight is available


@dataclass(frozen=True, slots=True)
class Event:
    """An event as queued: dispatched in (time, priority, sequence) order."""

    time_s: float
    priority: int
    sequence: int
    kind: EventKind
    payload: object = None

    @property
    def key(self) -> tuple[float, int, int]:
        """Dispatch order."""
        return (self.time_s, self.priority, self.sequence)


@dataclass(slots=True)
class Activation:
    """What a task gets when it runs: the tick, its start (its 'now'), its events; what it emits goes out at its
    finish."""

    tick_s: float
    now_s: float
    events: tuple[Event, ...]
    emitted: list[tuple[EventKind, object, int]] = field(default_factory=list)

    def emit(self, kind: EventKind, payload: object = None, priority: int = 0) -> None:
        """Post an event when this run finishes (its result exists only then)."""
        self.emitted.append((kind, payload, priority))

    def of(self, kind: EventKind) -> list[Event]:
        """This run's events of ``kind``, in dispatch order."""
        # most runs have no events: no comprehension to set up (kinds are enumeration members: identity)
        return [e for e in self.events if e.kind is kind] if self.events else []


Handler = Callable[[Activation], Work]


@dataclass(frozen=True)
class TaskSpec:
    """How a task is run: its handler, the events it subscribes to, and whether it runs without them."""

    handler: Handler
    subscribes: frozenset[EventKind] = frozenset()
    periodic: bool = True


class _Plan(NamedTuple):
    """A slot of a minor frame as the executive runs it."""

    task: Task
    spec: TaskSpec
    offset_s: float  # release, s after the tick
    deadline_s: float  # deadline, s after the tick
    critical: bool
    timers: tuple[tuple[EventKind, Callable[[], float | None]], ...]


class Run(NamedTuple):  # a named tuple: eleven are made every minor frame, at a fifth of a frozen dataclass's cost
    """One release of a task in a minor frame, with its modelled times (OBT s)."""

    task: Task
    frame: int  # minor frames since the executive started
    minor_frame: int  # index in the major frame
    release_s: float
    start_s: float
    finish_s: float
    deadline_s: float
    events: tuple[Event, ...] = ()
    ran: bool = True  # False: released with nothing to do, or skipped
    skipped: bool = False  # not run: the core was busy past the deadline (events kept for the next release)

    @property
    def execution_s(self) -> float:
        """Execution time, s."""
        return self.finish_s - self.start_s

    @property
    def overrun(self) -> bool:
        """Whether the task finished after its deadline."""
        return self.ran and self.finish_s > self.deadline_s


@dataclass(frozen=True, slots=True)
class FrameReport:
    """What happened in one minor frame."""

    tick_s: float
    frame: int
    minor_frame: int
    runs: tuple[Run, ...]
    busy_until_s: float  # when the frame's last task finished (the tick if none ran)
    overrun: bool  # work still running at the next tick


class Executive:
    """Releases the tasks of a schedule table on each tick and dispatches events to their subscribers."""

    def __init__(self, table: ScheduleTable, period_s: float, tasks: Mapping[Task, TaskSpec],
                 cost_s: Callable[[Task, Work], float], observer: Callable[[Run], None] | None = None) -> None:
        """``cost_s`` gives a task's execution time on the nominal processor; ``observer`` sees every run."""
        if not (math.isfinite(period_s) and period_s > 0):
            raise ValueError(f"period_s must be finite and > 0, got {period_s!r}")
        missing = sorted({s.task.name for s in table.slots if s.task not in tasks})
        if missing:
            raise ValueError(f"no handler for the table's task(s) {', '.join(missing)}")
        self.table = table
        self.period_s = float(period_s)
        self.tasks = dict(tasks)
        self._cost_s = cost_s
        self._observer = observer
        self._queues: dict[Task, list[tuple[tuple[float, int, int], Event]]] = {t: [] for t in self.tasks}
        # who hears each kind, looked up at every post (a scan of every task's subscriptions was most of post's time)
        self._subscribers: dict[EventKind, tuple[Task, ...]] = {
            k: tuple(t for t, spec in self.tasks.items() if k in spec.subscribes) for k in EventKind}
        self._timers: list[tuple[EventKind, Callable[[], float | None]]] = []
        # each minor frame's slots, prepared once (the table is data, fixed for the executive's life): task, spec,
        # offset and deadline from the tick (s), critical, and the timers the task hears
        self._plans: list[tuple[_Plan, ...]] = []
        self._plan()
        self._sequence = 0
        self._carry_s = 0.0  # work of the last minor frame still running at this tick, s after it
        self.frames = 0
        self.last_execution_s = {t: 0.0 for t in Task}
        self.max_execution_s = {t: 0.0 for t in Task}
        self.task_overruns = 0
        self.frame_overruns = 0
        self.skipped = 0

    # -- events --------------------------------------------------------------------------------------------
    def post(self, kind: EventKind, time_s: float, payload: object = None, priority: int = 0) -> None:
        """Queue an event for every task that subscribes to ``kind``."""
        if not math.isfinite(time_s):
            raise InternalFault(f"event {kind.name}: time {time_s!r} is not a finite OBT")
        ev = Event(float(time_s), int(priority), self._sequence, kind, payload)
        self._sequence += 1
        for task in self._subscribers[kind]:
            heapq.heappush(self._queues[task], (ev.key, ev))

    @property
    def sequence(self) -> int:
        """The sequence number the next event posted will get."""
        return self._sequence

    def shift_time(self, step_s: float, before_sequence: int,
                   payload: Callable[[EventKind, object], object] = lambda kind, p: p) -> None:
        """On-board time stepped by ``step_s``: every queued event posted before ``before_sequence`` (stamped on the
        old time scale) moves with it, its payload rewritten by ``payload``; events posted since keep their time."""
        for task, q in self._queues.items():
            moved = []
            for key, ev in q:
                if ev.sequence < before_sequence:
                    ev = Event(ev.time_s + step_s, ev.priority, ev.sequence, ev.kind, payload(ev.kind, ev.payload))
                moved.append((ev.key, ev))
            heapq.heapify(moved)
            self._queues[task] = moved

    def add_timer(self, kind: EventKind, due_s: Callable[[], float | None]) -> None:
        """A timer: at each release of a task subscribing to ``kind``, if ``due_s()`` has come and no such event is
        queued for it, post one at that time."""
        self._timers.append((kind, due_s))
        self._plan()

    def _plan(self) -> None:
        """Prepare each minor frame's slots (``_Plan``), in table order."""
        self._plans = [tuple(
            _Plan(s.task, self.tasks[s.task], s.offset_fraction * self.period_s, s.deadline_fraction * self.period_s,
                  s.critical, tuple((k, due) for k, due in self._timers if k in self.tasks[s.task].subscribes))
            for s in self.table.released(minor)) for minor in range(self.table.minor_frames)]

    def pending(self, task: Task) -> tuple[Event, ...]:
        """The events queued for ``task``, in dispatch order."""
        return tuple(ev for _, ev in sorted(self._queues[task]))

    def _poll_timers(self, task: Task, timers: tuple[tuple[EventKind, Callable[[], float | None]], ...],
                     now_s: float) -> None:
        for kind, due_s in timers:
            due = due_s()
            if due is not None and due <= now_s and all(ev.kind != kind for _, ev in self._queues[task]):
                self.post(kind, due)

    def _take(self, task: Task, now_s: float) -> tuple[Event, ...]:
        q = self._queues[task]
        out = []
        while q and q[0][1].time_s <= now_s:
            out.append(heapq.heappop(q)[1])
        return tuple(out)

    # -- the minor frame -----------------------------------------------------------------------------------
    def minor_frame(self, tick_s: float, slowdown: float = 1.0) -> FrameReport:
        """Run the slots of the next minor frame from the tick at ``tick_s`` (OBT), the processor ``slowdown``
        times slower than nominal (a hardware reading: 1 is nominal)."""
        if not math.isfinite(tick_s):
            raise InternalFault(f"executive: tick {tick_s!r} is not a finite OBT")
        if not (math.isfinite(slowdown) and slowdown > 0):
            raise InternalFault(f"executive: processor slow-down {slowdown!r} must be finite and > 0")
        minor = self.frames % self.table.minor_frames
        frame = self.frames
        free = tick_s + self._carry_s
        runs = []
        # locals: this loop runs eleven slots every control period
        queues, cost_s, observe, post = self._queues, self._cost_s, self._observer, self.post
        last, most = self.last_execution_s, self.max_execution_s
        isfinite = math.isfinite
        for task, spec, offset_s, deadline_s, critical, timers in self._plans[minor]:
            release = tick_s + offset_s
            deadline = tick_s + deadline_s
            start = release if release >= free else free  # max(release, free), as max() takes the first of equals
            if timers:
                self._poll_timers(task, timers, start)
            q = queues[task]
            if not spec.periodic and (not q or q[0][1].time_s > start):  # nothing due: not run
                runs.append(Run(task, frame, minor, release, start, start, deadline, ran=False))
                continue
            if start >= deadline and not critical:
                self.skipped += 1
                run = Run(task, frame, minor, release, start, start, deadline, ran=False, skipped=True)
                runs.append(run)
                if observe is not None:
                    observe(run)
                continue
            events = self._take(task, start) if q else ()
            act = Activation(tick_s, start, events)
            work = spec.handler(act)
            execution = cost_s(task, work) * slowdown
            if not (isfinite(execution) and execution >= 0):
                raise InternalFault(f"executive: {task.name} execution time {execution!r} s")
            finish = start + execution
            free = finish
            for kind, payload, priority in act.emitted:
                post(kind, finish, payload, priority)
            run = Run(task, frame, minor, release, start, finish, deadline, events)
            last[task] = execution
            if execution > most[task]:
                most[task] = execution
            if finish > deadline:  # run.overrun: it ran
                self.task_overruns += 1
            runs.append(run)
            if observe is not None:
                observe(run)
        end = max(free, tick_s)
        overrun = end > tick_s + self.period_s
        self.frame_overruns += overrun
        self._carry_s = max(0.0, end - (tick_s + self.period_s))
        self.frames += 1
        return FrameReport(tick_s, self.frames - 1, minor, tuple(runs), end, overrun)
