"""What a fault scenario expects of its run: the ``expect:`` block of a scenario file, checked by ``flyby campaign``.

Every field is optional; what is given must hold. Times of events are judged against the truth: an event's
detection latency is from the start of the scenario's first fault (true time) to the event's on-board time turned
into true time with the run's truth. Besides what is written here, every run of a campaign must end without a node
failure and with finite truth (``analysis.expectations``).
"""

from __future__ import annotations

from pydantic import Field, field_validator

from contracts.dictionary import DICTIONARY, EventReport
from contracts.mode import ModeValue
from contracts.model import Config

EVENT_NAMES = tuple(sorted(p.__name__ for p in DICTIONARY.packets if issubclass(p, EventReport)))


def _event_name(v: str) -> str:
    if v not in EVENT_NAMES:
        raise ValueError(f"{v!r} is not an event report of the dictionary: one of {', '.join(EVENT_NAMES)}")
    return v


class EventExpectation(Config):
    """An event report that must appear, at most ``within_s`` after the first fault began (its detection latency)."""

    event: str = Field(description="event report name of the dictionary, e.g. WheelFailedEvent")
    within_s: float | None = Field(None, gt=0, description="largest detection latency allowed: from the start of the "
                                   "scenario's first fault to the event, true s (none: any time)")
    severity: str | None = Field(None, description="the severity it must carry (INFO, LOW, MEDIUM, HIGH)")
    count_min: int = Field(1, ge=1, description="at least this many such events")

    @field_validator("event")
    @classmethod
    def _known(cls, v: str) -> str:
        return _event_name(v)

    @field_validator("severity")
    @classmethod
    def _severity(cls, v: str | None) -> str | None:
        if v is not None and v not in ("INFO", "LOW", "MEDIUM", "HIGH"):
            raise ValueError(f"must be INFO, LOW, MEDIUM or HIGH, got {v!r}")
        return v


class Expectation(Config):
    """The ``expect:`` block: what the run must show for the scenario to pass."""

    in_view_min: float | None = Field(None, ge=0, le=1, description="least fraction of camera frames with Dimorphos "
                                      "in the field of view, first frame of ACQUISITION to C/A + the report's "
                                      "window (score_run)")
    pointing_error_max_deg: float | None = Field(None, gt=0, description="largest true pointing error in that "
                                                 "window, deg")
    paper_requirements: bool = Field(False, description="every requirement of the paper holds (in view, pointing, "
                                     "peak rate, centroids: the report's requirement table)")
    events: tuple[EventExpectation, ...] = Field((), description="event reports that must appear")
    no_events: tuple[str, ...] = Field((), description="event report names that must not appear")
    final_mode: ModeValue | None = Field(None, description="the mode of the last housekeeping report")
    wheel_momentum_max_nms: float | None = Field(None, gt=0, description="largest true wheel momentum from the first "
                                                 "fault on, N m s (SAFE holds the wheels within their limit)")
    ground_lines: tuple[str, ...] = Field((), description="texts that must appear in ground's log (a WARNING, an "
                                          "ALARM...)")
    verifies: tuple[str, ...] = Field((), description="identifiers of the requirements this scenario verifies "
                                      "(configs/requirements.yaml), for the traceability matrix")

    @field_validator("no_events")
    @classmethod
    def _known(cls, v: tuple[str, ...]) -> tuple[str, ...]:
        return tuple(_event_name(x) for x in v)
