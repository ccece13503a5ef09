"""The flyby report of a run folder, and the ``flyby report`` command (its argparse wiring is in ``flyby/cli.py``).

``write_report(run_dir)`` loads the run (``analysis.runfolder``), scores it (``analysis.scoring``) and writes
``report.html`` (self-contained: every image a base64 data URI), the same images under ``report/``, the animated
``report/flyby.gif`` and ``figures.json``. A partial run still gets a report: every section says what it is missing.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from contracts.exitcodes import EXIT_CONFIG
from ground.archive import Archive, ArchiveError
from ground.config import ReportConfig
from analysis.frames import gif_section
from analysis.page import counts_section, events_section, report_html
from analysis.plots import chart_sections
from analysis.runfolder import RunFolderError, load_run
from analysis.scoring import RunFigures, score_run


def build_report(run_dir: Path, cfg: ReportConfig | None = None) -> tuple[Path, RunFigures]:
    """Write run_dir/report.html, its images under run_dir/report/, report/flyby.gif and run_dir/figures.json;
    return the path of report.html and the figures.

    ``cfg`` defaults to the scenario's ``ground.report``. Raises RunFolderError if the folder has no usable scenario.
    """
    run_dir = Path(run_dir)
    data = load_run(run_dir)
    cfg = cfg or data.scenario.ground.report
    figs, notes = score_run(data, cfg)
    out = run_dir / "report"
    out.mkdir(exist_ok=True)
    sections = [counts_section(data, figs), *chart_sections(data, figs, cfg), gif_section(data, figs, cfg),
                events_section(data, figs.true_ca_obt_s)]
    for s in sections:
        if s.png is not None and s.file_name is not None:
            (out / s.file_name).write_bytes(s.png)
    title = f"Flyby report: {data.scenario.name} (seed {data.scenario.seed})"
    path = run_dir / "report.html"
    path.write_text(report_html(title, figs, notes, data.missing, sections), encoding="utf-8")
    (run_dir / "figures.json").write_text(figs.model_dump_json(indent=2))
    return path, figs


def write_report(run_dir: Path, cfg: ReportConfig | None = None) -> Path:
    """``build_report`` returning only the path of report.html."""
    return build_report(run_dir, cfg)[0]


def archive_damage(run_dir: Path) -> str | None:
    """What is wrong with the run's archive.sqlite, or None if it is intact or absent."""
    db = Path(run_dir) / "archive.sqlite"
    if not db.is_file():
        return None
    try:
        Archive.read_only(db).close()
    except ArchiveError as exc:
        return str(exc)
    return None


def cmd_report(args: argparse.Namespace) -> int:
    """``flyby report RUN_DIR``: regenerate the report of a run; exit 2 if the folder cannot be reported on."""
    try:
        path, figs = build_report(args.run_dir)
    except RunFolderError as err:
        print(f"flyby report: {err}", file=sys.stderr)
        return EXIT_CONFIG
    verdict = "all requirements PASS" if figs.all_pass else "some requirement FAILS or was not assessed"
    print(f"{path}: {verdict}")
    damage = archive_damage(args.run_dir)
    if damage:  # the report was written from tm.bin; exit 2 so a script sees the damaged archive
        print(f"flyby report: {damage}", file=sys.stderr)
        return EXIT_CONFIG
    return 0
