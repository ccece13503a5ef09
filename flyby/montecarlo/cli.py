"""``flyby mc``: run a Monte Carlo campaign of a scenario on Dask, resume it, report it, replay one of its runs.

    flyby mc SCENARIO --runs N --out DIR [--fidelity centroid] [--dispersions FILE ...] [--scheduler tcp://HOST:8786]
    flyby mc SCENARIO --runs N --out DIR --resume       continue a killed or interrupted campaign
    flyby mc --out DIR --replay K                       run K again alone, in one process, against its stored row
    flyby mc --out DIR --report                         rewrite DIR/mc.html from the stored runs
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from typing import TYPE_CHECKING, get_args

from contracts.errors import ScenarioError
from contracts.exitcodes import EXIT_CHECK_FAILED, EXIT_CONFIG, EXIT_INTERRUPTED, EXIT_OK
from flyby.montecarlo.store import STORE_NAME
from universe.config import UniverseConfig

if TYPE_CHECKING:
    from flyby.montecarlo.campaign import Campaign
    from flyby.montecarlo.store import ResultStore

FIDELITIES = get_args(UniverseConfig.model_fields["fidelity"].annotation)
DEFAULT_GOAL = 0.99  # fraction of runs that must meet each requirement (the campaign targets of the README)


def _err(text: str) -> None:
    print(f"flyby mc: {text}", file=sys.stderr)


def _stored_campaign(store: ResultStore) -> Campaign | None:
    from flyby.montecarlo.campaign import Campaign

    meta = store.meta()
    return Campaign.from_json(meta["campaign"]) if "campaign" in meta else None


def _differences(a: Campaign, b: Campaign) -> list[str]:
    """The top-level parts in which two campaigns differ ('scenario.universe', 'seed', 'timeline')."""
    ja, jb = json.loads(a.to_json()), json.loads(b.to_json())
    out = [k for k in ("seed", "timeline") if ja[k] != jb[k]]
    sa, sb = ja["scenario"], jb["scenario"]
    out += [f"scenario.{k}" for k in sorted(set(sa) | set(sb)) if sa.get(k) != sb.get(k)]
    return out


def _existing(out: Path) -> tuple[Campaign, list[dict], dict[int, dict[str, float]]] | None:
    """The campaign stored in ``out``, its rows and drawn values; None (with a message) if there is none."""
    from flyby.montecarlo.store import open_store

    if (out / STORE_NAME).is_file():
        with open_store(out) as store:
            campaign = _stored_campaign(store)
            if campaign is not None:
                return campaign, store.rows(), store.values()
    _err(f"{out}: no campaign stored there (no {STORE_NAME} with a campaign)")
    return None


def cmd_replay(args: argparse.Namespace) -> int:
    """Run K of the stored campaign again in this process; compare its figures and values with the stored ones."""
    from flyby.montecarlo.campaign import SCENARIOS_DIR, run_one, write_run_scenario
    from flyby.montecarlo.figures import FIGURES

    found = _existing(args.out)
    if found is None:
        return EXIT_CONFIG
    campaign, rows, values = found
    stored = {r["run"]: r for r in rows}.get(args.replay)
    path = write_run_scenario(campaign, args.replay, args.out / SCENARIOS_DIR)
    print(f"run {args.replay}: scenario file {path} (flyby run {path} replays it over Zenoh)")
    result = run_one(campaign.to_json(), args.replay)
    if not result.ok:
        print(result.error, file=sys.stderr)
    for f in FIGURES:
        print(f"  {f.label}: {result.figures.get(f.name)} {f.unit}")
    print(f"  requirements: {'all PASS' if result.passed else 'some FAIL'}; wall {result.wall_s:.1f} s")
    if stored is None:
        print(f"run {args.replay} is not in the store: nothing to compare")
        return EXIT_OK
    same = (stored["status"] == result.status and stored["seed"] == result.seed
            and all(stored.get(k) == v for k, v in result.figures.items())
            and values.get(args.replay, {}) == result.values)
    print(f"run {args.replay}: the replay {'gives' if same else 'DIFFERS from'} the stored figures")
    return EXIT_OK if same else EXIT_CHECK_FAILED


def cmd_report(args: argparse.Namespace) -> int:
    """Rewrite DIR/mc.html from the stored runs."""
    from flyby.montecarlo.report import write_report
    from flyby.montecarlo.store import open_store

    found = _existing(args.out)
    if found is None:
        return EXIT_CONFIG
    with open_store(args.out) as store:
        page = write_report(args.out, store, found[0], args.goal, str(args.out))
    print(f"report: {page}")
    return EXIT_OK


def cmd_campaign(args: argparse.Namespace) -> int:
    """Run (or resume) the campaign, then write its report."""
    from flyby.montecarlo.campaign import build_campaign
    from flyby.montecarlo.store import StoreError, open_store

    if args.scenario is None or args.runs is None:
        _err("a campaign needs SCENARIO and --runs (or --replay K / --report with --out)")
        return EXIT_CONFIG
    try:
        campaign = build_campaign(args.scenario, seed=args.seed, fidelity=args.fidelity,
                                  centroid_model=args.centroid_model, dispersions=args.dispersions,
                                  in_view_required=args.in_view_required)
    except ScenarioError as err:
        print(err.listing("campaign"), file=sys.stderr)
        return EXIT_CONFIG
    try:
        with open_store(args.out) as store:
            return _run_in(store, campaign, args)
    except StoreError as exc:
        _err(str(exc))
        return EXIT_CONFIG


def _run_in(store: ResultStore, campaign: Campaign, args: argparse.Namespace) -> int:
    """Run the campaign's runs that ``store`` lacks, then write the report."""
    from flyby.montecarlo.engine import dask_client, run_campaign, worker_count
    from flyby.montecarlo.progress import Progress
    from flyby.montecarlo.report import write_report

    stored = _stored_campaign(store)
    if stored is not None and not args.resume:
        _err(f"{args.out} holds a campaign already ({len(store.done())} runs stored): add --resume to continue it, "
             "or choose another --out")
        return EXIT_CONFIG
    if stored is not None and _differences(stored, campaign):
        _err(f"{args.out} holds another campaign: it differs in {', '.join(_differences(stored, campaign))}")
        return EXIT_CONFIG
    store.set_meta({"campaign": campaign.to_json(), "runs": str(args.runs), "scenario_file": str(args.scenario)})
    done = store.done()
    todo = [k for k in range(args.runs) if k not in done]
    progress = Progress(args.runs, already=args.runs - len(todo))
    interrupted = False
    with dask_client(args.scheduler, args.workers, processes=not args.threads) as client:
        workers = worker_count(client)
        print(f"flyby mc: {len(todo)} run(s) of {campaign.scenario.name} to do ({len(done)} stored) on {workers} "
              f"worker(s); results in {args.out / STORE_NAME}", file=sys.stderr)
        try:
            run_campaign(client, campaign, todo, store, progress)
        except KeyboardInterrupt:
            interrupted = True
    page = write_report(args.out, store, campaign, args.goal, str(args.out))
    rows = store.rows()
    passed = sum(1 for r in rows if r["status"] == "ok" and r["all_pass"] == 1)
    print(f"flyby mc: {len(rows)} of {args.runs} runs stored, {passed} met every requirement; report: {page}")
    if interrupted:
        print("flyby mc: interrupted; the same command with --resume continues it", file=sys.stderr)
        return EXIT_INTERRUPTED
    return EXIT_OK if passed == len(rows) else EXIT_CHECK_FAILED


def cmd_fit(args: argparse.Namespace) -> int:
    """``flyby mc-fit``: see ``flyby.montecarlo.centroidfit``."""
    from flyby.montecarlo.centroidfit import cmd_fit as fit

    return fit(args)


def cmd_mc(args: argparse.Namespace) -> int:
    """Dispatch ``flyby mc`` to replay, report or campaign."""
    if args.replay is not None:
        return cmd_replay(args)
    if args.report:
        return cmd_report(args)
    return cmd_campaign(args)


def add_cluster_arguments(p: argparse.ArgumentParser) -> None:
    """Where the runs go: an existing scheduler, or a local cluster of processes (or threads)."""
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="an existing Dask scheduler (tcp://HOST:8786); default: a local cluster, one worker per core")
    p.add_argument("--workers", type=int, default=None, help="workers of the local cluster (default: one per core)")
    p.add_argument("--threads", action="store_true",
                   help="local workers as threads of this process (small campaigns, debugging), not processes")


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Add ``flyby mc`` and ``flyby mc-fit`` to the ``flyby`` command's sub-commands."""
    p = sub.add_parser("mc", help="Monte Carlo campaign of a scenario on Dask: runs, results store, statistics report",
                       description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("scenario", type=Path, nargs="?", help="scenario file (its dispersions: section)")
    p.add_argument("--out", type=Path, required=True, help=f"campaign folder: {STORE_NAME}, mc.html, scenarios/")
    p.add_argument("--runs", type=int, default=None, help="number of runs (run k is fixed by the campaign seed and k)")
    p.add_argument("--seed", type=int, default=None, help="campaign seed (default: the scenario's seed)")
    p.add_argument("--fidelity", choices=FIDELITIES, default=None,
                   help="image: render and process frames (the scenario's default); centroid: the measurement model")
    p.add_argument("--centroid-model", type=Path, default=None, metavar="FILE",
                   help="measurement model fitted by flyby mc-fit (universe: centroid_model: ...)")
    p.add_argument("--dispersions", type=Path, nargs="+", default=None, metavar="FILE",
                   help="YAML files whose dispersions: lists are added to the scenario's, in their order")
    p.add_argument("--in-view-required", type=float, default=None, metavar="FRACTION",
                   help="fraction of frames with the target in view a run needs (default: the scenario's report)")
    p.add_argument("--goal", type=float, default=DEFAULT_GOAL,
                   help=f"fraction of runs that must meet each requirement, for the report's verdicts (default "
                   f"{DEFAULT_GOAL:g})")
    add_cluster_arguments(p)
    p.add_argument("--resume", action="store_true", help="continue the campaign in --out, skipping stored runs")
    p.add_argument("--replay", type=int, default=None, metavar="K", help="run K of the campaign in --out again alone")
    p.add_argument("--report", action="store_true", help="only rewrite --out's mc.html")
    p.set_defaults(func=cmd_mc)
    f = sub.add_parser("mc-fit", help="fit the centroid-level measurement model on image-level runs",
                       description="Fit universe.centroid_model on image-level runs of a scenario (see "
                       "flyby.montecarlo.centroidfit) and write it for flyby mc --centroid-model.")
    f.add_argument("scenario", type=Path)
    f.add_argument("--runs", type=int, default=40, help="image-level runs to fit on (default 40)")
    f.add_argument("--out", type=Path, required=True, help="model file to write (YAML)")
    f.add_argument("--seed", type=int, default=None, help="campaign seed (default: the scenario's seed)")
    f.add_argument("--dispersions", type=Path, nargs="+", default=None, metavar="FILE",
                   help="dispersions to add (YAML files, in their order)")
    f.add_argument("--samples", type=Path, default=None, metavar="DIR",
                   help="where each run's frame samples are kept (default: OUT.samples beside the model file)")
    add_cluster_arguments(f)
    f.set_defaults(func=cmd_fit)
