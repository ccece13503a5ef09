"""The flyby report of a run folder, and the ``flyby report`` command (its argparse wiring is in ``flyby/cli.py``).

``write_report(run_dir)`` loads the run (``analysis.runfolder``), scores it (``analysis.scoring``) and writes
``report.html`` (self-contained: every image a base64 data URI), the same images under ``report/``, the animated
``report/flyby.gif`` and ``figures.json``. A partial run still gets a report: every section says what it is missing.
"""

from __future__ import annotations

import argparse
import logging
import multiprocessing
import sys
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path

from contracts.exitcodes import EXIT_CONFIG
from ground.archive import Archive, ArchiveError
from ground.config import ReportConfig
from analysis.frames import gif_section, gif_section_of
from analysis.page import counts_section, events_section, report_html
from analysis.plots import chart_sections
from analysis.runfolder import RunFolderError, load_run
from analysis.scoring import RunFigures, score_run

log = logging.getLogger(__name__)


def _start_gif(run_dir: Path, figs: RunFigures, cfg: ReportConfig) -> tuple[ProcessPoolExecutor, Future] | None:
    """The animation started in a fresh helper process, or None where one cannot be started."""
    try:
        pool = ProcessPoolExecutor(max_workers=1, mp_context=multiprocessing.get_context("spawn"))
    except (OSError, ValueError, NotImplementedError) as exc:
        log.warning("report: no helper process for the animation (%s); drawing it here", exc)
        return None
    try:
        return pool, pool.submit(gif_section_of, run_dir, figs, cfg)
    except (OSError, RuntimeError, AssertionError) as exc:  # e.g. a daemonic process may not have children
        log.warning("report: no helper process for the animation (%s); drawing it here", exc)
        pool.shutdown(wait=False, cancel_futures=True)
        return None


def build_report(run_dir: Path, cfg: ReportConfig | None = None, parallel: bool = False) -> tuple[Path, RunFigures]:
    """Write run_dir/report.html, its images under run_dir/report/, report/flyby.gif and run_dir/figures.json;
    return the path of report.html and the figures.

    ``cfg`` defaults to the scenario's ``ground.report``. ``parallel``: the animation (a third of the report's time)
    is drawn in a helper process while the charts are drawn here, for a caller with a core to spare (the ground
    node once the run is over, ``flyby report``; not a campaign's workers, which keep every core busy); the page is
    the same either way. Raises RunFolderError if the folder has no usable scenario.
    """
    run_dir = Path(run_dir)
    data = load_run(run_dir)
    cfg = cfg or data.scenario.ground.report
    figs, notes = score_run(data, cfg)
    out = run_dir / "report"
    out.mkdir(exist_ok=True)
    helper = _start_gif(run_dir, figs, cfg) if parallel and data.frames else None
    charts = chart_sections(data, figs, cfg)
    gif = None
    if helper is not None:
        pool, future = helper
        try:
            gif = future.result()
        except (BrokenProcessPool, OSError) as exc:  # the helper died: draw the animation here
            log.warning("report: the animation's helper process failed (%s); drawing it here", exc)
            gif = None
        finally:
            pool.shutdown()
    if gif is None:
        gif = gif_section(data, figs, cfg)
    sections = [counts_section(data, figs), *charts, gif, events_section(data, figs.true_ca_obt_s)]
    for s in sections:
        if s.png is not None and s.file_name is not None:
            (out / s.file_name).write_bytes(s.png)
    title = f"Flyby report: {data.scenario.name} (seed {data.scenario.seed})"
    path = run_dir / "report.html"
    path.write_text(report_html(title, figs, notes, data.missing, sections), encoding="utf-8")
    (run_dir / "figures.json").write_text(figs.model_dump_json(indent=2))
    return path, figs


def write_report(run_dir: Path, cfg: ReportConfig | None = None, parallel: bool = False) -> Path:
    """``build_report`` returning only the path of report.html."""
    return build_report(run_dir, cfg, parallel)[0]


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
        path, figs = build_report(args.run_dir, parallel=True)
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
