"""Three real node processes over Zenoh run a short flyby in lock-step; ground receives the telemetry."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from contracts import pus, sdls
from contracts.bus import free_tcp_port
from contracts.steplog import STEP_RECORD, StepLog
from tests.integration.conftest import DATA, flyby

pytestmark = pytest.mark.integration


def _packets(run: Path) -> list[tuple[pus.TmHeader, object]]:
    return [pus.decode_tm(p) for p in pus.split_packets((run / "tm.bin").read_bytes())]


def test_telemetry_reached_ground(short_runs: tuple[Path, Path]) -> None:
    """Ground archived housekeeping every second, the uploads' verifications, and the mode changes."""
    run = short_runs[0]
    packets = _packets(run)
    hk = [r for _, r in packets if isinstance(r, pus.Housekeeping)]
    # 30 s run, 1 s light time: about 29 housekeeping reports reach ground
    assert 25 <= len(hk) <= 31
    ver = [r for _, r in packets if isinstance(r, pus.Verification)]
    assert ver and all(v.success for v in ver), [v for v in ver if not v.success]
    modes = [r for _, r in packets if isinstance(r, pus.ModeChangedEvent)]
    assert modes and modes[0].to_mode == pus.Mode.ACQUISITION
    seqs = [h.seq_count for h, _ in packets]
    assert seqs == list(range(seqs[0], seqs[0] + len(seqs))), "sequence counts must be gapless"
    truth = (run / "truth.csv").read_text().splitlines()
    assert len(truth) == 1 + 301  # header + every control period from start to end
    assert (run / "summary.json").exists()


def test_same_seed_gives_identical_telemetry(short_runs: tuple[Path, Path]) -> None:
    """Two runs of the same scenario and seed write byte-identical telemetry and truth."""
    a, b = short_runs
    assert (a / "tm.bin").read_bytes() == (b / "tm.bin").read_bytes()
    assert (a / "truth.csv").read_bytes() == (b / "truth.csv").read_bytes()


def test_obsw_record_holds_the_downlink_and_replays(short_runs: tuple[Path, Path]) -> None:
    """The OBSW node's step record holds every period, its replies' packets are the telemetry ground received (in
    order, byte for byte), and ``flyby replay`` of the run finds it identical (exit 0)."""
    run = short_runs[0]
    log = StepLog(run / STEP_RECORD)
    steps = list(log.steps())
    assert not log.truncated and len(steps) == 300 and all(s.reply is not None for s in steps)
    assert any(s.frame is not None for s in steps)
    sent = b"".join(p for s in steps for p in s.reply.downlink)  # type: ignore[union-attr]
    assert sent == (run / "tm.bin").read_bytes()
    r = flyby("replay", str(run), "--out", str(run / "replay"))
    assert r.returncode == 0 and "IDENTICAL" in r.stdout, r.stdout + r.stderr


def test_killed_node_stops_the_others(tmp_path: Path) -> None:
    """Killing the OBSW mid-run makes universe and ground exit within the timeout, naming the OBSW."""
    ports = {n: free_tcp_port() for n in ("universe", "obsw", "ground")}
    ep = {n: f"tcp/127.0.0.1:{p}" for n, p in ports.items()}
    keys = tmp_path.parent / f"{tmp_path.name}-tc-keys.json"
    sdls.write_key_file(keys, sdls.KeyRing.generate())
    common = ["--config", str(DATA / "short.yaml"), "--run-id", f"kill-{ports['universe']}", "--out", str(tmp_path),
              "--insecure", "--tc-keys", str(keys)]
    cmds = {
        "universe": ["--listen", ep["universe"], "--realtime"],
        "obsw": ["--listen", ep["obsw"], "--connect", ep["universe"]],
        "ground": ["--listen", ep["ground"], "--connect", ep["universe"], "--connect", ep["obsw"]],
    }
    logs = {n: open(tmp_path / f"{n}.log", "w") for n in cmds}
    procs = {n: subprocess.Popen([sys.executable, "-m", n, *common, *a], stdout=logs[n], stderr=subprocess.STDOUT)
             for n, a in cmds.items()}
    try:
        deadline = time.monotonic() + 60
        while "peers up" not in (tmp_path / "universe.log").read_text():
            assert time.monotonic() < deadline, "universe never saw its peers"
            assert procs["universe"].poll() is None, (tmp_path / "universe.log").read_text()
            time.sleep(0.2)
        time.sleep(3.0)  # real-time pacing: about 3 s of simulated time
        procs["obsw"].send_signal(signal.SIGKILL)
        killed_at = time.monotonic()
        for n in ("universe", "ground"):
            code = procs[n].wait(timeout=20)
            assert code == 3, f"{n} exited with {code}"
        assert time.monotonic() - killed_at < 5.0 + 5.0  # the scenario's reply timeout plus a margin
        for n in ("universe", "ground"):
            text = (tmp_path / f"{n}.log").read_text()
            assert "node 'obsw'" in text and "at simulated time" in text, text[-2000:]
    finally:
        for p in procs.values():
            if p.poll() is None:
                p.kill()
            p.wait()
        for f in logs.values():
            f.close()
