"""Checks of physical well-posedness shared by the configs of several nodes (each returns a problem or None)."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np


def inertia_problem(matrix: Sequence[Sequence[float]]) -> str | None:
    """Why ``matrix`` is not the inertia of a rigid body (3x3, symmetric, positive definite, principal moments
    obeying the triangle inequality), or None."""
    m = np.asarray(matrix, dtype=float)
    if m.shape != (3, 3):
        return f"must be 3x3, got {len(matrix)} row(s) of {[len(r) for r in matrix]}"
    if not np.allclose(m, m.T, rtol=1e-9, atol=1e-12):
        return f"must be symmetric, got {m.tolist()}"
    moments = np.linalg.eigvalsh(m)
    if moments[0] <= 0:
        return f"must be positive definite, principal moments {np.round(moments, 6).tolist()} kg m^2"
    a, b, c = moments
    if a + b < c * (1 - 1e-9):
        return f"principal moments {np.round(moments, 6).tolist()} kg m^2 break the triangle inequality (no body has them)"
    return None


def parallel_problem(a: Sequence[float], b: Sequence[float], what_a: str, min_angle_deg: float = 1.0) -> str | None:
    """A problem if vectors ``a`` and ``b`` are within ``min_angle_deg`` of parallel or antiparallel, else None."""
    va, vb = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    sin = float(np.linalg.norm(np.cross(va, vb)) / (np.linalg.norm(va) * np.linalg.norm(vb)))
    if sin < math.sin(math.radians(min_angle_deg)):
        return f"is {math.degrees(math.asin(min(sin, 1.0))):.3g} deg from parallel to {what_a}: at least " \
               f"{min_angle_deg:g} deg needed"
    return None
