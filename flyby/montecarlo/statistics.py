"""Statistics of a campaign: pass rates with exact binomial confidence intervals, empirical distributions, and the
dispersed values that drive a figure."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy import stats

from flyby.montecarlo.figures import REQUIREMENTS

CONFIDENCE = 0.95


def clopper_pearson(k: int, n: int, confidence: float = CONFIDENCE) -> tuple[float, float]:
    """The exact (Clopper-Pearson) two-sided interval of a binomial proportion of k successes in n trials:
    the alpha/2 quantile of Beta(k, n - k + 1) and the 1 - alpha/2 quantile of Beta(k + 1, n - k); 0 and 1 at the
    ends (Clopper and Pearson 1934)."""
    if not 0 <= k <= n or n < 1:
        raise ValueError(f"need 0 <= k <= n and n >= 1, got k={k}, n={n}")
    alpha = 1.0 - confidence
    low = 0.0 if k == 0 else float(stats.beta.ppf(alpha / 2, k, n - k + 1))
    high = 1.0 if k == n else float(stats.beta.ppf(1 - alpha / 2, k + 1, n - k))
    return low, high


@dataclass(frozen=True)
class PassRate:
    """How many runs met a requirement, of those assessed, with the interval of the rate."""

    requirement: str
    passed: int
    assessed: int
    low: float
    high: float

    @property
    def rate(self) -> float:
        """Fraction of assessed runs that passed."""
        return self.passed / self.assessed if self.assessed else float("nan")

    def verdict(self, goal: float) -> str:
        """Against a goal rate: met when the whole interval is at or above it, missed when it is all below."""
        if not self.assessed:
            return "not assessed"
        if self.low >= goal:
            return "met"
        if self.high < goal:
            return "missed"
        return "undecided: more runs needed"


def pass_rates(rows: list[dict[str, Any]]) -> list[PassRate]:
    """Per requirement, then all together, the pass rate over the runs (a run that raised counts as a failure of
    every requirement: it did not show it was met)."""
    out = []
    for req, _ in (*REQUIREMENTS, ("all", "")):
        col = "all_pass" if req == "all" else f"{req}_pass"
        verdicts = [0 if r["status"] != "ok" else r[col] for r in rows]
        assessed = [v for v in verdicts if v is not None]
        k, n = int(sum(assessed)), len(assessed)
        low, high = clopper_pearson(k, n) if n else (float("nan"), float("nan"))
        out.append(PassRate(req, k, n, low, high))
    return out


def ecdf(values: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The empirical CDF of the finite values: sorted values and the fraction at or below each."""
    x = np.sort(values[np.isfinite(values)])
    return x, np.arange(1, x.size + 1) / max(x.size, 1)


def drivers(figure: NDArray[np.float64], values: dict[str, NDArray[np.float64]], top: int = 3
            ) -> list[tuple[str, float]]:
    """The dispersed columns most associated with a figure: |Spearman rank correlation|, largest first (columns
    constant over the runs, or with fewer than 5 finite pairs, are skipped)."""
    out = []
    for name, x in values.items():
        ok = np.isfinite(figure) & np.isfinite(x)
        if ok.sum() < 5 or np.ptp(x[ok]) == 0 or np.ptp(figure[ok]) == 0:
            continue
        rho = float(stats.spearmanr(x[ok], figure[ok]).statistic)
        if np.isfinite(rho):
            out.append((name, rho))
    return sorted(out, key=lambda t: -abs(t[1]))[:top]
