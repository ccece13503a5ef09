"""On-board and ground knowledge against the truth: which scenario field knows which.

The flight software is built from ``obsw`` (what is on board) and the ground from ``ground``; the universe from
``universe`` (the truth). Each pair below names a fact that both sides hold. A scenario that leaves the knowing
side out gets the truth (a perfectly calibrated spacecraft); one that sets both differently must list the knowing
path under ``knowledge_errors``, so a typo never passes for a miscalibration.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

KNOWLEDGE_PAIRS: tuple[tuple[str, str], ...] = (
    ("obsw.control_period_s", "universe.control_period_s"),
    ("obsw.inertia_kgm2", "universe.spacecraft.inertia_kgm2"),
    ("obsw.wheels.layout", "universe.spacecraft.wheels.layout"),
    ("obsw.wheels.pyramid_angle_deg", "universe.spacecraft.wheels.pyramid_angle_deg"),
    ("obsw.wheels.max_torque_nm", "universe.spacecraft.wheels.max_torque_nm"),
    ("obsw.wheels.max_momentum_nms", "universe.spacecraft.wheels.max_momentum_nms"),
    ("obsw.wheels.inertia_kgm2", "universe.spacecraft.wheels.inertia_kgm2"),
    ("obsw.camera.fov_deg", "universe.camera.fov_deg"),
    ("obsw.camera.resolution_px", "universe.camera.resolution_px"),
    ("obsw.camera.bit_depth", "universe.camera.bit_depth"),
    ("obsw.camera.boresight_body", "universe.camera.boresight_body"),
    ("obsw.camera.exposure_s", "universe.camera.exposure_s"),
    ("obsw.camera.frame_period_s", "universe.camera.frame_period_s"),
    ("obsw.targets.didymos_diameter_m", "universe.bodies.didymos_diameter_m"),
    ("obsw.targets.dimorphos_diameter_m", "universe.bodies.dimorphos_diameter_m"),
    ("obsw.targets.orbit_radius_m", "universe.bodies.orbit_radius_m"),
    ("obsw.targets.sun_direction_inertial", "universe.bodies.sun_direction"),
    ("obsw.attitude.star_tracker_noise_arcsec", "universe.sensors.star_tracker.noise_arcsec"),
    ("obsw.attitude.gyro_arw_deg_sqrt_h", "universe.sensors.gyro.arw_deg_sqrt_h"),
    ("ground.link.one_way_light_time_s", "universe.link.one_way_light_time_s"),
    ("ground.link.downlink_rate_bps", "universe.link.downlink_rate_bps"),
    ("ground.link.uplink_rate_bps", "universe.link.uplink_rate_bps"),
)
"""(knowing path, true path) pairs."""

MUST_AGREE: tuple[tuple[str, str, str], ...] = (
    ("ground.apid", "obsw.apid", "ground addresses its telecommands to the on-board software's APID"),
)
"""Fields of two sections that must be equal for a run to work at all (never a knowledge error)."""


def get_path(data: Any, path: str) -> Any:
    """The value at a dotted path of nested mappings or models; KeyError if a part is missing."""
    node = data
    for part in path.split("."):
        if isinstance(node, Mapping):
            node = node[part]
        elif hasattr(node, part):
            node = getattr(node, part)
        else:
            raise KeyError(path)
    return node


def _has(data: Any, path: str) -> bool:
    try:
        get_path(data, path)
    except KeyError:
        return False
    return True


def fill_knowledge(raw: dict[str, Any]) -> dict[str, Any]:
    """A copy of a raw scenario mapping in which every knowing path that is absent takes its true value (only values
    the file gives; the models' defaults agree on both sides)."""
    out = _deep_copy(raw)
    for known, true in KNOWLEDGE_PAIRS:
        if _has(out, known) or not _has(out, true):
            continue
        node = out
        parts = known.split(".")
        for part in parts[:-1]:
            child = node.get(part)
            if child is None:
                child = node[part] = {}
            elif not isinstance(child, dict):
                break  # the section is malformed: the model's own validation reports it
            node = child
        else:
            node[parts[-1]] = get_path(out, true)
    return out


def filled_paths(raw: Any) -> set[str]:
    """The knowing paths that ``fill_knowledge`` copies from the truth for this raw mapping (an error in such a
    value is the truth's, already reported at the true path)."""
    if not isinstance(raw, dict):
        return set()
    return {known for known, true in KNOWLEDGE_PAIRS if not _has(raw, known) and _has(raw, true)}


def _deep_copy(x: Any) -> Any:
    if isinstance(x, dict):
        return {k: _deep_copy(v) for k, v in x.items()}
    if isinstance(x, list):
        return [_deep_copy(v) for v in x]
    return x


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, (tuple, list)) and isinstance(b, (tuple, list)):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    return bool(a == b)


def knowledge_problems(scenario: Any, declared: set[str]) -> list[str]:
    """One line per knowing field that differs from the truth without being declared, and per field of
    ``MUST_AGREE`` that differs; a declared path that names no knowledge pair is a problem too."""
    problems = []
    known_paths = {k for k, _ in KNOWLEDGE_PAIRS}
    for path in sorted(declared - known_paths):
        problems.append(f"knowledge_errors: {path!r} is not an on-board or ground knowledge field "
                        f"(known: {', '.join(sorted(known_paths))})")
    for known, true in KNOWLEDGE_PAIRS:
        a, b = get_path(scenario, known), get_path(scenario, true)
        if not _same(a, b) and known not in declared:
            problems.append(f"{known}: {a!r} differs from the truth {true} = {b!r}; list {known!r} under "
                            "knowledge_errors if the difference is meant")
    for left, right, why in MUST_AGREE:
        a, b = get_path(scenario, left), get_path(scenario, right)
        if not _same(a, b):
            problems.append(f"{left}: {a!r} differs from {right} = {b!r} ({why})")
    return problems
