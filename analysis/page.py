"""The report's HTML page: the requirements and C/A estimates tables on top, then one section per image or table,
self-contained (every image inlined as a base64 data URI)."""

from __future__ import annotations

import base64
import html
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from analysis.runfolder import RunData
from analysis.scoring import RunFigures
from analysis.telemetry import MODE_NAMES


@dataclass
class Section:
    """One section of the report: a title, what to read in it, an image (or why it is missing), notes."""

    title: str
    caption: str
    png: bytes | None = None
    file_name: str | None = None
    missing: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    html_body: str = ""


_CSS = """
body{font-family:system-ui,sans-serif;margin:1.5em auto;max-width:1100px;color:#222}
h1{font-size:1.5em}h2{font-size:1.2em;margin-top:1.6em;border-bottom:1px solid #ccc}
table{border-collapse:collapse;margin:.5em 0}td,th{border:1px solid #bbb;padding:.25em .6em;text-align:left}
th{background:#eee}.pass{background:#c8f0c8;font-weight:bold}.fail{background:#f5c0c0;font-weight:bold}
.na{background:#eee;color:#666;font-weight:bold}.missing{color:#a40;font-style:italic}
.caption{color:#555}img{max-width:100%;border:1px solid #ddd}
"""


def _verdict(passed: bool | None) -> str:
    if passed is None:
        return '<td class="na">NOT ASSESSED</td>'
    return '<td class="pass">PASS</td>' if passed else '<td class="fail">FAIL</td>'


def _cells(row: Sequence[Any]) -> str:
    return "".join(f"<td>{html.escape(str(c))}</td>" for c in row)


def html_table(head: Sequence[str], rows: Sequence[Sequence[Any]], table_id: str = "") -> str:
    """An HTML table of text cells (escaped) under a header row."""
    h = "".join(f"<th>{html.escape(str(c))}</th>" for c in head)
    attr = f' id="{table_id}"' if table_id else ""
    return f"<table{attr}><tr>{h}</tr>" + "".join(f"<tr>{_cells(r)}</tr>" for r in rows) + "</table>"


def html_list(items: Sequence[str], cls: str = "") -> str:
    """An HTML bullet list of text items (escaped); empty without items."""
    if not items:
        return ""
    attr = f' class="{cls}"' if cls else ""
    return f"<ul{attr}>" + "".join(f"<li>{html.escape(i)}</li>" for i in items) + "</ul>"


def requirements_table(figs: RunFigures) -> str:
    """The requirements table: requirement, threshold, this run's figure, verdict, source."""
    out = '<table id="requirements"><tr><th>requirement</th><th>threshold</th><th>this run</th><th>verdict</th>' \
          "<th>source</th></tr>"
    for r in figs.requirement_rows():
        out += (f"<tr>{_cells((r.requirement, r.threshold, r.figure))}{_verdict(r.passed)}"
                f"{_cells((r.source,))}</tr>")
    return out + "</table>"


def estimates_table(figs: RunFigures) -> str:
    """The on-board C/A estimates at C/A - estimate_before_ca_s minus the true C/A to Dimorphos and to the
    Didymos barycentre ("-" where the telemetry has none)."""
    rows = [(r.estimate, r.reference, r.time_text(), r.distance_text()) for r in figs.estimate_rows()]
    return html_table(("on-board estimate", "minus the true C/A to", "C/A time error, s", "C/A distance error, km"),
                      rows, "ca-estimates")


def report_html(title: str, figs: RunFigures, notes: list[str], missing: list[str], sections: list[Section]) -> str:
    """The self-contained HTML page: requirements and C/A estimates on top, then each section with its image."""
    top = ["<h2>Requirements</h2>", requirements_table(figs),
           f"<h2>C/A estimates at C/A-{figs.estimate_before_ca_s:g} s</h2>",
           "<p class='caption'>The on-board estimates of the closest approach standing then, minus the true "
           "closest approach to Dimorphos (the body the camera measures: the scored figures) and, for comparison, "
           "to the Didymos barycentre (the point ground's nominal trajectory describes).</p>",
           estimates_table(figs), html_list(notes)]
    if missing:
        top += ["<p class='missing'>This run is incomplete:</p>", html_list(missing, "missing")]
    return page_html(title, top, sections)


def page_html(title: str, top: list[str], sections: list[Section]) -> str:
    """A self-contained HTML page: the title, the ``top`` HTML parts, then each section with its image inlined."""
    parts = [f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>",
             f"<style>{_CSS}</style></head><body><h1>{html.escape(title)}</h1>", *top]
    for s in sections:
        parts.append(f"<h2>{html.escape(s.title)}</h2><p class='caption'>{html.escape(s.caption)}</p>")
        parts.append(html_list(s.missing, "missing"))
        if s.png is not None:
            uri = base64.b64encode(s.png).decode("ascii")
            parts.append(f"<img alt='{html.escape(s.title)}' src='data:image/png;base64,{uri}'>")
        parts.append(s.html_body)
        parts.append(html_list(s.notes))
    parts.append("</body></html>")
    return "\n".join(p for p in parts if p)


def counts_section(data: RunData, figs: RunFigures) -> Section:
    """Counts of packets, gaps, undecodable packets, frames and events, and the time-correlation line."""
    s = Section("Counts", "What arrived: telemetry packets and their gaps, frames, events; the ground's OBT-UTC fit.")
    tm, truth = data.telemetry, data.truth
    rows: list[tuple[str, Any]] = []
    if data.counts is not None:
        c = data.counts
        rows += [("packets archived", c.get("stored", 0)), ("undecodable", c.get("undecodable", 0)),
                 ("sequence gaps", c.get("gaps", 0)), ("packets missing in gaps", c.get("missing", 0)),
                 ("duplicates / late", f"{c.get('duplicates', 0)} / {c.get('late', 0)}"),
                 ("alarms (ground's log and summary say which)", c.get("alarms", 0))]
    elif tm is not None:
        s.missing.append("no archive.sqlite: counts from the packet stream, no sequence-gap analysis")
        rows += [("packets in " + tm.source, tm.packets), ("undecodable", tm.undecodable)]
    else:
        s.missing.append("no telemetry: no packet counts")
    if tm is not None:
        rows += [(f"TM[{svc},{sub}] {name}", n) for (svc, sub, name), n in sorted(tm.by_type.items())]
        rows += [("events (service 5)", len(tm.events)), ("mode changes", len(tm.mode_changes))]
    if truth is not None:
        rows += [("control periods of truth", len(truth)), ("camera frames exposed", int((truth.frame_id >= 0).sum()))]
    rows += [("frame PNGs saved", len(data.frames)), ("detections compared with truth", figs.centroid_count)]
    s.html_body = html_table(("what", "count"), rows)
    if data.summary_lines is None:
        s.missing.append("no summary.json: no time-correlation line")
    else:
        corr = [line for line in data.summary_lines if line.startswith("time correlation")]
        s.notes += corr or ["summary.json has no time-correlation line"]
        s.notes += [f"summary: {line}" for line in data.summary_lines if not line.startswith("time correlation")]
    return s


def events_section(data: RunData, ca_obt: float, limit: int = 60) -> Section:
    """The service 5 events, in time order (the first ``limit``)."""
    s = Section("Events", "On-board events (service 5): mode changes, target acquired or lost, faults, saturation.")
    tm = data.telemetry
    if tm is None or not tm.events:
        s.missing.append("no telemetry" if tm is None else "no event reports in the telemetry")
        return s
    rows = []
    for t, ev in sorted(tm.events, key=lambda e: e[0])[:limit]:
        fields = {k: v for k, v in ev.model_dump().items() if k != "severity"}
        detail = ", ".join(f"{k}={MODE_NAMES.get(v, v) if k.endswith('_mode') else v}" for k, v in fields.items())
        rows.append((f"{t - ca_obt:+.1f}", type(ev).__name__, ev.severity.name, detail))
    if len(tm.events) > limit:
        s.notes.append(f"{len(tm.events) - limit} later event(s) not listed")
    s.html_body = html_table(("t - C/A, s", "event", "severity", "detail"), rows)
    return s
