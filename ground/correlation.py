"""Time correlation: a least-squares fit of on-board time (OBT) against UTC from the spacecraft's time reports.

Model: ``OBT = offset_s + (1 + drift) * utc_s``, with ``utc_s`` the seconds from the scenario epoch, ``offset_s``
the OBT at the epoch and ``drift`` the dimensionless rate error (1e-6 = 1 ppm). A time report carries the OBT
stamped on board when it was generated; ground knows when it received it and the one-way light time, so the
report was generated at ``received_utc_s - light_time_s``. The OBT stamps carry the noise (oscillator jitter,
stamping resolution); ground's UTC is taken as exact.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from pydantic import Field, field_validator

from contracts.errors import FlybyError
from contracts.model import Frozen


class CorrelationError(FlybyError):
    """Time reports cannot give a correlation (too few, all at one time, or an invalid value)."""


class TimeReport(Frozen):
    """One time report as ground sees it."""

    obt_s: float = Field(description="OBT stamped on board when the report was generated, s")
    received_utc_s: float = Field(description="UTC at which ground received the report, s from the epoch")
    light_time_s: float = Field(ge=0, description="one-way light time of the report, s")

    @field_validator("obt_s", "received_utc_s", "light_time_s")
    @classmethod
    def _is_finite(cls, v: float) -> float:
        if not math.isfinite(v):
            raise ValueError(f"must be a finite number, got {v}")
        return v

    @property
    def generated_utc_s(self) -> float:
        """UTC at which the report was generated on board, s from the epoch."""
        return self.received_utc_s - self.light_time_s


def _readonly(a: np.ndarray) -> np.ndarray:
    """A read-only float copy of ``a`` (a frozen correlation must not change under its users)."""
    out = np.array(a, dtype=float)
    out.setflags(write=False)
    return out


@dataclass(frozen=True)
class Correlation:
    """A linear OBT-UTC correlation with the covariance of its parameters.

    ``covariance`` is the 2x2 covariance of (offset_s [s], drift [1]). ``design_covariance`` is (X^T X)^-1 of the
    fit (the covariance per unit noise variance), kept for worst-case bounds; ``n_reports`` the reports fitted.
    """

    offset_s: float
    drift: float
    covariance: np.ndarray = field(default_factory=lambda: _readonly(np.zeros((2, 2))))
    design_covariance: np.ndarray = field(default_factory=lambda: _readonly(np.zeros((2, 2))))
    n_reports: int = 0
    residual_rms_s: float = 0.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.offset_s) and math.isfinite(self.drift)):
            raise CorrelationError(f"offset_s and drift must be finite, got {self.offset_s}, {self.drift}")
        if self.drift <= -1.0:
            raise CorrelationError(f"drift must be > -1 (OBT must advance with UTC), got {self.drift}")
        for name in ("covariance", "design_covariance"):
            a = _readonly(getattr(self, name))
            if a.shape != (2, 2):
                raise CorrelationError(f"{name} must be 2x2, got shape {a.shape}")
            object.__setattr__(self, name, a)

    @classmethod
    def exact(cls, offset_s: float, drift: float) -> Correlation:
        """A correlation known without error (e.g. the oscillator's own parameters)."""
        return cls(offset_s=offset_s, drift=drift)

    @property
    def drift_ppm(self) -> float:
        """Rate error, parts per million."""
        return self.drift * 1e6

    @property
    def offset_sigma_s(self) -> float:
        """One-sigma uncertainty of the offset, s."""
        return math.sqrt(self.covariance[0, 0])

    @property
    def drift_sigma_ppm(self) -> float:
        """One-sigma uncertainty of the drift, ppm."""
        return math.sqrt(self.covariance[1, 1]) * 1e6

    def to_obt(self, utc_s: float) -> float:
        """On-board time at ``utc_s`` (s from the epoch), s."""
        return self.offset_s + (1.0 + self.drift) * utc_s

    def to_utc(self, obt_s: float) -> float:
        """UTC (s from the epoch) at on-board time ``obt_s``: the inverse of ``to_obt``."""
        return (obt_s - self.offset_s) / (1.0 + self.drift)

    def obt_sigma_s(self, utc_s: float) -> float:
        """One-sigma uncertainty of ``to_obt(utc_s)``, s (grows away from the reports' span)."""
        g = np.array([1.0, utc_s])
        return math.sqrt(max(float(g @ self.covariance @ g), 0.0))

    def obt_error_bound_s(self, utc_s: float, envelope_s: float) -> float:
        """Worst-case error of ``to_obt(utc_s)`` if every report's OBT error is within +-``envelope_s``, s.

        The fitted value is a linear combination c.n of the report errors n with ||c||^2 = g^T (X^T X)^-1 g,
        so by Cauchy-Schwarz |c.n| <= envelope * sqrt(N * g^T (X^T X)^-1 g).
        """
        if envelope_s < 0:
            raise CorrelationError(f"envelope_s must be >= 0, got {envelope_s}")
        g = np.array([1.0, utc_s])
        return envelope_s * math.sqrt(self.n_reports * max(float(g @ self.design_covariance @ g), 0.0))

    def offset_error_bound_s(self, envelope_s: float) -> float:
        """Worst-case error of ``offset_s`` if every report's OBT error is within +-``envelope_s``, s."""
        return self.obt_error_bound_s(0.0, envelope_s)


def fitted_correlation(reports: Sequence[TimeReport], obt_sigma_s: float | None = None) -> Correlation:
    """Least-squares fit of OBT against UTC at generation.

    ``obt_sigma_s``: the one-sigma noise of the OBT stamps if known (covariance = sigma^2 (X^T X)^-1, needs two
    reports at distinct times); if None it is estimated from the residuals (needs three reports).
    """
    if obt_sigma_s is not None and not (math.isfinite(obt_sigma_s) and obt_sigma_s >= 0):
        raise CorrelationError(f"obt_sigma_s must be a finite number >= 0, got {obt_sigma_s}")
    needed = 2 if obt_sigma_s is not None else 3
    if len(reports) < needed:
        why = "" if obt_sigma_s is not None else " (the noise is estimated from the residuals)"
        raise CorrelationError(f"need at least {needed} time reports{why}, got {len(reports)}")
    utc = np.array([r.generated_utc_s for r in reports], dtype=float)
    # Fit OBT - UTC = offset + drift * UTC, so the small drift is computed directly, not as slope - 1.
    lag = np.array([r.obt_s for r in reports], dtype=float) - utc
    # Centre UTC so the normal equations stay well conditioned far from the epoch.
    t0 = float(utc.mean())
    dt = utc - t0
    sxx = float(dt @ dt)
    if sxx <= 0.0:
        raise CorrelationError(f"all {len(reports)} time reports were generated at one UTC ({t0} s); need a span")
    drift = float(dt @ (lag - lag.mean())) / sxx
    lag_t0 = float(lag.mean())
    residuals = lag - (lag_t0 + drift * dt)
    n = len(reports)
    rss = float(residuals @ residuals)
    variance = obt_sigma_s**2 if obt_sigma_s is not None else rss / (n - 2)
    # (X^T X)^-1 for parameters (value at t0, slope) is diag(1/n, 1/sxx); move it to (value at epoch, slope).
    jac = np.array([[1.0, -t0], [0.0, 1.0]])
    design = jac @ np.diag([1.0 / n, 1.0 / sxx]) @ jac.T
    return Correlation(
        offset_s=lag_t0 - drift * t0,
        drift=drift,
        covariance=variance * design,
        design_covariance=design,
        n_reports=n,
        residual_rms_s=math.sqrt(rss / n),
    )
