"""Mutations of valid scenario and timeline files, for the fuzz test and bench/fuzz_inputs.py.

Independent of the loader under test: a mutation works on the YAML text or on the parsed mapping, naming fields
from the models' declared field names only.
"""

from __future__ import annotations

import math
from typing import Any

import yaml
from hypothesis import strategies as st
from pydantic import BaseModel

from scenario.model import Scenario

BASE_SCENARIO: dict[str, Any] = {
    "name": "fuzz",
    "seed": 3,
    "universe": {"start_s": 100.0, "end_s": 104.0, "save_frames_every": 0, "link": {"one_way_light_time_s": 1.0}},
    "ground": {"timeline_file": "timeline.yaml"},
}
BASE_TIMELINE: dict[str, Any] = {
    "description": "fuzz",
    "commands": [
        {"time": "CA-66s", "command": "set_mode", "args": {"mode": "ACQUISITION"}},
        {"time": "+0s", "command": "start_imaging", "args": {"period_s": 0.5}},
        {"time": "+1s", "command": "set_camera_cadence", "args": {"period_s": 0.5, "exposure_s": 0.01}},
    ],
}


def field_paths(model: type[BaseModel], prefix: tuple[str, ...] = ()) -> list[tuple[str, ...]]:
    """Every field path of a model, nested models included (list items are reached through index 0)."""
    out = []
    for name, info in model.model_fields.items():
        path = (*prefix, name)
        out.append(path)
        ann = info.annotation
        if isinstance(ann, type) and issubclass(ann, BaseModel):
            out += field_paths(ann, path)
    return out


SCENARIO_PATHS = field_paths(Scenario) + [("universe", "faults", "0", k) for k in
                                           ("kind", "start_s", "end_s", "wheel", "magnitude")]
TIMELINE_PATHS = [("commands", str(i), k) for i in range(3) for k in ("time", "command", "args")] + [
    ("commands", "1", "args", "period_s"), ("commands", "2", "args", "exposure_s"), ("description",), ("extra",)]

plausible_values = st.one_of(st.floats(-1000.0, 1000.0), st.floats(0.0, 2.0), st.integers(0, 5),
                             st.sampled_from([0.001, 0.01, 0.1, 0.5, 1.0, 10.0, 100.0]))
odd_values = st.one_of(
    plausible_values, plausible_values, plausible_values,
    st.none(), st.booleans(), st.integers(-10**12, 10**12),
    st.floats(allow_nan=True, allow_infinity=True), st.sampled_from([0.0, -0.0, 1e-300, 1e300, -1.0, math.nan]),
    st.text(max_size=12), st.sampled_from(["2.9", "nan", "CA-240s", "SAFE", "pyramid", "frame_lost", "+0s"]),
    st.lists(st.floats(-10, 10), max_size=4), st.dictionaries(st.text(max_size=4), st.integers(), max_size=2),
)


def set_path(data: Any, path: tuple[str, ...], value: Any, delete: bool) -> None:
    """Set (or delete) ``path`` in nested mappings and lists, creating mappings on the way."""
    node = data
    for part in path[:-1]:
        if isinstance(node, list):
            i = int(part) if part.isdigit() else 0
            if i >= len(node):
                node.append({})
                i = len(node) - 1
            node = node[i]
        elif isinstance(node, dict):
            child = node.get(part)
            if not isinstance(child, (dict, list)):
                child = node[part] = [] if part == "faults" else {}
            node = child
        else:
            return
    last = path[-1]
    if isinstance(node, dict):
        if delete:
            node.pop(last, None)
        else:
            node[last] = value
    elif isinstance(node, list) and last.isdigit() and int(last) < len(node):
        if delete:
            node.pop(int(last))
        else:
            node[int(last)] = value


@st.composite
def mutated_texts(draw: st.DrawFn) -> tuple[bytes, bytes, str]:
    """(scenario file, timeline file, what was done): a few mutations of the parsed files, then maybe of the text."""
    import copy

    sc, tl = copy.deepcopy(BASE_SCENARIO), copy.deepcopy(BASE_TIMELINE)
    done = []
    for _ in range(draw(st.integers(1, 3))):
        target, paths, name = draw(st.sampled_from([(sc, SCENARIO_PATHS, "scenario"), (tl, TIMELINE_PATHS, "timeline")]))
        path = draw(st.sampled_from(paths))
        delete = draw(st.booleans()) and draw(st.booleans())
        value = None if delete else draw(odd_values)
        set_path(target, path, value, delete)
        done.append(f"{name} {'.'.join(path)} {'deleted' if delete else '= ' + repr(value)[:40]}")
    texts = [yaml.safe_dump(sc, sort_keys=False).encode(), yaml.safe_dump(tl, sort_keys=False).encode()]
    how = draw(st.sampled_from(["none", "none", "duplicate_key", "bytes", "truncate"]))
    i = draw(st.integers(0, 1))
    if how == "duplicate_key":
        first = texts[i].split(b"\n", 1)[0]
        texts[i] = texts[i] + first + b"\n"
    elif how == "bytes":
        pos = draw(st.integers(0, len(texts[i])))
        texts[i] = texts[i][:pos] + draw(st.binary(min_size=1, max_size=8)) + texts[i][pos:]
    elif how == "truncate":
        texts[i] = texts[i][: draw(st.integers(0, len(texts[i])))]
    if how != "none":
        done.append(f"{['scenario', 'timeline'][i]} text: {how}")
    return texts[0], texts[1], "; ".join(done)


_KEY = r"""(?:\[(?:\d+|'(?:[^'\\]|\\.)*'|"(?:[^"\\]|\\.)*")\])"""
PROBLEM_LINE = (r"^(\(file\)|line \d+, column \d+|"
                rf"(?:[A-Za-z_]\w*|{_KEY})(?:\.[A-Za-z_]\w*|{_KEY})*( \([^)]*\))?): \S")
"""A problem line opens with where: the file, a line and column, or a field path such as universe.faults[2].wheel
(a key that is not a name in brackets and quotes), optionally followed by the file it points at."""


def outcome(folder: Any, scenario_text: bytes, timeline_text: bytes, max_steps: int = 20) -> str:
    """'refused' (every problem line names its field) or 'ran' (the in-process run went through ``max_steps``).

    Anything else (an exception, a problem line without a path) raises AssertionError with what happened.
    """
    import re

    from contracts.errors import ScenarioError
    from flyby.inprocess import run_in_process
    from scenario.model import load_run_inputs

    (folder / "scenario.yaml").write_bytes(scenario_text)
    (folder / "timeline.yaml").write_bytes(timeline_text)
    try:
        scenario, timeline = load_run_inputs(folder / "scenario.yaml")
    except ScenarioError as err:
        bad = [p for p in err.problems if not re.match(PROBLEM_LINE, p)]
        assert err.problems and not bad, f"problem lines without a path: {bad or '(none given)'}"
        return "refused"
    run_in_process(scenario, timeline, max_steps=max_steps)
    return "ran"
