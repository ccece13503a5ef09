"""The schedule table of the on-board executive: which task is released in which slot of which minor frame.

A major frame is ``minor_frames`` minor frames; a minor frame is one control period, started by the on-board time
tick. A slot binds a task to a window of the minor frame, released at ``offset_fraction`` of it after the tick
and due at ``deadline_fraction`` of it (fractions, so the table holds at any control rate), at a rate: every
``every``-th minor frame, from minor frame ``phase`` of the major frame. The slots released in a minor frame run in
table order, one after the other, on the one processor core the navigation software runs on. As in the schedule definition table of cFS SCH or the rate groups of F Prime, the
order of work is data (``obsw.executive`` in the scenario), not code.

The default table reproduces the zero-time flight software's order of work, every task in every minor frame,
released at the tick and run back to back; the deadlines share out the 100 ms period with margin over the
default execution times of ``obsw.timing``.
"""

from __future__ import annotations

from pydantic import Field, model_validator

from contracts.model import Config
from contracts.task import Task, TaskValue

CRITICAL_TASKS = (Task.ATTITUDE, Task.CONTROL)  # the wheel torques of every period depend on them


class SlotConfig(Config):
    """One slot of the schedule table: a task, its window in the minor frame and its rate."""

    task: TaskValue = Field(description="the task released in this slot (a name of contracts.task.Task)")
    offset_fraction: float = Field(
        0.0, ge=0, lt=1, description="release of the slot after the minor frame's tick, in fractions of the minor "
        "frame (0: at the tick; the task then runs as soon as the tasks before it in the table are done, as in an "
        "F Prime rate group)"
    )
    deadline_fraction: float = Field(
        gt=0, le=1, description="the task must have finished this far into the minor frame, in fractions of it; a "
        "later finish is an overrun"
    )
    every: int = Field(1, ge=1, description="released in every n-th minor frame (rate: the control rate / n), count")
    phase: int = Field(0, ge=0, description="released in the minor frames m of the major frame with m % every == "
                       "phase, count")
    critical: bool = Field(
        False, description="never skipped: when the processor is still busy past the slot's deadline the task runs "
        "late; a task that is not critical is then skipped and its events wait for its next release"
    )

    @model_validator(mode="after")
    def _window(self) -> SlotConfig:
        if self.phase >= self.every:
            raise ValueError(f"phase: {self.phase} must be below every ({self.every})")
        if self.deadline_fraction <= self.offset_fraction:
            raise ValueError(f"deadline_fraction: {self.deadline_fraction:g} must be after offset_fraction "
                             f"{self.offset_fraction:g}")
        return self

    def released_in(self, minor_frame: int) -> bool:
        """Whether this slot is released in minor frame ``minor_frame`` of the major frame."""
        return minor_frame % self.every == self.phase


def _slot(task: Task, deadline_fraction: float) -> SlotConfig:
    return SlotConfig(task=task, deadline_fraction=deadline_fraction, critical=task in CRITICAL_TASKS)


# deadlines (ms after the tick in the 100 ms period) of about four times each task's default execution time
# (obsw.timing); the imaging and recognition windows sized on the longest runs measured with the default timing (a
# plume-filled frame near C/A with Dimorphos's limb fit: up to 69.4 ms in the five flybys, 75.6 ms in the tests'
# short flyby, from a start about 2 ms after the tick; a recognition holding several hundred measurements, up to
# 7.4 ms) with some 10 % to spare, so a nominal flyby reports no overrun
DEFAULT_SLOTS = (
    _slot(Task.TIME, 0.02),
    _slot(Task.TELECOMMANDS, 0.12),
    _slot(Task.SCHEDULE, 0.16),
    _slot(Task.ATTITUDE, 0.18),
    _slot(Task.IMAGING, 0.85),
    _slot(Task.RECOGNITION, 0.93),
    _slot(Task.MODES, 0.94),
    _slot(Task.CONTROL, 0.95),
    _slot(Task.FDIR, 0.96),
    _slot(Task.CAMERA, 0.97),
    _slot(Task.TELEMETRY, 0.99),
)


class ScheduleTable(Config):
    """The executive's schedule table: the minor frames of a major frame and the slots, in the order they run."""

    minor_frames: int = Field(
        10, ge=1, le=256, description="minor frames per major frame, count (10: a 1 s major frame at the 10 Hz control "
        "tick; at most 256, the octet of the overrun events)"
    )
    slots: tuple[SlotConfig, ...] = Field(
        DEFAULT_SLOTS, description="the slots in the order they run within a minor frame; the default is the "
        "zero-time flight software's order, every task at every tick"
    )

    @model_validator(mode="after")
    def _consistent(self) -> ScheduleTable:
        problems = []
        for i, s in enumerate(self.slots):
            if self.minor_frames % s.every:
                problems.append(f"slots[{i}].every: {s.every} does not divide minor_frames ({self.minor_frames}): "
                                "the pattern would not repeat each major frame")
            if i and s.offset_fraction < self.slots[i - 1].offset_fraction:
                problems.append(f"slots[{i}].offset_fraction: {s.offset_fraction:g} is before the previous slot's "
                                f"{self.slots[i - 1].offset_fraction:g}: the table runs in order")
        for m in range(self.minor_frames):
            tasks = [s.task for s in self.slots if s.released_in(m)]
            twice = sorted({t.name for t in tasks if tasks.count(t) > 1})
            if twice:
                problems.append(f"slots: {', '.join(twice)} released twice in minor frame {m}")
        missing = [t.name for t in Task if all(s.task != t for s in self.slots)]
        if missing:
            problems.append(f"slots: no slot for {', '.join(missing)}: the flight software needs every task")
        for i, s in enumerate(self.slots):
            if s.task in CRITICAL_TASKS and (s.every != 1 or not s.critical):
                problems.append(f"slots[{i}]: {s.task.name} must be critical and released in every minor frame "
                                "(the wheel torques of every period need it)")
        order = [s.task for s in self.slots]
        if Task.ATTITUDE in order and Task.CONTROL in order and order.index(Task.ATTITUDE) > order.index(Task.CONTROL):
            problems.append("slots: ATTITUDE must come before CONTROL (the control needs the period's attitude)")
        if problems:
            raise ValueError("\n".join(problems))
        return self

    def released(self, minor_frame: int) -> tuple[SlotConfig, ...]:
        """The slots released in minor frame ``minor_frame`` (0 .. minor_frames - 1), in table order."""
        return tuple(s for s in self.slots if s.released_in(minor_frame))
