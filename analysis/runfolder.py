"""A run folder as the nodes left it: scenario.yaml, truth.csv, tm.bin or archive.sqlite, frames/, summary.json.

A partial run (a node died: truth cut short, no frames, no telemetry of some kind) still loads: ``RunData.missing``
says, one line each, what it lacks.
"""

from __future__ import annotations

import json
import sqlite3
from dataclasses import dataclass, field
from pathlib import Path

from contracts.errors import FlybyError, ScenarioError
from contracts.truthtable import TruthTableError
from ground.archive import Archive, ArchiveError
from scenario.model import Scenario, load_scenario
from analysis.telemetry import Telemetry, load_telemetry
from analysis.truth import Truth, load_truth


class RunFolderError(FlybyError):
    """The run folder cannot be used at all (no such folder, no readable scenario.yaml)."""


def archive_counts(run_dir: Path, missing: list[str]) -> dict[str, int] | None:
    """Archive.counts() of the run's archive.sqlite, or None if it has none or it is damaged (said in ``missing``)."""
    db = run_dir / "archive.sqlite"
    if not db.is_file():
        return None
    try:
        archive = Archive.read_only(db)
        try:
            return archive.counts()
        finally:
            archive.close()
    except (ArchiveError, sqlite3.DatabaseError) as exc:
        missing.append(f"archive.sqlite unusable ({exc}): no sequence-gap analysis")
        return None


def frame_paths(run_dir: Path) -> dict[int, Path]:
    """frame id -> PNG path of every frames/frame_NNNNN.png."""
    out = {}
    for p in sorted((run_dir / "frames").glob("frame_*.png")):
        stem = p.stem.removeprefix("frame_")
        if stem.isdigit():
            out[int(stem)] = p
    return out


@dataclass
class RunData:
    """Everything known of a run; ``missing`` lists what a partial run lacks, one line each."""

    run_dir: Path
    scenario: Scenario
    truth: Truth | None
    telemetry: Telemetry | None
    frames: dict[int, Path] = field(default_factory=dict)
    summary_lines: list[str] | None = None
    counts: dict[str, int] | None = None
    missing: list[str] = field(default_factory=list)


def _truth(path: Path, missing: list[str]) -> Truth | None:
    """truth.csv, or None with the reason added to ``missing``."""
    if not path.is_file():
        missing.append("no truth.csv: every figure that needs the simulation truth is missing")
        return None
    if path.stat().st_size == 0:
        missing.append("truth.csv is empty: the universe sent no truth")
        return None
    try:
        truth = load_truth(path)
    except (TruthTableError, UnicodeDecodeError) as err:
        missing.append(f"truth.csv unusable: {err}")
        return None
    if truth.skipped_rows:
        missing.append(f"truth.csv: {truth.skipped_rows} incomplete row(s) skipped (first: {truth.skip_reason})")
    if len(truth) == 0:
        missing.append("truth.csv has no rows: the universe sent no truth")
        return None
    return truth


def load_run(run_dir: Path) -> RunData:
    """Read a run folder; raise RunFolderError only if the folder or its scenario.yaml is unusable."""
    run_dir = Path(run_dir)
    if not run_dir.is_dir():
        raise RunFolderError(f"{run_dir}: no such run folder")
    try:
        scenario = load_scenario(run_dir / "scenario.yaml")
    except ScenarioError as err:
        raise RunFolderError(f"{run_dir}: cannot report without the scenario: {err}") from None
    missing: list[str] = []
    truth = _truth(run_dir / "truth.csv", missing)
    try:
        telemetry = load_telemetry(run_dir)
        if telemetry is None:
            missing.append("no tm.bin and no archive.sqlite: no telemetry was received")
    except ArchiveError as exc:
        telemetry = None
        missing.append(f"no tm.bin and archive.sqlite is unusable ({exc}): no telemetry")
    if telemetry is not None and telemetry.truncated_tail_octets:
        missing.append(f"tm.bin ends with {telemetry.truncated_tail_octets} octets of an incomplete packet")
    frames = frame_paths(run_dir)
    if not frames:
        missing.append("no camera frames in frames/: no mosaic and no animation")
    summary = None
    if (run_dir / "summary.json").is_file():
        try:
            summary = [str(x) for x in json.loads((run_dir / "summary.json").read_text())["lines"]]
        except (ValueError, KeyError, TypeError) as err:
            missing.append(f"summary.json unreadable: {err!r}")
    else:
        missing.append("no summary.json: the ground node did not finish")
    counts = archive_counts(run_dir, missing)
    return RunData(run_dir, scenario, truth, telemetry, frames, summary, counts, missing)
