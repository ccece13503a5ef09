"""``flyby run``: start the three nodes as processes on loopback, show progress, and make sure none outlives the run.

Each node gets its own free TCP port; the universe listens, the OBSW connects to it, ground connects to both, and
the launcher joins the bus only to watch status and shutdown messages. The bus runs over TLS with mutual
authentication and access control, with credentials made for the run in a private temporary folder (deleted at
the end; ``flyby.credentials``), unless ``insecure`` asks for plain TCP. Children die with the launcher
(``PR_SET_PDEATHSIG`` on Linux) and are terminated, then killed, if they do not stop on their own, so no orphan
is left behind whatever happens.
"""

from __future__ import annotations

import ctypes
import json
import logging
import os
import re
import shutil
import signal
import subprocess
import sys
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

import zenoh

from contracts.bus import LAUNCHER, NODES, Keys, free_tcp_port
from flyby.credentials import TC_KEY_FILE, run_credentials
from flyby.nodecli import bus_settings
from contracts.clock import WallClock, utc_stamp
from contracts.errors import DecodeError
from contracts.exitcodes import EXIT_INTERNAL, EXIT_INTERRUPTED, EXIT_OK, EXIT_PEER
from contracts.messages import Shutdown, Status, decode
from contracts.runtime import Attachment
from contracts.shared_blobs import run_folder as shared_run_folder
from contracts.shared_blobs import shared_memory_available
from contracts.steplog import FrameKeeping
from scenario.model import Scenario



def _die_with_parent() -> None:
    """In the child: receive SIGTERM when the launcher dies, so no node is orphaned."""
    if sys.platform.startswith("linux"):
        libc = ctypes.CDLL("libc.so.6", use_errno=True)
        libc.prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG


@dataclass
class Watch:
    """What the launcher has heard on the bus."""

    status: dict[str, Status] = field(default_factory=dict)
    shutdowns: list[Shutdown] = field(default_factory=list)
    lock: threading.Lock = field(default_factory=threading.Lock)


def run_folder(scenario: Scenario, out: Path | None) -> Path:
    """The folder for this run's outputs: ``out``, or ``runs/<scenario>-<UTC stamp>`` (made unique)."""
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        return out
    base = Path("runs") / f"{scenario.name}-{utc_stamp()}"
    path, n = base, 1
    while path.exists():
        n += 1
        path = base.with_name(f"{base.name}-{n}")
    path.mkdir(parents=True)
    return path


def endpoints(ports: dict[str, int], secured: bool) -> dict[str, str]:
    """The loopback endpoint of each node."""
    return {n: f"{'tls' if secured else 'tcp'}/127.0.0.1:{ports[n]}" for n in NODES}


def node_commands(config: Path, run_id: str, out: Path, ports: dict[str, int], realtime: bool,
                  log_level: str, credentials: Path | None, python: str = sys.executable,
                  record_frames: FrameKeeping = "reference", shared_memory: bool = False) -> dict[str, list[str]]:
    """The command line of each node: universe listens, obsw connects to it, ground connects to both; over TLS with
    the identities in ``credentials``, or plain TCP when None; the OBSW's step record keeps camera frames as
    ``record_frames`` says; ``shared_memory``: frames go from the universe to the OBSW through shared memory."""
    ep = endpoints(ports, credentials is not None)
    security = ["--credentials", str(credentials)] if credentials is not None else ["--insecure"]
    common = ["--config", str(config), "--run-id", run_id, "--out", str(out), "--log-level", log_level, *security]
    return {
        "universe": [python, "-m", "universe", *common, "--listen", ep["universe"],
                     *(["--realtime"] if realtime else []), *(["--shared-memory"] if shared_memory else [])],
        "obsw": [python, "-m", "obsw", *common, "--listen", ep["obsw"], "--connect", ep["universe"],
                 "--record-frames", record_frames],
        "ground": [python, "-m", "ground", *common, "--listen", ep["ground"], "--connect", ep["universe"],
                   "--connect", ep["obsw"]],
    }


def _watch_nodes(session: zenoh.Session, keys: Keys, watch: Watch) -> list[zenoh.Subscriber]:
    """Keep the nodes' latest status and every Shutdown in ``watch`` (undecodable samples ignored); the subscribers
    live as long as the list returned."""
    def keeping(kind: type[Status] | type[Shutdown], keep: Callable[[Any], None]) -> Callable[[zenoh.Sample], None]:
        def on_sample(sample: zenoh.Sample) -> None:
            try:
                msg, _ = decode(kind, sample.payload.to_bytes())
            except DecodeError:
                return
            with watch.lock:
                keep(msg)
        return on_sample

    return [session.declare_subscriber(keys.status_all, keeping(Status, lambda m: watch.status.__setitem__(m.node, m))),
            session.declare_subscriber(keys.shutdown, keeping(Shutdown, watch.shutdowns.append))]


def trace_file(node: str) -> str:
    """The name of ``node``'s hop trace in a run folder (``flyby run --trace``)."""
    return f"{node}.trace.csv"


def _stepping(watch: Watch) -> bool:
    """Whether the universe has reported its status: the nodes are up and the run steps."""
    with watch.lock:
        return "universe" in watch.status


def _progress_line(watch: Watch, end_s: float) -> str:
    with watch.lock:
        u = watch.status.get("universe")
        o = watch.status.get("obsw")
    if u is None:
        return "starting nodes (the first run after an install also compiles their kernels, about 40 s)..."
    rtf = f"{u.real_time_factor:6.1f}x" if u.real_time_factor is not None else "   -  "
    mode = o.mode if o is not None and o.mode else "-"
    return f"t = {u.sim_time_s:8.1f} s / {end_s:.1f} s   real-time factor {rtf}   mode {mode:<20}"


def launch(config: Path, scenario: Scenario, out: Path | None = None, realtime: bool = False,
           log_level: str = "INFO", stream: IO[str] = sys.stdout, insecure: bool = False,
           tc_keys: Path | None = None, record_frames: FrameKeeping = "reference", trace: bool = False) -> int:
    """Run the scenario with the three nodes as local processes; return an exit code (0 = success).

    The bus is secured with fresh credentials (and ``tc_keys``, a TC key file, instead of fresh TC keys) unless
    ``insecure``; ``record_frames``: how the OBSW's step record keeps camera frames (``contracts.steplog``);
    ``trace``: each node writes the time marks of its lock-step to ``NODE.trace.csv`` in the run folder
    (``contracts.hoptrace``)."""
    if insecure:
        with run_credentials(tc_keys) as credentials:  # the TCs stay authenticated even on a plain bus
            return _launch(config, scenario, out, realtime, log_level, stream, None, credentials, record_frames,
                           trace)
    with run_credentials(tc_keys) as credentials:
        return _launch(config, scenario, out, realtime, log_level, stream, credentials, credentials, record_frames,
                       trace)


def _launch(config: Path, scenario: Scenario, out: Path | None, realtime: bool, log_level: str, stream: IO[str],
            credentials: Path | None, key_folder: Path, record_frames: FrameKeeping = "reference",
            trace: bool = False) -> int:
    folder = run_folder(scenario, out)
    shutil.copyfile(config, folder / "scenario.yaml")
    run_id = re.sub(r"[^A-Za-z0-9_.-]", "_", f"{folder.name}-{os.getpid()}")
    keys = Keys(run_id)
    ports = {n: free_tcp_port() for n in NODES}
    # the three nodes share this host: frames travel through its shared memory when it has some
    cmds = node_commands(config, run_id, folder, ports, realtime, log_level, credentials, record_frames=record_frames,
                         shared_memory=shared_memory_available())
    for node in ("obsw", "ground"):
        cmds[node] += ["--tc-keys", str(key_folder / TC_KEY_FILE)]
    if trace:
        for node in NODES:
            cmds[node] += ["--trace", str(folder / trace_file(node))]
    ep = endpoints(ports, credentials is not None)
    print(f"run folder: {folder}", file=stream)
    security = f"--credentials {credentials}" if credentials is not None else "--insecure"
    print(f"run id {run_id}; operator console: flyby ground --connect {ep['ground']} {security} "
          f"--run-id {run_id} --watch", file=stream)
    watch = Watch()
    clock = WallClock()
    conf = bus_settings(LAUNCHER, [], list(ep.values()), run_id, credentials, credentials is None,
                        scenario.bus.multicast_scouting)
    procs: dict[str, subprocess.Popen[bytes]] = {}
    logs: dict[str, IO[bytes]] = {}
    interrupted = False
    tty = stream.isatty()
    try:
        # the nodes first: opening a session waits about 0.5 s for endpoints not yet listening, while the nodes
        # take seconds to import and build their cores (their status and any Shutdown come after that)
        for node in NODES:
            logs[node] = open(folder / f"{node}.log", "wb")
            procs[node] = subprocess.Popen(cmds[node], stdout=logs[node], stderr=subprocess.STDOUT,
                                           stdin=subprocess.DEVNULL, preexec_fn=_die_with_parent,
                                           start_new_session=True)
        with zenoh.open(conf) as session:
            subs = _watch_nodes(session, keys, watch)
            last_print = -1e9
            stepping = False  # the universe's first status: a line says so at once, not at the next interval
            first_exit: float | None = None
            grace = scenario.bus.reply_timeout_s + 10.0
            while any(p.poll() is None for p in procs.values()):
                try:
                    now = clock.now()
                    started = not stepping and _stepping(watch)
                    if now - last_print >= (0.5 if tty else 10.0) or started:
                        line = _progress_line(watch, scenario.universe.end_s)
                        print(("\r" + line) if tty else line, end="" if tty else "\n", file=stream, flush=True)
                        last_print = now
                        stepping = stepping or started
                    failed = [n for n, p in procs.items() if p.returncode not in (None, 0)]
                    if first_exit is None and (failed or procs["universe"].poll() is not None):
                        first_exit = now
                    if first_exit is not None and now - first_exit > grace:
                        break
                    threading.Event().wait(0.1)
                except KeyboardInterrupt:
                    if interrupted:
                        break
                    interrupted = True
                    print("\ninterrupted: stopping the nodes (Ctrl-C again to kill them)", file=stream, flush=True)
                    att = Attachment(session, keys, "launcher", clock, logging.getLogger("launcher"))
                    att.shutdown("interrupted by the user (Ctrl-C)", failed=True)
                    first_exit = clock.now()
            del subs
    finally:
        for p in procs.values():
            if p.poll() is None:
                p.terminate()
        for p in procs.values():
            try:
                p.wait(timeout=5)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
        for f in logs.values():
            f.close()
        shutil.rmtree(shared_run_folder(run_id), ignore_errors=True)  # frames a node that died left behind
    if tty:
        print(file=stream)
    return _summarise(folder, procs, watch, interrupted, stream)


def _summarise(folder: Path, procs: dict[str, subprocess.Popen[bytes]], watch: Watch, interrupted: bool,
               stream: IO[str]) -> int:
    codes = {n: p.returncode for n, p in procs.items()}
    failures = [s for s in watch.shutdowns if s.failed]
    print("nodes: " + ", ".join(f"{n} exit {c}" for n, c in codes.items()), file=stream)
    if failures:
        print(f"run FAILED: {failures[0].reason}", file=stream)
    elif any(c != 0 for c in codes.values()):
        bad = next(n for n, c in codes.items() if c != 0)
        print(f"run FAILED: node '{bad}' exited with code {codes[bad]}; see {folder / (bad + '.log')}", file=stream)
    summary = folder / "summary.json"
    if summary.exists():
        data = json.loads(summary.read_text())
        for line in data.get("lines", []):
            print(line, file=stream)
    print(f"outputs in {folder}", file=stream)
    if interrupted:
        return EXIT_INTERRUPTED
    if failures or any(c != 0 for c in codes.values()):
        return EXIT_PEER if any(c == EXIT_PEER for c in codes.values()) or failures else EXIT_INTERNAL
    return EXIT_OK
