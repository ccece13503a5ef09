"""``flyby campaign DIR --out OUT``: run every scenario of a folder, judge each run against its ``expect:`` block.

Each scenario (``DIR/*.yaml``) runs in process (``flyby.inprocess``: the three cores exchanging, through the codec,
exactly the messages the nodes exchange), several at once on the Monte Carlo engine's Dask cluster
(``run_scenarios``: a local cluster of the machine's cores, or ``--scheduler`` an existing one whose workers share
the output folder). Each run gets its folder ``OUT/<scenario>/`` as ``flyby run`` leaves one
(scenario.yaml, truth.csv, tm.bin, archive.sqlite, summary.json, log.txt) and its report (report.html); then its
expectations are checked (``analysis.expectations``). Beside the run folders: ``campaign.html``,
``campaign.junit.xml`` and ``traceability.html`` (``analysis.campaign_report``). Exit 0 only if every expectation of
every scenario holds, 4 otherwise, 2 if a scenario or the requirements file is invalid (nothing runs then).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import traceback
from dataclasses import dataclass
from pathlib import Path

from analysis.campaign_report import ScenarioOutcome, campaign_html, junit_xml, traceability_html
from analysis.expectations import judge, nonfinite_truth
from analysis.runfolder import load_run
from analysis.scoring import score_run
from contracts.clock import WallClock
from contracts.errors import ScenarioError
from contracts.exitcodes import EXIT_CHECK_FAILED, EXIT_CONFIG, EXIT_OK
from scenario.model import load_run_inputs
from scenario.requirements import Requirements, load_requirements

REQUIREMENTS_FILE = "requirements.yaml"


@dataclass(frozen=True)
class Job:
    """One scenario to run: its file and its run folder."""

    scenario: Path
    run_dir: Path


def _write_run_folder(job: Job, run: object) -> None:
    """What the nodes leave in a run folder, from an in-process run."""
    from ground.archive import Archive
    from ground.node import TruthLog

    folder = job.run_dir
    shutil.copyfile(job.scenario, folder / "scenario.yaml")
    truth = TruthLog(folder / "truth.csv")
    for rec in run.truth:  # type: ignore[attr-defined]
        truth.add(rec)
    truth.close()
    with Archive(folder / "archive.sqlite", tm_bin=folder / "tm.bin") as archive:
        for p in run.received:  # type: ignore[attr-defined]
            stored = archive.store(p.raw, p.receipt_utc_s)
            if p.alarm is not None:
                archive.alarm(p.receipt_utc_s, p.alarm, stored.packet_id)
        for utc, text in run.alarms:  # type: ignore[attr-defined]
            archive.alarm(utc, text)
    (folder / "log.txt").write_text("\n".join(run.log) + "\n", encoding="utf-8")  # type: ignore[attr-defined]


def run_one(job: Job) -> ScenarioOutcome:
    """Run one scenario in process, write its run folder and report, and judge it."""
    from analysis.report import build_report  # matplotlib: loaded by the runs, not by the command line's parser
    from flyby.inprocess import InProcessRun, run_in_process

    clock = WallClock()
    start = clock.now()
    scenario, timeline = load_run_inputs(job.scenario)
    job.run_dir.mkdir(parents=True, exist_ok=True)
    error = None
    run = InProcessRun()
    try:
        run = run_in_process(scenario, timeline, through_codec=True)
    except Exception as exc:  # a node failing is a verdict of the campaign, not its end
        error = f"{type(exc).__name__}: {exc}"
        (job.run_dir / "traceback.txt").write_text(traceback.format_exc(), encoding="utf-8")
    _write_run_folder(job, run)
    data = load_run(job.run_dir)
    figures, _ = score_run(data, scenario.ground.report)
    verdict = judge(data, figures, error, nonfinite_truth(run.truth),
                    [line.removeprefix("ground: ") for line in run.log if line.startswith("ground: ")])
    lines = figures.summary_lines() + [f"{'PASS' if c.passed else 'FAIL'} {c.name}: {c.detail}"
                                       for c in verdict.checks]
    (job.run_dir / "summary.json").write_text(json.dumps({"lines": lines}, indent=2), encoding="utf-8")
    report = None
    try:
        build_report(job.run_dir)
        report = f"{job.run_dir.name}/report.html"
    except Exception as exc:  # the verdict stands without its report; say why
        (job.run_dir / "report-error.txt").write_text(f"{type(exc).__name__}: {exc}\n", encoding="utf-8")
    faults = tuple(f"{f.kind}" + (f" wheel {f.wheel}" if f.wheel is not None else "")
                   + (f" x{f.magnitude:g}" if f.magnitude is not None else "")
                   + f" at t = {f.start_s:g}..{f.end_s:g} s" for f in scenario.universe.faults)
    expect = scenario.expect
    return ScenarioOutcome(scenario.name, job.scenario.name, scenario.description, faults, job.run_dir.name, report,
                           verdict, () if expect is None else expect.verifies, clock.now() - start)


def run_scenarios(jobs: list[Job], workers: int, scheduler: str | None = None) -> list[ScenarioOutcome]:
    """Run the jobs on the campaign engine's Dask cluster (``workers`` local processes, or the cluster at
    ``scheduler``), saying each verdict as it comes; outcomes in the order of ``jobs``."""
    if scheduler is None and (workers <= 1 or len(jobs) <= 1):
        return [_said(run_one(j), i, len(jobs)) for i, j in enumerate(jobs)]
    from distributed import as_completed

    from flyby.montecarlo.engine import dask_client

    outcomes: dict[int, ScenarioOutcome] = {}
    with dask_client(scheduler, min(workers, len(jobs))) as client:
        futures = client.map(run_one, jobs, pure=False)
        index = {f.key: i for i, f in enumerate(futures)}
        for future in as_completed(futures):
            outcomes[index[future.key]] = _said(future.result(), len(outcomes), len(jobs))
    return [outcomes[i] for i in range(len(jobs))]


def _said(outcome: ScenarioOutcome, done: int, total: int) -> ScenarioOutcome:
    """Print one finished scenario's verdict (a campaign takes minutes: show it as it goes)."""
    mark = "PASS" if outcome.verdict.passed else "FAIL"
    print(f"[{done + 1}/{total}] {mark}  {outcome.name}", flush=True)
    return outcome


def find_requirements(folder: Path) -> Path | None:
    """The nearest ``requirements.yaml`` in ``folder`` or one of its parents."""
    for d in (folder.resolve(), *folder.resolve().parents):
        if (d / REQUIREMENTS_FILE).is_file():
            return d / REQUIREMENTS_FILE
    return None


def check_inputs(folder: Path, requirements: Path | None) -> tuple[list[Path], Requirements | None, list[str]]:
    """The scenario files of ``folder``, the requirements, and every problem (a line each) found before any run."""
    problems = []
    # the folder's own requirements file, found as find_requirements finds it, is not a scenario
    paths = sorted(p for p in folder.glob("*.yaml") if p.name != REQUIREMENTS_FILE) if folder.is_dir() else []
    if not folder.is_dir():
        problems.append(f"{folder}: no such folder")
    elif not paths:
        problems.append(f"{folder}: no scenario (*.yaml) in it")
    reqs = None
    if requirements is not None:
        try:
            reqs = load_requirements(requirements)
        except ScenarioError as err:
            problems += [f"{err.source}: {p}" for p in err.problems]
    known = {r.id for r in reqs.requirements} if reqs is not None else None
    names: dict[str, Path] = {}
    for p in paths:
        try:
            sc, _ = load_run_inputs(p)
        except ScenarioError as err:
            problems += [f"{err.source}: {line}" for line in err.problems]
            continue
        if sc.expect is None:
            problems.append(f"{p}: expect: a campaign scenario needs an expect: block")
        elif known is not None:
            problems += [f"{p}: expect.verifies: {i!r} is not a requirement of {requirements}"
                         for i in sc.expect.verifies if i not in known]
        if sc.name in names:
            problems.append(f"{p}: name: {sc.name!r} is also the name of {names[sc.name]} (run folders would clash)")
        names[sc.name] = p
    return paths, reqs, problems


def cmd_campaign(args: argparse.Namespace) -> int:
    """Run a folder of fault scenarios and judge each; exit 0 only if every expectation holds."""
    req_path = args.requirements if args.requirements is not None else find_requirements(args.folder)
    paths, reqs, problems = check_inputs(args.folder, req_path)
    if problems:
        print(f"flyby campaign: {len(problems)} problem(s), nothing run:", file=sys.stderr)
        for line in problems:
            print(f"  {line}", file=sys.stderr)
        return EXIT_CONFIG
    jobs = []
    for p in paths:
        sc, _ = load_run_inputs(p)
        jobs.append(Job(p, args.out / sc.name))
    # a run folder's archive and truth are appended to: a second run into it would mix two runs' telemetry
    earlier = [j.run_dir for j in jobs if j.run_dir.is_dir() and any(j.run_dir.iterdir())]
    if earlier and not args.replace:
        print(f"flyby campaign: {len(earlier)} run folder(s) of an earlier campaign in {args.out}, nothing run:",
              file=sys.stderr)
        for d in earlier:
            print(f"  {d}: holds a run already; give a new --out, or --replace to delete it and run again",
                  file=sys.stderr)
        return EXIT_CONFIG
    for d in earlier:
        shutil.rmtree(d)
        print(f"flyby campaign: --replace: deleted the earlier run in {d}", flush=True)
    args.out.mkdir(parents=True, exist_ok=True)
    workers = args.jobs or max(1, os.cpu_count() or 1)
    print(f"flyby campaign: {len(jobs)} scenario(s) of {args.folder}, {workers} at a time, into {args.out}",
          flush=True)
    outcomes = run_scenarios(jobs, workers, args.scheduler)
    title = f"Fault campaign: {args.folder.name}"
    (args.out / "campaign.html").write_text(campaign_html(title, outcomes), encoding="utf-8")
    (args.out / "campaign.junit.xml").write_text(junit_xml(args.folder.name, outcomes), encoding="utf-8")
    requirements = reqs.requirements if reqs is not None else ()
    (args.out / "traceability.html").write_text(
        traceability_html(f"Requirements traceability: {args.folder.name}", requirements, outcomes), encoding="utf-8")
    for o in outcomes:
        mark = "PASS" if o.verdict.passed else "FAIL"
        print(f"{mark}  {o.name}" + "".join(f"\n      unmet: {c.name}: {c.detail}" for c in o.verdict.failures))
    passed = sum(o.verdict.passed for o in outcomes)
    print(f"{passed} of {len(outcomes)} scenario(s) pass: {args.out / 'campaign.html'}, campaign.junit.xml, "
          "traceability.html")
    return EXIT_OK if passed == len(outcomes) else EXIT_CHECK_FAILED


def add_parser(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """The ``campaign`` sub-command."""
    c = sub.add_parser("campaign", help="run every fault scenario of a folder in process, check each expect: block, "
                       "write campaign.html, campaign.junit.xml and traceability.html")
    c.add_argument("folder", type=Path, help="folder of scenario files, each with an expect: block")
    c.add_argument("--out", type=Path, required=True, help="output folder: one run folder per scenario and the "
                   "campaign's pages")
    c.add_argument("--jobs", type=int, default=None, help="scenarios run at once (default: the local cores)")
    c.add_argument("--replace", action="store_true",
                   help="delete the run folders an earlier campaign left in --out and run them again (without it, "
                   "such folders are refused: a run folder is appended to, never mixed)")
    c.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="an existing Dask scheduler (tcp://HOST:8786) whose workers see --out; default: a local "
                   "cluster of --jobs processes")
    c.add_argument("--requirements", type=Path, default=None, metavar="FILE",
                   help=f"requirements to trace (default: the nearest {REQUIREMENTS_FILE} in the folder or a parent)")
    c.set_defaults(func=cmd_campaign)
