"""Dispersions of a scenario for Monte Carlo campaigns: which fields vary, how, and run k's draw of them.

A scenario's ``dispersions:`` section lists entries, each naming a field by its path in the file (``universe.bodies.
orbit_phase_deg``; elements by index, ``obsw.inertia_kgm2[0][0]``) and one distribution:

- ``normal: {sigma, mean, truncate_sigma, relative}``: about the nominal value unless ``mean`` is given; with
  ``relative`` the value is nominal x (1 + N(0, sigma)); draws beyond ``truncate_sigma`` sigmas are drawn again;
- ``uniform: {low, high, relative}``: between the bounds, or nominal x (1 + U(low, high)) with ``relative``;
- ``direction: {sigma_deg, truncate_sigma}``: a 3-vector turned by an angle N(0, sigma_deg) about an axis
  perpendicular to it, uniform in azimuth (an approach direction, a boresight misalignment).

A vector field without an index gets one independent draw per component. An on-board or ground knowledge path
(``obsw.*`` of ``scenario.knowledge.KNOWLEDGE_PAIRS``), or a truth that the spacecraft knows, then differs from its
pair: the knowing path is added to ``knowledge_errors`` for that run, a deliberate miscalibration.

Run k of a campaign draws only from (campaign seed, k): ``numpy.random.SeedSequence([campaign_seed, k])`` spawns
the run's scenario seed and one stream per entry (by position, so adding an entry at the end never changes the
draws of the others). Any run is therefore rebuilt alone, by ``dispersed_run`` or from the scenario file it writes.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from pydantic import Field, model_validator

from contracts.model import Config
from scenario.knowledge import KNOWLEDGE_PAIRS

if TYPE_CHECKING:
    from scenario.model import Scenario

_TOKEN = re.compile(r"([A-Za-z_][A-Za-z0-9_]*)|\[(\d+)\]|(\.)")
MAX_REDRAWS = 1000  # a truncated normal redraws at most this often (a 0.01-sigma truncation still accepts 1 in 125)


class NormalDraw(Config):
    """A normal distribution, about the nominal value unless ``mean`` is given."""

    sigma: float = Field(gt=0, description="one-sigma spread, in the field's unit (a fraction with relative)")
    mean: float | None = Field(None, description="mean, in the field's unit (default: the nominal value)")
    truncate_sigma: float | None = Field(None, gt=0, description="draws beyond this many sigmas are drawn again")
    relative: bool = Field(False, description="the value is nominal x (1 + N(0, sigma))")

    @model_validator(mode="after")
    def _mean_or_relative(self) -> NormalDraw:
        if self.relative and self.mean is not None:
            raise ValueError("mean: a relative draw is centred on the nominal value; give mean or relative, not both")
        return self


class UniformDraw(Config):
    """A uniform distribution between two bounds."""

    low: float = Field(description="lower bound, in the field's unit (a fraction of the nominal with relative)")
    high: float = Field(description="upper bound, same unit as low")
    relative: bool = Field(False, description="the value is nominal x (1 + U(low, high))")

    @model_validator(mode="after")
    def _ordered(self) -> UniformDraw:
        if not self.high > self.low:
            raise ValueError(f"high: {self.high:g} must be above low {self.low:g}")
        return self


class DirectionDraw(Config):
    """A 3-vector turned away from its nominal direction by a normal angle, its length kept."""

    sigma_deg: float = Field(gt=0, description="one-sigma angle between the drawn and the nominal direction, deg")
    truncate_sigma: float | None = Field(None, gt=0, description="angles beyond this many sigmas are drawn again")


class Dispersion(Config):
    """One dispersed field: its path in the scenario file and exactly one distribution."""

    path: str = Field(min_length=1, description="the field's path, e.g. universe.bodies.orbit_phase_deg or "
                      "obsw.inertia_kgm2[0][0]")
    normal: NormalDraw | None = None
    uniform: UniformDraw | None = None
    direction: DirectionDraw | None = None

    @model_validator(mode="after")
    def _one_distribution(self) -> Dispersion:
        given = [k for k in ("normal", "uniform", "direction") if getattr(self, k) is not None]
        if len(given) != 1:
            raise ValueError(f"path {self.path!r}: give exactly one distribution (normal, uniform or direction), "
                             f"got {', '.join(given) or 'none'}")
        return self


class DispersionError(ValueError):
    """A dispersion that cannot apply to the scenario; the message opens with the entry's path in the file."""


def path_parts(path: str) -> list[str | int]:
    """The keys and indices of a path: ``obsw.inertia_kgm2[0][1]`` -> ['obsw', 'inertia_kgm2', 0, 1]."""
    parts: list[str | int] = []
    pos = 0
    expect_name = True
    for m in _TOKEN.finditer(path):
        if m.start() != pos:
            break
        name, index, dot = m.groups()
        if name is not None and expect_name:
            parts.append(name)
            expect_name = False
        elif index is not None and not expect_name:
            parts.append(int(index))
        elif dot is not None and not expect_name:
            expect_name = True
        else:
            break
        pos = m.end()
    if pos != len(path) or expect_name or not parts:
        raise DispersionError(f"{path!r} is not a field path (names joined by '.', indices as [n])")
    return parts


def _resolve(data: Any, path: str) -> tuple[Any, str | int]:
    """The container holding the field at ``path`` in a dumped scenario, and the field's key or index."""
    node: Any = data
    where = ""
    container, key = None, None
    for part in path_parts(path):
        at = where or "the scenario"
        if isinstance(part, str):
            if not isinstance(node, dict) or part not in node:
                fields = ", ".join(sorted(node)) if isinstance(node, dict) else "none: it is a value"
                raise DispersionError(f"{path!r}: {at} has no field {part!r} (fields: {fields})")
            where = f"{where}.{part}" if where else part
        else:
            if not isinstance(node, list) or part >= len(node):
                size = f"{len(node)} elements" if isinstance(node, list) else "no elements: it is not a list"
                raise DispersionError(f"{path!r}: {at} has no element [{part}] ({size})")
            where = f"{where}[{part}]"
        container, key, node = node, part, node[part]
    assert key is not None
    return container, key


def _is_number(x: Any) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def nominal_value(data: Any, d: Dispersion) -> float | int | list[float]:
    """The nominal value of a dispersion's field in a dumped scenario (0.0 for an unset optional number, which only
    an absolute draw may set); DispersionError if it cannot be dispersed."""
    if path_parts(d.path)[0] in ("seed", "dispersions"):
        raise DispersionError(f"{d.path!r}: not dispersable (each run draws its own seed from the campaign seed)")
    container, key = _resolve(data, d.path)
    value = container[key]
    if value is None:  # an optional field left out: only a draw that needs no nominal value can set it
        absolute = (d.normal is not None and d.normal.mean is not None) or (d.uniform is not None
                                                                            and not d.uniform.relative)
        if not absolute:
            raise DispersionError(f"{d.path!r}: unset (None), so there is no nominal value to draw about: give "
                                  "normal.mean, or uniform bounds without relative")
        return 0.0
    if _is_number(value):
        if d.direction is not None:
            raise DispersionError(f"{d.path!r}: a direction disperses a 3-vector, this field is a number")
        return value
    if isinstance(value, list) and value and all(_is_number(v) for v in value):
        if d.direction is not None and len(value) != 3:
            raise DispersionError(f"{d.path!r}: a direction disperses a 3-vector, this field has {len(value)} values")
        return list(value)
    if isinstance(value, dict):
        raise DispersionError(f"{d.path!r}: a section (fields: {', '.join(sorted(value))}), not a number")
    if isinstance(value, list) and value and all(isinstance(v, list) for v in value):
        raise DispersionError(f"{d.path!r}: a matrix: disperse its elements by index ({d.path}[0][0], ...)")
    raise DispersionError(f"{d.path!r}: {value!r} is not a number or a vector of numbers")


def _normal(rng: np.random.Generator, truncate: float | None) -> float:
    for _ in range(MAX_REDRAWS):
        z = float(rng.standard_normal())
        if truncate is None or abs(z) <= truncate:
            return z
    raise DispersionError(f"no normal draw within {truncate:g} sigma in {MAX_REDRAWS} tries")


def _scalar(d: Dispersion, nominal: float, rng: np.random.Generator) -> float:
    if d.normal is not None:
        n = d.normal
        z = _normal(rng, n.truncate_sigma)
        if n.relative:
            return nominal * (1.0 + n.sigma * z)
        return (nominal if n.mean is None else n.mean) + n.sigma * z
    assert d.uniform is not None
    u = d.uniform
    x = float(rng.uniform(u.low, u.high))
    return nominal * (1.0 + x) if u.relative else x


def turned(vector: list[float], angle_rad: float, azimuth_rad: float) -> list[float]:
    """``vector`` turned by ``angle_rad`` about the perpendicular axis at ``azimuth_rad`` around it (length kept)."""
    v = np.asarray(vector, dtype=float)
    norm = float(np.linalg.norm(v))
    e = v / norm
    ref = np.array([1.0, 0.0, 0.0]) if abs(e[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    p = np.cross(e, ref)
    p /= np.linalg.norm(p)
    q = np.cross(e, p)
    axis = math.cos(azimuth_rad) * p + math.sin(azimuth_rad) * q
    out = e * math.cos(angle_rad) + np.cross(axis, e) * math.sin(angle_rad)  # Rodrigues, axis perpendicular to e
    return [float(c) for c in norm * out]


def draw(d: Dispersion, nominal: float | int | list[float], rng: np.random.Generator
         ) -> tuple[float | int | list[float], dict[str, float]]:
    """The drawn value of one dispersion and its columns for the results (one per component; a direction also
    records the angle it turned, deg)."""
    if d.direction is not None:
        assert isinstance(nominal, list)
        angle = math.radians(d.direction.sigma_deg * _normal(rng, d.direction.truncate_sigma))
        value = turned(nominal, angle, float(rng.uniform(0.0, 2.0 * math.pi)))
        cols = {f"{d.path}[{i}]": c for i, c in enumerate(value)}
        cols[f"{d.path}.angle_deg"] = abs(math.degrees(angle))
        return value, cols
    if isinstance(nominal, list):
        value = [_scalar(d, float(c), rng) for c in nominal]
        return value, {f"{d.path}[{i}]": c for i, c in enumerate(value)}
    x = _scalar(d, float(nominal), rng)
    if isinstance(nominal, int):  # a count or a seed: the nearest whole number
        return int(round(x)), {d.path: float(round(x))}
    return x, {d.path: x}


def _touches(path: str, field_path: str) -> bool:
    """Whether a dispersion path is the field or inside it (``obsw.inertia_kgm2[0][0]`` touches obsw.inertia_kgm2)."""
    return path == field_path or path.startswith(field_path + "[") or path.startswith(field_path + ".")


def knowing_paths(paths: list[str]) -> list[str]:
    """The knowledge fields a set of dispersed paths makes differ from their pair (either side dispersed)."""
    return [known for known, true in KNOWLEDGE_PAIRS if any(_touches(p, known) or _touches(p, true) for p in paths)]


def dispersion_problems(scenario_data: dict[str, Any], dispersions: tuple[Dispersion, ...]) -> list[str]:
    """One 'dispersions[i].path: ...' line per entry that cannot apply to the dumped scenario, or that disperses a
    field another entry disperses too."""
    problems = []
    for i, d in enumerate(dispersions):
        try:
            nominal_value(scenario_data, d)
        except DispersionError as exc:
            problems.append(f"dispersions[{i}].path: {exc}")
            continue
        for j, other in enumerate(dispersions[:i]):
            if _touches(d.path, other.path) or _touches(other.path, d.path):
                problems.append(f"dispersions[{i}].path: {d.path!r} overlaps dispersions[{j}] {other.path!r}: "
                                "a field is dispersed once")
    return problems


def run_seeds(campaign_seed: int, k: int, n_dispersions: int) -> tuple[int, list[np.random.Generator]]:
    """Run k's scenario seed and one generator per dispersion entry, fixed by (campaign seed, k) only."""
    run_ss, draws_ss = np.random.SeedSequence([campaign_seed, k]).spawn(2)
    seed = int(run_ss.generate_state(1, dtype=np.uint32)[0])
    return seed, [np.random.default_rng(s) for s in draws_ss.spawn(n_dispersions)]


@dataclass(frozen=True)
class DispersedRun:
    """Run k of a campaign: its scenario (no dispersions left, seed and knowledge errors set) and drawn values."""

    k: int
    scenario: Scenario
    values: dict[str, float]


def drawn_values(base: Scenario, campaign_seed: int, k: int) -> tuple[int, dict[str, Any], dict[str, float]]:
    """Run k's seed, its scenario as a mapping (dispersions drawn from (campaign seed, k) and applied, not yet
    validated) and the drawn values by column."""
    data = base.model_dump(mode="json")
    seed, rngs = run_seeds(campaign_seed, k, len(base.dispersions))
    values: dict[str, float] = {}
    for d, rng in zip(base.dispersions, rngs, strict=True):
        value, cols = draw(d, nominal_value(data, d), rng)
        container, key = _resolve(data, d.path)
        container[key] = value
        values.update(cols)
    data["seed"] = seed
    data["name"] = f"{base.name}-run{k:05d}"
    data["description"] = f"run {k} of the Monte Carlo campaign of {base.name} (campaign seed {campaign_seed})"
    data["dispersions"] = []
    known = list(base.knowledge_errors)
    data["knowledge_errors"] = known + [p for p in knowing_paths([d.path for d in base.dispersions]) if p not in known]
    return seed, data, values


def dispersed_run(base: Scenario, campaign_seed: int, k: int) -> DispersedRun:
    """Run k of the campaign of ``base``: its dispersions drawn from (campaign seed, k), applied; raises
    ScenarioError (source 'run k') if the drawn values make an invalid scenario."""
    from scenario.model import scenario_from_dict

    _, data, values = drawn_values(base, campaign_seed, k)
    return DispersedRun(k, scenario_from_dict(data, f"run {k}"), values)
