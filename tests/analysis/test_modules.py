"""The analysis package's modules import each other without a cycle, lazy imports inside functions included."""

from __future__ import annotations

import sys
from pathlib import Path

import grimp
import pytest


def import_cycle(package: str) -> list[str] | None:
    """A cycle of imports among the package's modules (grimp reads every import statement), or None."""
    graph = grimp.build_graph(package)
    state: dict[str, str] = {}

    def visit(m: str, path: list[str]) -> list[str] | None:
        state[m] = "open"
        for n in sorted(graph.find_modules_directly_imported_by(m)):
            if state.get(n) == "open":
                return [*path, m, n]
            if n not in state and (found := visit(n, [*path, m])) is not None:
                return found
        state[m] = "done"
        return None

    for m in sorted(graph.modules):
        if m not in state and (found := visit(m, [])) is not None:
            return found
    return None


def test_no_import_cycle_inside_analysis() -> None:
    """No module of analysis imports, directly or through others, a module that imports it back."""
    assert import_cycle("analysis") is None


def test_a_lazy_import_cycle_is_found(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The check sees a cycle closed by an import inside a function (the one report and plots used to have)."""
    pkg = tmp_path / "cyclic"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "report.py").write_text("def build():\n    from cyclic import plots\n    return plots\n")
    (pkg / "plots.py").write_text("from cyclic.report import build\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    try:
        assert import_cycle("cyclic") == ["cyclic.plots", "cyclic.report", "cyclic.plots"]
    finally:
        sys.modules.pop("cyclic", None)


def test_scoring_draws_nothing() -> None:
    """Loading and scoring a run need neither matplotlib nor the HTML page (the benchmark imports only them)."""
    graph = grimp.build_graph("analysis", "matplotlib", include_external_packages=True)
    assert graph.find_shortest_chain(importer="analysis.report", imported="matplotlib") is not None
    for module in ("analysis.scoring", "analysis.runfolder", "analysis.closest_approach"):
        for far in ("matplotlib", "analysis.plots", "analysis.page", "analysis.frames", "analysis.report"):
            assert graph.find_shortest_chain(importer=module, imported=far) is None, (module, far)
