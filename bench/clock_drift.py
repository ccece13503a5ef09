"""Release error of every timeline command at the flyby, against truth: ground correlation only vs on-board
C/A re-anchoring (issue 5's figure).

Runs ``configs/scenarios/clock-drift.yaml`` with the three processes (or analyses ``--run-dir``), then for each
command of the uploaded PUS 11 insert:
  intended   the true time the timeline means: true C/A + the command's C/A offset (or its absolute time)
  ground     the true time at which the on-board clock reaches the tag ground uploaded (ground's correlation and
             ground's C/A knowledge only), plus the scheduler's tick
  on board   the true time at which the OBSW actually released it (its service 1 completion report's OBT stamp),
             after re-anchoring C/A-relative commands on the C/A recognised on board
and prints both errors per command, with their median and worst absolute values, and the ground's fitted
correlation against the true oscillator.

    python bench/clock_drift.py [--run-dir DIR] [--scenario FILE]
"""

from __future__ import annotations

import argparse
import csv
import json
import statistics
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:  # run as a script: import the project, not bench/'s own files
    sys.path.insert(0, str(ROOT))

from contracts import pus  # noqa: E402
from scenario.model import load_scenario  # noqa: E402
from universe.oscillator import Oscillator  # noqa: E402


def true_time_of_obt(run: Path) -> tuple[np.ndarray, np.ndarray]:
    """(obt_s, t_s) of every control period, from the run's truth."""
    with open(run / "truth.csv") as f:
        rows = list(csv.DictReader(f))
    return np.array([float(r["obt_s"]) for r in rows]), np.array([float(r["t_s"]) for r in rows])


def main() -> None:
    """Run or analyse the scenario and print the release errors."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", type=Path, default=ROOT / "configs" / "scenarios" / "clock-drift.yaml")
    ap.add_argument("--run-dir", type=Path, default=None, help="analyse this run folder instead of running")
    args = ap.parse_args()
    run = args.run_dir
    if run is None:
        run = ROOT / "runs" / "clock-drift-bench"
        print(f"running {args.scenario} into {run} (three processes over Zenoh)...", flush=True)
        r = subprocess.run([sys.executable, "-m", "flyby.cli", "run", str(args.scenario), "--out", str(run)],
                           cwd=ROOT)
        if r.returncode != 0:
            sys.exit(f"the run failed (exit {r.returncode}); see {run}")
    sc = load_scenario(run / "scenario.yaml")
    obt_axis, t_axis = true_time_of_obt(run)

    def true_of(obt: float) -> float:
        return float(np.interp(obt, obt_axis, t_axis))

    # what ground uploaded: every activity of every PUS 11 insert
    activities: dict[int, pus.ScheduledActivity | pus.CaRelativeActivity] = {}
    for raw in pus.split_packets((run / "tc.bin").read_bytes()):
        _, cmd = pus.decode_tc(raw)
        if isinstance(cmd, pus.InsertActivities | pus.InsertCaRelativeActivities):
            for a in cmd.activities:
                activities[pus.request_id_of(a.tc_packet).seq_count] = a
    # when the OBSW released them
    released: dict[int, float] = {}
    with open(run / "tm.bin", "rb") as f:
        stream = f.read()
    for raw in pus.split_packets(stream):
        header, rep = pus.decode_tm(raw)
        if isinstance(rep, pus.Verification) and rep.stage == pus.Stage.COMPLETION:
            released.setdefault(rep.request_id.seq_count, header.obt_s)
    ca = sc.universe.flyby.ca_time_s
    tick = sc.universe.control_period_s
    print(f"\ntrue C/A at t = {ca:.3f} s; control tick {tick} s; oscillator {sc.universe.oscillator.drift_ppm:g} ppm, "
          f"offset {sc.universe.oscillator.initial_offset_s:.3f} s")
    print(f"{'command':<28}{'C/A offset s':>13}{'ground only, s':>16}{'on board, s':>13}")
    ground_err, board_err = [], []
    for rid, a in sorted(activities.items(), key=lambda kv: kv[1].release_obt_s):
        _, cmd = pus.decode_tc(a.tc_packet)
        ca_offset_s = a.ca_offset_s if isinstance(a, pus.CaRelativeActivity) else None
        intended = ca + ca_offset_s if ca_offset_s is not None else true_of(a.release_obt_s)
        # the scheduler releases at the first tick at or after the tag
        g = true_of(a.release_obt_s)
        g = t_axis[np.searchsorted(t_axis, g - 1e-9)] if g <= t_axis[-1] else g
        e_ground = g - intended
        e_board = true_of(released[rid]) - intended if rid in released else float("nan")
        ground_err.append(abs(e_ground))
        if rid in released:
            board_err.append(abs(e_board))
        name = type(cmd).__name__ + (f"({cmd.mode.name})" if isinstance(cmd, pus.SetMode) else "")
        off = "-" if ca_offset_s is None else f"{ca_offset_s:+.0f}"
        print(f"{name:<28}{off:>13}{e_ground:>+16.3f}{e_board:>+13.3f}")
    print(f"\n|release error|   median   worst   (over {len(ground_err)} commands; {len(board_err)} released in the run)")
    print(f"ground only     {statistics.median(ground_err):7.3f} {max(ground_err):7.3f} s")
    if board_err:
        print(f"on board        {statistics.median(board_err):7.3f} {max(board_err):7.3f} s")
    # the ground's OBT-UTC fit against the true oscillator
    fit = json.loads((run / "correlation.json").read_text())
    osc = Oscillator(sc.universe.oscillator, np.random.default_rng(0))
    fitted_at_ca = fit["offset_s"] + (1.0 + fit["drift"]) * ca
    true_at_ca = osc.obt_mean_s(ca)
    print(f"\nground's correlation from {fit['n_reports']} time reports: offset {fit['offset_s']:.6f} s "
          f"(+- {fit['offset_sigma_s']:.2e}), drift {fit['drift'] * 1e6:.4f} ppm (+- {fit['drift_sigma_ppm']:.2e}); "
          f"true {sc.universe.oscillator.initial_offset_s:.6f} s, {sc.universe.oscillator.drift_ppm:.4f} ppm")
    print(f"OBT at true C/A: fitted {fitted_at_ca:.6f} s, true {true_at_ca:.6f} s, error "
          f"{(fitted_at_ca - true_at_ca) * 1e6:+.1f} us")


if __name__ == "__main__":
    main()
