"""Every input found wrong by users is refused before anything runs, with the path of the offending field."""

from __future__ import annotations

from pathlib import Path

import pytest

from contracts.errors import ScenarioError
from scenario.model import load_run_inputs, load_scenario, scenario_from_dict, timeline_checks

REFUSED = [
    # (scenario fields, the start of the expected problem line)
    ({"universe": {"end_s": float("inf")}}, "universe.end_s: must be a finite number, got inf"),
    ({"universe": {"start_s": float("nan")}}, "universe.start_s: must be a finite number, got nan"),
    ({"universe": {"flyby": {"ca_time_s": float("nan")}}}, "universe.flyby.ca_time_s: must be a finite number"),
    ({"universe": {"spacecraft": {"inertia_kgm2": [[-0.1, 0, 0], [0, 0.1, 0], [0, 0, 0.1]]}}},
     "universe.spacecraft.inertia_kgm2: must be positive definite"),
    ({"universe": {"spacecraft": {"inertia_kgm2": [[1, 0, 0], [0, 0.1, 0], [0, 0, 0.1]]}}},
     "universe.spacecraft.inertia_kgm2: principal moments"),
    ({"universe": {"flyby": {"approach_direction": [1, 0, 0], "ca_direction": [-3, 0, 0]}}},
     "universe.flyby.ca_direction: is 0 deg from parallel to approach_direction"),
    ({"epoch_utc": "yesterday"}, "epoch_utc: cannot read 'yesterday'"),
    ({"universe": {"faults": [{"kind": "gyro_bias_step", "start_s": 0, "end_s": 1, "magnitude": float("nan")}]}},
     "universe.faults[0].magnitude: must be a finite number"),
    ({"universe": {"oscillator": {"drift_ppm": float("nan")}}}, "universe.oscillator.drift_ppm: must be a finite"),
    ({"universe": {"faults": [{"kind": "plume_brightening", "start_s": 0, "end_s": 1, "magnitude": -3}]}},
     "universe.faults[0].magnitude: a brightness factor must be > 0"),
    ({"universe": {"faults": [{"kind": "frame_lost", "start_s": float("nan"), "end_s": 1}]}},
     "universe.faults[0].start_s: must be a finite number"),
    ({"universe": {"camera": {"fov_deg": True}}}, "universe.camera.fov_deg: must be a number, got True (bool)"),
    ({"universe": {"camera": {"fov_deg": "2.9"}}}, "universe.camera.fov_deg: must be a number, got '2.9' (str)"),
    ({"universe": {"camera": {"fov_deg": float("nan")}}}, "universe.camera.fov_deg: must be a finite number"),
    ({"universe": {"faults": [{"kind": "frame_blank", "start_s": 0, "end_s": 1, "wheel": 1}]}},
     "universe.faults[0].wheel: a frame_blank fault has no wheel"),
    ({"universe": {"camera": {"exposure_s": 5.0}}}, "universe.camera.exposure_s: 5 s must be shorter than"),
    ({"universe": {"faults": [{"kind": "frame_lost", "start_s": 1000, "end_s": 1010}]}},
     "universe.faults[0].start_s: the window 1000..1010 s is outside the run"),
    ({"universe": {"spacecraft": {"initial_rate_deg_s": [0, "1", 0]}}},
     "universe.spacecraft.initial_rate_deg_s[1]: must be a number, got '1' (str)"),
    ({"seed": True}, "seed: must be a whole number, got True (bool)"),
    # found by bench/fuzz_inputs.py: OBT before zero at the start, and a C/A beyond the 32-bit CUC seconds
    ({"universe": {"oscillator": {"initial_offset_s": -964.0}}},
     "universe.start_s: on-board time OBT -1096 s at t = -132 s is outside the CUC range"),
    ({"universe": {"flyby": {"ca_time_s": 1.2856254793347456e16}}},
     "universe.flyby.ca_time_s: on-board time OBT 1.28563e+16 s"),
    ({"universe": {"control_period_s": 1e7}}, "universe.control_period_s: 1e+07 s is 1e+09 RK4 substeps"),
    ({"universe": {"spacecraft": {"integration_substep_s": 1e-7}}},
     "universe.spacecraft: the attitude dynamics would take 1e+07 RK4 substeps per simulated second"),
]


@pytest.mark.parametrize(("fields", "expected"), REFUSED, ids=[e for _, e in REFUSED])
def test_bad_field_is_refused_with_its_path(fields: dict, expected: str) -> None:
    """Each bad value is refused at load, the problem line opening with the field's path."""
    with pytest.raises(ScenarioError) as err:
        scenario_from_dict({"name": "x", **fields})
    assert any(p.startswith(expected) for p in err.value.problems), err.value.problems


def test_a_duplicate_yaml_key_is_refused_with_both_lines(tmp_path: Path) -> None:
    """A key given twice is refused naming it and the line of its first use, not silently overwritten."""
    f = tmp_path / "dup.yaml"
    f.write_text("name: x\nuniverse:\n  end_s: 100\n  end_s: 200\n")
    with pytest.raises(ScenarioError) as err:
        load_scenario(f)
    assert err.value.problems == ["line 4, column 3: not valid YAML: duplicate key 'end_s' (first at line 3)"]


@pytest.mark.parametrize("content", [bytes(range(256)), b"name: x\n\x00\x01\x02", b"\x89PNG\r\n\x1a\n" + bytes(50)])
def test_a_binary_file_is_refused_in_one_line(tmp_path: Path, content: bytes) -> None:
    """A file that is not UTF-8 text gets one line saying so, never a traceback."""
    f = tmp_path / "binary.yaml"
    f.write_bytes(content)
    with pytest.raises(ScenarioError) as err:
        load_scenario(f)
    (line,) = err.value.problems
    assert line.startswith("(file): not")


def test_a_binary_timeline_is_refused_in_one_line(tmp_path: Path) -> None:
    """A timeline file that is not text is refused naming the scenario field that points at it."""
    (tmp_path / "t.yaml").write_bytes(bytes(range(200, 256)))
    (tmp_path / "s.yaml").write_text("name: x\nground: {timeline_file: t.yaml}\n")
    with pytest.raises(ScenarioError) as err:
        load_run_inputs(tmp_path / "s.yaml")
    (line,) = err.value.problems
    assert line.startswith("ground.timeline_file (t.yaml): (file): not UTF-8 text")


def _with_timeline(tmp_path: Path, commands: str) -> Path:
    (tmp_path / "t.yaml").write_text("commands:\n" + commands)
    (tmp_path / "s.yaml").write_text("name: x\nground: {timeline_file: t.yaml}\n")
    return tmp_path / "s.yaml"


def test_a_duplicated_timeline_row_is_an_error(tmp_path: Path) -> None:
    """Two identical rows would run the command twice: refused, naming both rows."""
    path = _with_timeline(tmp_path, "  - {time: CA-240s, command: set_mode, args: {mode: ACQUISITION}}\n"
                                    "  - {time: CA-240s, command: set_mode, args: {mode: ACQUISITION}}\n")
    with pytest.raises(ScenarioError, match="row 2: repeats row 1"):
        load_run_inputs(path)


def test_a_timeline_row_after_the_run_is_a_warning(tmp_path: Path) -> None:
    """A row due after the run's end is loaded but warned about: it would never be released."""
    path = _with_timeline(tmp_path, "  - {time: CA-240s, command: set_mode, args: {mode: ACQUISITION}}\n"
                                    "  - {time: CA+500s, command: stop_imaging}\n")
    scenario, timeline = load_run_inputs(path)
    assert timeline is not None
    errors, warnings = timeline_checks(scenario, timeline)
    assert errors == []
    assert len(warnings) == 1 and warnings[0].startswith("row 2 (stop_imaging): due at t = 668.0 s, after the run")
