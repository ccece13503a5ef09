"""Imaging latency against the closed loop: in-view fraction and largest pointing error, with and without the late
measurement propagated to the present, for latencies from 0 to 1 s.

Each point is one in-process run of the scenario (default the nominal flyby) with the processing times of the
timing model off (``obsw.timing.modelled: false``) and an ``imaging_latency`` fault over the whole run, so every
frame's line of sight reaches the flight software the swept latency after its exposure (the executive picks it up
at the next tick, so the latencies are whole control periods; the one measured from housekeeping is printed). The
tracking loop takes each late measurement either at its exposure time, carried to the present by the trajectory
(``obsw.tracking.propagate_late_measurements: true``, the flight software's default), or as if it had been
exposed when it arrived (false). Each run is scored by the report's own scoring (``analysis.scoring.score_run``)
with bench/closedloop.py's thresholds: in view at least 99.5 % of the frames for the nominal (98 % for the
others), pointing error at most half the 2.9 deg field of view, from the first frame of ACQUISITION to C/A+60 s. Beside
them, the largest pointing error within 60 s of C/A, where the line of sight turns fastest (the window's largest
is at acquisition while the latency does not matter).

    python bench/latency.py [scenario.yaml] [--latencies 0 0.1 ...] [--jobs N] [--out runs/latency]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
# run as a script, bench/ leads sys.path and bench/universe.py would shadow the universe package
sys.path[:] = [str(ROOT)] + [p for p in sys.path if Path(p or ".").resolve() != ROOT / "bench"]

import numpy as np  # noqa: E402

from analysis.runfolder import RunData  # noqa: E402
from analysis.scoring import score_run  # noqa: E402
from analysis.telemetry import received_telemetry  # noqa: E402
from analysis.truth import Truth  # noqa: E402
from bench.closedloop import bench_config  # noqa: E402
from contracts import pus  # noqa: E402
from flyby.inprocess import run_in_process  # noqa: E402
from scenario.model import load_run_inputs, scenario_from_dict  # noqa: E402

NOMINAL = ROOT / "configs" / "scenarios" / "nominal.yaml"
LATENCIES_S = (0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.7, 1.0, 1.5, 2.0, 3.0)
TICK_MARGIN_S = 1e-6  # a latency of n periods lands just before the n-th tick, never just after it
NEAR_CA_S = 60.0  # the fast part of the flyby, where the line of sight turns up to 7 deg/s


@dataclass(frozen=True)
class Point:
    """One run of the sweep."""

    latency_s: float
    propagate: bool
    measured_latency_s: float | None  # median exposure-to-centroid latency of the housekeeping
    in_view_fraction: float | None
    max_pointing_error_deg: float | None
    max_error_near_ca_deg: float | None  # largest true pointing error within NEAR_CA_S of the true C/A
    in_view_pass: bool | None
    pointing_pass: bool | None


def run_point(scenario_path: Path, latency_s: float, propagate: bool) -> Point:
    """Run the scenario with every frame ``latency_s`` late and score it."""
    scenario, timeline = load_run_inputs(scenario_path)
    data = scenario.model_dump(mode="json")
    data["obsw"]["timing"]["modelled"] = False
    data["obsw"]["tracking"]["propagate_late_measurements"] = propagate
    u = data["universe"]
    if latency_s > 0:
        u["faults"] = [*u["faults"], {"kind": "imaging_latency", "start_s": u["start_s"], "end_s": u["end_s"],
                                      "magnitude": max(latency_s - TICK_MARGIN_S, 0.0)}]
    sc = scenario_from_dict(data, str(scenario_path))
    run = run_in_process(sc, timeline)
    tm = received_telemetry(run.received, "in-process")
    truth = Truth.from_records(run.truth)
    figs, _ = score_run(RunData(Path("<in-process>"), sc, truth, tm), bench_config(sc))
    near = np.abs(truth.obt_s - figs.true_ca_obt_s) <= NEAR_CA_S
    lat = [hk.exposure_to_centroid_s for p in run.received if isinstance(hk := p.report, pus.Housekeeping)
           and hk.exposure_to_centroid_s is not None]
    return Point(latency_s, propagate, statistics.median(lat) if lat else None, figs.in_view_fraction,
                 figs.max_pointing_error_deg, float(np.degrees(truth.pointing_error_rad[near].max())),
                 figs.in_view_pass, figs.pointing_pass)


def _passes(p: Point) -> bool:
    return p.in_view_pass is True and p.pointing_pass is True


def first_failure(points: list[Point], propagate: bool) -> float | None:
    """The smallest latency whose run misses the in-view or the pointing requirement, or None."""
    failed = [p.latency_s for p in points if p.propagate == propagate and not _passes(p)]
    return min(failed) if failed else None


def table(points: list[Point]) -> str:
    """The sweep as a Markdown table, one row per latency."""
    lines = ["| latency | measured | propagated: in view | max error | max error near C/A "
             "| not propagated: in view | max error | max error near C/A |", "|" + "---|" * 8]
    by = {(p.latency_s, p.propagate): p for p in points}
    for lat in sorted({p.latency_s for p in points}):
        cells = []
        measured = "-"
        for prop in (True, False):
            p = by.get((lat, prop))
            if p is None:
                cells += ["-", "-", "-"]
                continue
            if p.measured_latency_s is not None and prop:
                measured = f"{p.measured_latency_s:.3f} s"
            mark = "" if _passes(p) else " FAIL"
            cells += ["-" if p.in_view_fraction is None else f"{100 * p.in_view_fraction:.2f} %{mark}",
                      "-" if p.max_pointing_error_deg is None else f"{p.max_pointing_error_deg:.3f} deg",
                      "-" if p.max_error_near_ca_deg is None else f"{p.max_error_near_ca_deg:.3f} deg"]
        lines.append(f"| {lat:.1f} s | {measured} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def plot(points: list[Point], scenario: str, path: Path) -> None:
    """In-view fraction and largest pointing error against latency, with and without propagation, as a PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a, b) = plt.subplots(2, 1, figsize=(7, 6.5), sharex=True)
    for prop, colour in ((True, "tab:blue"), (False, "tab:orange")):
        pts = sorted((p for p in points if p.propagate == prop), key=lambda p: p.latency_s)
        label = "propagated to the present" if prop else "taken as if fresh"
        x = [p.latency_s for p in pts]
        a.plot(x, [100 * (p.in_view_fraction or 0.0) for p in pts], "o-", color=colour, label=label)
        b.plot(x, [p.max_pointing_error_deg or float("nan") for p in pts], "o-", color=colour, label=label)
        b.plot(x, [p.max_error_near_ca_deg or float("nan") for p in pts], "s:", color=colour,
               label=f"{label}, within {NEAR_CA_S:g} s of C/A")
    b.set_yscale("log")
    a.set_ylabel("frames with Dimorphos in view, %")
    b.set_ylabel("largest pointing error, deg")
    b.axhline(1.45, color="r", lw=0.8, label="half field of view")
    b.set_xlabel("imaging latency (exposure to line of sight on board), s")
    a.set_title(f"{scenario}: imaging latency sweep")
    a.legend(fontsize=8)
    b.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    """Run the sweep, print the table and the failing latencies; write the points and the plot."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenario", nargs="?", type=Path, default=NOMINAL)
    ap.add_argument("--latencies", type=float, nargs="+", default=list(LATENCIES_S), help="s")
    ap.add_argument("--jobs", type=int, default=1, help="runs at once")
    ap.add_argument("--out", type=Path, default=ROOT / "runs" / "latency", help="folder of the points and the plot")
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    cases = [(lat, prop) for lat in args.latencies for prop in (True, False)]
    with ProcessPoolExecutor(max_workers=max(1, min(args.jobs, len(cases), os.cpu_count() or 1))) as pool:
        points = list(pool.map(run_point, [args.scenario.resolve()] * len(cases), *zip(*cases, strict=True)))
    name = args.scenario.stem
    print(f"Imaging latency sweep, {name}, in one process (processing times off, latency from an imaging_latency "
          "fault)")
    print(table(points))
    for prop in (True, False):
        fail = first_failure(points, prop)
        how = "propagated to the present" if prop else "taken as if fresh"
        print(f"{how}: " + ("passes at every latency swept" if fail is None else
                            f"first fails at {fail:.1f} s of latency"))
    (args.out / f"{name}.json").write_text(json.dumps([asdict(p) for p in points], indent=1))
    plot(points, name, args.out / f"{name}.png")
    print(f"points and plot: {args.out / name}.json, .png")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
