# Theory of operation
# -------------------
# The spacecraft is always in exactly one of five modes. It waits in STANDBY; a time-tagged command (the
# timeline's "C/A-240 s" entry) puts it in ACQUISITION, where the camera points along the ground's nominal
# trajectory until the imaging subsystem reports the target. The first detection moves it to
# NOMINAL_TRACKING (the nominal trajectory corrected by image feedback). When on-board time reaches the
# on-board C/A estimate minus ``autonomous_before_ca_s`` (C/A-30 s) it hands over to AUTONOMOUS_TRACKING,
# which follows the trajectory recognised on board; ``standby_after_ca_s`` after C/A the flyby is over
# and it returns to STANDBY. Losing the target for ``target_lost_timeout_s`` in NOMINAL_TRACKING sends it
# back to ACQUISITION; in AUTONOMOUS_TRACKING it does not, because near C/A the on-board trajectory points
# the camera better than a search would. A false lock found in NOMINAL_TRACKING (a line of sight refused because
# the recognised trajectory cannot explain it) hands over to AUTONOMOUS_TRACKING at once: the image feedback is
# on something else, the ground's nominal alone drifts off, and the recognised trajectory, which only accepted
# lines of sight shaped, is the best pointing left. A fault or a wheel saturation sends any mode but SAFE to SAFE;
# only a command leaves SAFE (to STANDBY).
#
# Everything is one table: EVENT_TRANSITIONS for on-board events (first matching row wins, so at most one
# transition per call) and COMMANDABLE for the modes the ground may command from each mode. ``handle``
# returns exactly one ModeEvent per transition and None otherwise; a commanded change outside COMMANDABLE
# raises IllegalTransition (a CommandRejected: the ground's fault) and leaves the mode alone. An on-board
# event that means nothing in the current mode (a late detection in SAFE) is ignored, never an error.
# Time is on-board time passed in by the caller; the manager never reads a clock.
"""The mode manager: SAFE, STANDBY, ACQUISITION, NOMINAL_TRACKING, AUTONOMOUS_TRACKING as a transition table."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from enum import StrEnum

from contracts.mode import Mode
from obsw.config import ModesConfig
from obsw.errors import IllegalTransition, InternalFault


class Cause(StrEnum):
    """Why a transition happened (the cause field of the mode event report)."""

    COMMANDED = "COMMANDED"
    TARGET_ACQUIRED = "TARGET_ACQUIRED"
    TARGET_LOST = "TARGET_LOST"
    WHEEL_SATURATION = "WHEEL_SATURATION"
    FAULT = "FAULT"
    AUTONOMY_TIME = "AUTONOMY_TIME"
    FALSE_LOCK = "FALSE_LOCK"
    FLYBY_OVER = "FLYBY_OVER"


# --- triggers ----------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class SetMode:
    """A ground command (immediate or time-tagged) to change mode."""

    mode: Mode


@dataclass(frozen=True, slots=True)
class TargetDetected:
    """The imaging subsystem found the target in the latest frame."""


@dataclass(frozen=True, slots=True)
class FalseLock:
    """The false-lock gate refused the line of sight of frame ``frame_id``: the recognised trajectory cannot explain
    it (obsw.lock_gate)."""

    frame_id: int


@dataclass(frozen=True, slots=True)
class WheelSaturation:
    """A reaction wheel reached its momentum or torque limit."""

    wheel: int | None = None


@dataclass(frozen=True, slots=True)
class Fault:
    """An on-board fault that requires SAFE; ``what`` names it for the event report."""

    what: str


@dataclass(frozen=True, slots=True)
class CaEstimate:
    """A new on-board estimate of the C/A time was accepted, OBT s."""

    ca_obt_s: float


@dataclass(frozen=True, slots=True)
class Tick:
    """On-board time has advanced: check the time-driven rows (C/A-30 s, flyby over, target lost)."""


Trigger = SetMode | TargetDetected | FalseLock | WheelSaturation | Fault | CaEstimate | Tick


@dataclass(frozen=True, slots=True)
class ModeEvent:
    """The report of one mode transition."""

    obt_s: float
    from_mode: Mode
    to_mode: Mode
    cause: Cause
    detail: str = ""


# --- the table ---------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class _State:
    """What the guards may look at."""

    obt_s: float
    cfg: ModesConfig
    ca_obt_s: float | None
    last_seen_obt_s: float | None


Guard = Callable[[_State], bool]


def _always(_: _State) -> bool:
    return True


def _flyby_over(s: _State) -> bool:
    return s.ca_obt_s is not None and s.obt_s >= s.ca_obt_s + s.cfg.standby_after_ca_s


def _autonomy_time(s: _State) -> bool:
    return s.ca_obt_s is not None and s.obt_s >= s.ca_obt_s - s.cfg.autonomous_before_ca_s


def _target_lost(s: _State) -> bool:
    return s.last_seen_obt_s is not None and s.obt_s - s.last_seen_obt_s > s.cfg.target_lost_timeout_s


@dataclass(frozen=True, slots=True)
class _Row:
    sources: frozenset[Mode]
    trigger: type
    guard: Guard
    target: Mode
    cause: Cause


_S, _SB, _AQ, _NT, _AT = (
    Mode.SAFE,
    Mode.STANDBY,
    Mode.ACQUISITION,
    Mode.NOMINAL_TRACKING,
    Mode.AUTONOMOUS_TRACKING,
)
_NOT_SAFE = frozenset({_SB, _AQ, _NT, _AT})
_FLYING_BY = frozenset({_AQ, _NT, _AT})
_TRACKING = frozenset({_NT, _AT})

EVENT_TRANSITIONS: tuple[_Row, ...] = (
    _Row(_NOT_SAFE, Fault, _always, _S, Cause.FAULT),
    _Row(_NOT_SAFE, WheelSaturation, _always, _S, Cause.WHEEL_SATURATION),
    _Row(frozenset({_AQ}), TargetDetected, _always, _NT, Cause.TARGET_ACQUIRED),
    _Row(_FLYING_BY, Tick, _flyby_over, _SB, Cause.FLYBY_OVER),
    _Row(frozenset({_NT}), FalseLock, _always, _AT, Cause.FALSE_LOCK),
    _Row(frozenset({_NT}), Tick, _autonomy_time, _AT, Cause.AUTONOMY_TIME),
    _Row(frozenset({_NT}), Tick, _target_lost, _AQ, Cause.TARGET_LOST),
)

COMMANDABLE: dict[Mode, frozenset[Mode]] = {
    _S: frozenset({_SB}),
    _SB: frozenset({_S, _AQ}),
    _AQ: frozenset({_S, _SB}),
    _NT: frozenset({_S, _SB, _AQ, _AT}),
    _AT: frozenset({_S, _SB}),
}


def allowed_transitions() -> frozenset[tuple[Mode, Mode]]:
    """Every (from, to) pair the table can produce, commanded or on-board."""
    edges = {(a, b) for a, targets in COMMANDABLE.items() for b in targets}
    edges |= {(a, row.target) for row in EVENT_TRANSITIONS for a in row.sources}
    return frozenset(edges)


# --- the manager -------------------------------------------------------------------------------------


class ModeManager:
    """The current mode, the C/A estimate and the last target detection; ``handle`` applies the table."""

    def __init__(self, cfg: ModesConfig, initial: Mode = Mode.STANDBY, obt_s: float = 0.0) -> None:
        """Start in ``initial`` (STANDBY: the spacecraft waits for the timeline) at on-board time ``obt_s``."""
        self.cfg = cfg
        self.mode = Mode(initial)
        self.since_obt_s = obt_s
        self.ca_obt_s: float | None = None
        self.last_seen_obt_s: float | None = None

    def shift_time(self, step_s: float) -> None:
        """On-board time stepped by ``step_s``: the C/A estimate, the last detection and the mode's start move with
        it (they stand for physical times)."""
        self.since_obt_s += step_s
        if self.ca_obt_s is not None:
            self.ca_obt_s += step_s
        if self.last_seen_obt_s is not None:
            self.last_seen_obt_s += step_s

    def handle(self, trigger: Trigger, obt_s: float) -> ModeEvent | None:
        """Apply ``trigger`` at on-board time ``obt_s``: the transition's event report, or None if the mode stays."""
        if not (isinstance(obt_s, (int, float)) and math.isfinite(obt_s)):
            raise InternalFault(f"mode manager: obt_s must be a finite OBT, got {obt_s!r}")
        if isinstance(trigger, SetMode):
            return self._commanded(trigger, obt_s)
        if isinstance(trigger, CaEstimate):
            if not math.isfinite(trigger.ca_obt_s):
                raise InternalFault(f"mode manager: CaEstimate.ca_obt_s must be finite, got {trigger.ca_obt_s!r}")
            self.ca_obt_s = float(trigger.ca_obt_s)
            return None
        if not isinstance(trigger, (TargetDetected, FalseLock, WheelSaturation, Fault, Tick)):
            raise InternalFault(f"mode manager: unknown trigger {trigger!r}")
        state = _State(obt_s, self.cfg, self.ca_obt_s, self.last_seen_obt_s)
        event = None
        for row in EVENT_TRANSITIONS:
            if self.mode in row.sources and isinstance(trigger, row.trigger) and row.guard(state):
                event = self._enter(row.target, obt_s, row.cause, _detail(trigger, row.cause, state))
                break
        if isinstance(trigger, TargetDetected) and self.mode in _TRACKING:
            self.last_seen_obt_s = obt_s
        return event

    def _commanded(self, cmd: SetMode, obt_s: float) -> ModeEvent | None:
        try:
            target = Mode(cmd.mode)
        except ValueError as err:
            raise InternalFault(f"mode manager: SetMode.mode {cmd.mode!r} is not a mode") from err
        if target == self.mode:
            return None  # re-asserting the current mode is accepted and changes nothing
        if target not in COMMANDABLE[self.mode]:
            allowed = tuple(sorted(m.name for m in COMMANDABLE[self.mode]))
            raise IllegalTransition(self.mode.name, target.name, allowed)
        return self._enter(target, obt_s, Cause.COMMANDED, "")

    def _enter(self, target: Mode, obt_s: float, cause: Cause, detail: str) -> ModeEvent:
        event = ModeEvent(obt_s=obt_s, from_mode=self.mode, to_mode=target, cause=cause, detail=detail)
        self.mode = target
        self.since_obt_s = obt_s
        if target not in _TRACKING:
            self.last_seen_obt_s = None  # the lost-target clock only runs while tracking
        return event


def _detail(trigger: Trigger, cause: Cause, s: _State) -> str:
    """A short human text for the event report."""
    if isinstance(trigger, Fault):
        return trigger.what
    if isinstance(trigger, WheelSaturation):
        return "" if trigger.wheel is None else f"wheel {trigger.wheel}"
    if isinstance(trigger, FalseLock):
        return f"frame {trigger.frame_id} refused"
    if cause == Cause.TARGET_LOST:
        return f"target unseen since OBT {s.last_seen_obt_s:.3f} s"
    if cause in (Cause.AUTONOMY_TIME, Cause.FLYBY_OVER):
        return f"C/A estimate OBT {s.ca_obt_s:.3f} s"
    return ""
