"""The ``flyby`` command: run, validate and inspect flyby scenarios."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from flyby.errors import ScenarioError
from flyby.scenario import Scenario, load_run_inputs

EXIT_CONFIG = 2


def _load_or_report(path: Path) -> Scenario | None:
    """Load a scenario, or print every problem with its path in the file and return None."""
    try:
        return load_run_inputs(path)[0]
    except ScenarioError as err:
        print(f"{err.source}: invalid scenario ({len(err.problems)} problem(s))", file=sys.stderr)
        for line in err.problems:
            print(f"  {line}", file=sys.stderr)
        return None


def cmd_validate(args: argparse.Namespace) -> int:
    """Check scenario files; print every error; exit 2 if any file is invalid."""
    bad = 0
    for f in args.files:
        if _load_or_report(f) is None:
            bad += 1
        else:
            print(f"{f}: ok")
    return EXIT_CONFIG if bad else 0


def cmd_run(args: argparse.Namespace) -> int:
    """Validate, then run a scenario with the three nodes."""
    from flyby.launcher import launch

    scenario = _load_or_report(args.scenario)
    if scenario is None:
        return EXIT_CONFIG
    return launch(args.scenario, scenario, out=args.out, realtime=args.realtime, log_level=args.log_level)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of every sub-command."""
    p = argparse.ArgumentParser(prog="flyby", description=__doc__)
    sub = p.add_subparsers(dest="command", required=True)
    r = sub.add_parser("run", help="run a scenario: universe, obsw and ground as three processes over Zenoh")
    r.add_argument("scenario", type=Path)
    r.add_argument("--out", type=Path, default=None, help="run folder (default runs/<scenario>-<UTC stamp>)")
    r.add_argument("--realtime", action="store_true", help="pace the universe to the wall clock")
    r.add_argument("--log-level", default="INFO", choices=["DEBUG", "INFO", "WARNING", "ERROR"])
    r.set_defaults(func=cmd_run)
    v = sub.add_parser("validate", help="check scenario files and print every error with its path")
    v.add_argument("files", type=Path, nargs="+")
    v.set_defaults(func=cmd_validate)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``flyby`` console command."""
    args = build_parser().parse_args(argv)
    return int(args.func(args))


if __name__ == "__main__":
    sys.exit(main())
