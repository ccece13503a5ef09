"""The compiled attitude integrator is cached next to its source, so later processes do not recompile it."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

from universe import attitude_rk4

ROOT = Path(__file__).resolve().parents[2]

_PROBE = """
import json
from universe import attitude_rk4
attitude_rk4.warm_up()
s = attitude_rk4.integrate.stats
print(json.dumps([s.cache_path, len(s.cache_hits), len(s.cache_misses)]))
"""


def test_a_new_process_loads_the_integrator_from_the_cache_next_to_its_source() -> None:
    """After one warm-up, a fresh process's warm-up only hits the cache in universe/__pycache__."""
    attitude_rk4.warm_up()  # writes the cache if this process compiled the kernel
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    out = subprocess.run([sys.executable, "-c", _PROBE], capture_output=True, text=True, env=env, cwd=ROOT,
                         timeout=120, check=True)
    path, hits, misses = json.loads(out.stdout.strip().splitlines()[-1])
    assert Path(path) == Path(attitude_rk4.__file__).parent / "__pycache__"
    assert hits > 0 and misses == 0, (hits, misses)
