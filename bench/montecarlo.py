"""Monte Carlo campaign throughput and results: runs per second per core and the real-time factor per run, beside a
single in-process run timed in the same process, and each requirement's pass rate with its 95 % interval.

For each scenario it runs the campaign with ``flyby mc`` (a local Dask cluster, one worker per core) into
OUT/<scenario>-<fidelity> (resumable: run it again with more --runs and it adds the missing runs), then times
run 0 of the campaign alone in this process (the reference), and prints:

    single run     wall time and real-time factor (simulated s per wall s) of the reference run
    campaign       runs stored, worker-seconds spent, runs per second per core, median wall time and real-time
                   factor of a run inside the campaign, and its ratio to the reference
    1000 runs      the extrapolated wall time of 1000 runs on this machine's cores, against the 45 min target
    pass rates     per requirement, runs passing / assessed, with the Clopper-Pearson 95 % interval

    python bench/montecarlo.py [scenario.yaml ...] --runs 100 [--fidelity image|centroid]
        [--centroid-model FILE] [--dispersions configs/dispersions/flyby.yaml] [--out runs/mc-bench] [--workers N]
"""

from __future__ import annotations

import argparse
import io
import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
# run as a script, bench/ leads sys.path and bench/universe.py would shadow the universe package
sys.path[:] = [str(ROOT)] + [p for p in sys.path if Path(p or ".").resolve() != ROOT / "bench"]

import numpy as np  # noqa: E402

from flyby.cli import main as flyby_main  # noqa: E402
from flyby.montecarlo.campaign import Campaign, run_one  # noqa: E402
from flyby.montecarlo.statistics import pass_rates  # noqa: E402
from flyby.montecarlo.store import ResultStore, open_store  # noqa: E402

SCENARIOS = tuple(ROOT / "configs" / "scenarios" / f"{n}.yaml"
                  for n in ("nominal", "worst-early-near", "worst-early-far", "worst-late-near", "worst-late-far"))
TARGET_1000_MIN = 45.0  # the campaign target: 1000 runs in at most 45 minutes on this 2-core machine
IN_VIEW_NOMINAL, IN_VIEW_CORNER = 0.995, 0.98  # in-view fraction a run needs: nominal, 3-sigma corners


def reference_run(campaign: Campaign) -> tuple[float, float]:
    """Wall time (s) and real-time factor of run 0 alone in this process (the compiled kernels already loaded)."""
    payload = campaign.to_json()
    run_one(payload, 0)  # warm: kernels compiled or loaded from their cache, imports done
    r = run_one(payload, 0)
    return r.wall_s, r.sim_s / r.wall_s


def campaign_figures(store: ResultStore) -> dict[str, float]:
    """Runs stored, worker-seconds they took, runs per second per core (one over the mean wall time of a run on
    its worker: kill-proof, as each row keeps its own time), median run wall time and real-time factor."""
    rows = [r for r in store.rows() if r["status"] == "ok"]
    wall = np.array([r["wall_s"] for r in rows])
    sim = np.array([r["sim_s"] for r in rows])
    return {"runs": float(len(store.rows())), "busy_s": float(wall.sum()), "per_core": 1.0 / float(np.mean(wall)),
            "wall_s": float(np.median(wall)), "rtf": float(np.median(sim / wall))}


def mc_arguments(path: Path, folder: Path, args: argparse.Namespace) -> list[str]:
    """The ``flyby mc`` command line of a scenario's campaign (resumable: it adds the runs the folder lacks)."""
    need = IN_VIEW_NOMINAL if path.stem == "nominal" else IN_VIEW_CORNER
    out = ["mc", str(path), "--runs", str(args.runs), "--out", str(folder), "--fidelity", args.fidelity,
           "--dispersions", str(args.dispersions), "--in-view-required", str(need), "--resume"]
    if args.centroid_model is not None:
        out += ["--centroid-model", str(args.centroid_model)]
    if args.workers is not None:
        out += ["--workers", str(args.workers)]
    return out


def bench_one(path: Path, args: argparse.Namespace) -> tuple[str, str]:
    """Time the reference, run the campaign with ``flyby mc``, return its speed and pass-rate rows (Markdown)."""
    folder = args.out / f"{path.stem}-{args.fidelity}"
    mc = mc_arguments(path, folder, args)
    flyby_main(mc)
    with open_store(folder) as store:
        campaign = Campaign.from_json(store.meta()["campaign"])
        f = campaign_figures(store)
        rates = pass_rates(store.rows())
    ref_wall, ref_rtf = reference_run(campaign)
    extrap_min = 1000 / f["per_core"] / (os.cpu_count() or 1) / 60
    speed = (f"| {campaign.scenario.name} | {args.fidelity} | {ref_wall:.2f} s, {ref_rtf:.1f} x "
             f"| {int(f['runs'])} runs, {f['busy_s']:.0f} worker-s | {f['per_core']:.3f} | "
             f"{f['wall_s']:.2f} s ({f['wall_s'] / ref_wall:.2f} x the single run), {f['rtf']:.1f} x | "
             f"{extrap_min:.0f} min ({'within' if extrap_min <= TARGET_1000_MIN else 'over'} "
             f"{TARGET_1000_MIN:g} min) |")
    cells = " | ".join(f"{r.passed}/{r.assessed} = {100 * r.rate:.1f} % [{100 * r.low:.1f}, {100 * r.high:.1f}]"
                       for r in rates)
    print(f"{campaign.scenario.name}: flyby {' '.join(mc)}", file=sys.stderr)
    return speed, f"| {campaign.scenario.name} | {args.fidelity} | {cells} |"


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark of each scenario and print the two tables."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenarios", nargs="*", type=Path, default=list(SCENARIOS))
    ap.add_argument("--runs", type=int, default=100)
    ap.add_argument("--fidelity", choices=("image", "centroid"), default="image")
    ap.add_argument("--centroid-model", type=Path, default=None)
    ap.add_argument("--dispersions", type=Path, default=ROOT / "configs" / "dispersions" / "flyby.yaml")
    ap.add_argument("--out", type=Path, default=ROOT / "runs" / "mc-bench")
    ap.add_argument("--workers", type=int, default=None, help="local workers (default: one per core)")
    args = ap.parse_args(argv)
    speed, rates = [], []
    for path in args.scenarios:
        s, r = bench_one(path.resolve(), args)
        speed.append(s)
        rates.append(r)
    print(f"Monte Carlo throughput on {os.cpu_count()} cores (reference: run 0 alone in this process)")
    print("| scenario | fidelity | single run: wall, real-time factor | campaign | runs/s per core "
          "| run in the campaign: wall, real-time factor | 1000 runs |")
    print("|" + "---|" * 7)
    print("\n".join(speed))
    print("\nPass rates (runs passing / assessed, Clopper-Pearson 95 % interval, %)")
    print("| scenario | fidelity | in view | pointing | rate | centroid | all |")
    print("|" + "---|" * 7)
    print("\n".join(rates))
    return 0


if __name__ == "__main__":
    sys.stdout = io.TextIOWrapper(sys.stdout.buffer, line_buffering=True)
    raise SystemExit(main())
