"""The `flyby` command: each sub-command parses, and the light ones start without the heavy modules."""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

import pytest

from flyby.cli import LIGHT_COMMANDS, build_parser

ROOT = Path(__file__).resolve().parents[2]
HEAVY = ("obsw.software", "flyby.replay", "flyby.montecarlo.engine", "dask", "matplotlib")


def _sub_commands(light_only: bool) -> dict[str, argparse.ArgumentParser]:
    """The sub-command parsers of ``build_parser(light_only)``, by name."""
    return next(a.choices for a in build_parser(light_only)._actions if isinstance(getattr(a, "choices", None), dict))


def test_validate_loads_neither_the_flight_software_nor_the_campaign_tools() -> None:
    """`flyby validate` (a light sub-command, parsed as `flyby run` is) imports none of the modules only the other
    sub-commands need."""
    code = ("import sys; from flyby.cli import main; rc = main(['validate', 'configs/scenarios/nominal.yaml']); "
            f"print(rc, [m for m in {HEAVY!r} if m in sys.modules])")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True)
    assert out.stdout.strip().splitlines()[-1] == "0 []", out.stdout + out.stderr


@pytest.mark.parametrize("command", sorted(LIGHT_COMMANDS))
def test_a_light_sub_command_parses_the_same_with_the_full_parser(command: str) -> None:
    """Every light sub-command is declared the same in the light parser and in the full one."""
    def actions(light_only: bool) -> list[tuple[str, ...]]:
        return [(*x.option_strings, x.dest) for x in _sub_commands(light_only)[command]._actions]
    assert actions(True) == actions(False)


def test_every_sub_command_is_in_the_full_parser() -> None:
    """The full parser holds the light sub-commands and the others (replay, mc, campaign, ground, tm)."""
    choices = set(_sub_commands(False))
    assert LIGHT_COMMANDS < choices and {"replay", "mc", "campaign", "ground", "tm"} <= choices
