"""Benchmark of memory against run length: each node's peak resident memory in a run ten times longer.

Run: .venv/bin/python bench/memory_growth.py [--scenario PATH] [--factor 10]

``flyby run`` (three processes over Zenoh, image in the loop) of the scenario as it is, then of the same flyby with
its start moved earlier so that the run lasts ``--factor`` times longer (a longer quiet approach before the same
C/A): the universe, flight software and ground log their processor time and peak RSS at the end (``resources:``
lines, ``contracts.clock.ProcessUsage``). Prints each node's peak RSS in both runs and the ratio long / short; a
node that keeps what it writes to disk also in memory grows with the run, one that does not stays flat.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from contracts.clock import ProcessUsage  # noqa: E402
from scenario.model import load_run_inputs  # noqa: E402

NODES = ("universe", "obsw", "ground")


def longer_scenario(path: Path, factor: float, folder: Path) -> tuple[Path, float, float]:
    """A copy of the scenario starting earlier so that it lasts ``factor`` times as long; its timeline path made
    absolute. Returns the file and both durations, s."""
    scenario, _ = load_run_inputs(path)
    u = scenario.universe
    short_s = u.end_s - u.start_s
    data = yaml.safe_load(path.read_text(encoding="utf-8"))
    data.setdefault("universe", {})["start_s"] = u.end_s - factor * short_s
    data["name"] = f"{scenario.name}-x{factor:g}"
    timeline = data.get("ground", {}).get("timeline_file")
    if timeline is not None:
        data["ground"]["timeline_file"] = str((path.parent / timeline).resolve())
    out = folder / f"{data['name']}.yaml"
    out.write_text(yaml.safe_dump(data), encoding="utf-8")
    return out, short_s, factor * short_s


def peak_rss(scenario: Path, run_dir: Path) -> dict[str, float]:
    """Run ``flyby run`` and return each node's peak RSS, MB, from its log."""
    cmd = [sys.executable, "-m", "flyby.cli", "run", str(scenario), "--out", str(run_dir), "--log-level", "INFO"]
    done = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, check=False)
    if done.returncode not in (0, 4):  # 4: a requirement missed, the run itself complete
        raise SystemExit(f"flyby run {scenario.name} exited {done.returncode}:\n{done.stderr[-2000:]}")
    out = {}
    for node in NODES:
        text = (run_dir / f"{node}.log").read_text(encoding="utf-8")
        usage = ProcessUsage.parse(text)
        if usage is None:
            raise SystemExit(f"{run_dir / f'{node}.log'}: no resources line")
        out[node] = usage.peak_rss_mb
        loop = ProcessUsage.parse("".join(line for line in text.splitlines(True) if "before the report" in line))
        if loop is not None:  # ground: the run's own peak, before the report reads the whole run back
            out[f"{node} before its report"] = loop.peak_rss_mb
    return out


def main() -> int:
    """Run both lengths, print the table."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenario", type=Path, default=ROOT / "configs" / "scenarios" / "nominal.yaml")
    p.add_argument("--factor", type=float, default=10.0, help="how many times longer the long run is")
    args = p.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        long_path, short_s, long_s = longer_scenario(args.scenario.resolve(), args.factor, folder)
        short = peak_rss(args.scenario.resolve(), folder / "short")
        print(f"{short_s:.0f} s run done", file=sys.stderr, flush=True)
        long = peak_rss(long_path, folder / "long")
    print(f"| node | peak RSS, {short_s:.0f} s run | peak RSS, {long_s:.0f} s run | ratio |")
    print("|---|---|---|---|")
    for node in short:
        print(f"| {node} | {short[node]:.1f} MB | {long[node]:.1f} MB | {long[node] / short[node]:.3f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
