"""A real run through C/A: the summary ground wrote, figures.json and the report's tables say the same figures and
the same verdicts (one scoring function feeds them all), read back from their text as a user would."""

from __future__ import annotations

import json
import re
from html.parser import HTMLParser
from pathlib import Path

import pytest

from tests.integration.conftest import DATA, flyby

pytestmark = pytest.mark.integration

NUMBER = r"[-+]?\d+\.\d+"


@pytest.fixture(scope="module")
def ca_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The short slice through C/A, run once with the three nodes over Zenoh."""
    out = tmp_path_factory.mktemp("runs") / "short-ca"
    r = flyby("run", str(DATA / "short-ca.yaml"), "--out", str(out), timeout=300)
    assert r.returncode == 0, f"{r.stdout}\n{r.stderr}"
    return out


class Tables(HTMLParser):
    """Every table with an id: its rows as (cell text, cell class) lists."""

    def __init__(self) -> None:
        super().__init__()
        self.tables: dict[str, list[list[tuple[str, str]]]] = {}
        self._table: str | None = None
        self._cell: list[str] | None = None
        self._class = ""

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        a = dict(attrs)
        if tag == "table" and a.get("id"):
            self._table = a["id"]
            self.tables[self._table] = []
        elif tag == "tr" and self._table is not None:
            self.tables[self._table].append([])
        elif tag == "td" and self._table is not None:
            self._cell, self._class = [], a.get("class") or ""

    def handle_data(self, data: str) -> None:
        if self._cell is not None:
            self._cell.append(data)

    def handle_endtag(self, tag: str) -> None:
        if tag == "td" and self._cell is not None and self._table is not None:
            self.tables[self._table][-1].append(("".join(self._cell), self._class))
            self._cell = None
        elif tag == "table":
            self._table = None


def shown(text: str, value: float | None, scale: float = 1.0) -> None:
    """``text`` is ``value`` (times scale) as printed: equal to within half a unit of its last decimal."""
    assert value is not None, f"{text!r} printed for a missing figure"
    decimals = len(text.split(".")[1])
    assert abs(float(text) - scale * value) <= 0.5 * 10.0**-decimals + 1e-9, (text, value)


def test_summary_figures_json_and_report_agree(ca_run: Path) -> None:
    """Every figure and verdict of summary.json's lines is the one in figures.json and in the report's tables."""
    figs = json.loads((ca_run / "figures.json").read_text())
    lines = json.loads((ca_run / "summary.json").read_text())["lines"]
    parser = Tables()
    parser.feed((ca_run / "report.html").read_text())
    req = [row for row in parser.tables["requirements"] if row]
    est = [row for row in parser.tables["ca-estimates"] if row]

    # requirement figures: summary line, then the report's "this run" column, against figures.json
    line = next(x for x in lines if x.startswith("target in field of view:"))
    keys = (("in_view_fraction", 100.0), ("max_pointing_error_deg", 1.0), ("peak_rate_deg_s", 1.0),
            ("max_centroid_error_px", 1.0))
    summary_numbers = re.findall(NUMBER, line)
    for (key, scale), text, row in zip(keys, summary_numbers, req, strict=True):
        shown(text, figs[key], scale)
        (table_text,) = re.findall(NUMBER, row[2][0])
        shown(table_text, figs[key], scale)
        assert table_text == text
    assert f"over {figs['centroid_count']} frames" in line and f"over {figs['centroid_count']} frames" in req[3][2][0]

    # verdicts: summary line, the table's verdict cells, figures.json
    verdict_line = next(x for x in lines if x.startswith("requirements:"))
    said = dict(re.findall(r"(in view|pointing|rate|centroids) (PASS|FAIL|NOT ASSESSED)", verdict_line))
    names = ("in view", "pointing", "rate", "centroids")
    flags = ("in_view_pass", "pointing_pass", "rate_pass", "centroid_pass")
    word = {True: "PASS", False: "FAIL", None: "NOT ASSESSED"}
    for name, flag, row in zip(names, flags, req, strict=True):
        assert said[name] == word[figs[flag]] == row[3][0]
    assert verdict_line.startswith("requirements: all PASS") == all(figs[f] is True for f in flags)

    # C/A: the Dimorphos truth and the errors against it, summary line and report table
    ca_line = next(x for x in lines if x.startswith("C/A estimates"))
    obt, dist, grid_t, grid_d, cont_t, cont_d = re.findall(NUMBER, ca_line)
    shown(obt, figs["true_ca_obt_s"])
    shown(dist, figs["true_ca_distance_km"])
    rows = {(r[0][0], r[1][0]): (r[2][0], r[3][0]) for r in est}
    for (name, t_text, d_text), (t_key, d_key) in zip(
            (("grid", grid_t, grid_d), ("continuous", cont_t, cont_d)),
            (("ca_time_error_grid_s", "ca_distance_error_grid_km"),
             ("ca_time_error_continuous_s", "ca_distance_error_continuous_km")), strict=True):
        shown(t_text, figs[t_key])
        shown(d_text, figs[d_key])
        assert rows[name, "Dimorphos"] == (t_text, d_text)
        bary_t, bary_d = rows[name, "Didymos barycentre"]
        shown(bary_t, figs[t_key] + figs["true_ca_obt_s"] - figs["didymos_ca_obt_s"])
        shown(bary_d, figs[d_key] + figs["true_ca_distance_km"] - figs["didymos_ca_distance_km"])


def test_true_ca_is_the_closest_range_to_dimorphos(ca_run: Path) -> None:
    """The scored true C/A lies within one control period of the truth's smallest range to Dimorphos, no farther."""
    from analysis.truth import load_truth

    figs = json.loads((ca_run / "figures.json").read_text())
    truth = load_truth(ca_run / "truth.csv")
    i = int(truth.range_m.argmin())
    assert abs(truth.obt_s[i] - figs["true_ca_obt_s"]) <= 0.05 + 1e-9  # 10 Hz rows: the vertex is within half a step
    assert figs["true_ca_distance_km"] * 1e3 <= truth.range_m[i] <= figs["true_ca_distance_km"] * 1e3 + 2.0
