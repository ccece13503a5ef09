"""Ctrl-C stops every node and leaves no process behind; garbage on the bus is counted, logged and survived."""

from __future__ import annotations

import os
import select
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from contextlib import ExitStack
from pathlib import Path

import pytest
import zenoh

from contracts.bus import Keys, TlsIdentity, access_control, session_config
from flyby.credentials import write_credentials
from tests.integration.conftest import DATA, start_nodes, stop_nodes

pytestmark = pytest.mark.integration


def _processes_mentioning(text: str) -> list[int]:
    """PIDs of live processes whose command line contains ``text``."""
    pids = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                cmd = (d / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
            except OSError:
                continue
            if text in cmd and int(d.name) != os.getpid():
                pids.append(int(d.name))
    return pids


def _default_sigint() -> None:
    """In the child before exec: SIGINT back to its default action, so Python turns it into KeyboardInterrupt."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _wait_for_exit(pids: list[int], timeout_s: float) -> None:
    """Wait for each process to exit (its pidfd becomes readable: the event), up to ``timeout_s`` in all."""
    deadline = time.monotonic() + timeout_s
    for pid in pids:
        try:
            fd = os.pidfd_open(pid)
        except ProcessLookupError:
            continue  # gone already
        try:
            select.select([fd], [], [], max(deadline - time.monotonic(), 0.0))
        finally:
            os.close(fd)


def _read_progress_until(launcher: subprocess.Popen[str], done: Callable[[str], bool], what: str) -> None:
    """Read the launcher's output until a progress line for which ``done`` holds (each read blocks until the next
    line, the event waited on; pytest's timeout bounds a launcher that never prints one)."""
    assert launcher.stdout is not None
    seen = []
    for line in launcher.stdout:
        seen.append(line)
        if line.startswith("t =") and done(line):
            return
    pytest.fail(f"the run ended before {what}:\n" + "".join(seen))


def _wait_for_progress(launcher: subprocess.Popen[str], mode: str) -> None:
    """Wait for a progress line whose mode contains ``mode``."""
    _read_progress_until(launcher, lambda line: mode in line.split("mode ", 1)[-1],
                         f"a progress line in mode {mode!r}")


def _wait_for_shared_frames(launcher: subprocess.Popen[str], folder: Path) -> None:
    """Wait for a progress line once the run's shared-memory folder exists (the universe makes it for its first frame
    and keeps it to the run's end)."""
    _read_progress_until(launcher, lambda _: folder.is_dir(), "the universe shared a frame")


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_ctrl_c_stops_everything(tmp_path: Path) -> None:
    """SIGINT to `flyby run` ends it with code 130 and no node process survives."""
    out = tmp_path / "run"
    # a shell starts a background job with SIGINT ignored, and a child inherits that: give the launcher the default
    launcher = subprocess.Popen([sys.executable, "-m", "flyby.cli", "run", str(DATA / "operator.yaml"), "--realtime",
                                 "--out", str(out)], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                preexec_fn=_default_sigint)
    _wait_for_progress(launcher, "")  # the first progress line: the nodes are up and stepping
    assert len(_processes_mentioning(str(out))) >= 3
    launcher.send_signal(signal.SIGINT)
    text, _ = launcher.communicate(timeout=60)
    assert launcher.returncode == 130, text
    assert "interrupted" in text
    _wait_for_exit(_processes_mentioning(str(out)), 10.0)  # generous: the launcher waited for its nodes already
    assert _processes_mentioning(str(out)) == [], "orphan node processes"


def test_garbage_messages_are_counted_and_survived(tmp_path: Path) -> None:
    """Undecodable messages on every key of the lock-step are logged and counted; the run still completes."""
    creds = tmp_path / "credentials"
    write_credentials(creds)
    procs, ep, run_id = start_nodes(tmp_path, DATA / "short.yaml", realtime=False, credentials=creds)
    keys = Keys(run_id)
    # each key from the role allowed to publish on it (another role's puts are refused by access control)
    roles = {"universe": (keys.step, keys.ground_step), "obsw": (keys.reply,), "ground": (keys.ground_reply,)}
    try:
        with ExitStack() as stack:
            pubs = []
            for role, published in roles.items():
                conf = session_config(connect=list(ep.values()), tls=TlsIdentity.in_folder(creds, role),
                                      acl=access_control(keys))
                s = stack.enter_context(zenoh.open(conf))
                pubs += [s.declare_publisher(k) for k in published]
            deadline = time.monotonic() + 120
            while procs["universe"].poll() is None:
                assert time.monotonic() < deadline, "the run did not end"
                for p in pubs:
                    p.put(b"\x00\x00\x00\x04{no}")
                time.sleep(0.02)
        codes = {n: p.wait(timeout=30) for n, p in procs.items()}
        assert codes == {"universe": 0, "obsw": 0, "ground": 0}
        logs = {n: (tmp_path / f"{n}.log").read_text() for n in procs}
        assert "undecodable message" in logs["universe"] and "undecodable message" in logs["obsw"]
        assert "undecodable message" in logs["ground"]
        assert "run complete" in logs["universe"]
    finally:
        stop_nodes(procs)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc and /dev/shm")
def test_a_killed_universe_leaves_no_frame_in_shared_memory(tmp_path: Path) -> None:
    """`flyby run` passes frames through the host's shared memory; when the universe is killed mid-run the run's
    shared-memory folder is gone once the run has ended."""
    from contracts.shared_blobs import run_folder

    out = tmp_path / "run"
    launcher = subprocess.Popen([sys.executable, "-m", "flyby.cli", "run", str(DATA / "short.yaml"), "--realtime",
                                 "--out", str(out)], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    folder = run_folder(f"run-{launcher.pid}")  # the launcher names the run after its folder and its process
    try:
        _wait_for_shared_frames(launcher, folder)  # the run is up and frames are flowing
        universe = [p for p in _processes_mentioning(str(out)) if b"-m\0universe" in
                    Path(f"/proc/{p}/cmdline").read_bytes()]
        assert len(universe) == 1
        os.kill(universe[0], signal.SIGKILL)
        text, _ = launcher.communicate(timeout=60)
        assert launcher.returncode != 0, text
        assert not folder.exists(), sorted(p.name for p in folder.iterdir())
    finally:
        if launcher.poll() is None:
            launcher.kill()
            launcher.wait()
