"""The flyby's geometry envelope: a scenario flown with its flyby plane turned about the approach direction and with
Dimorphos at each orbital phase, each run in one process and scored by the report's own scoring.

The dispersions of the Monte Carlo campaigns move the geometry by degrees (approach direction 1 deg, orbital phase
5 deg); this sweeps what they do not reach: the plane's roll about the approach (0 deg: the scenario's own C/A
direction) and Dimorphos's phase (where it sits on its orbit at the epoch), on a grid. Prints one line per run, then
a grid of verdicts (P: every requirement kept; V: the target out of view too often, A: the pointing error beyond
half the FOV, C: a centroid beyond its tolerance, R: the peak rate below its requirement, E: the run raised) and
writes it as a picture.

    .venv/bin/python bench/envelope.py [SCENARIO] [--roll-step-deg 45] [--phase-step-deg 30] [--jobs 2] [--out DIR]
"""

from __future__ import annotations

import argparse
import math
import sys
import traceback
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
# run as a script, bench/ leads sys.path and bench/universe.py would shadow the universe package
sys.path[:] = [str(ROOT)] + [p for p in sys.path if Path(p or ".").resolve() != ROOT / "bench"]

import numpy as np  # noqa: E402

from analysis.runfolder import RunData  # noqa: E402
from analysis.scoring import score_run  # noqa: E402
from analysis.telemetry import received_telemetry  # noqa: E402
from analysis.truth import Truth  # noqa: E402
from flyby.inprocess import run_in_process  # noqa: E402
from scenario.model import load_run_inputs, scenario_from_dict  # noqa: E402

NOMINAL = ROOT / "configs" / "scenarios" / "nominal.yaml"
VERDICTS = (("in_view_pass", "V"), ("pointing_pass", "A"), ("centroid_pass", "C"), ("rate_pass", "R"))


def rolled(ca: np.ndarray, approach: np.ndarray, roll_deg: float) -> list[float]:
    """The C/A direction turned by ``roll_deg`` about the approach direction (Rodrigues), made orthogonal to it."""
    e_v = approach / np.linalg.norm(approach)
    c = ca - (ca @ e_v) * e_v
    c /= np.linalg.norm(c)
    a = math.radians(roll_deg)
    return [float(x) for x in c * math.cos(a) + np.cross(e_v, c) * math.sin(a)]


def fly(scenario_path: Path, roll_deg: float, phase_deg: float) -> tuple[float, float, str, dict[str, float]]:
    """One run of the grid: (roll, phase, verdict letters, figures)."""
    try:
        sc, timeline = load_run_inputs(scenario_path)
        data = sc.model_dump(mode="json")
        f = sc.universe.flyby
        data["universe"]["flyby"]["ca_direction"] = rolled(np.asarray(f.ca_direction, dtype=float),
                                                           np.asarray(f.approach_direction, dtype=float), roll_deg)
        data["universe"]["bodies"]["orbit_phase_deg"] = phase_deg
        world = scenario_from_dict(data, f"{scenario_path.name} rolled {roll_deg:g} deg, phase {phase_deg:g} deg")
        out = run_in_process(world, timeline)
        run = RunData(Path("<envelope>"), world, Truth.from_records(out.truth),
                      received_telemetry(out.received, "envelope"))
        figs, _ = score_run(run, world.ground.report)
    except Exception:  # noqa: BLE001 - a run that raises is a result of the sweep, shown with its traceback
        return roll_deg, phase_deg, "E", {"error": traceback.format_exc()}  # type: ignore[dict-item]
    letters = "".join(code for name, code in VERDICTS if getattr(figs, name) is False) or "P"
    return roll_deg, phase_deg, letters, {
        "in_view": figs.in_view_fraction, "pointing_deg": figs.max_pointing_error_deg,
        "centroid_px": figs.max_centroid_error_px, "peak_rate_deg_s": figs.peak_rate_deg_s}


def picture(results: list[tuple[float, float, str, dict[str, float]]], rolls: list[float], phases: list[float],
            path: Path) -> None:
    """The grid as an image: each cell green when every requirement is kept, red otherwise, with its letters."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cell = {(r, p): (v, f) for r, p, v, f in results}
    fig, ax = plt.subplots(figsize=(1.0 + 0.55 * len(phases), 1.0 + 0.45 * len(rolls)))
    grid = np.array([[0.0 if cell[(r, p)][0] == "P" else 1.0 for p in phases] for r in rolls])
    ax.imshow(grid, cmap="RdYlGn_r", vmin=-0.3, vmax=1.3, aspect="auto")
    for i, r in enumerate(rolls):
        for j, p in enumerate(phases):
            v, f = cell[(r, p)]
            text = v if v != "P" else f"{f['centroid_px']:.0f}"
            ax.text(j, i, text, ha="center", va="center", fontsize=7)
    ax.set_xticks(range(len(phases)), [f"{p:g}" for p in phases])
    ax.set_yticks(range(len(rolls)), [f"{r:g}" for r in rolls])
    ax.set_xlabel("Dimorphos's orbital phase at the epoch, deg")
    ax.set_ylabel("flyby plane rolled about the approach, deg")
    ax.set_title("kept every requirement (worst centroid, px) / letters: what was missed", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main() -> int:
    """Run the grid; exit 1 if any run raised."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenario", nargs="?", type=Path, default=NOMINAL)
    ap.add_argument("--roll-step-deg", type=float, default=45.0)
    ap.add_argument("--phase-step-deg", type=float, default=30.0)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", type=Path, default=Path("runs/envelope"), help="folder of the grid's picture")
    args = ap.parse_args()
    for name in ("roll_step_deg", "phase_step_deg"):
        step = getattr(args, name)
        if not 0.0 < step <= 360.0:
            ap.error(f"--{name.replace('_', '-')}: must be in (0, 360], got {step:g}")
    load_run_inputs(args.scenario)  # a bad scenario is refused here, before any run
    rolls = [float(x) for x in np.arange(0.0, 360.0 - 1e-9, args.roll_step_deg)]
    phases = [float(x) for x in np.arange(0.0, 360.0 - 1e-9, args.phase_step_deg)]
    print(f"{args.scenario}: {len(rolls)} rolls x {len(phases)} phases = {len(rolls) * len(phases)} runs, "
          f"{args.jobs} at a time", flush=True)
    results = []
    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        futures = [pool.submit(fly, args.scenario.resolve(), r, p) for r in rolls for p in phases]
        for k, fut in enumerate(futures, 1):
            r, p, v, f = fut.result()
            results.append((r, p, v, f))
            if v == "E":
                print(f"[{k}/{len(futures)}] roll {r:5.1f} phase {p:5.1f}  raised:\n{f['error']}", flush=True)
            else:
                print(f"[{k}/{len(futures)}] roll {r:5.1f} phase {p:5.1f}  {v:4s} in view {f['in_view']:.3f}  "
                      f"pointing {f['pointing_deg']:.2f} deg  centroid {f['centroid_px']:.1f} px  "
                      f"peak rate {f['peak_rate_deg_s']:.2f} deg/s", flush=True)
    cell = {(r, p): v for r, p, v, _ in results}
    print("\nroll \\ phase " + "".join(f"{p:>6g}" for p in phases))
    for r in rolls:
        print(f"{r:>12g} " + "".join(f"{cell[(r, p)]:>6s}" for p in phases))
    kept = sum(v == "P" for v in cell.values())
    print(f"\n{kept} of {len(cell)} runs keep every requirement")
    args.out.mkdir(parents=True, exist_ok=True)
    picture(results, rolls, phases, args.out / "envelope.png")
    print(f"picture: {args.out / 'envelope.png'}")
    return 1 if any(v == "E" for v in cell.values()) else 0


if __name__ == "__main__":
    sys.exit(main())
