"""Random streams of a run: one independent generator per subsystem, all fixed by the scenario seed.

Spawning from one ``SeedSequence`` means adding draws to one subsystem never changes another's, and the ground's
draw of the nominal trajectory is the same in every process that needs it.
"""

from __future__ import annotations

import numpy as np

STREAMS = ("nominal", "sensors", "camera", "oscillator", "initial")


def rng_streams(seed: int) -> dict[str, np.random.Generator]:
    """One generator per name in ``STREAMS``, fixed by ``seed``."""
    children = np.random.SeedSequence(seed).spawn(len(STREAMS))
    return {name: np.random.default_rng(s) for name, s in zip(STREAMS, children)}
