"""Three real node processes over Zenoh run a short flyby in lock-step; ground receives the telemetry."""

from __future__ import annotations

import csv
import hashlib
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from contracts import pus, sdls
from contracts.bus import free_tcp_port
from contracts.hoptrace import hop_table, read_traces
from contracts.steplog import STEP_RECORD, StepLog
from flyby.launcher import trace_file
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


def test_the_ground_node_draws_the_animation_in_its_helper_process(short_runs: tuple[Path, Path]) -> None:
    """The ground node's report drew its animation in the helper process it starts, without falling back to drawing
    it in the node, and wrote it."""
    for run in short_runs:
        log = (run / "ground.log").read_text()
        assert "report: " in log and "helper process" not in log, log[-3000:]
        assert (run / "report" / "flyby.gif").stat().st_size > 0


def test_a_traced_run_times_every_period_of_its_loop(short_runs: tuple[Path, Path]) -> None:
    """`flyby run --trace` leaves each node's hop trace; every period of the run has its whole chain, each link
    within one node lasting no less than zero, and the links of a period adding up to its time from request to
    request (the untraced run's telemetry is the same: see the next test)."""
    run = short_runs[1]
    marks = read_traces(run / trace_file(n) for n in ("universe", "obsw", "ground"))
    table = hop_table(marks)
    periods = len((run / "truth.csv").read_text().splitlines()) - 2  # header; the last period has no reply
    assert {len(s.durations_s) for s in table[:-1]} == {periods}
    assert len(table[-1].durations_s) == periods - 1
    for s in table:
        if "->" in s.name and ": " not in s.name.split("->")[1]:  # both marks taken by the same node
            assert min(s.durations_s) >= 0.0, s.name
    first: dict[int, int] = {}
    for m in marks:
        if m.node == "universe" and m.what == "publish:obsw/step":
            first.setdefault(m.step, m.t_ns)
    request_to_request = sum(first[k + 1] - first[k] for k in range(periods - 1)) * 1e-9
    assert sum(sum(s.durations_s[:periods - 1]) for s in table) == pytest.approx(request_to_request, rel=1e-9)
    assert any(m.node == "ground" and m.what == "work" for m in marks)


def test_same_seed_gives_identical_telemetry(short_runs: tuple[Path, Path]) -> None:
    """Two runs of the same scenario and seed write byte-identical telemetry and truth."""
    a, b = short_runs
    assert (a / "tm.bin").read_bytes() == (b / "tm.bin").read_bytes()
    assert (a / "truth.csv").read_bytes() == (b / "truth.csv").read_bytes()


def test_obsw_record_holds_the_downlink_and_replays(short_runs: tuple[Path, Path]) -> None:
    """The OBSW node's step record holds every period, its replies' packets are the telemetry ground received (in
    order, byte for byte), its frames by reference (a digest, no pixels, no truth: the node has none), and
    ``flyby replay`` of the run renders them again from truth.csv and finds everything identical (exit 0)."""
    run = short_runs[0]
    log = StepLog(run / STEP_RECORD)
    steps = list(log.steps())
    assert not log.truncated and len(steps) == 300 and all(s.reply is not None for s in steps)
    framed = [s for s in steps if s.request.frame is not None]
    assert framed and all(s.frame is None and s.frame_digest is not None and s.frame_truth is None for s in framed)
    assert (run / STEP_RECORD).stat().st_size < 400 * len(steps)  # 2 MB of pixels a frame would be 60 kB a period
    sent = b"".join(p for s in steps for p in s.reply.downlink)  # type: ignore[union-attr]
    assert sent == (run / "tm.bin").read_bytes()
    r = flyby("replay", str(run), "--out", str(run / "replay"))
    assert r.returncode == 0 and "IDENTICAL" in r.stdout, r.stdout + r.stderr
    assert f"{len(framed)} camera frames kept by reference rendered again" in r.stdout


def test_raw_record_holds_the_pixels_the_digests_name(short_runs: tuple[Path, Path]) -> None:
    """The second run recorded its frames raw: the same requests as the first (the telecommands' security envelope
    aside: each run has fresh keys, so compared by the TC packets the authentication passed), each frame's pixels
    hashing (BLAKE2b-64, computed here) to the digest the first run recorded; it replays identically without
    rendering."""
    ref, raw = (list(StepLog(run / STEP_RECORD).steps()) for run in short_runs)
    assert [s.request.model_copy(update={"uplink": ()}) for s in ref] == \
        [s.request.model_copy(update={"uplink": ()}) for s in raw]
    assert [s.verdicts for s in ref] == [s.verdicts for s in raw] and any(s.verdicts for s in ref)
    framed = [(a, b) for a, b in zip(ref, raw, strict=True) if a.request.frame is not None]
    assert framed and all(b.frame is not None and b.frame_digest is None for _, b in framed)
    assert all(hashlib.blake2b(b.frame.astype("<u2").tobytes(), digest_size=8).digest() == a.frame_digest
               for a, b in framed)  # type: ignore[union-attr]
    r = flyby("replay", str(short_runs[1]), "--out", str(short_runs[1] / "replay"))
    assert r.returncode == 0 and "IDENTICAL" in r.stdout and "rendered again" not in r.stdout, r.stdout + r.stderr


def test_replay_stops_at_a_frame_whose_truth_changed(short_runs: tuple[Path, Path], tmp_path: Path) -> None:
    """A copy of the run whose truth.csv has one frame's body rate changed (1 mrad/s about x): the replay stops at
    that frame, naming it, exit 2; the frames before it rendered as recorded."""
    run = tmp_path / "run"
    shutil.copytree(short_runs[0], run, ignore=shutil.ignore_patterns("replay"))
    with open(run / "truth.csv", newline="") as f:
        rows = list(csv.reader(f))
    head = rows[0]
    framed = [r for r in rows[1:] if r[head.index("frame_id")]]
    assert len(framed) >= 3
    row = framed[2]
    row[head.index("omega_x_rad_s")] = repr(float(row[head.index("omega_x_rad_s")]) + 1e-3)
    with open(run / "truth.csv", "w", newline="") as f:
        csv.writer(f).writerows(rows)
    r = flyby("replay", str(run))
    assert r.returncode == 2, r.stdout + r.stderr
    assert f"frame {row[head.index('frame_id')]} (step " in r.stderr
    assert "the universe or the scenario changed" in r.stderr


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


def test_frames_went_through_shared_memory(short_runs: tuple[Path, Path]) -> None:
    """`flyby run` hands frames to the OBSW through shared memory (the replay tests above find every frame the OBSW
    took from there identical to the one rendered again in process)."""
    for run in short_runs:
        assert "camera frames go to the OBSW through shared memory" in (run / "universe.log").read_text()
