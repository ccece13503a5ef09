"""Helpers for tests that start real node processes over Zenoh."""

from __future__ import annotations

import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from tests.conftest import wait_for_kernels

DATA = Path(__file__).parent / "data"


@pytest.fixture(scope="session", autouse=True)
def compiled_kernels() -> None:
    """The nodes' kernels compiled before any node process needs them (the session's background compilation,
    ``tests/conftest.py``): the first run after an install pays about a minute for it (announced by ``flyby run``),
    which would otherwise eat into these tests' time windows."""
    wait_for_kernels()


def flyby(*args: str, timeout: float = 240.0, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    """Run the ``flyby`` command as a user would, capturing its output."""
    return subprocess.run([sys.executable, "-m", "flyby.cli", *args], capture_output=True, text=True,
                          timeout=timeout, cwd=cwd)


@pytest.fixture(scope="session")
def short_runs(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """The short scenario run twice with the same seed, at the same time on this host (as two users' runs may be),
    the second recording its frames raw and tracing its hops (shared by the tests of the run, of replay and of
    PUS-C conformance)."""
    base = tmp_path_factory.mktemp("runs")
    extras = {1: ("--record-frames", "reference"), 2: ("--record-frames", "raw", "--trace")}
    outs = {i: base / f"run{i}" for i in extras}
    with ThreadPoolExecutor(max_workers=len(extras)) as pool:
        done = {i: pool.submit(flyby, "run", str(DATA / "short.yaml"), "--out", str(outs[i]), *extra, timeout=400)
                for i, extra in extras.items()}
    for i, future in done.items():
        r, out = future.result(), outs[i]
        assert r.returncode == 0, f"run {i} failed:\n{r.stdout}\n{r.stderr}\n" + "\n".join(
            f"--- {n}.log\n{(out / f'{n}.log').read_text()[-3000:]}" for n in ("universe", "obsw", "ground")
            if (out / f"{n}.log").exists())
    return outs[1], outs[2]


def start_nodes(out: Path, scenario: Path, realtime: bool = True, credentials: Path | None = None,
                hold: tuple[str, ...] = ()) -> tuple[dict[str, subprocess.Popen[bytes]], dict[str, str], str]:
    """Start the three nodes as separate processes (as on three hosts), over TLS with the identities in
    ``credentials`` (plain TCP, ``--insecure``, when None); return them, their endpoints, the run id.

    The nodes named in ``hold`` are not started: ``launch_held`` starts them later. The universe waits for every
    node, so holding one back holds the run at its start, e.g. until a test's own session is listening."""
    from contracts.bus import free_tcp_port

    ports = {n: free_tcp_port() for n in ("universe", "obsw", "ground")}
    ep = {n: f"{'tls' if credentials else 'tcp'}/127.0.0.1:{p}" for n, p in ports.items()}
    run_id = f"test-{ports['universe']}"
    security = ["--credentials", str(credentials)] if credentials else ["--insecure", "--tc-keys",
                                                                          str(_insecure_keys(out))]
    common = ["--config", str(scenario), "--run-id", run_id, "--out", str(out), *security]
    extra = {
        "universe": ["--listen", ep["universe"], *(["--realtime"] if realtime else [])],
        "obsw": ["--listen", ep["obsw"], "--connect", ep["universe"]],
        "ground": ["--listen", ep["ground"], "--connect", ep["universe"], "--connect", ep["obsw"]],
    }
    procs: dict[str, subprocess.Popen[bytes]] = {}
    _HELD[run_id] = {n: [sys.executable, "-m", n, *common, *a] for n, a in extra.items() if n in hold}
    for n, a in extra.items():
        if n not in hold:
            procs[n] = _launch(out, n, [sys.executable, "-m", n, *common, *a])
    return procs, ep, run_id


_HELD: dict[str, dict[str, list[str]]] = {}  # run id -> the command lines of the nodes held back at its start


def _launch(out: Path, name: str, argv: list[str]) -> subprocess.Popen[bytes]:
    with open(out / f"{name}.log", "wb") as log:
        return subprocess.Popen(argv, stdout=log, stderr=subprocess.STDOUT)


def launch_held(out: Path, run_id: str, procs: dict[str, subprocess.Popen[bytes]]) -> None:
    """Start the nodes ``start_nodes`` held back for ``run_id``, adding them to ``procs``."""
    for name, argv in _HELD.pop(run_id).items():
        procs[name] = _launch(out, name, argv)


def _insecure_keys(out: Path) -> Path:
    """A TC key file beside the run folder (TCs are authenticated on a plain-TCP bus too)."""
    from contracts import sdls

    path = out.parent / f"{out.name}-tc-keys.json"
    if not path.exists():
        sdls.write_key_file(path, sdls.KeyRing.generate())
    return path


def stop_nodes(procs: dict[str, subprocess.Popen[bytes]]) -> None:
    """Kill whatever is still running."""
    for p in procs.values():
        if p.poll() is None:
            p.kill()
        p.wait()
