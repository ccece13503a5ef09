"""Scenario files are validated with every problem named by its path in the file."""

from __future__ import annotations

from pathlib import Path

import pytest

from contracts.errors import ScenarioError
from scenario.model import load_scenario, scenario_from_dict


def test_defaults_are_a_valid_scenario() -> None:
    """A scenario with only a name takes every default and is valid."""
    s = scenario_from_dict({"name": "x"})
    assert s.universe.camera.fov_deg == 2.9
    assert s.universe.flyby.ca_distance_km == 55.0


def test_every_error_is_named_by_its_path() -> None:
    """Two bad fields give two messages, each with its dotted path."""
    with pytest.raises(ScenarioError) as err:
        scenario_from_dict({"name": "x", "universe": {"camera": {"fov_deg": 0}, "flyby": {"speed_km_s": -1}}})
    problems = err.value.problems
    assert "universe.camera.fov_deg: must be > 0" in problems
    assert "universe.flyby.speed_km_s: must be > 0" in problems
    assert len(problems) == 2


def test_unknown_field_is_refused() -> None:
    """A misspelt field is an error, not silently ignored."""
    with pytest.raises(ScenarioError) as err:
        scenario_from_dict({"name": "x", "universe": {"camra": {}}})
    assert err.value.problems == ["universe.camra: unknown field"]


def test_bad_yaml_names_line(tmp_path: Path) -> None:
    """A YAML syntax error names its line."""
    f = tmp_path / "bad.yaml"
    f.write_text("name: x\nuniverse: [\n")
    with pytest.raises(ScenarioError) as err:
        load_scenario(f)
    assert err.value.problems[0].startswith("line ")


def test_missing_file_is_a_scenario_error(tmp_path: Path) -> None:
    """A missing file is reported as such, not as a traceback."""
    with pytest.raises(ScenarioError) as err:
        load_scenario(tmp_path / "nope.yaml")
    assert "cannot read" in err.value.problems[0]


def test_incomplete_faults_are_refused_at_load() -> None:
    """A wheel fault without a valid wheel, or a bias step without its size, is an error naming the fault."""
    with pytest.raises(ScenarioError) as err:
        scenario_from_dict({"name": "x", "universe": {"faults": [
            {"kind": "wheel_stuck", "start_s": 0, "end_s": 1},
            {"kind": "wheel_failed", "start_s": 0, "end_s": 1, "wheel": 3},
            {"kind": "gyro_bias_step", "start_s": 0, "end_s": 1},
        ]}})
    assert err.value.problems == [
        "universe.faults[0].wheel: a wheel_stuck fault needs the wheel index",
        "universe.faults[1].wheel: 3 is not one of the 3 wheels (0..2)",
        "universe.faults[2].magnitude: a gyro_bias_step fault needs its magnitude",
    ]
    pyramid = {"spacecraft": {"wheels": {"layout": "pyramid"}},
               "faults": [{"kind": "wheel_failed", "start_s": 0, "end_s": 1, "wheel": 3}]}
    assert scenario_from_dict({"name": "x", "universe": pyramid}).universe.faults[0].wheel == 3
