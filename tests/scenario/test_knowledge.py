"""On-board knowledge defaults to the truth; a difference must be declared; each core sees only its own section."""

from __future__ import annotations

import pytest

from contracts.errors import ScenarioError
from scenario import compose
from scenario.knowledge import KNOWLEDGE_PAIRS, get_path
from scenario.model import scenario_from_dict


def test_knowledge_left_out_takes_the_true_value() -> None:
    """A scenario that sets only the truth gives the flight software the same value (a calibrated spacecraft)."""
    sc = scenario_from_dict({"name": "k", "universe": {"camera": {"fov_deg": 3.1, "exposure_s": 0.02},
                                                       "spacecraft": {"wheels": {"layout": "pyramid"}},
                                                       "link": {"one_way_light_time_s": 2.0}}})
    assert sc.obsw.camera.fov_deg == 3.1 and sc.obsw.camera.exposure_s == 0.02
    assert sc.obsw.wheels.layout == "pyramid"
    assert sc.ground.link.one_way_light_time_s == 2.0
    for known, true in KNOWLEDGE_PAIRS:
        assert get_path(sc, known) == get_path(sc, true), known


def test_an_undeclared_difference_is_refused_with_both_paths() -> None:
    """Setting on-board knowledge apart from the truth without declaring it names the field and the truth."""
    with pytest.raises(ScenarioError) as err:
        scenario_from_dict({"name": "k", "obsw": {"camera": {"fov_deg": 3.0}}})
    (line,) = err.value.problems
    assert line.startswith("obsw.camera.fov_deg: 3.0 differs from the truth universe.camera.fov_deg = 2.9")


def test_a_declared_knowledge_error_reaches_the_flight_software_and_not_the_universe() -> None:
    """A declared miscalibration is what the flight software is built with, while the universe keeps the truth."""
    sc = scenario_from_dict({"name": "k", "knowledge_errors": ["obsw.camera.fov_deg", "obsw.inertia_kgm2"],
                             "obsw": {"camera": {"fov_deg": 3.0},
                                      "inertia_kgm2": [[0.16, 0, 0], [0, 0.12, 0], [0, 0, 0.06]]}})
    fsw, sim = compose.flight_software(sc, None), compose.universe(sc)
    assert fsw.camera.fov_deg == 3.0 and sim.cfg.camera.fov_deg == 2.9
    assert fsw.inertia[0, 0] == 0.16 and sim.cfg.spacecraft.inertia_kgm2[0][0] == 0.152


def test_a_declared_path_that_is_not_knowledge_is_refused() -> None:
    """knowledge_errors may only name knowing fields."""
    with pytest.raises(ScenarioError, match="knowledge_errors: 'universe.camera.fov_deg' is not"):
        scenario_from_dict({"name": "k", "knowledge_errors": ["universe.camera.fov_deg"]})


def test_sections_that_must_agree_are_checked() -> None:
    """Ground addressing another APID than the flight software's is refused before anything runs."""
    with pytest.raises(ScenarioError, match="ground.apid: 194 differs from obsw.apid = 193"):
        scenario_from_dict({"name": "k", "ground": {"apid": 194}})


def test_an_error_in_a_true_value_is_reported_once_at_its_true_path() -> None:
    """A bad true value copied into knowledge is reported at the truth only, not twice."""
    with pytest.raises(ScenarioError) as err:
        scenario_from_dict({"name": "k", "universe": {"camera": {"fov_deg": -1}}})
    assert err.value.problems == ["universe.camera.fov_deg: must be > 0"]
