"""Replay of a recorded run: the unchanged build reproduces it exactly; a changed gain is caught at the first period
whose torques differ, found here independently by stepping the changed software on the captured inputs."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from analysis.stepdiff import COMMANDS
from contracts.exitcodes import EXIT_CHECK_FAILED, EXIT_CONFIG, EXIT_OK
from contracts.messages import StepReply, StepRequest
from contracts.steplog import STEP_RECORD
from flyby.cli import main
from flyby.inprocess import run_in_process
from flyby.replay import replay
from obsw.config import ObswConfig
from obsw.software import FlightSoftware
from scenario.model import Scenario, load_run_inputs

NOMINAL = Path(__file__).parents[2] / "configs" / "scenarios" / "nominal.yaml"
STEPS = 560  # to C/A-184 s: the imaging burst has begun and the tracking loop has closed on the image


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


def test_unchanged_build_replays_identically(recorded: tuple[Scenario, Path, Captured], tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    """``flyby replay`` of the record with the current build: every period identical, exit 0, text and HTML written."""
    _, run, captured = recorded
    code = main(["replay", str(run), "--out", str(tmp_path)])
    text = capsys.readouterr().out
    assert code == EXIT_OK, text
    assert f"{len(captured)} control periods" in text and "IDENTICAL" in text
    assert "IDENTICAL" in (tmp_path / "replay.txt").read_text()
    assert "IDENTICAL" in (tmp_path / "replay.html").read_text()


@pytest.mark.parametrize(("section", "name", "value"), [
    ("control", "kp_nm_per_rad", 0.3),  # the attitude controller's proportional gain
    ("tracking", "natural_frequency_rad_s", 0.5),  # the image tracking loop's gain: acts only once it is closed
])
def test_changed_gain_diverges_where_torques_first_differ(recorded: tuple[Scenario, Path, Captured], section: str,
                                                          name: str, value: float) -> None:
    """The replay's first divergence is the first period whose commanded torques differ from the recorded ones."""
    scenario, run, captured = recorded
    cfg = _changed(scenario.obsw, section, name, value)
    fsw = FlightSoftware(cfg)
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
