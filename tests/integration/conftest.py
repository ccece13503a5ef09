"""Helpers for tests that start real node processes over Zenoh."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

DATA = Path(__file__).parent / "data"


def flyby(*args: str, timeout: float = 240.0, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    """Run the ``flyby`` command as a user would, capturing its output."""
    return subprocess.run([sys.executable, "-m", "flyby.cli", *args], capture_output=True, text=True,
                          timeout=timeout, cwd=cwd)
