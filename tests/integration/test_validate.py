"""`flyby validate` names every problem of a broken scenario by its path, and `flyby run` refuses it."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.integration.conftest import DATA, flyby

EXPECTED = {
    "broken-fov.yaml": ["universe.camera.fov_deg: must be > 0"],
    "broken-many.yaml": [
        "name: must match",
        "seed: must be >= 0",
        "universe.end_s: must be after start_s",
        "universe.flyby.speed_km_s: must be > 0",
        "universe.camra: unknown field",
    ],
    "broken-yaml.yaml": ["line 3, column 1: not valid YAML"],
    "broken-timeline.yaml": [
        "ground.timeline_file (bad-timeline.yaml): row 1, field 'args.mode'",
        "ground.timeline_file (bad-timeline.yaml): row 2, field 'time'",
        "ground.timeline_file (bad-timeline.yaml): row 2, field 'command': unknown command 'fly'",
    ],
}


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_validate_reports_every_problem(name: str) -> None:
    """Each expected message appears, one per line, and the exit code is 2."""
    r = flyby("validate", str(DATA / name), timeout=60)
    assert r.returncode == 2, r.stderr
    lines = [line.strip() for line in r.stderr.splitlines()]
    for want in EXPECTED[name]:
        assert any(line.startswith(want) for line in lines), f"{want!r} not in:\n{r.stderr}"
    assert f"({len(EXPECTED[name])} problem(s))" in r.stderr


def test_valid_files_pass() -> None:
    """The shipped scenarios validate, those kept in subfolders (fault campaigns, Monte Carlo runs) too: a kept file
    writes out every field, so a field removed from a config must be removed from it."""
    scenarios = sorted((Path(__file__).parents[2] / "configs" / "scenarios").rglob("*.yaml"))
    assert scenarios
    r = flyby("validate", *map(str, scenarios), timeout=60)
    assert r.returncode == 0, r.stderr


def test_run_refuses_invalid_file_before_starting(tmp_path: Path) -> None:
    """`flyby run` on an invalid file prints the same errors and creates no run folder."""
    r = flyby("run", str(DATA / "broken-fov.yaml"), "--out", str(tmp_path / "run"), timeout=60)
    assert r.returncode == 2
    assert "universe.camera.fov_deg: must be > 0" in r.stderr
    assert not (tmp_path / "run").exists()
