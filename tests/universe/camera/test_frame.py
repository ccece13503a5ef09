"""The frame: the camera's compiled kernels are cached next to their source, so later processes do not recompile."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

from universe.camera import raycast, readout, warm_up

ROOT = Path(__file__).resolve().parents[3]

_PROBE = """
import json
from universe.camera import raycast, readout, warm_up
warm_up()
stats = {d.__name__: d.stats for d in (raycast.cast_body, readout.digitise, readout.dark_frame)}
print(json.dumps({k: [s.cache_path, len(s.cache_hits), len(s.cache_misses)] for k, s in stats.items()}))
"""


def test_a_new_process_loads_the_kernels_from_the_cache_next_to_their_source() -> None:
    """After one warm-up, a fresh process's warm-up only hits the cache in universe/camera/__pycache__."""
    warm_up()  # writes the cache if this process compiled the kernels
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    out = subprocess.run([sys.executable, "-c", _PROBE], capture_output=True, text=True, env=env, cwd=ROOT,
                         timeout=120, check=True)
    stats = json.loads(out.stdout.strip().splitlines()[-1])
    here = Path(raycast.__file__).parent / "__pycache__"
    assert Path(readout.__file__).parent / "__pycache__" == here
    for name, (path, hits, misses) in stats.items():
        assert Path(path) == here, name
        assert hits > 0 and misses == 0, (name, hits, misses)
