"""The tasks of the on-board executive: one enum for the schedule table, the housekeeping and the overrun events.

The value is the task's wire code (one octet in an overrun event, its index in housekeeping's per-task arrays);
the name is how the scenario's schedule table and the logs spell it.
"""

from __future__ import annotations

from enum import IntEnum

from contracts.model import named_enum


class Task(IntEnum):
    """On-board tasks and their wire codes, in the order of the zero-time flight software's period."""

    TIME = 0  # OBT jump monitor and PUS 9 time reports
    TELECOMMANDS = 1  # decode, verify (PUS 1) and execute the telecommands received
    SCHEDULE = 2  # release the PUS 11 time-tagged commands whose tag has come
    ATTITUDE = 3  # attitude determination: star tracker, gyro propagation in an outage
    IMAGING = 4  # software stage of the imaging chain: features, identification, line of sight
    RECOGNITION = 5  # trajectory recognition: grid and continuous C/A estimates
    MODES = 6  # mode manager
    CONTROL = 7  # tracking loop and PD attitude control: the wheel torques
    FDIR = 8  # failure detection, isolation and recovery: reports and recovers failed parameter checks
    CAMERA = 9  # camera commanding: frame requests at the imaging cadence
    TELEMETRY = 10  # housekeeping and estimate reports


TASK_COUNT = len(Task)


TaskValue = named_enum(Task)
"""A task field: accepts a name or a code, holds a ``Task``, serialises to its name in JSON."""
