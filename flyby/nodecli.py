"""Command line shared by the three nodes (``python -m universe|obsw|ground``), so each starts alone on any host."""

from __future__ import annotations

import argparse
import logging
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

import zenoh

from flyby.bus import session_config
from flyby.errors import ScenarioError
from flyby.scenario import Scenario, load_run_inputs

EXIT_CONFIG = 2


def node_main(node: str, run: Callable[[zenoh.Config, Scenario, argparse.Namespace], int],
              argv: Sequence[str] | None = None) -> int:
    """Parse the common node options, load the scenario, set up logging, and call ``run``."""
    p = argparse.ArgumentParser(prog=f"python -m {node}", description=f"The {node} node of a flyby run.")
    p.add_argument("--config", required=True, type=Path, help="scenario YAML file")
    p.add_argument("--listen", action="append", default=[], metavar="ENDPOINT",
                   help="Zenoh endpoint to listen on, e.g. tcp/0.0.0.0:7447 (repeatable)")
    p.add_argument("--connect", action="append", default=[], metavar="ENDPOINT",
                   help="Zenoh endpoint of a peer, e.g. tcp/HOST:7447 (repeatable)")
    p.add_argument("--run-id", default="default", help="run identifier shared by the three nodes")
    p.add_argument("--out", type=Path, default=Path("."), help="folder for this node's outputs")
    p.add_argument("--realtime", action="store_true", help="pace the universe to the wall clock")
    p.add_argument("--log-level", default="INFO", choices=["DEBUG", "INFO", "WARNING", "ERROR"])
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
    conf = session_config(args.listen, args.connect, scenario.bus.multicast_scouting)
    args.out.mkdir(parents=True, exist_ok=True)
    return run(conf, scenario, args)
