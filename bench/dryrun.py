"""Benchmark of the timeline dry run and of the replay, against runs of the same flyby measured in the same session.

Run: .venv/bin/python bench/dryrun.py [--rounds N] [--jobs J] [--no-dry-run] [--no-replay]
Measured, each round in turn (so a slow spell of this shared machine hits them alike):
- reference: one in-process run of the nominal flyby at centroid-level fidelity (what one dry-run case costs);
- the dry run of configs/timelines/flyby-imaging.yaml on the nominal scenario (five cases, J at a time, default one
  per core);
- the same on ground-early-knowledge (the C/A-240 s rows refused: no imaging, mostly STANDBY);
- the command an operator types, ``flyby ground --dry-run configs/timelines/flyby-imaging.yaml --scenario
  configs/scenarios/nominal.yaml``, from start to exit (its imports and start-up included);
- the replay of a recorded nominal run (4200 periods, 463 frames) through the flight software, image level, its
  frames kept by reference (rendered again and checked) and kept raw (read from the record).
Medians over the rounds and their ratios to the reference are printed; also the two records' sizes.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path
from time import perf_counter

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from contracts.steplog import STEP_RECORD  # noqa: E402
from flyby.dryrun import dry_run  # noqa: E402
from flyby.inprocess import run_in_process  # noqa: E402
from flyby.replay import replay  # noqa: E402
from scenario.model import load_run_inputs, load_scenario  # noqa: E402
from timeline.parse import load_timeline  # noqa: E402

SCENARIOS = ROOT / "configs" / "scenarios"
TIMELINE = ROOT / "configs" / "timelines" / "flyby-imaging.yaml"


def main() -> None:
    """Time each item ``--rounds`` times, interleaved; print medians and ratios to the reference."""
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--jobs", type=int, default=None,
                   help="cases at a time (default: one per core, as flyby ground does)")
    p.add_argument("--no-dry-run", action="store_true", help="time the reference and the replays only")
    p.add_argument("--no-replay", action="store_true", help="time the reference and the dry runs only")
    args = p.parse_args()
    nominal, timeline = load_run_inputs(SCENARIOS / "nominal.yaml")
    assert timeline is not None
    centroid = nominal.model_copy(update={"universe": nominal.universe.model_copy(update={"fidelity": "centroid"})})
    early = load_scenario(SCENARIOS / "ground-early-knowledge.yaml")
    imaging = load_timeline(TIMELINE)
    with tempfile.TemporaryDirectory() as tmp:
        records = {} if args.no_replay else {frames: Path(tmp) / f"{frames}-{STEP_RECORD}"
                                             for frames in ("reference", "raw")}
        for frames, record in records.items():
            t0 = perf_counter()
            run_in_process(nominal, timeline, record=record, record_frames=frames)  # type: ignore[arg-type]
            print(f"recorded nominal run (image level, frames {frames}) in {perf_counter() - t0:.1f} s: "
                  f"{STEP_RECORD} {record.stat().st_size / 1e6:.2f} MB")
        items = {"reference: one centroid-level in-process run": lambda: run_in_process(centroid, timeline)}
        at_a_time = f"one per core ({os.cpu_count()})" if args.jobs is None else args.jobs
        if not args.no_dry_run:
            items[f"dry run, nominal (5 cases, {at_a_time} at a time)"] = lambda: dry_run(nominal, imaging,
                                                                                          jobs=args.jobs)
            items[f"dry run, ground-early-knowledge (5 cases, {at_a_time} at a time)"] = lambda: dry_run(
                early, imaging, jobs=args.jobs)
            items[f"the command: flyby ground --dry-run, nominal ({at_a_time} at a time), start to exit"] = \
                lambda: _command(args.jobs)
        if records:
            items["replay of the recorded nominal run, frames by reference (rendered again)"] = lambda: replay(
                records["reference"])
            items["replay of the recorded nominal run, frames raw"] = lambda: replay(records["raw"])
        times: dict[str, list[float]] = {k: [] for k in items}
        for r in range(args.rounds):
            for name, fn in items.items():
                t0 = perf_counter()
                fn()
                times[name].append(perf_counter() - t0)
                print(f"round {r + 1}: {name}: {times[name][-1]:.2f} s", file=sys.stderr, flush=True)
    ref = statistics.median(next(iter(times.values())))
    print(f"\n| | median of {args.rounds} | ratio to the reference |\n|---|---|---|")
    for name, ts in times.items():
        print(f"| {name} | {statistics.median(ts):.2f} s | {statistics.median(ts) / ref:.2f} |")


def _command(jobs: int | None) -> None:
    """The dry run as an operator starts it, in a new process; its exit code checked (0: every case passes)."""
    cmd = [sys.executable, "-m", "flyby.cli", "ground", "--dry-run", str(TIMELINE), "--scenario",
           str(SCENARIOS / "nominal.yaml"), *([] if jobs is None else ["--jobs", str(jobs)])]
    subprocess.run(cmd, cwd=ROOT, check=True, stdout=subprocess.DEVNULL)


if __name__ == "__main__":
    main()
