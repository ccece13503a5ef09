"""What a fault campaign writes beside its run folders: ``campaign.html`` (one row per scenario, with a link to each
run's report), ``campaign.junit.xml`` (one test case per scenario, one failure per unmet expectation, for CI
systems) and ``traceability.html`` (each requirement, the runs that verify it, the verdict)."""

from __future__ import annotations

import html
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass

from analysis.expectations import Verdict
from analysis.page import _CSS, _cells, _verdict
from scenario.requirements import Requirement


@dataclass(frozen=True)
class ScenarioOutcome:
    """One scenario of a campaign as it ran: its names, its faults, where its run folder is, and its verdict."""

    name: str
    file: str  # the scenario file's name in the campaign folder
    description: str
    faults: tuple[str, ...]  # "kind (wheel k) at t = s" of each injected fault
    run_dir: str  # relative to the campaign's output folder
    report: str | None  # report.html relative to the campaign's output folder (None: not written)
    verdict: Verdict
    verifies: tuple[str, ...]
    wall_s: float


def _page(title: str, body: list[str]) -> str:
    return "\n".join([f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>",
                      f"<style>{_CSS}</style></head><body><h1>{html.escape(title)}</h1>", *body, "</body></html>"])


def _link(target: str | None, text: str) -> str:
    return html.escape(text) if target is None else f"<a href='{html.escape(target)}'>{html.escape(text)}</a>"


def _latencies(v: Verdict) -> str:
    return "; ".join(f"{name} {'never' if t is None else f'{t:+.1f} s'}" for name, t in v.latencies.items()) or "-"


def campaign_html(title: str, outcomes: Sequence[ScenarioOutcome]) -> str:
    """The campaign page: a summary line, then one row per scenario (faults, each expectation with its figure, the
    detection latencies, the verdict, the link to its report)."""
    passed = sum(o.verdict.passed for o in outcomes)
    rows = []
    for o in outcomes:
        checks = "<br>".join(f"{'&#10003;' if c.passed else '&#10007;'} {html.escape(c.name)}: "
                             f"{html.escape(c.detail)}" for c in o.verdict.checks)
        rows.append(f"<tr><td>{_link(o.report, o.name)}<br><small>{html.escape(o.file)}</small></td>"
                    f"{_cells((o.description, '; '.join(o.faults) or 'none'))}<td>{checks}</td>"
                    f"{_cells((_latencies(o.verdict),))}{_verdict(o.verdict.passed)}"
                    f"{_cells((f'{o.wall_s:.0f} s',))}</tr>")
    head = "".join(f"<th>{h}</th>" for h in ("scenario (report)", "description", "faults injected",
                                             "expectations: figure", "detection latency", "verdict", "wall time"))
    body = [f"<p>{passed} of {len(outcomes)} scenarios pass every expectation. A detection latency is from the start of "
            "the scenario's first fault to the first expected event (true time).</p>",
            f"<table id='campaign'><tr>{head}</tr>{''.join(rows)}</table>"]
    return _page(title, body)


def junit_xml(suite: str, outcomes: Sequence[ScenarioOutcome]) -> str:
    """JUnit XML: one test case per scenario, one failure element per unmet expectation."""
    failures = sum(len(o.verdict.failures) for o in outcomes)
    root = ET.Element("testsuites", name=suite, tests=str(len(outcomes)), failures=str(failures))
    ts = ET.SubElement(root, "testsuite", name=suite, tests=str(len(outcomes)),
                       failures=str(sum(not o.verdict.passed for o in outcomes)), errors="0",
                       time=f"{sum(o.wall_s for o in outcomes):.1f}")
    for o in outcomes:
        tc = ET.SubElement(ts, "testcase", classname=suite, name=o.name, file=o.file, time=f"{o.wall_s:.1f}")
        for c in o.verdict.failures:
            f = ET.SubElement(tc, "failure", message=f"{c.name}: {c.detail}", type="ExpectationNotMet")
            f.text = f"{o.name}: expected {c.name}; got {c.detail}"
        out = ET.SubElement(tc, "system-out")
        out.text = "\n".join(f"{'PASS' if c.passed else 'FAIL'} {c.name}: {c.detail}" for c in o.verdict.checks)
    ET.indent(root)
    return ET.tostring(root, encoding="unicode", xml_declaration=True) + "\n"


def traceability_rows(requirements: Sequence[Requirement], outcomes: Sequence[ScenarioOutcome]
                      ) -> list[tuple[Requirement, list[ScenarioOutcome], bool | None]]:
    """Each requirement, the runs that verify it, and its verdict: every such run passed (None: no run verifies
    it)."""
    out = []
    for r in requirements:
        runs = [o for o in outcomes if r.id in o.verifies]
        out.append((r, runs, all(o.verdict.passed for o in runs) if runs else None))
    return out


def traceability_html(title: str, requirements: Sequence[Requirement], outcomes: Sequence[ScenarioOutcome]) -> str:
    """The requirements traceability matrix: requirement, source, verifying runs (linked), verdict."""
    rows = []
    for r, runs, ok in traceability_rows(requirements, outcomes):
        links = "<br>".join(f"{_link(o.report, o.name)} ({'pass' if o.verdict.passed else 'FAIL'})" for o in runs)
        rows.append(f"<tr>{_cells((r.id, r.text, r.source))}<td>{links or 'none'}</td>{_verdict(ok)}</tr>")
    head = "".join(f"<th>{h}</th>" for h in ("requirement", "text", "source", "verified by", "verdict"))
    unknown = sorted({i for o in outcomes for i in o.verifies} - {r.id for r in requirements})
    body = ["<p>A requirement passes when every run that verifies it passes all its expectations; NOT ASSESSED: no "
            "run of this campaign verifies it.</p>", f"<table id='traceability'><tr>{head}</tr>{''.join(rows)}</table>"]
    if unknown:
        body.append(f"<p class='missing'>Scenarios name requirements the file does not define: "
                    f"{html.escape(', '.join(unknown))}</p>")
    return _page(title, body)
