"""Scenario files are validated with every problem named by its path in the file."""

from __future__ import annotations

from pathlib import Path

import pytest

from flyby.errors import ScenarioError
from flyby.scenario import load_scenario, scenario_from_dict


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
