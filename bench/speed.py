"""Benchmark of one run's speed (issue 13) and of the timeline dry run, against another build of the code measured in
the same session.

Run: .venv/bin/python bench/speed.py [--rounds N] [--reference-code DIR] [--scenario PATH] [--basilisk-python PATH]

Every item runs in a child process of its own (so its peak resident memory is its own, read from ``wait4``), in
rounds, the builds taking turns within each round, each going first in every other round (so a slow spell of this shared
machine hits them alike):
- in process, image in the loop (``run_in_process``): wall time, real-time factor, time per control period, of the
  first run in a fresh process (loading the compiled kernels, about 0.3 s, and the modules a run imports) and of a
  further run in the same process (what each run of a Monte Carlo worker costs; its telemetry is checked equal);
- in process, centroid level (no rendering; the imaging chain's output modelled);
- ``flyby run`` with three processes over Zenoh, image in the loop: start to report written, and its loop (the
  universe log's "peers up" to "run complete"), with each node's processor time and peak RSS from its log;
- the dry run of configs/timelines/flyby-imaging.yaml on the scenario (five cases, two at a time), as
  ``flyby ground --dry-run`` runs it;
- Basilisk's equivalent closed loop (bench/basilisk_loop.py: the scenario's hub and wheels at its integration
  substep, a Python PD law every control period, no images), printed beside the centroid-level run with the ratio
  of their real-time factors (ours on a first run in a process and on a further run; Basilisk's set-up excluded,
  as its loop is timed alone). It runs in the interpreter given by ``--basilisk-python`` or, by default, in this one
  if it imports Basilisk (the ``bench`` extra: ``pip install .[bench]``); otherwise it is skipped, said in one line.
With ``--reference-code DIR`` (a copy of another build, e.g. ``git archive main | tar -x -C DIR``) each item runs
with that code too and the ratio this build / reference is printed; without it, this build's figures alone.
The first round is a warm-up (Numba caches of a fresh copy compile there) and is not counted, unless
``--no-warm-up``. Processor times (the child's and its children's, ``wait4``) are printed beside wall times: on a
shared machine they are the steadier figure.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
from datetime import datetime
from pathlib import Path
from time import perf_counter  # the benchmark, not the simulator, reads the clock

ROOT = Path(__file__).resolve().parent.parent
SCENARIO = ROOT / "configs" / "scenarios" / "nominal.yaml"
TIMELINE = ROOT / "configs" / "timelines" / "flyby-imaging.yaml"
BASILISK_LOOP = ROOT / "bench" / "basilisk_loop.py"

# the child: one item with the code on its path; prints one JSON line of figures
_CHILD = r"""
import json, sys
from pathlib import Path
from time import perf_counter, process_time
item, scenario_path, timeline_path = sys.argv[1:4]
from scenario.model import load_run_inputs
sc, timeline = load_run_inputs(Path(scenario_path))
if item == "dryrun":
    from flyby.dryrun import dry_run
    from timeline.parse import load_timeline
    imaging = load_timeline(Path(timeline_path))
    t0 = perf_counter()
    results = dry_run(sc, imaging, jobs=2)
    print(json.dumps({"wall_s": perf_counter() - t0, "ok": all(r.ok for r in results)}))
else:
    from flyby.inprocess import run_in_process
    if item == "centroid":
        sc = sc.model_copy(update={"universe": sc.universe.model_copy(update={"fidelity": "centroid"})})
    t0, c0 = perf_counter(), process_time()
    run = run_in_process(sc, timeline)
    wall, cpu = perf_counter() - t0, process_time() - c0
    # the same run again in this process: what each run of a campaign's worker costs, once the kernels are loaded
    t1 = perf_counter()
    again = run_in_process(sc, timeline)
    print(json.dumps({"wall_s": wall, "loop_cpu_s": cpu, "further_run_wall_s": perf_counter() - t1,
                      "sim_s": sc.universe.end_s - sc.universe.start_s, "periods": len(run.truth) - 1,
                      "frames": run.frames,
                      "same_telemetry": [r.raw for r in run.received] == [r.raw for r in again.received]}))
"""

_STAMP = re.compile(r"^(\d{4}-\d\d-\d\d \d\d:\d\d:\d\d,\d{3}) universe INFO (.*)$", re.M)


def _run_child(code: Path, args: list[str], cwd: Path, python: str = sys.executable) -> tuple[str, float, float]:
    """Run ``python args`` with ``code`` first on the path; its output, its peak resident memory (MB) and its
    processor time with its children's (s), both from ``wait4``."""
    env = dict(os.environ, PYTHONPATH=str(code))
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
        p = subprocess.Popen([python, *args], cwd=cwd, env=env, stdout=out, stderr=err)
        _, status, usage = os.wait4(p.pid, 0)
        p.returncode = os.waitstatus_to_exitcode(status)
        out.seek(0)
        err.seek(0)
        text = out.read().decode()
        if p.returncode != 0:
            raise SystemExit(f"{args[:4]} with {code} failed ({p.returncode}):\n{text[-2000:]}"
                             f"{err.read().decode()[-3000:]}")
    return text, usage.ru_maxrss / 1024.0, usage.ru_utime + usage.ru_stime  # Linux: KiB


def in_process(code: Path, item: str, scenario: Path) -> dict[str, float]:
    """One in-process item (``image``, ``centroid`` or ``dryrun``) with ``code``."""
    text, rss, cpu = _run_child(code, ["-c", _CHILD, item, str(scenario), str(TIMELINE)], code)
    got = json.loads(text.strip().splitlines()[-1])
    got["process_cpu_s"] = cpu  # with the imports (and, for the dry run, its worker processes)
    got["peak_rss_mb"] = rss
    return got


def basilisk_python(given: str | None) -> tuple[str | None, str]:
    """The interpreter to run Basilisk's loop with (``given``, else this one if it imports Basilisk), or None and
    why not."""
    python = given or sys.executable
    try:
        probe = subprocess.run([python, "-c", "import Basilisk.simulation.spacecraft"], capture_output=True, text=True)
    except OSError as e:  # no such interpreter
        return None, f"basilisk: --basilisk-python {python} cannot be run ({e})"
    if probe.returncode == 0:
        return python, ""
    why = (probe.stderr.strip().splitlines() or ["no output"])[-1]
    return None, (f"basilisk: {'' if given else 'skipped, '}Basilisk is not importable by {python} ({why}); install "
                  "the bench extra (pip install .[bench]) or pass --basilisk-python PATH")


def basilisk_config(scenario: Path) -> str:
    """bench/basilisk_loop.py's configuration of ``scenario`` as JSON, read by this build's loader in a child."""
    text, _, _ = _run_child(ROOT, [str(BASILISK_LOOP), "--print-config", "--scenario", str(scenario)], ROOT)
    return text.strip().splitlines()[-1]


def basilisk(python: str, config: str) -> dict[str, float]:
    """Basilisk's closed loop of ``config`` run by ``python`` (bench/basilisk_loop.py)."""
    text, rss, cpu = _run_child(ROOT, [str(BASILISK_LOOP), "--config", config], ROOT, python)
    got = json.loads(text.strip().splitlines()[-1])
    got["process_cpu_s"] = cpu  # with Basilisk's imports and set-up
    got["peak_rss_mb"] = rss
    return got


def three_processes(code: Path, scenario: Path, tmp: Path) -> dict[str, float]:
    """``flyby run`` of ``scenario`` with ``code``: start to report written, the loop, each node's resources."""
    out = tmp / f"run-{len(list(tmp.iterdir()))}"
    t0 = perf_counter()
    text, _, cpu = _run_child(code, ["-m", "flyby.cli", "run", str(scenario), "--out", str(out)], code)
    wall = perf_counter() - t0
    if "requirements: all PASS" not in text:
        raise SystemExit(f"flyby run with {code} did not pass:\n{text[-3000:]}")
    log = (out / "universe.log").read_text()
    start, end = (next(datetime.strptime(m.group(1), "%Y-%m-%d %H:%M:%S,%f") for m in _STAMP.finditer(log)
                       if m.group(2).startswith(what)) for what in ("peers up", "run complete"))
    got = {"wall_s": wall, "loop_s": (end - start).total_seconds(), "process_cpu_s": cpu}
    for node in ("universe", "obsw", "ground"):
        m = re.findall(r"resources: cpu ([\d.]+) s user, ([\d.]+) s system, peak RSS ([\d.]+) MB",
                       (out / f"{node}.log").read_text())
        if m:
            got[f"{node}_cpu_s"] = float(m[-1][0]) + float(m[-1][1])
            got[f"{node}_rss_mb"] = float(m[-1][2])
    return got


def _print_basilisk(got: dict[tuple[str, str], list[dict[str, float]]], builds: dict[str, Path]) -> None:
    """Basilisk's real-time factor, and each build's centroid-level one over it (wall and processor time)."""
    bsk = got[("basilisk", "Basilisk")]
    wall = statistics.median(r["wall_s"] for r in bsk)
    cpu = statistics.median(r["loop_cpu_s"] for r in bsk)
    print(f"basilisk Basilisk: real-time factor {bsk[0]['sim_s'] / wall:.0f}x, "
          f"{wall / bsk[0]['periods'] * 1e6:.0f} us per control period")
    for n in builds:
        if ("centroid", n) not in got:
            continue
        mine = got[("centroid", n)]
        if mine[0]["sim_s"] != bsk[0]["sim_s"]:
            print(f"basilisk {n}: no ratio, the runs differ in length ({mine[0]['sim_s']} s, {bsk[0]['sim_s']} s)")
            continue
        # the same simulated span: the ratio of real-time factors is Basilisk's time over ours
        print(f"basilisk {n}: centroid-level real-time factor / Basilisk's, first run in a process: "
              f"{wall / statistics.median(r['wall_s'] for r in mine):.3f} (wall), "
              f"{cpu / statistics.median(r['loop_cpu_s'] for r in mine):.3f} (processor time of the loops)")
        # Basilisk's figure leaves out its imports and set-up; ours on a first run holds the compiled kernels'
        # loading (about 0.5 s once per process), which a further run in the same process does not
        if all("further_run_wall_s" in r for r in mine):
            print(f"basilisk {n}: centroid-level real-time factor / Basilisk's, a further run: "
                  f"{wall / statistics.median(r['further_run_wall_s'] for r in mine):.3f} (wall)")


def main() -> None:
    """Run every item with each build, ``--rounds`` counted rounds after one warm-up; print medians and ratios."""
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--reference-code", type=Path, help="a copy of another build to compare with (e.g. main)")
    p.add_argument("--scenario", type=Path, default=SCENARIO)
    p.add_argument("--no-warm-up", action="store_true", help="count every round (the caches are compiled)")
    p.add_argument("--skip", nargs="*", default=[], choices=["image", "centroid", "basilisk", "flyby", "dryrun"])
    p.add_argument("--basilisk-python", help="an interpreter that imports Basilisk (bsk), for Basilisk's loop; "
                   "default: this one, if it does")
    args = p.parse_args()
    builds = {"this build": ROOT}
    if args.reference_code is not None:
        builds["reference"] = args.reference_code.resolve()
    items = [i for i in ("image", "centroid", "basilisk", "flyby", "dryrun") if i not in args.skip]
    if "basilisk" in items:
        bsk_python, why = basilisk_python(args.basilisk_python)
        if bsk_python is None:
            if args.basilisk_python:
                raise SystemExit(why)
            print(why, flush=True)
            items.remove("basilisk")
        else:
            bsk_config = basilisk_config(args.scenario.resolve())
    got: dict[tuple[str, str], list[dict[str, float]]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for rnd in range(1 if args.no_warm_up else 0, args.rounds + 1):
            for item in items:
                # Basilisk is the reference of every build: it runs once a round; the builds go first in turn
                # (whichever ran first was measured slower in some spells, the same code either way)
                turns = list(({"Basilisk": ROOT} if item == "basilisk" else builds).items())
                for name, code in turns[::-1] if rnd % 2 else turns:
                    if item == "basilisk":
                        r = basilisk(bsk_python, bsk_config)
                    elif item == "flyby":
                        r = three_processes(code, args.scenario.resolve(), Path(tmp))
                    else:
                        r = in_process(code, item, args.scenario.resolve())
                    print(f"round {rnd}{' (warm-up)' if rnd == 0 else ''}: {item:8s} {name:10s} "
                          + ", ".join(f"{k} {v:.3g}" for k, v in r.items()), flush=True)
                    if rnd:
                        got.setdefault((item, name), []).append(r)
    print(f"\nmedians of {args.rounds} rounds" + (", ratio this build / reference" if len(builds) > 1 else ""))
    for item in items:
        names = ["Basilisk"] if item == "basilisk" else list(builds)
        first = got[(item, names[0])][0]
        for key in first:
            if not isinstance(first[key], (int, float)) or isinstance(first[key], bool):
                continue
            meds = {n: statistics.median(r[key] for r in got[(item, n)]) for n in names
                    if all(key in r for r in got[(item, n)])}
            line = f"{item:8s} {key:16s} " + "  ".join(f"{n}: {v:9.3f}" for n, v in meds.items())
            if len(meds) == 2 and meds["reference"]:
                line += f"  ratio {meds['this build'] / meds['reference']:.3f}"
            print(line)
        if item == "basilisk":
            _print_basilisk(got, builds)
            continue
        mine = got[(item, "this build")]
        if item in ("image", "centroid"):
            sim = mine[0]["sim_s"]
            for n in builds:
                for key, what in (("wall_s", "first run in a process"), ("further_run_wall_s", "a further run")):
                    if not all(key in r for r in got[(item, n)]):
                        continue  # a reference build whose bench child predates the figure
                    w = statistics.median(r[key] for r in got[(item, n)])
                    print(f"{item:8s} {n}, {what}: real-time factor {sim / w:.0f}x, "
                          f"{w / mine[0]['periods'] * 1e6:.0f} us per control period")
        if item == "flyby":
            sim = got[("image", "this build")][0]["sim_s"] if "image" in items else None
            for n in builds:
                loop = statistics.median(r["loop_s"] for r in got[(item, n)])
                if sim:
                    print(f"flyby    {n}: loop real-time factor {sim / loop:.0f}x")


if __name__ == "__main__":
    main()
