"""Mutated scenarios and timelines either fail validation with a path or run without an exception."""

from __future__ import annotations

import tempfile
from pathlib import Path

from hypothesis import HealthCheck, given, settings

from tests.scenario.mutations import mutated_texts, outcome


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(texts=mutated_texts())
def test_a_mutated_input_is_refused_with_a_path_or_runs(texts: tuple[bytes, bytes, str]) -> None:
    """Whatever the mutation, the outcome is a clean refusal naming fields, or a run that goes through."""
    scenario_text, timeline_text, what = texts
    with tempfile.TemporaryDirectory() as d:
        try:
            outcome(Path(d), scenario_text, timeline_text)
        except Exception as exc:
            raise AssertionError(f"after {what}: {type(exc).__name__}: {exc}") from exc
