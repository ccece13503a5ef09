"""Does the centroid-level fidelity fly like the image level? Two-sample Kolmogorov-Smirnov tests of the in-view
fraction, the largest pointing error, the worst centroid and the detection latency over the runs of two campaigns
of the same scenario and dispersions, one at image level and one at centroid level (its model fitted by
``flyby mc-fit`` on runs of another campaign seed), as ``bench/montecarlo.py`` or ``flyby mc`` leave them:

    python bench/montecarlo.py configs/scenarios/nominal.yaml --runs 200 --fidelity image --out runs/mc-bench
    python bench/montecarlo.py configs/scenarios/nominal.yaml --runs 200 --fidelity centroid --out runs/mc-bench
    python bench/centroid_fidelity.py runs/mc-bench/nominal-image runs/mc-bench/nominal-centroid [--runs 200]

Prints per figure the runs, medians and 99th percentiles of both, the KS statistic D and its p-value
(``scipy.stats.ks_2samp``): a small p-value says the two levels fly differently.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
# run as a script, bench/ leads sys.path and bench/universe.py would shadow the universe package
sys.path[:] = [str(ROOT)] + [p for p in sys.path if Path(p or ".").resolve() != ROOT / "bench"]

import numpy as np  # noqa: E402
from scipy.stats import ks_2samp  # noqa: E402

from flyby.montecarlo.store import open_store  # noqa: E402

FIGURES = (("in_view_fraction", "target in view, fraction of frames"),
           ("max_pointing_error_deg", "largest pointing error, deg"),
           ("max_centroid_error_px", "worst Dimorphos centroid, px"),
           ("detection_latency_s", "ACQUISITION to TargetAcquired, s"))


def figure(folder: Path, name: str, runs: int | None = None) -> np.ndarray:
    """A figure over the completed runs of a campaign folder (those numbered below ``runs``, if given)."""
    with open_store(folder) as store:
        return np.array([r[name] for r in store.rows() if r["status"] == "ok" and r[name] is not None
                         and (runs is None or r["run"] < runs)], dtype=float)


def main(argv: list[str] | None = None) -> int:
    """Print the comparison of the two campaigns."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("image", type=Path, help="campaign folder at image level")
    ap.add_argument("centroid", type=Path, help="campaign folder at centroid level")
    ap.add_argument("--runs", type=int, help="compare runs 0..N-1 of each (the same draws when both campaigns have "
                    "the same campaign seed); default: every stored run")
    args = ap.parse_args(argv)
    for folder in (args.image, args.centroid):
        if not (folder / "results.sqlite").is_file():
            print(f"{folder}: no campaign results there", file=sys.stderr)
            return 2
    print(f"Image level ({args.image}) against centroid level ({args.centroid}), two-sample Kolmogorov-Smirnov")
    print("| figure | runs (image / centroid) | median (image / centroid) | 99 % (image / centroid) | D | p-value |")
    print("|" + "---|" * 6)
    for name, label in FIGURES:
        a, b = figure(args.image, name, args.runs), figure(args.centroid, name, args.runs)
        ks = ks_2samp(a, b)
        print(f"| {label} | {a.size} / {b.size} | {np.median(a):.4g} / {np.median(b):.4g} "
              f"| {np.percentile(a, 99):.4g} / {np.percentile(b, 99):.4g} | {ks.statistic:.3f} | {ks.pvalue:.3g} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
