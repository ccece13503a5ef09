"""Replay of a recorded run: the unchanged build reproduces it exactly, its frames kept by reference rendered again
bit for bit (also through frame faults and a clock jump); a changed gain is caught at the first period whose torques
differ, found here independently by stepping the changed software on the captured inputs; a changed universe is
caught at the first frame it renders differently."""

from __future__ import annotations

import gzip
import hashlib
import json
import re
import struct
from pathlib import Path

import numpy as np
import pytest
import yaml

from analysis.stepdiff import COMMANDS
from contracts import sdls
from contracts.exitcodes import EXIT_CHECK_FAILED, EXIT_CONFIG, EXIT_OK
from contracts.messages import FrameMeta, SensorData, StepReply, StepRequest, encode
from contracts.steplog import STEP_RECORD, StepLog, StepLogWriter, _record
from flyby.cli import main
from flyby.inprocess import run_in_process
from flyby.recorded_frames import FrameMismatch, RecordedFramesError
from flyby.replay import ReplayInputError, replay
from ground.node import TruthLog
from obsw.config import ObswConfig
from obsw.software import FlightSoftware
from scenario.model import Scenario, load_run_inputs, scenario_from_dict

ROOT = Path(__file__).parents[2]
NOMINAL = ROOT / "configs" / "scenarios" / "nominal.yaml"
SHORT = ROOT / "tests" / "integration" / "data" / "short.yaml"
STEPS = 740  # the imaging burst has begun and the tracking loop is closed (its gain first moves a torque at 719)


Captured = list[tuple[StepRequest, np.ndarray | None, StepReply]]


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> tuple[Scenario, Path, Captured]:
    """The nominal flyby's first periods, run in process with a record, and the same periods captured in memory."""
    scenario, timeline = load_run_inputs(NOMINAL)
    run = tmp_path_factory.mktemp("run")
    captured: Captured = []
    out = run_in_process(scenario, timeline, max_steps=STEPS, record=run / STEP_RECORD,
                         on_step=lambda q, r, f: captured.append((q, None if f is None else f.copy(), r)))
    assert out.record_error is None and out.frames > 0
    return scenario, run, captured


def _changed(cfg: ObswConfig, section: str, name: str, value: float) -> ObswConfig:
    return cfg.model_copy(update={section: getattr(cfg, section).model_copy(update={name: value})})


def _read_noise_changed(scenario: Scenario) -> Scenario:
    """The scenario with its camera's read noise 10 % higher."""
    d = scenario.model_dump(mode="json")
    d["universe"]["camera"]["read_noise_e"] *= 1.1
    return scenario_from_dict(d)


def _digest(frame: np.ndarray) -> str:
    return hashlib.blake2b(frame.astype("<u2").tobytes(), digest_size=8).hexdigest()


def test_unchanged_build_replays_identically(recorded: tuple[Scenario, Path, Captured], tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    """``flyby replay`` of the record with the current build: every period identical, every frame rendered again,
    exit 0, text and HTML written."""
    _, run, captured = recorded
    frames = sum(f is not None for _, f, _ in captured)
    code = main(["replay", str(run), "--out", str(tmp_path)])
    text = capsys.readouterr().out
    assert code == EXIT_OK, text
    assert f"{len(captured)} control periods" in text and "IDENTICAL" in text
    assert f"{frames} camera frames kept by reference rendered again" in text
    assert "IDENTICAL" in (tmp_path / "replay.txt").read_text()
    assert "IDENTICAL" in (tmp_path / "replay.html").read_text()


def test_record_keeps_frames_by_reference(recorded: tuple[Scenario, Path, Captured]) -> None:
    """The record holds each frame's digest (that of the pixels the software got) and no pixels: its size is
    bounded by its messages, about 200 octets a period, not by the frames' 2 MB of pixels each."""
    scenario, run, captured = recorded
    log = StepLog(run / STEP_RECORD)
    steps = list(log.steps())
    framed = [(st, f) for st, (_, f, _) in zip(steps, captured, strict=True) if f is not None]
    assert framed and all(st.frame is None and st.frame_digest is not None for st, _ in framed)
    assert all(st.frame_digest.hex() == _digest(f) for st, f in framed)  # type: ignore[union-attr]
    assert log.header["frames"] == "reference" and scenario_from_dict(log.header["scenario"]) == scenario
    messages = sum(len(encode(q)) + len(encode(r)) for q, _, r in captured)
    size = (run / STEP_RECORD).stat().st_size
    # uncompressed: the header, the messages, digest and truth of each frame, a 5-octet head per record
    assert size <= len(json.dumps(log.header)) + messages + len(framed) * (8 + 64) + 5 * (2 * len(steps) + 2 * len(
        framed)) + 100
    assert size < 400 * len(steps)


def test_changed_universe_stops_at_the_first_frame(recorded: tuple[Scenario, Path, Captured], tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    """Frames rendered from a scenario whose camera reads out noisier do not hash as recorded: the replay stops at
    frame 0 naming it and both digests (the recorded one that of the pixels the software got), exit 2."""
    scenario, run, captured = recorded
    first = next((q, f) for q, f, _ in captured if f is not None)
    with pytest.raises(FrameMismatch) as err:
        replay(run, scenario=_read_noise_changed(scenario))
    message = str(err.value)
    assert message.startswith(f"frame 0 (step {first[0].step}, OBT {first[0].obt_s:.3f} s)")
    digests = re.findall(r"\b[0-9a-f]{16}\b", message)
    assert len(digests) == 2 and digests[1] == _digest(first[1]) and digests[0] != digests[1]
    changed = tmp_path / "changed.yaml"
    changed.write_text(yaml.safe_dump(_read_noise_changed(scenario).model_dump(mode="json")))
    assert main(["replay", str(run), "--scenario", str(changed), "--out", str(tmp_path)]) == EXIT_CONFIG
    assert f"frame 0 (step {first[0].step}" in capsys.readouterr().err
    assert not (tmp_path / "replay.txt").exists()


def test_raw_record_replays_without_the_universe(tmp_path: Path) -> None:
    """A record keeping frames raw holds their pixels and replays from them: identical, nothing rendered, even
    against a scenario whose frames would render differently."""
    scenario, timeline = load_run_inputs(NOMINAL)
    out = run_in_process(scenario, timeline, max_steps=STEPS, record=tmp_path / STEP_RECORD, record_frames="raw")
    assert out.record_error is None and out.frames > 0
    log = StepLog(tmp_path / STEP_RECORD)
    assert log.header["frames"] == "raw"
    assert sum(st.frame is not None and st.frame_digest is None for st in log.steps()) == out.frames
    result = replay(tmp_path, scenario=_read_noise_changed(scenario))
    assert result.identical and result.rendered_frames == 0 and result.replayed_steps == STEPS


@pytest.mark.parametrize(("section", "name", "value"), [
    ("control", "kp_nm_per_rad", 0.3),  # the attitude controller's proportional gain
    ("tracking", "natural_frequency_rad_s", 0.5),  # the image tracking loop's gain: acts only once it is closed
])
def test_changed_gain_diverges_where_torques_first_differ(recorded: tuple[Scenario, Path, Captured], section: str,
                                                          name: str, value: float) -> None:
    """The replay's first divergence is the first period whose commanded torques differ from the recorded ones."""
    scenario, run, captured = recorded
    cfg = _changed(scenario.obsw, section, name, value)
    fsw = FlightSoftware(cfg, sdls.KeyRing.derived(scenario.seed))  # the keys an in-process run derives
    expected = None
    for req, frame, reply in captured:
        if fsw.step(req, frame).wheel_torque_nm != reply.wheel_torque_nm:
            expected = req
            break
    assert expected is not None, "the changed gain never changed a torque in these periods"
    result = replay(run, obsw=cfg)
    assert not result.identical
    first = result.diff.first()
    assert first is not None and first.packet == COMMANDS and first.parameter.startswith("wheel_torque_nm[")
    assert (first.first_step, first.first_obt_s) == (expected.step, expected.obt_s)
    torques = [p for p in result.diff.rows() if p.packet == COMMANDS and p.parameter.startswith("wheel_torque_nm")]
    assert min(p.first_step for p in torques) == expected.step


def test_set_option_changes_the_replayed_build(recorded: tuple[Scenario, Path, Captured], tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    """``--set control.kp_nm_per_rad=0.3`` replays a changed build: exit 4, the first divergence printed."""
    _, run, _ = recorded
    code = main(["replay", str(run / STEP_RECORD), "--set", "control.kp_nm_per_rad=0.3", "--out", str(tmp_path)])
    text = capsys.readouterr().out
    assert code == EXIT_CHECK_FAILED, text
    assert "with control.kp_nm_per_rad=0.3" in text and "DIFFERENT" in text
    assert "first divergence: commands (StepReply) wheel_torque_nm[" in text
    assert "wheel_torque_nm[" in (tmp_path / "replay.html").read_text()


@pytest.mark.parametrize(("change", "message"), [
    ("control.no_such_gain=1", "obsw.control.no_such_gain is not an on-board setting"),
    ("control.kp_nm_per_rad=-1", "obsw.control.kp_nm_per_rad"),
    ("kp_nm_per_rad", "expected PATH=VALUE"),
])
def test_bad_change_is_refused_before_replaying(recorded: tuple[Scenario, Path, Captured], tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str], change: str, message: str) -> None:
    """A --set that names no setting or breaks its bounds exits 2 naming the field."""
    _, run, _ = recorded
    assert main(["replay", str(run), "--set", change, "--out", str(tmp_path)]) == EXIT_CONFIG
    assert message in capsys.readouterr().err


def test_folder_without_record_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A run folder without a record exits 2 naming the missing file."""
    assert main(["replay", str(tmp_path)]) == EXIT_CONFIG
    assert STEP_RECORD in capsys.readouterr().err


def test_centroid_level_record_replays_identically(tmp_path: Path) -> None:
    """A centroid-level run (a campaign's fidelity: measurements instead of pixels) records no pixels and replays
    identically."""
    scenario, timeline = load_run_inputs(NOMINAL)
    scenario = scenario.model_copy(update={"universe": scenario.universe.model_copy(update={"fidelity": "centroid"})})
    out = run_in_process(scenario, timeline, max_steps=STEPS, record=tmp_path / STEP_RECORD)
    assert out.record_error is None and out.frames > 0
    result = replay(tmp_path)
    assert result.identical and result.replayed_steps == STEPS


def _without_truth(src: Path, dst: Path) -> None:
    """Copy a record without its truth records (``T``), as the OBSW node writes it, by the format's description."""
    data, out, pos = gzip.decompress(src.read_bytes()), bytearray(), 0
    while pos < len(data):
        kind, n = struct.unpack_from(">cI", data, pos)
        if kind != b"T":
            out += data[pos: pos + 5 + n]
        pos += 5 + n
    dst.write_bytes(gzip.compress(bytes(out)))


def test_frame_faults_and_a_clock_jump_replay_identically(tmp_path: Path) -> None:
    """Through a clock jump, lost frames, blank frames and a brightened plume, every frame renders again as the run
    rendered it, from the record's own truth and from a truth.csv as ground writes it; without either, the replay
    names the missing file."""
    scenario, timeline = load_run_inputs(SHORT)
    d = scenario.model_dump(mode="json")
    d["universe"]["faults"] = [
        {"kind": "clock_jump", "start_s": 120.05, "end_s": 120.05, "magnitude": 2.5},
        {"kind": "frame_lost", "start_s": 121.0, "end_s": 122.9},  # frames at x.5 s: the jump moves no frame
        {"kind": "frame_blank", "start_s": 123.0, "end_s": 124.5},
        {"kind": "plume_brightening", "start_s": 125.0, "end_s": 130.0, "magnitude": 3.0}]
    scenario = scenario_from_dict(d)
    run = tmp_path / "run"
    run.mkdir()
    out = run_in_process(scenario, timeline, record=run / "in-process.rec")
    assert out.record_error is None
    assert any("fault start t=120.10 s: clock_jump" in line for line in out.log)
    lost = sum("frame lost" in line for line in out.log)
    framed = [r for r in out.truth if r.frame_id is not None]
    assert lost >= 2 and len(framed) == out.frames >= 8
    assert any(123.0 <= r.t_s < 124.5 for r in framed) and any(125.0 <= r.t_s < 130.0 for r in framed)
    result = replay(run / "in-process.rec")
    assert result.identical and result.rendered_frames == out.frames
    _without_truth(run / "in-process.rec", run / STEP_RECORD)
    assert not any(st.frame_truth is not None for st in StepLog(run / STEP_RECORD).steps())
    with pytest.raises(RecordedFramesError, match="kept by reference without its truth.*truth.csv"):
        replay(run)
    truth = TruthLog(run / "truth.csv")
    for rec in out.truth:
        truth.add(rec)
    truth.close()
    result = replay(run)
    assert result.identical and result.rendered_frames == out.frames


def test_record_with_a_frame_missing_is_refused(tmp_path: Path) -> None:
    """Every frame's noise follows from the frames before it: a record whose first frame is not frame 0 names the
    frame and exits 2."""
    scenario, _ = load_run_inputs(NOMINAL)
    req = StepRequest(step=0, obt_s=1.0, sensors=SensorData(star_tracker_q=None, gyro_rad_s=(0.0, 0.0, 0.0),
                                                             wheel_speed_rad_s=(0.0, 0.0, 0.0)),
                      frame=FrameMeta(frame_id=1, obt_s=1.0, width=2, height=1, bit_depth=12, exposure_s=0.01))
    with StepLogWriter(tmp_path / STEP_RECORD, {"scenario": scenario.model_dump(mode="json"),
                                                "obsw": scenario.obsw.model_dump(mode="json")}, threaded=False) as w:
        w.step(req, b"\0\0\0\0", StepReply(step=0, wheel_torque_nm=(0.0, 0.0, 0.0)))
    with pytest.raises(RecordedFramesError, match="frame 1 .step 0, OBT 1.000 s. is not frame 0"):
        replay(tmp_path)
    assert main(["replay", str(tmp_path), "--out", str(tmp_path)]) == EXIT_CONFIG


def test_a_replay_without_keys_takes_the_recorded_authentication_outcomes(recorded: tuple[Scenario, Path, Captured],
                                                                          tmp_path: Path) -> None:
    """A record whose keys are not kept (a run over the bus) replays identically on the recorded outcomes of the
    authentication checks, and a unit that is not the recorded one is refused as unusable input."""
    _, run, _ = recorded
    log = StepLog(run / STEP_RECORD)
    assert any(st.verdicts for st in log.steps())  # the run's uplink was checked, and the outcomes recorded
    header = {k: v for k, v in log.header.items() if k != "tc_keys"}  # as the OBSW node records it
    keyless = tmp_path / STEP_RECORD
    records = list(StepLog(run / STEP_RECORD)._read_records())
    with gzip.open(keyless, "wb") as f:  # the same records under the header of a run whose keys are not kept
        f.write(_record(b"H", json.dumps(header).encode()))
        f.write(b"".join(_record(kind, payload) for kind, payload in records[1:]))
    result = replay(keyless)
    assert result.identical, result.diff.rows()
    assert result.authentication.startswith("the recorded outcomes")
    tampered = tmp_path / "tampered.rec"
    first_a = next(i for i, (kind, _) in enumerate(records) if kind == b"A")
    outcomes = json.loads(records[first_a][1])
    assert "tc" in outcomes[0]  # the first check of the run passed its TC (the nominal trajectory upload)
    tc = bytearray.fromhex(outcomes[0]["tc"])
    tc[-1] ^= 0xFF  # a packet the recorded unit does not carry
    outcomes[0] = {"tc": tc.hex()}
    with gzip.open(tampered, "wb") as f:
        f.write(_record(b"H", json.dumps(header).encode()))
        f.write(b"".join(_record(kind, json.dumps(outcomes).encode() if i == first_a else payload)
                         for i, (kind, payload) in enumerate(records) if i > 0))
    with pytest.raises(ReplayInputError, match="does not carry the TC packet"):
        replay(tampered)
