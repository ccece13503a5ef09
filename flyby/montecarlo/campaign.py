"""A Monte Carlo campaign: the base scenario (its dispersions, fidelity and thresholds), the timeline, the campaign
seed, and the function that runs one of its runs on a worker.

Everything a worker needs travels as one JSON text (``Campaign.to_json``), so a worker on another host rebuilds
run k exactly from it: ``run_one(payload, k)`` draws the run's dispersions from (campaign seed, k), runs the three
cores in one process (``flyby.inprocess``) and scores the run with the report's own scoring. It never raises: a run
that fails is returned as a failure with its traceback, so one bad draw never stops a campaign.
"""

from __future__ import annotations

import gc
import json
import traceback
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any

from analysis.runfolder import RunData
from analysis.telemetry import received_telemetry
from analysis.truth import Truth
from contracts.clock import WallClock
from contracts.errors import ScenarioError
from contracts.textfile import TextFileError, load_yaml, read_text
from flyby.inprocess import run_in_process
from flyby.montecarlo.figures import run_row
from scenario.dispersions import drawn_values, run_seeds
from scenario.model import Scenario, load_run_inputs, scenario_from_dict
from timeline.model import Timeline
from universe.config import CentroidModelConfig

@dataclass(frozen=True)
class Campaign:
    """What defines a campaign's runs: run k is fixed by these and k alone."""

    scenario: Scenario
    timeline: Timeline | None
    seed: int

    def to_json(self) -> str:
        """The campaign as one JSON text (what workers receive and the results store keeps)."""
        return json.dumps({"scenario": self.scenario.model_dump(mode="json"), "seed": self.seed,
                           "timeline": None if self.timeline is None else self.timeline.model_dump(mode="json")},
                          sort_keys=True)

    @classmethod
    def from_json(cls, text: str) -> Campaign:
        """The campaign of ``to_json``."""
        d = json.loads(text)
        timeline = None if d["timeline"] is None else Timeline.model_validate(d["timeline"])
        return cls(scenario_from_dict(d["scenario"], "campaign"), timeline, int(d["seed"]))


@lru_cache(maxsize=4)
def campaign_of(payload: str) -> Campaign:
    """A worker parses a campaign once, however many of its runs it makes."""
    return Campaign.from_json(payload)


@dataclass
class RunResult:
    """One run's row of the results store: identity, outcome, timing, figures and drawn values."""

    run: int
    seed: int
    status: str  # "ok" or "error"
    error: str | None
    wall_s: float
    sim_s: float
    figures: dict[str, Any] = field(default_factory=dict)
    values: dict[str, float] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        """The run completed and was scored (it may still fail requirements)."""
        return self.status == "ok"

    @property
    def passed(self) -> bool:
        """The run completed and met every requirement."""
        return self.ok and self.figures.get("all_pass") == 1


def _freeze_heap() -> None:
    """After a process's first run, move what is alive then (modules, compiled kernels, the campaign) out of the
    garbage collector's sight: a Dask worker holds 200,000 such objects, which every full collection walked again
    (71 ms of collection a centroid-level run against 24 ms frozen, measured in a worker)."""
    if gc.get_freeze_count() == 0:
        gc.collect()
        gc.freeze()


def run_one(payload: str, k: int) -> RunResult:
    """Run k of the campaign ``payload`` (``Campaign.to_json``); a failure is returned with its traceback."""
    clock = WallClock()  # contracts.clock is the one module reading the machine's time
    t0 = clock.now()
    campaign = campaign_of(payload)
    sc = campaign.scenario
    seed, _ = run_seeds(campaign.seed, k, 0)
    values: dict[str, float] = {}
    try:
        seed, data, values = drawn_values(sc, campaign.seed, k)
        scenario = scenario_from_dict(data, f"run {k}")
        out = run_in_process(scenario, campaign.timeline)
        tm = received_telemetry(out.received, f"run {k}")
        row, _ = run_row(RunData(Path(f"<run {k}>"), scenario, Truth.from_records(out.truth), tm),
                         scenario.ground.report)
        status, error = "ok", None
    except Exception:  # noqa: BLE001 - any failure of a run is a result of the campaign, stored with its traceback
        row, status, error = {}, "error", traceback.format_exc()
    _freeze_heap()
    return RunResult(run=k, seed=seed, status=status, error=error, wall_s=clock.now() - t0,
                     sim_s=sc.universe.end_s - sc.universe.start_s, figures=row, values=values)


def failed_result(campaign: Campaign, k: int, error: str) -> RunResult:
    """The result of a run whose worker failed outside ``run_one`` (a worker killed, a lost connection)."""
    seed, _ = run_seeds(campaign.seed, k, 0)
    try:
        _, _, values = drawn_values(campaign.scenario, campaign.seed, k)
    except Exception:  # noqa: BLE001 - the values are a courtesy here; the error is what is stored
        values = {}
    sc = campaign.scenario
    return RunResult(run=k, seed=seed, status="error", error=error, wall_s=0.0,
                     sim_s=sc.universe.end_s - sc.universe.start_s, values=values)


def dispersions_file(path: Path) -> list[Any]:
    """The ``dispersions:`` list of a dispersions file; ScenarioError naming the file if it has none."""
    try:
        data = load_yaml(read_text(path))
    except TextFileError as exc:
        raise ScenarioError(str(path), [str(exc)]) from None
    if not isinstance(data, dict) or set(data) != {"dispersions"} or not isinstance(data["dispersions"], list):
        raise ScenarioError(str(path), ["(file): must be a mapping with one key, dispersions: a list of entries"])
    return data["dispersions"]


def centroid_model_file(path: Path) -> dict[str, Any]:
    """The fitted measurement model a ``flyby mc-fit`` file holds (``universe: centroid_model: ...``)."""
    try:
        data = load_yaml(read_text(path))
    except TextFileError as exc:
        raise ScenarioError(str(path), [str(exc)]) from None
    model = data.get("universe", {}).get("centroid_model") if isinstance(data, dict) else None
    if not isinstance(model, dict) or set(data) != {"universe"} or set(data["universe"]) != {"centroid_model"}:
        raise ScenarioError(str(path), ["(file): must hold universe: centroid_model: {...} and nothing else "
                                        "(as flyby mc-fit writes it)"])
    try:
        CentroidModelConfig.model_validate(model)
    except ValueError as exc:
        raise ScenarioError(str(path), [f"universe.centroid_model: {exc}"]) from None
    return model


def build_campaign(scenario_path: Path, *, seed: int | None = None, fidelity: str | None = None,
                   centroid_model: Path | None = None, dispersions: Sequence[Path] | None = None,
                   in_view_required: float | None = None) -> Campaign:
    """The campaign of a scenario file with the command's options applied: the fidelity, a fitted centroid model,
    dispersions appended from files (in their order), the in-view requirement. ScenarioError lists
    every problem."""
    scenario, timeline = load_run_inputs(scenario_path)
    data = scenario.model_dump(mode="json")
    source = str(scenario_path)
    if fidelity is not None:
        data["universe"]["fidelity"] = fidelity
    if centroid_model is not None:
        data["universe"]["centroid_model"] = centroid_model_file(centroid_model)
        source += f" + {centroid_model}"
    for path in dispersions or ():
        data["dispersions"] = data["dispersions"] + dispersions_file(path)
        source += f" + {path}"
    if in_view_required is not None:
        data["ground"]["report"]["in_view_required"] = in_view_required
    return Campaign(scenario_from_dict(data, source), timeline, scenario.seed if seed is None else seed)


SCENARIOS_DIR = "scenarios"
TIMELINE_NAME = "timeline.yaml"


def write_run_scenario(campaign: Campaign, k: int, folder: Path) -> Path:
    """Write run k as a scenario file of its own (``flyby run`` replays it alone: the drawn values, its seed, its
    knowledge errors; the campaign's timeline beside it) into ``folder``; return its path."""
    import yaml

    from timeline.parse import timeline_yaml_text

    folder.mkdir(parents=True, exist_ok=True)
    _, data, values = drawn_values(campaign.scenario, campaign.seed, k)
    if campaign.timeline is not None:
        (folder / TIMELINE_NAME).write_text(timeline_yaml_text(campaign.timeline, "the campaign's timeline"),
                                            encoding="utf-8")
        data["ground"]["timeline_file"] = TIMELINE_NAME
    else:
        data["ground"]["timeline_file"] = None
    head = (f"# Run {k} of the Monte Carlo campaign of {campaign.scenario.name}, campaign seed {campaign.seed}:\n"
            f"# every field written out, the dispersed ones at their drawn values:\n"
            + "".join(f"#   {p} = {v!r}\n" for p, v in values.items()))
    path = folder / f"{data['name']}.yaml"
    path.write_text(head + yaml.safe_dump(data, sort_keys=False, default_flow_style=None), encoding="utf-8")
    return path
