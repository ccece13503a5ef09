"""Closed-loop flybys: the nominal scenario and the four 3-sigma corners, scored against issue 4's targets.

Runs each scenario (by default over Zenoh, the three processes, ``flyby run <scenario> --out <dir>/<name>``; with
``--in-process`` the three cores in one process, same messages and seeds, for quick iterations), and scores it with
the report's own scoring function (``analysis.scoring.score_run``: the figures of figures.json, the run summary
and the report's requirement table), with the in-view requirement raised to issue 4's targets:

    in view     fraction of camera frames with Dimorphos in the FOV, first frame of ACQUISITION to C/A+60 s
    max err     largest true pointing error (boresight to Dimorphos) in that window, deg
    peak rate   largest true body rate of the run, deg/s
    C/A errors  the on-board estimates standing at true C/A-30 s (EstimateReport), grid and continuous, minus the
                true C/A (OBT s, km) of the spacecraft to Dimorphos, the body the camera measures
    centroid    largest distance of a reported Dimorphos centroid from its true projection, binned px

A run passes when every requirement of the report passes: in view (nominal >= 99.5 %, corners >= 98 %, issue 4;
the paper asks 98 %), pointing <= half the FOV (1.45 deg), peak rate >= 7 deg/s, every centroid <= 15 px.

    python bench/closedloop.py [scenario.yaml ...] [--in-process] [--out runs/closedloop] [--jobs N]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
# run as a script, bench/ leads sys.path and bench/universe.py would shadow the universe package
sys.path[:] = [str(ROOT)] + [p for p in sys.path if Path(p or ".").resolve() != ROOT / "bench"]

import numpy as np  # noqa: E402

from analysis.runfolder import RunData, load_run  # noqa: E402
from analysis.scoring import RunFigures, score_run  # noqa: E402
from analysis.telemetry import received_telemetry  # noqa: E402
from analysis.truth import Truth  # noqa: E402
from ground.config import ReportConfig  # noqa: E402
from scenario.model import Scenario, load_run_inputs, scenario_from_dict  # noqa: E402

SCENARIOS = tuple(ROOT / "configs" / "scenarios" / f"{n}.yaml"
                  for n in ("nominal", "worst-early-near", "worst-early-far", "worst-late-near", "worst-late-far"))
IN_VIEW_NOMINAL = 0.995  # issue 4: nominal, at least 99.5 % of frames (the paper reached 98 %)
IN_VIEW_CORNER = 0.98  # issue 4: the four 3-sigma corners, at least 98 % (the paper reached 90 %)
RUN_TIMEOUT_S = 1800.0  # wall-clock limit of one `flyby run` (the nominal takes about a minute on 2 cores)


@dataclass(frozen=True)
class Result:
    """The figures of one run, as the report's scoring gives them, and notes on the run."""

    scenario: str
    figures: RunFigures
    notes: tuple[str, ...]


def bench_config(scenario: Scenario) -> ReportConfig:
    """The scenario's report thresholds with the in-view requirement raised to issue 4's target."""
    cfg = scenario.ground.report
    target = IN_VIEW_NOMINAL if scenario.name == "nominal" else IN_VIEW_CORNER
    return cfg.model_copy(update={"in_view_required": max(cfg.in_view_required, target)})


def run_data(scenario_path: Path, in_process: bool, out: Path, zero_time: bool = False) -> RunData:
    """Run one scenario and return what the report reads from its run folder (``zero_time``, in process only: the
    on-board processing times off, ``obsw.timing.modelled: false``)."""
    if not in_process:
        run_dir = out / scenario_path.stem
        cmd = [sys.executable, "-m", "flyby.cli", "run", str(scenario_path), "--out", str(run_dir), "--log-level",
               "WARNING"]
        done = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=RUN_TIMEOUT_S, check=False)
        if done.returncode != 0:
            raise RuntimeError(f"{scenario_path.name}: flyby run exited {done.returncode}:\n{done.stdout[-2000:]}"
                               f"\n{done.stderr[-2000:]}")
        return load_run(run_dir)
    from flyby.inprocess import run_in_process

    scenario, timeline = load_run_inputs(scenario_path)
    if zero_time:
        data = scenario.model_dump(mode="json")
        data["obsw"]["timing"]["modelled"] = False
        scenario = scenario_from_dict(data, f"{scenario_path.name} with the timing off")
    r = run_in_process(scenario, timeline)
    tm = received_telemetry(r.received, "in-process")
    return RunData(Path("<in-process>"), scenario, Truth.from_records(r.truth), tm)


def score(scenario_path: Path, in_process: bool, out: Path, zero_time: bool = False) -> Result:
    """Run and score one scenario."""
    data = run_data(scenario_path, in_process, out, zero_time)
    figs, notes = score_run(data, bench_config(data.scenario))
    truth, tm = data.truth, data.telemetry
    assert truth is not None and tm is not None, f"{scenario_path.name}: {data.missing}"
    ca = figs.true_ca_obt_s
    modes = [f"{m.from_mode.name}->{m.to_mode.name} at C/A{t - ca:+.1f} s" for t, m in tm.mode_changes]
    win = (truth.obt_s >= figs.window_obt_s[0]) & (truth.obt_s <= figs.window_obt_s[1])
    worst = ""
    if win.any():
        i = int(np.flatnonzero(win)[np.argmax(truth.pointing_error_rad[win])])
        worst = f"largest pointing error at C/A{truth.obt_s[i] - ca:+.1f} s"
    return Result(data.scenario.name, figs, (*notes, *figs.summary_lines(), worst, "modes: " + ", ".join(modes)))


def _fmt(x: float | None, spec: str) -> str:
    return "-" if x is None else format(x, spec)


def table(results: list[Result]) -> str:
    """The figures as a Markdown table (the README's)."""
    head = ("| scenario | target in view | max pointing error | peak rate | grid C/A error | continuous C/A error "
            "| worst centroid | result |")
    lines = [head, "|" + "---|" * 8]
    for r in results:
        f = r.figures
        in_view = "-" if f.in_view_fraction is None else f"{100 * f.in_view_fraction:.2f} %"
        est = {row.estimate: row.text() for row in f.estimate_rows() if row.reference == "Dimorphos"}
        failed = [name for name, row in zip(("in view", "pointing", "rate", "centroids"), f.requirement_rows(),
                                            strict=True) if row.passed is not True]
        lines.append(
            f"| {r.scenario} | {in_view} (need {100 * f.in_view_required:g} %) "
            f"| {_fmt(f.max_pointing_error_deg, '.3f')} deg | {_fmt(f.peak_rate_deg_s, '.2f')} deg/s "
            f"| {est['grid']} | {est['continuous']} | {_fmt(f.max_centroid_error_px, '.2f')} px "
            f"| {'PASS' if f.all_pass else 'FAIL: ' + ', '.join(failed)} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """Run the scenarios, print the table; exit 1 if any run misses a target."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenarios", nargs="*", type=Path, default=list(SCENARIOS))
    ap.add_argument("--in-process", action="store_true", help="the three cores in one process (no Zenoh)")
    ap.add_argument("--out", type=Path, default=ROOT / "runs" / "closedloop", help="folder of the run folders")
    ap.add_argument("--jobs", type=int, default=1,
                    help="runs at once (default 1: over Zenoh each run is three processes)")
    ap.add_argument("--verbose", action="store_true", help="print each run's notes (windows, modes, C/A truth)")
    ap.add_argument("--zero-time", action="store_true",
                    help="with --in-process: the on-board processing times off (obsw.timing.modelled: false)")
    args = ap.parse_args(argv)
    if args.zero_time and not args.in_process:
        ap.error("--zero-time needs --in-process")
    args.out.mkdir(parents=True, exist_ok=True)
    paths = [p.resolve() for p in args.scenarios]
    with ProcessPoolExecutor(max_workers=max(1, min(args.jobs, len(paths), os.cpu_count() or 1))) as pool:
        results = list(pool.map(score, paths, [args.in_process] * len(paths), [args.out] * len(paths),
                                [args.zero_time] * len(paths)))
    how = "in one process" if args.in_process else "over Zenoh, three processes each"
    how += ", on-board timing off" if args.zero_time else ""
    print(f"Closed-loop flybys ({how}); C/A errors at true C/A-30 s against the spacecraft-Dimorphos truth")
    print(table(results))
    if args.verbose:
        for r in results:
            print(f"\n{r.scenario}:\n  " + "\n  ".join(r.notes))
    (args.out / "closedloop.json").write_text(json.dumps(
        [{"scenario": r.scenario, "figures": r.figures.model_dump(mode="json"), "notes": r.notes} for r in results],
        indent=1))
    return 0 if all(r.figures.all_pass for r in results) else 1


if __name__ == "__main__":
    raise SystemExit(main())
