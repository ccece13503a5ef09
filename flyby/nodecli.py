"""Command line shared by the three nodes (``python -m universe|obsw|ground``), so each starts alone on any host.

This is the composition root of a node process: it loads the scenario, builds the node's core from its own
section (``scenario.compose``) and hands it to the node's bus adapter. The nodes' ``__main__`` modules are the
only node modules that import this package (see the import-linter contracts in pyproject.toml).
"""

from __future__ import annotations

import argparse
import logging
import shutil
import sys
from collections.abc import Sequence
from pathlib import Path

from contracts import sdls
from contracts.bus import EndpointError, Keys, TlsIdentity, access_control, session_config
from contracts.clock import process_usage
from contracts.errors import ScenarioError
from contracts.exitcodes import EXIT_CONFIG
from contracts.shared_blobs import SHM_ROOT, shared_memory_available
from contracts.steplog import FRAME_KEEPING, STEP_RECORD
from flyby.credentials import TC_KEY_FILE
from scenario import compose
from scenario.model import Scenario, load_run_inputs

log = logging.getLogger("flyby")


def ground_finisher(scenario: Scenario):  # type: ignore[no-untyped-def]
    """What the ground node does once its run folder is complete: score the run and write the report."""

    def finish(out: Path, lines: list[str], completed: bool) -> list[str]:
        from analysis.report import build_report
        from analysis.runfolder import RunFolderError

        head = [f"scenario {scenario.name}, seed {scenario.seed}"]
        try:
            report, figures = build_report(out, parallel=True)  # the run is over: its cores are free
        except RunFolderError as exc:
            log.error("no report: %s", exc)
            return head + lines
        # the figures' own lines: the same numbers and verdicts as figures.json and the report's tables
        return head + figures.summary_lines() + lines + [f"report: {report}"]

    return finish


def _start(node: str, conf, scenario: Scenario, args: argparse.Namespace) -> int:  # type: ignore[no-untyped-def]
    if node == "obsw":
        from obsw.node import main as obsw_main

        return obsw_main(conf, compose.flight_software(scenario, args.keys), scenario.bus, args.run_id,
                         record=args.out / STEP_RECORD, record_header={"scenario": scenario.model_dump(mode="json")},
                         record_frames=args.record_frames, trace=args.trace)
    if node == "universe":
        from universe.node import main as universe_main

        return universe_main(conf, lambda: compose.universe(scenario), scenario.bus, args.run_id, args.out,
                             args.realtime, args.shared_memory, trace=args.trace)
    from ground.node import main as ground_main

    # the report reads the scenario from the run folder; keep a copy there when started alone
    if not (args.out / "scenario.yaml").exists():
        shutil.copyfile(args.config, args.out / "scenario.yaml")
    return ground_main(conf, compose.ground_segment(scenario, args.timeline, args.keys), scenario.bus, args.run_id,
                       args.out, ground_finisher(scenario), trace=args.trace)


INSECURE_WARNING = ("WARNING: plain-TCP bus (--insecure): no TLS, no access control; anyone who reaches the "
                    "endpoints can drive or command the run. For debugging only.")


def bus_settings(role: str, listen: Sequence[str], connect: Sequence[str], run_id: str, credentials: Path | None,
                 insecure: bool, multicast_scouting: bool = False):  # type: ignore[no-untyped-def]
    """The Zenoh configuration of ``role``: TLS with its identity in ``credentials`` and the run's access control,
    or plain TCP with a warning on stderr when ``insecure``; ValueError naming the option that is wrong."""
    if insecure == (credentials is not None):
        raise ValueError("give --credentials DIR (TLS with access control) or --insecure (plain TCP), not both "
                         "and not neither")
    if insecure:
        print(INSECURE_WARNING, file=sys.stderr)
        return session_config(listen, connect, multicast_scouting)
    assert credentials is not None
    tls = TlsIdentity.in_folder(credentials, role)
    if tls.missing():
        raise ValueError(f"--credentials {credentials}: {tls.missing()[0].name} is missing (flyby credentials makes "
                         "a set)")
    return session_config(listen, connect, multicast_scouting, tls=tls, acl=access_control(Keys(run_id)))


def node_main(node: str, argv: Sequence[str] | None = None) -> int:
    """Parse the common node options, load the scenario, set up logging, and run ``node``."""
    p = argparse.ArgumentParser(prog=f"python -m {node}", description=f"The {node} node of a flyby run.")
    p.add_argument("--config", required=True, type=Path, help="scenario YAML file")
    p.add_argument("--listen", action="append", default=[], metavar="ENDPOINT",
                   help="Zenoh endpoint to listen on, e.g. tcp/0.0.0.0:7447 (repeatable)")
    p.add_argument("--connect", action="append", default=[], metavar="ENDPOINT",
                   help="Zenoh endpoint of a peer, e.g. tcp/HOST:7447 (repeatable)")
    p.add_argument("--run-id", default="default", help="run identifier shared by the three nodes")
    p.add_argument("--out", type=Path, default=Path("."), help="folder for this node's outputs")
    p.add_argument("--realtime", action="store_true", help="pace the universe to the wall clock")
    p.add_argument("--shared-memory", action="store_true",
                   help="universe: hand camera frames to the OBSW through this host's shared memory (" +
                   str(SHM_ROOT) + ") instead of in the messages; the OBSW must run on the same host")
    p.add_argument("--record-frames", choices=FRAME_KEEPING, default=FRAME_KEEPING[0],
                   help="how the OBSW node's step record keeps camera frames: by reference (a digest; the replay "
                   "renders them again) or raw (the pixels, about 0.55 MB a frame)")
    p.add_argument("--log-level", default="INFO", choices=["DEBUG", "INFO", "WARNING", "ERROR"])
    p.add_argument("--trace", type=Path, default=None, metavar="FILE",
                   help="write the time marks of this node's lock-step messages and work to FILE when it ends "
                        "(bench/loop_trace.py reads them: where the loop's time goes)")
    p.add_argument("--credentials", type=Path, default=None, metavar="DIR",
                   help="folder with ca.pem and this node's certificate and key (flyby credentials makes one): the "
                        "bus runs over TLS with mutual authentication and access control; endpoints are tls/...")
    p.add_argument("--tc-keys", type=Path, default=None, metavar="FILE",
                   help="the telecommand key file (obsw and ground; default: tc-keys.json in --credentials)")
    p.add_argument("--insecure", action="store_true", help="plain TCP, no TLS nor access control (debugging only)")
    args = p.parse_args(argv)
    logging.basicConfig(level=args.log_level, stream=sys.stderr,
                        format=f"%(asctime)s {node} %(levelname)s %(message)s")
    try:
        scenario, args.timeline = load_run_inputs(args.config)
    except ScenarioError as err:
        print(f"{err.source}: invalid scenario", file=sys.stderr)
        for line in err.problems:
            print(f"  {line}", file=sys.stderr)
        return EXIT_CONFIG
    args.keys = None
    try:
        conf = bus_settings(node, args.listen, args.connect, args.run_id, args.credentials, args.insecure,
                            scenario.bus.multicast_scouting)
        if node in ("obsw", "ground"):
            key_file = args.tc_keys or (args.credentials / TC_KEY_FILE if args.credentials else None)
            if key_file is None:
                raise ValueError("--tc-keys FILE: the telecommand key file is needed (flyby credentials makes one)")
            args.keys = sdls.load_key_file(key_file)
    except (ValueError, EndpointError, sdls.KeyFileError) as err:
        print(f"python -m {node}: {err}", file=sys.stderr)
        return EXIT_CONFIG
    if args.shared_memory and not shared_memory_available():
        print(f"python -m {node}: --shared-memory: this host has no writable {SHM_ROOT}", file=sys.stderr)
        return EXIT_CONFIG
    args.out.mkdir(parents=True, exist_ok=True)
    try:
        return _start(node, conf, scenario, args)
    finally:
        logging.getLogger(node).info("%s", process_usage().line())
