"""A scenario: one YAML file that fixes everything a run depends on, seed included.

Loading turns every problem into a line that names its path in the file
(``universe.camera.fov_deg: must be > 0``) so a user can fix the file in one pass.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import yaml
from pydantic import Field, ValidationError, model_validator

from contracts.bus import BusConfig
from contracts.errors import ScenarioError
from contracts.model import Frozen
from ground.config import GroundConfig
from obsw.config import ObswConfig
from scenario.knowledge import filled_paths, fill_knowledge, knowledge_problems
from universe.config import UniverseConfig

if TYPE_CHECKING:
    from timeline.model import Timeline


class Scenario(Frozen):
    """The root of a scenario file."""

    name: str = Field(min_length=1, pattern=r"^[A-Za-z0-9_.-]+$", description="short name, used in run folders")
    description: str = ""
    seed: int = Field(0, ge=0, description="seed of every random draw of the run")
    epoch_utc: str = Field(
        "2022-09-26T23:14:24Z", description="UTC of true time zero (default: the DART impact)"
    )
    universe: UniverseConfig = UniverseConfig()
    obsw: ObswConfig = ObswConfig()
    ground: GroundConfig = GroundConfig()
    bus: BusConfig = BusConfig()
    knowledge_errors: tuple[str, ...] = Field(
        (),
        description="knowing fields (obsw.*, ground.link.*) allowed to differ from the truth they know, as dotted "
        "paths: a deliberate miscalibration; any other difference is refused (see scenario.knowledge)",
    )

    @model_validator(mode="before")
    @classmethod
    def _knowledge_defaults_to_truth(cls, data: Any) -> Any:
        return fill_knowledge(data) if isinstance(data, dict) else data

    @model_validator(mode="after")
    def _sections_agree(self) -> Scenario:
        problems = knowledge_problems(self, set(self.knowledge_errors))
        if problems:
            raise ValueError("\n".join(problems))  # one line each, each opening with its path
        return self


def _message(err: dict[str, Any]) -> str:
    """Turn one pydantic error into 'path: message'."""
    loc = ".".join(str(p) for p in err["loc"]) or "(file)"
    msg = err["msg"]
    if err["type"] == "extra_forbidden":
        msg = "unknown field"
    elif err["type"] in ("greater_than", "greater_than_equal", "less_than", "less_than_equal"):
        op = {"greater_than": ">", "greater_than_equal": ">=", "less_than": "<", "less_than_equal": "<="}
        bound = next(iter(err["ctx"].values()))
        msg = f"must be {op[err['type']]} {bound:g}" if isinstance(bound, float) else f"must be {op[err['type']]} {bound}"
    elif err["type"] == "string_pattern_mismatch":
        msg = f"must match {err['ctx']['pattern']} (letters, digits, '.', '_', '-'), got {err['input']!r}"
    elif msg.startswith("Value error, "):
        msg = msg[len("Value error, ") :]
    return f"{loc}: {msg}"


def scenario_from_dict(data: Any, source: str = "<scenario>") -> Scenario:
    """Validate parsed YAML into a Scenario, or raise ScenarioError listing every problem."""
    if not isinstance(data, dict):
        raise ScenarioError(source, ["(file): must be a mapping of fields, got " + type(data).__name__])
    try:
        return Scenario.model_validate(data)
    except ValidationError as exc:
        lines = []
        copied = filled_paths(data)
        for e in exc.errors():
            if ".".join(str(p) for p in e["loc"]) in copied:
                continue  # a true value copied into on-board knowledge: its error is reported at the true path
            if not e["loc"] and e["type"] == "value_error":  # cross-section rules: lines that name their paths
                lines += _message(e).removeprefix("(file): ").split("\n")
            else:
                lines.append(_message(e))
        raise ScenarioError(source, lines) from None


def load_scenario(path: str | Path) -> Scenario:
    """Read and validate a scenario file."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as exc:
        raise ScenarioError(str(p), [f"(file): cannot read: {exc.strerror}"]) from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}, column {mark.column + 1}" if mark else "(file)"
        raise ScenarioError(str(p), [f"{where}: not valid YAML: {getattr(exc, 'problem', exc)}"]) from None
    return scenario_from_dict(data, str(p))


def scenario_timeline(scenario: Scenario, scenario_path: str | Path) -> Timeline | None:
    """The command timeline the scenario's ground uploads (``ground.timeline_file``), validated, or None.

    A relative path is taken from the scenario file's folder; every problem is reported as a ScenarioError line
    prefixed with ``ground.timeline_file``.
    """
    from timeline.model import TimelineError
    from timeline.parse import load_timeline

    name = scenario.ground.timeline_file
    if name is None:
        return None
    path = Path(name)
    if not path.is_absolute():
        path = Path(scenario_path).parent / path
    try:
        return load_timeline(path)
    except TimelineError as err:
        raise ScenarioError(str(scenario_path), [f"ground.timeline_file ({name}): {p}" for p in err.problems]) from None


def load_run_inputs(path: str | Path) -> tuple[Scenario, Timeline | None]:
    """The scenario and the timeline it names, both validated."""
    scenario = load_scenario(path)
    return scenario, scenario_timeline(scenario, path)
