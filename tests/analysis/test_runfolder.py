"""Loading a run folder: whatever is missing or broken is named in ``missing``, never raised, but the scenario."""

from __future__ import annotations

from pathlib import Path

import pytest

from analysis.runfolder import RunFolderError, load_run
from tests.analysis.synthetic import SAVED_FRAME_KS, make_run


def test_complete_folder(full_run) -> None:
    """A complete run loads with nothing missing: truth, telemetry, frames, summary and archive counts."""
    run, _, _ = full_run
    data = load_run(run)
    assert data.missing == []
    assert data.truth is not None and len(data.truth) == 4200
    assert data.telemetry is not None and data.telemetry.source == "tm.bin"
    assert sorted(data.frames) == [k + 300 for k in SAVED_FRAME_KS]
    assert data.counts is not None and data.counts["stored"] == data.telemetry.packets


def test_empty_and_unusable_truth(tmp_path: Path) -> None:
    """An empty truth.csv and one whose header lacks range_m are each named in ``missing``; the run still loads."""
    run = make_run(tmp_path / "r", telemetry=False, frames=False, truth_rows=10)
    header, *rows = (run / "truth.csv").read_text().splitlines()
    (run / "truth.csv").write_text("")
    assert "truth.csv is empty: the universe sent no truth" in load_run(run).missing
    (run / "truth.csv").write_text("\n".join([header.replace("range_m,", "distance,"), *rows]) + "\n")
    data = load_run(run)
    assert data.truth is None
    assert any(m.startswith("truth.csv unusable:") and "lacks column(s) range_m" in m for m in data.missing)


def test_no_such_folder(tmp_path: Path) -> None:
    """A folder that does not exist is a RunFolderError naming it."""
    with pytest.raises(RunFolderError, match="nowhere: no such run folder"):
        load_run(tmp_path / "nowhere")
