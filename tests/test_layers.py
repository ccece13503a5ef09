"""The package layers of pyproject.toml hold (import-linter), and a forbidden import does fail them."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("contracts", "obsw", "universe", "ground", "timeline", "scenario", "analysis", "flyby")


def _lint(tree: Path) -> subprocess.CompletedProcess[str]:
    """Run import-linter on ``tree`` (a folder holding pyproject.toml and the packages)."""
    exe = Path(sys.executable).with_name("lint-imports")
    env = {**os.environ, "PYTHONPATH": str(tree)}
    return subprocess.run([str(exe), "--config", str(tree / "pyproject.toml"), "--no-cache"], cwd=tree, env=env,
                          capture_output=True, text=True, timeout=300)


def test_the_project_keeps_its_layers() -> None:
    """Every contract of pyproject.toml is kept by the code as it is."""
    result = _lint(ROOT)
    assert result.returncode == 0, result.stdout + result.stderr
    assert "0 broken" in result.stdout


def test_a_flight_software_import_of_the_universe_breaks_the_contracts(tmp_path: Path) -> None:
    """The flight software importing the truth (universe) is reported as a broken contract, naming the import."""
    shutil.copy(ROOT / "pyproject.toml", tmp_path / "pyproject.toml")
    for pkg in PACKAGES:
        shutil.copytree(ROOT / pkg, tmp_path / pkg, ignore=shutil.ignore_patterns("__pycache__", "*.nbi", "*.nbc"))
    (tmp_path / "obsw" / "peek.py").write_text('"""A leak of the truth."""\n\nfrom universe.config import CameraConfig\n')
    result = _lint(tmp_path)
    assert result.returncode != 0
    assert "obsw.peek -> universe.config" in result.stdout
    assert "BROKEN" in result.stdout


def test_two_nodes_importing_each_other_break_the_layers(tmp_path: Path) -> None:
    """The ground importing the flight software is refused: nodes never import each other."""
    shutil.copy(ROOT / "pyproject.toml", tmp_path / "pyproject.toml")
    for pkg in PACKAGES:
        shutil.copytree(ROOT / pkg, tmp_path / pkg, ignore=shutil.ignore_patterns("__pycache__", "*.nbi", "*.nbc"))
    (tmp_path / "ground" / "peek.py").write_text('"""A node reaching into another."""\n\nimport obsw.modes\n')
    result = _lint(tmp_path)
    assert result.returncode != 0
    assert "ground.peek -> obsw.modes" in result.stdout
