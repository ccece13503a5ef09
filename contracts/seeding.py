"""Random streams of a run: one independent generator per subsystem, all fixed by the scenario seed.

Spawning from one ``SeedSequence`` means adding draws to one subsystem never changes another's, and the ground's
draw of the nominal trajectory is the same in every process that needs it.
"""

from __future__ import annotations

import numpy as np

# new names go last: a stream's seed follows from its position, so appending keeps every existing stream
STREAMS = ("nominal", "sensors", "camera", "oscillator", "initial", "cosmic_rays", "dark_frame")


def rng_streams(seed: int) -> dict[str, np.random.Generator]:
    """One generator per name in ``STREAMS``, fixed by ``seed``."""
    children = np.random.SeedSequence(seed).spawn(len(STREAMS))
    return {name: np.random.default_rng(s) for name, s in zip(STREAMS, children)}
