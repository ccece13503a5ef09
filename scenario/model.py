"""A scenario: one YAML file that fixes everything a run depends on, seed included.

Loading turns every problem into a line that names its path in the file
(``universe.camera.fov_deg: must be > 0``) so a user can fix the file in one pass.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from pydantic import Field, ValidationError, field_validator, model_validator

from contracts.bus import BusConfig
from contracts.cuc import MAX_OBT_S
from contracts.errors import ScenarioError
from contracts.model import Config
from contracts.seeding import rng_streams
from contracts.textfile import TextFileError, load_yaml, read_text
from ground.config import GroundConfig
from obsw.config import ObswConfig
from scenario.dispersions import Dispersion, dispersion_problems
from scenario.expectation import Expectation
from scenario.knowledge import fill_knowledge, filled_paths, knowledge_problems
from timeline.convert import epoch_datetime
from universe.config import UniverseConfig
from universe.geometry import GeometryError, dimorphos_line, nominal_ca
from universe.oscillator import ClockModelError, Oscillator, clock_jumps_s

if TYPE_CHECKING:
    from timeline.model import Timeline


class Scenario(Config):
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
    dispersions: tuple[Dispersion, ...] = Field(
        (), description="fields drawn anew for each run of a Monte Carlo campaign (flyby mc; see scenario.dispersions); "
        "a single run (flyby run) uses the nominal values")
    expect: Expectation | None = Field(None, description="what a fault campaign expects of the run "
                                       "(scenario.expectation; flyby campaign)")
    knowledge_errors: tuple[str, ...] = Field(
        (),
        description="knowing fields (obsw.*, ground.link.*) allowed to differ from the truth they know, as dotted "
        "paths: a deliberate miscalibration; any other difference is refused (see scenario.knowledge)",
    )

    @model_validator(mode="before")
    @classmethod
    def _knowledge_defaults_to_truth(cls, data: Any) -> Any:
        return fill_knowledge(data) if isinstance(data, dict) else data

    def _grid_fits_the_belief(self) -> list[str]:
        """The on-board recognition grid around ground's nominal (the target's truth plus the seeded error) must stay
        at positive C/A distances, or the flight software refuses the nominal trajectory."""
        u, rec = self.universe, self.obsw.recognition
        try:
            line = dimorphos_line(u.flyby, u.bodies)
        except GeometryError as exc:
            return [f"universe.flyby: {exc}"]
        try:
            _, ca_km = nominal_ca(line, u.uncertainty, rng_streams(self.seed)["nominal"])
        except GeometryError as exc:
            return [f"universe.uncertainty.ca_distance_sigma_km: {exc}"]
        low = ca_km - rec.grid_span_sigma * u.uncertainty.ca_distance_sigma_km
        if low <= 0:
            return [f"universe.uncertainty.ca_distance_sigma_km: ground's nominal C/A distance {ca_km:.3f} km minus "
                    f"obsw.recognition.grid_span_sigma {rec.grid_span_sigma:g} x {u.uncertainty.ca_distance_sigma_km:g} "
                    f"km is {low:.3f} km: the on-board grid would reach non-positive distances"]
        return []

    def _obt_encodable(self) -> list[str]:
        """The on-board time of the run's instants (start, end, the true C/A and ground's C/A) must fit the CUC
        range of the packets that carry it, or a time-tagged packet cannot be built mid-run."""
        u = self.universe
        try:
            clock = Oscillator(u.oscillator, np.random.default_rng(0), clock_jumps_s(u.faults))
            instants = {"universe.start_s": u.start_s, "universe.end_s": u.end_s,
                        "universe.flyby.ca_time_s": u.flyby.ca_time_s}
            ca_s, _ = nominal_ca(u.flyby, u.uncertainty, rng_streams(self.seed)["nominal"])
            instants["universe.uncertainty.ca_time_sigma_s"] = ca_s  # ground's C/A: truth plus its error
            margin_s = u.oscillator.jitter_bound_sigma * u.oscillator.jitter_s
            problems = []
            for path, t in instants.items():
                obt = clock.obt_mean_s(t)
                if not margin_s <= obt <= MAX_OBT_S - margin_s:
                    what = "ground's C/A" if path.startswith("universe.uncertainty") else "on-board time"
                    problems.append(f"{path}: {what} OBT {obt:.6g} s at t = {t:.6g} s is outside the CUC range "
                                    f"0..{MAX_OBT_S:.0f} s (universe.oscillator.initial_offset_s is OBT at the epoch)")
            return problems
        except (ClockModelError, GeometryError) as exc:
            return [f"universe.oscillator: {exc}"]

    @field_validator("epoch_utc")
    @classmethod
    def _epoch_readable(cls, v: str) -> str:
        try:
            epoch_datetime(v)
        except ValueError as exc:
            raise ValueError(str(exc).removeprefix("epoch_utc: ")) from None
        return v

    @model_validator(mode="after")
    def _sections_agree(self) -> Scenario:
        problems = knowledge_problems(self, set(self.knowledge_errors))
        problems += self._grid_fits_the_belief()
        problems += self._obt_encodable()
        if self.dispersions:
            problems += dispersion_problems(self.model_dump(mode="json"), self.dispersions)
        u, upload = self.universe, self.ground.upload_nominal_at_s
        if upload is not None and not u.start_s - 1e-9 <= upload < u.end_s:
            problems.append(f"ground.upload_nominal_at_s: {upload:g} s is outside the run {u.start_s:g}..{u.end_s:g} s: "
                            "the nominal trajectory would never be uploaded")
        if problems:
            raise ValueError("\n".join(problems))  # one line each, each opening with its path
        return self


def field_path(loc: tuple[int | str, ...]) -> str:
    """A pydantic error location as the scenario file names it: ``universe.faults[2].wheel``."""
    out = ""
    for part in loc:
        if isinstance(part, int) or not (str(part).isidentifier() and str(part).isascii()):
            out += f"[{part!r}]" if isinstance(part, str) else f"[{part}]"
        else:
            out += f".{part}" if out else str(part)
    return out


def _message(err: dict[str, Any]) -> str:
    """Turn one pydantic error into 'path: message'."""
    loc = field_path(err["loc"]) or "(file)"
    msg = err["msg"]
    if err["type"] == "extra_forbidden":
        msg = "unknown field"
    elif err["type"] in ("greater_than", "greater_than_equal", "less_than", "less_than_equal"):
        op = {"greater_than": ">", "greater_than_equal": ">=", "less_than": "<", "less_than_equal": "<="}
        bound = next(iter(err["ctx"].values()))
        msg = f"must be {op[err['type']]} {bound:g}" if isinstance(bound, float) else f"must be {op[err['type']]} {bound}"
    elif err["type"] in ("float_type", "int_type"):
        kind = "a whole number" if err["type"] == "int_type" else "a number"
        msg = f"must be {kind}, got {err['input']!r} ({type(err['input']).__name__})"
    elif err["type"] == "finite_number":
        msg = f"must be a finite number, got {err['input']!r}"
    elif err["type"] == "string_pattern_mismatch":
        msg = f"must match {err['ctx']['pattern']} (letters, digits, '.', '_', '-'), got {err['input']!r}"
    elif msg.startswith("Value error, "):
        msg = msg[len("Value error, ") :]
    return f"{loc}: {msg}"


_RELATIVE_PATH = re.compile(r"^[A-Za-z_][\w.\[\]]*: ")


def _lines(err: dict[str, Any]) -> list[str]:
    """'path: message' lines of one pydantic error; a rule across fields (a model validator) raises lines that open
    with their path inside the model, which is joined to the model's own path."""
    if err["type"] != "value_error":
        return [_message(err)]
    base = field_path(err["loc"])
    text = _message(err).split(": ", 1)[1] if base else _message(err).removeprefix("(file): ")
    out = []
    for line in text.split("\n"):
        if _RELATIVE_PATH.match(line):
            out.append(f"{base}.{line}" if base else line)
        else:
            out.append(f"{base or '(file)'}: {line}")
    return out


def scenario_from_dict(data: Any, source: str = "<scenario>") -> Scenario:
    """Validate parsed YAML into a Scenario, or raise ScenarioError listing every problem."""
    if not isinstance(data, dict):
        raise ScenarioError(source, ["(file): must be a mapping of fields, got " + type(data).__name__])
    try:
        return Scenario.model_validate(data)
    except ValidationError as exc:
        copied = filled_paths(data)
        lines = [line for e in exc.errors() for line in _lines(e)
                 if line.split(": ", 1)[0] not in copied]  # a true value copied into knowledge: reported at the truth
        raise ScenarioError(source, lines) from None


def load_scenario(path: str | Path) -> Scenario:
    """Read and validate a scenario file."""
    p = Path(path)
    try:
        data = load_yaml(read_text(p))
    except TextFileError as exc:
        raise ScenarioError(str(p), [str(exc)]) from None
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
        timeline = load_timeline(path)
    except TimelineError as err:
        raise ScenarioError(str(scenario_path), [f"ground.timeline_file ({name}): {p}" for p in err.problems]) from None
    errors, _ = timeline_checks(scenario, timeline)
    if errors:
        raise ScenarioError(str(scenario_path), [f"ground.timeline_file ({name}): {p}" for p in errors])
    return timeline


def timeline_checks(scenario: Scenario, timeline: Timeline) -> tuple[list[str], list[str]]:
    """(errors, warnings) of a timeline against the run, one 'row N: ...' line each.

    Error: a row repeating an earlier one (same tag, command and arguments: it would run twice). Warning: a row
    whose tag falls after the run's end (it is never released) or before the timeline can reach the spacecraft
    (ground refuses it at upload). Tags are placed on the truth's C/A and the a-priori OBT offset, so a warning is
    approximate by ground's knowledge error; ``flyby ground --dry-run`` places them as ground will.
    """
    from timeline.convert import utc_seconds
    from timeline.model import AfterPreviousTag, CaTag, ObtTag, UtcTag

    u, g = scenario.universe, scenario.ground
    upload = g.upload_nominal_at_s if g.upload_nominal_at_s is not None else u.start_s
    reach = upload + g.link.one_way_light_time_s + g.upload_margin_s
    errors: list[str] = []
    warnings: list[str] = []
    seen: dict[str, int] = {}
    t_prev: float | None = None
    for row, entry in enumerate(timeline.entries, start=1):
        key = entry.model_dump_json()
        if key in seen:
            errors.append(f"row {row}: repeats row {seen[key]} (same time, command and arguments: it would run twice)")
        seen.setdefault(key, row)
        tag = entry.tag
        if isinstance(tag, UtcTag):
            t = utc_seconds(tag.utc, scenario.epoch_utc)
        elif isinstance(tag, CaTag):
            t = u.flyby.ca_time_s + tag.ca_offset_s
        elif isinstance(tag, ObtTag):
            t = tag.obt_s - g.a_priori_obt_offset_s
        elif isinstance(tag, AfterPreviousTag) and t_prev is not None:
            t = t_prev + tag.delay_s
        else:
            t = None
        t_prev = t
        if t is None:
            continue
        if t >= u.end_s:
            warnings.append(f"row {row} ({entry.command.name}): due at t = {t:.1f} s, after the run ends at "
                            f"{u.end_s:g} s: it will never be released")
        elif t < reach:
            warnings.append(f"row {row} ({entry.command.name}): due at t = {t:.1f} s, before the timeline can reach "
                            f"the spacecraft (upload at {upload:g} s + light time + margin = {reach:.1f} s): "
                            "ground will refuse it")
    return errors, warnings


def load_run_inputs(path: str | Path) -> tuple[Scenario, Timeline | None]:
    """The scenario and the timeline it names, both validated."""
    scenario = load_scenario(path)
    return scenario, scenario_timeline(scenario, path)
