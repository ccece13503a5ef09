"""Process exit codes of every command and node, defined once.

A script or CI job can tell what went wrong from the code alone: a bad input (2) is the user's to fix, a failed
node (3) is the run's, an internal error (1) is ours.
"""

from __future__ import annotations

from enum import IntEnum


class ExitCode(IntEnum):
    """What a process's exit status means."""

    OK = 0  # success; for a check (validate, campaign, replay) also "everything held"
    INTERNAL = 1  # a bug: an unexpected exception; for console requests, the ground refused the request
    INVALID_INPUT = 2  # a scenario, timeline, run folder or command line that cannot be used; nothing was run
    PEER_FAILED = 3  # a node of the run died or stopped answering (the console: no ground node answered)
    CHECK_FAILED = 4  # a check ran and found a fault: a replay that differs, a dry run predicting a refusal or a failure
    INTERRUPTED = 130  # stopped by the user (Ctrl-C), as a shell reports SIGINT


EXIT_OK = ExitCode.OK
EXIT_INTERNAL = ExitCode.INTERNAL
EXIT_CONFIG = ExitCode.INVALID_INPUT
EXIT_PEER = ExitCode.PEER_FAILED
EXIT_CHECK_FAILED = ExitCode.CHECK_FAILED
EXIT_INTERRUPTED = ExitCode.INTERRUPTED
