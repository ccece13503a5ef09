"""Compiled algebra of 3-vectors and 3x3 matrices (Numba) for the control path's kernels (``obsw.tracking_kernels``,
``obsw.control_kernels``): products summed in index order, in double precision without fast-math."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a x b``."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


@njit(cache=True, nogil=True)
def matvec(a: np.ndarray, v: np.ndarray, transpose: bool) -> np.ndarray:
    """``a v`` (or ``a^T v``) of a 3x3 matrix and a 3-vector."""
    out = np.empty(3)
    for r in range(3):
        if transpose:
            out[r] = a[0, r] * v[0] + a[1, r] * v[1] + a[2, r] * v[2]
        else:
            out[r] = a[r, 0] * v[0] + a[r, 1] * v[1] + a[r, 2] * v[2]
    return out


@njit(cache=True, nogil=True)
def matmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a b`` of two 3x3 matrices."""
    out = np.empty((3, 3))
    for r in range(3):
        for s in range(3):
            out[r, s] = a[r, 0] * b[0, s] + a[r, 1] * b[1, s] + a[r, 2] * b[2, s]
    return out
