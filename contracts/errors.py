"""Errors of the shared package, split by who is at fault."""

from __future__ import annotations


class FlybyError(Exception):
    """Base of every error raised by the shared package."""


class ScenarioError(FlybyError):
    """The user's scenario file is missing, unreadable or invalid; ``problems`` lists each one."""

    def __init__(self, source: str, problems: list[str]) -> None:
        self.source = source
        self.problems = problems
        super().__init__(f"{source}: " + "; ".join(problems))

    def listing(self, what: str) -> str:
        """The error as a command prints it: ``SOURCE: invalid WHAT (N problem(s))``, then one problem a line."""
        return "\n".join([f"{self.source}: invalid {what} ({len(self.problems)} problem(s))",
                          *(f"  {p}" for p in self.problems)])


class DecodeError(FlybyError):
    """A message on the bus could not be decoded (a peer's fault, never fatal to the receiver)."""


class NodeFailure(FlybyError):
    """Another node died or stopped answering; names the node and the simulated time."""

    def __init__(self, node: str, sim_time_s: float | None, why: str) -> None:
        self.node = node
        self.sim_time_s = sim_time_s
        self.why = why
        at = "before the first step" if sim_time_s is None else f"at simulated time {sim_time_s:.1f} s"
        super().__init__(f"node '{node}' {why} {at}")
