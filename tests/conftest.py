"""Test-wide settings: Hypothesis never times an example against the wall clock (a loaded CI machine would fail
tests that are right); each test still bounds its examples with ``max_examples``, drawn the same at every run unless
``FLYBY_HYPOTHESIS=explore``. The compiled kernels are compiled (or loaded from their cache) in two background
processes as the session starts: on a fresh install that is about a minute of compilation the first test to need them
no longer pays alone. The suite runs on every core (pytest-xdist, ``-n auto --dist loadfile`` in pyproject.toml: a
test file's tests on one worker, so its module fixtures run once); the session's controller starts the compilations,
and a worker that needs the kernels loads them, compiling whatever is not cached yet (``-n 0``: one process)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import settings

# the suite's examples are the same at every run (derandomize: the README's test command, CI), so a red run is a
# change's, never a draw's; FLYBY_HYPOTHESIS=explore draws new examples each run, to look for cases on purpose
settings.register_profile("flyby", deadline=None, derandomize=True)
settings.register_profile("explore", deadline=None)
settings.load_profile("explore" if os.environ.get("FLYBY_HYPOTHESIS") == "explore" else "flyby")

ROOT = Path(__file__).resolve().parents[1]

# each node's own warm-up, as the node calls it before its first period (obsw/node.py, universe/node.py)
_WARM_UPS = (
    "from obsw import kernels; kernels.warm_up()",
    "from universe import kernels; kernels.warm_up()",
)
_warming: list[subprocess.Popen[bytes]] = []


def _env() -> dict[str, str]:
    """This environment with the checkout first on the path (the kernels' caches are next to its sources)."""
    return {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))}


def _xdist_worker() -> bool:
    """Whether this process is one of pytest-xdist's workers (the controller runs no test)."""
    return "PYTEST_XDIST_WORKER" in os.environ


def pytest_sessionstart(session: pytest.Session) -> None:
    """Start the kernels' compilation in the background, once per session (in the controller, not in each worker);
    a test that needs a kernel sooner compiles it itself, and Numba writes each cache file whole (a temporary file
    moved into place), so any process's copy serves."""
    if _xdist_worker():
        return
    for code in _WARM_UPS:
        _warming.append(subprocess.Popen([sys.executable, "-c", code], cwd=ROOT, env=_env(),
                                         stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))


def wait_for_kernels(deadline_s: float = 600.0) -> None:
    """Return once every node's kernels are compiled and cached: the background compilations waited for (a generous
    deadline), one that failed run again in the foreground, so that its error is shown. In a worker, which did not
    start them, each node's warm-up runs here: a load from the cache once the controller's have finished."""
    if _xdist_worker():
        for code in _WARM_UPS:
            subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=_env(), check=True, timeout=deadline_s)
        return
    for proc, code in zip(_warming, _WARM_UPS):
        if proc.wait(timeout=deadline_s) != 0:
            subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=_env(), check=True, timeout=deadline_s)


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    """Leave no warm-up process behind (a short session may end before they do)."""
    for proc in _warming:
        if proc.poll() is None:
            proc.kill()
        proc.wait()
