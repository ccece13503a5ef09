"""The statistics report of a campaign, ``DIR/mc.html``: pass rates with their 95 % intervals, the distribution of
every figure against its limit, the dispersed values that drive each requirement's figure, and the worst runs with
the commands that replay each alone (their scenario files are written into ``DIR/scenarios``).

Self-contained HTML (matplotlib Agg, images inlined), built from the results store only.
"""

from __future__ import annotations

import shlex
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure as MplFigure

from analysis.page import Section, html_list, html_table, page_html
from analysis.plots import LIMIT_COLOUR, png_bytes
from flyby.montecarlo.campaign import SCENARIOS_DIR, Campaign, write_run_scenario
from flyby.montecarlo.figures import FIGURES, REQUIREMENTS, Figure
from flyby.montecarlo.statistics import CONFIDENCE, PassRate, drivers, ecdf, pass_rates
from flyby.montecarlo.store import ResultStore

REPORT_NAME = "mc.html"
DPI = 90
WORST_PER_FIGURE = 3
LISTED_FAILURES = 25  # failing runs listed (and written as scenario files) at most
PASS_COLOUR, FAIL_COLOUR = "tab:blue", "tab:red"


@dataclass(frozen=True)
class CampaignTables:
    """The stored runs as arrays: one per figure, limit and dispersed column, aligned on ``runs``."""

    rows: list[dict[str, Any]]
    runs: np.ndarray
    ok: np.ndarray
    passed: np.ndarray
    values: dict[str, np.ndarray]

    @classmethod
    def of(cls, store: ResultStore) -> CampaignTables:
        """Read the store."""
        rows = store.rows()
        drawn = store.values()
        names = sorted({p for v in drawn.values() for p in v})
        runs = np.array([r["run"] for r in rows], dtype=np.int64)
        values = {n: np.array([drawn.get(int(k), {}).get(n, np.nan) for k in runs], dtype=float) for n in names}
        return cls(rows, runs, np.array([r["status"] == "ok" for r in rows], dtype=bool),
                   np.array([r["status"] == "ok" and r["all_pass"] == 1 for r in rows], dtype=bool), values)

    def column(self, name: str) -> np.ndarray:
        """A stored column as floats (NaN where missing)."""
        return np.array([np.nan if r.get(name) is None else float(r[name]) for r in self.rows], dtype=float)


def _new_figure(cols: int, height_in: float = 3.0) -> tuple[MplFigure, list]:
    fig = MplFigure(figsize=(10, height_in), layout="constrained")
    FigureCanvasAgg(fig)
    return fig, [fig.add_subplot(1, cols, i + 1) for i in range(cols)]


def _limit(t: CampaignTables, f: Figure) -> float | None:
    if f.limit is None:
        return None
    lim = t.column(f.limit)
    lim = lim[np.isfinite(lim)]
    return float(np.median(lim)) if lim.size else None


def distribution_section(t: CampaignTables, f: Figure) -> Section:
    """Histogram and empirical CDF of one figure over the completed runs, with its limit."""
    x = t.column(f.name)
    s = Section(f"{f.label} ({f.unit})", f"Distribution of {f.label} over the runs that completed"
                + (", with the requirement's limit (red)" if f.limit else "") + ".")
    finite = x[np.isfinite(x)]
    if finite.size == 0:
        s.missing.append("no run has this figure")
        return s
    fig, (ax_h, ax_c) = _new_figure(2)
    ax_h.hist(finite, bins=min(50, max(5, finite.size // 4)), color=PASS_COLOUR)
    ax_h.set_xlabel(f"{f.label}, {f.unit}")
    ax_h.set_ylabel("runs")
    xs, cdf = ecdf(finite)
    ax_c.step(np.r_[xs[0], xs], np.r_[0.0, cdf], where="post", color=PASS_COLOUR)
    ax_c.set_ylim(0.0, 1.02)
    ax_c.set_xlabel(f"{f.label}, {f.unit}")
    ax_c.set_ylabel("fraction of runs at or below")
    limit = _limit(t, f)
    if limit is not None:
        for ax in (ax_h, ax_c):
            ax.axvline(limit, color=LIMIT_COLOUR, linestyle="--", label=f"limit {limit:g}")
        ax_c.legend(loc="best")
        bad = finite < limit if f.passes == "above" else finite > limit
        s.notes.append(f"{int(bad.sum())} of {finite.size} runs beyond the limit {limit:g} {f.unit}")
    s.notes.append(f"median {np.median(finite):.4g}, 1 % {np.percentile(finite, 1):.4g}, 99 % "
                   f"{np.percentile(finite, 99):.4g}, min {finite.min():.4g}, max {finite.max():.4g} {f.unit}")
    s.png = png_bytes(fig, DPI)
    return s


def drivers_section(t: CampaignTables, f: Figure) -> Section:
    """The figure against the three dispersed values most rank-correlated with it."""
    x = t.column(f.name)
    s = Section(f"What drives {f.label}", f"{f.label} against the dispersed values with the largest |Spearman rank "
                "correlation| with it; red: runs that failed a requirement.")
    top = drivers(x, t.values)
    if not top:
        s.missing.append("no dispersed value varies with this figure (or the campaign disperses nothing)")
        return s
    fig, axes = _new_figure(len(top))
    limit = _limit(t, f)
    for ax, (name, rho) in zip(axes, top, strict=True):
        v = t.values[name]
        ax.scatter(v[t.passed], x[t.passed], s=6, color=PASS_COLOUR, label="passed")
        ax.scatter(v[~t.passed], x[~t.passed], s=10, color=FAIL_COLOUR, label="failed")
        if limit is not None:
            ax.axhline(limit, color=LIMIT_COLOUR, linestyle="--")
        ax.set_xlabel(name, fontsize=8)
        ax.set_ylabel(f"{f.label}, {f.unit}", fontsize=8)
        ax.set_title(f"rank correlation {rho:+.2f}", fontsize=9)
    s.png = png_bytes(fig, DPI)
    return s


def worst_runs(t: CampaignTables) -> list[tuple[int, str]]:
    """(run, why) of the runs worth replaying: those that raised, those that failed a requirement (at most
    LISTED_FAILURES of both), and the worst few of each requirement's figure."""
    out: dict[int, list[str]] = {}
    for r in t.rows:
        if len(out) >= LISTED_FAILURES:
            break
        if r["status"] != "ok":
            out.setdefault(r["run"], []).append("raised: " + (r["error"] or "").strip().splitlines()[-1][:160])
        elif r["all_pass"] != 1:
            failed = [req for req, _ in REQUIREMENTS if r[f"{req}_pass"] != 1]
            out.setdefault(r["run"], []).append("failed " + ", ".join(failed))
    for f in FIGURES:
        if f.passes is None:
            continue
        x = t.column(f.name)
        finite = x[np.isfinite(x)]
        if finite.size == 0 or finite.min() == finite.max():
            continue  # every run alike: none is worst
        order = np.argsort(x if f.passes == "above" else -x)  # NaN last either way
        for i in [i for i in order if np.isfinite(x[i])][:WORST_PER_FIGURE]:
            out.setdefault(int(t.runs[i]), []).append(f"{f.label} {x[i]:.4g} {f.unit}")
    return [(k, "; ".join(why)) for k, why in sorted(out.items())]


def rates_table(rates: list[PassRate], goal: float) -> str:
    """Per requirement: runs passing of those assessed, the rate, its interval, and the verdict against the goal."""
    rows = [(r.requirement, f"{r.passed} / {r.assessed}", f"{100 * r.rate:.2f} %",
             f"{100 * r.low:.2f} % .. {100 * r.high:.2f} %", r.verdict(goal)) for r in rates]
    return html_table(("requirement", "runs passing", "pass rate", f"{100 * CONFIDENCE:g} % interval "
                       "(Clopper-Pearson)", f"goal: at least {100 * goal:g} % of runs"), rows, "pass-rates")


def summary_rows(t: CampaignTables, meta: dict[str, str], campaign: Campaign) -> list[tuple[str, str]]:
    """The campaign's identity and speed, as (what, value) rows."""
    wall = t.column("wall_s")[t.ok]
    sim = t.column("sim_s")[t.ok]
    rtf = sim / wall if wall.size else np.array([])
    rows = [("scenario", campaign.scenario.name), ("campaign seed", str(campaign.seed)),
            ("fidelity", campaign.scenario.universe.fidelity),
            ("runs stored", f"{len(t.rows)} of {meta.get('runs', '?')} requested"),
            ("runs that raised", str(int((~t.ok).sum()))),
            ("dispersed values", str(len(campaign.scenario.dispersions)) + " entries, " + str(len(t.values))
             + " columns")]
    if wall.size:
        rows += [("wall time per run (median)", f"{np.median(wall):.2f} s"),
                 ("real-time factor per run (median)", f"{np.median(rtf):.1f} x (simulated s per wall s)")]
    if wall.size:
        rows.append(("runs per second per core",
                     f"{1 / np.mean(wall):.3f} (one over the mean wall time of a run on its worker)"))
    return rows


def write_report(folder: Path, store: ResultStore, campaign: Campaign, goal: float, shown_folder: str) -> Path:
    """Write ``folder/mc.html`` and the scenario files of the runs it lists; return the page's path.
    ``shown_folder`` is the campaign folder as the user named it, for the replay commands."""
    t = CampaignTables.of(store)
    meta = store.meta()
    rates = pass_rates(t.rows) if t.rows else []
    top = ["<h2>Campaign</h2>", html_table(("what", "value"), summary_rows(t, meta, campaign))]
    if rates:
        top += ["<h2>Requirements</h2>", "<p class='caption'>A run that raised counts as failing every requirement. "
                "The verdict is met when the whole interval is at or above the goal, missed when it is all below."
                "</p>", rates_table(rates, goal)]
    listed = worst_runs(t)
    scen_dir = folder / SCENARIOS_DIR
    q = shlex.quote
    rows = []
    for k, why in listed:
        path = write_run_scenario(campaign, k, scen_dir)
        rows.append((k, why, f"flyby mc --out {q(shown_folder)} --replay {k}",
                     f"flyby run {q(str(Path(shown_folder) / SCENARIOS_DIR / path.name))}"))
    if rows:
        top += ["<h2>Runs to look at</h2>", "<p class='caption'>Runs that raised or failed a requirement, and the "
                "worst of each requirement's figure. Each replays alone: in one process with its figures compared "
                "to the stored ones, or as a full three-node run of its scenario file.</p>",
                html_table(("run", "why", "replay in one process", "replay over Zenoh"), rows, "worst-runs")]
    if t.values:
        vrows = []
        for name, v in t.values.items():
            f = v[np.isfinite(v)]
            if f.size:
                vrows.append((name, f"{f.min():.8g}", f"{np.median(f):.8g}", f"{f.max():.8g}"))
        top += ["<h2>Dispersed values</h2>", html_table(("column", "min", "median", "max"), vrows, "dispersed")]
    sections = []
    for f in FIGURES:
        sections.append(distribution_section(t, f))
        if f.passes is not None:
            sections.append(drivers_section(t, f))
    errors = [r for r in t.rows if r["status"] != "ok"]
    if errors:
        s = Section("Runs that raised", "Each run's last traceback line; the full traceback is in the results store "
                    "(runs.error).")
        s.html_body = html_list([f"run {r['run']}: " + (r["error"] or "").strip().splitlines()[-1]
                                 for r in errors[:LISTED_FAILURES]])
        sections.append(s)
    page = folder / REPORT_NAME
    page.write_text(page_html(f"Monte Carlo campaign of {campaign.scenario.name}", top, sections),
                    encoding="utf-8")
    return page
