"""The flight software's compiled kernels (Numba), loaded together: the attitude filter, the imaging chain's block
statistics and limb circles, the trajectory recognition's continuous estimate, the tracking loop and the control law. Compiled the first time after an install (seconds), then loaded
from the cache next to each module; a process that runs the flight software calls ``warm_up`` before its first
control period, so that no period pays for it.
"""

from __future__ import annotations

from obsw import control, imaging_kernels, imaging_limb, mekf_kernels, recognition_kernels, tracking


def warm_up() -> None:
    """Compile, or load from the cache, every kernel of the flight software."""
    mekf_kernels.warm_up()
    imaging_kernels.warm_up()
    imaging_limb.warm_up()
    recognition_kernels.warm_up()
    tracking.warm_up()
    control.warm_up()
