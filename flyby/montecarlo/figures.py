"""The figures of one Monte Carlo run: the report's own scoring (``analysis.scoring.score_run``) plus what the
campaign statistics need besides (detection latency, modes entered, events), as one flat row.

``FIGURES`` lists the numeric figures with their unit and, where a requirement bounds them, the requirement and
the side of the limit that passes; the results store's columns and the statistics report are derived from it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from analysis.runfolder import RunData
from analysis.scoring import RunFigures, score_run, window_start_obt_s
from contracts import pus
from ground.config import ReportConfig


@dataclass(frozen=True)
class Figure:
    """A numeric figure of a run: its column, label and unit; ``limit`` names the RunFigures field holding the
    requirement's threshold and ``passes`` the side of it that passes (None: not a requirement)."""

    name: str
    label: str
    unit: str
    limit: str | None = None
    passes: Literal["above", "below"] | None = None
    requirement: str | None = None


FIGURES: tuple[Figure, ...] = (
    Figure("in_view_fraction", "target in view", "fraction of frames", "in_view_required", "above", "in_view"),
    Figure("max_pointing_error_deg", "max pointing error", "deg", "pointing_limit_deg", "below", "pointing"),
    Figure("peak_rate_deg_s", "peak body rate", "deg/s", "peak_rate_required_deg_s", "above", "rate"),
    Figure("max_centroid_error_px", "worst Dimorphos centroid", "binned px", "centroid_tolerance_px", "below",
           "centroid"),
    Figure("centroid_count", "centroids compared", "frames"),
    Figure("ca_time_error_grid_s", "grid C/A time error", "s"),
    Figure("ca_distance_error_grid_km", "grid C/A distance error", "km"),
    Figure("ca_time_error_continuous_s", "continuous C/A time error", "s"),
    Figure("ca_distance_error_continuous_km", "continuous C/A distance error", "km"),
    Figure("detection_latency_s", "detection latency", "s"),
    Figure("mode_changes", "mode changes", "count"),
)
"""The numeric figures of a run, in report order."""

REQUIREMENTS: tuple[tuple[str, str], ...] = (
    ("in_view", "in_view_pass"), ("pointing", "pointing_pass"), ("rate", "rate_pass"), ("centroid", "centroid_pass"))
"""(requirement, RunFigures verdict field), in the order of the report's requirement table."""

LIMITS: tuple[str, ...] = tuple(f.limit for f in FIGURES if f.limit is not None)
EVENT_NAMES: tuple[str, ...] = tuple(sorted(cls.__name__ for cls in pus.DICTIONARY.events.values()))


def detection_latency_s(data: RunData) -> float | None:
    """OBT from the requirement window's start (the first frame of the first ACQUISITION, ``window_start_obt_s``)
    to the first TargetAcquiredEvent, s; None if either never came."""
    start = window_start_obt_s(data.telemetry, data.truth)
    if start is None or data.telemetry is None:
        return None
    acquired = [t for t, ev in data.telemetry.events if isinstance(ev, pus.TargetAcquiredEvent) and t >= start]
    return min(acquired) - start if acquired else None


def run_row(data: RunData, cfg: ReportConfig) -> tuple[dict[str, float | int | str | None], RunFigures]:
    """The figures, verdicts, thresholds, modes and event counts of a run, scored by ``score_run``."""
    figs, _ = score_run(data, cfg)
    tm = data.telemetry
    changes = [] if tm is None else [ev for _, ev in tm.mode_changes]
    row: dict[str, float | int | str | None] = {f.name: getattr(figs, f.name) for f in FIGURES
                                                if f.name in RunFigures.model_fields}
    row["detection_latency_s"] = detection_latency_s(data)
    row["mode_changes"] = len(changes)
    row["modes"] = ",".join(ev.to_mode.name for ev in changes)
    for name in LIMITS:
        row[name] = getattr(figs, name)
    for req, verdict in REQUIREMENTS:
        v = getattr(figs, verdict)
        row[f"{req}_pass"] = None if v is None else int(v)
    row["all_pass"] = int(figs.all_pass)
    counts = {n: 0 for n in EVENT_NAMES}
    for _, ev in [] if tm is None else tm.events:
        counts[type(ev).__name__] += 1
    for n, c in counts.items():
        row[f"events_{n}"] = c
    return row, figs
