"""The complete synthetic run and its report, built once for the analysis tests."""

from __future__ import annotations

from pathlib import Path

import pytest

from analysis.report import build_report
from analysis.scoring import RunFigures
from tests.analysis.synthetic import make_run


@pytest.fixture(scope="session")
def full_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, RunFigures]:
    """A complete synthetic run folder, its report.html and its figures."""
    run = make_run(tmp_path_factory.mktemp("runs") / "full")
    path, figs = build_report(run)
    return run, path, figs
