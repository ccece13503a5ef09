"""Where the three-process loop's time goes: `flyby run --trace` of a scenario, and the table of its hops.

Run: .venv/bin/python bench/loop_trace.py [--scenario PATH] [--run-dir DIR]

Runs the scenario with the three nodes (``flyby run --trace``; each node marks the time of every lock-step message
it sends and receives, and of its own work, on the host's monotonic clock: ``contracts.hoptrace``), or reads the
traces of an earlier ``--run-dir``, and prints one line per link of a period's chain (universe publishes the
request, the flight software's bus thread receives and decodes it, its loop takes it, steps, publishes the reply,
the universe receives, decodes and takes it, advances, and publishes the next request): median and 90th percentile
in us, total over the run in s and its share of the loop. Then the same sums grouped: the two nodes' work, the
bus (publishing, the hops, decoding, the hand-over to the main thread) and the universe between its advance and
the next request (the ground step, the frame's hand-over).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from contracts.hoptrace import NEXT_REQUEST, Segment, hop_table, read_traces  # noqa: E402
from flyby.launcher import trace_file  # noqa: E402

NODES = ("universe", "obsw", "ground")


def group(segment: Segment) -> str:
    """The part of the loop a link belongs to: a node's work, the universe between periods, or the bus."""
    if segment.name == NEXT_REQUEST:
        return "universe between its advance and the next request"
    if segment.name == "obsw: work -> worked":
        return "flight software's step"
    if segment.name == "universe: work -> worked":
        return "universe's advance"
    return "bus: publishing, hops, decoding, hand-over to the main loop"


def main() -> int:
    """Run (or read) a traced flyby and print where its loop's time went."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenario", type=Path, default=ROOT / "configs" / "scenarios" / "nominal.yaml")
    p.add_argument("--run-dir", type=Path, default=None,
                   help="read the traces of this run folder (made by `flyby run --trace`) instead of running")
    args = p.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.run_dir
        if folder is None:
            folder = Path(tmp) / "run"
            print(f"flyby run --trace {args.scenario} ...", flush=True)
            r = subprocess.run([sys.executable, "-m", "flyby.cli", "run", str(args.scenario), "--out", str(folder),
                                "--trace"], cwd=ROOT, capture_output=True, text=True)
            if r.returncode != 0:
                print(r.stdout[-3000:], r.stderr[-3000:], file=sys.stderr)
                return r.returncode
        missing = [n for n in NODES if not (folder / trace_file(n)).exists()]
        if missing:
            print(f"{folder}: no trace of {', '.join(missing)} (run `flyby run --trace`)", file=sys.stderr)
            return 2
        table = hop_table(read_traces(folder / trace_file(n) for n in NODES))
    if not table:
        print("no complete period in the traces", file=sys.stderr)
        return 1
    periods = len(table[0].durations_s)
    loop_s = sum(s.total_s for s in table)
    print(f"{periods} periods; the chain's links add up to {loop_s:.2f} s "
          f"({1e6 * loop_s / periods:.0f} us a period)\n")
    print(f"{'link':68s} {'median us':>10s} {'p90 us':>10s} {'total s':>8s} {'share':>6s}")
    for s in table:
        print(f"{s.name:68s} {s.median_us:10.1f} {s.p90_us:10.1f} {s.total_s:8.2f} {100 * s.total_s / loop_s:5.1f}%")
    groups: dict[str, float] = {}
    for s in table:
        groups[group(s)] = groups.get(group(s), 0.0) + s.total_s
    print()
    for name, total in sorted(groups.items(), key=lambda kv: -kv[1]):
        print(f"{name:68s} {'':10s} {'':10s} {total:8.2f} {100 * total / loop_s:5.1f}%")
    return 0


if __name__ == "__main__":
    sys.exit(main())
