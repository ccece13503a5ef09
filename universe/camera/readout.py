"""Compiled detector readout: scene electrons and per-pixel normal codes to digital numbers, in one pass (Numba).

The camera's noise model (``universe.camera.detector``): a pixel holding ``s`` scene electrons (clamped at 0) reads
``offset + dark/g + (s + sqrt(s + dark + read^2) z) / g`` DN, rounded to nearest (ties to even) and clipped to
[0, max_dn], where ``z`` is the standard normal deviate of the pixel's 16-bit code. One fused loop reads each input
once and writes the frame once (the OpenCV element-wise passes it replaces made six passes over the frame).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True, inline="always")
def _dn(s: np.float32, z: np.float32, v0: np.float32, g: np.float32, b: np.float32, top: np.float32) -> np.uint16:
    """DN of a pixel of ``s`` electrons (clamped at 0) with the normal deviate ``z`` (single precision)."""
    s = max(s, np.float32(0.0))
    v = (s + np.sqrt(s + v0) * z) * g + b
    return np.uint16(np.rint(min(max(v, np.float32(0.0)), top)))


@njit(cache=True, nogil=True)
def digitise(
    signal_e: np.ndarray, codes: np.ndarray, quantiles: np.ndarray, var0: float, inv_g: float, bias: float,
    max_dn: int, out: np.ndarray,
) -> None:
    """Fill ``out`` (rows, cols) uint16 with the DN of pixels holding ``signal_e`` (rows, cols) float32 electrons
    whose normal deviates are ``quantiles[codes]`` (codes uint16); ``var0`` is dark + read noise variance (e-^2),
    ``inv_g`` the inverse gain (DN/e-), ``bias`` offset plus dark (DN)."""
    rows, cols = signal_e.shape
    # single precision throughout, as the frame is stored: half the cost of double-precision square roots; per row,
    # the deviates are gathered first so that the arithmetic loop has no table look-up and vectorises
    top = np.float32(max_dn)
    v0, g, b = np.float32(var0), np.float32(inv_g), np.float32(bias)
    z = np.empty(cols, dtype=np.float32)
    for i in range(rows):
        s_row, c_row, o_row = signal_e[i], codes[i], out[i]
        for j in range(cols):
            z[j] = quantiles[np.uint32(c_row[j])]
        for j in range(cols):
            o_row[j] = _dn(s_row[j], z[j], v0, g, b, top)


@njit(cache=True, nogil=True)
def digitise_dark(
    signal_e: np.ndarray, dark_e_s: np.ndarray, exposure_s: float, codes: np.ndarray, quantiles: np.ndarray,
    var0: float, inv_g: float, bias: float, max_dn: int, out: np.ndarray,
) -> None:
    """``digitise`` of ``signal_e`` plus each pixel's own dark charge ``dark_e_s * exposure_s`` (float32 (rows,
    cols) e-/s; the sum in single precision, as ``signal_e + dark_e_s * float32(exposure_s)`` in NumPy): a
    non-uniform dark current read in the same pass."""
    rows, cols = signal_e.shape
    top = np.float32(max_dn)
    v0, g, b, t = np.float32(var0), np.float32(inv_g), np.float32(bias), np.float32(exposure_s)
    z = np.empty(cols, dtype=np.float32)
    for i in range(rows):
        s_row, d_row, c_row, o_row = signal_e[i], dark_e_s[i], codes[i], out[i]
        for j in range(cols):
            z[j] = quantiles[np.uint32(c_row[j])]
        for j in range(cols):
            o_row[j] = _dn(s_row[j] + d_row[j] * t, z[j], v0, g, b, top)


@njit(cache=True, nogil=True)
def dark_frame(codes: np.ndarray, dn_of_code: np.ndarray, out: np.ndarray) -> None:
    """Fill ``out`` (rows, cols) uint16 with the DN of pixels without scene signal: ``dn_of_code`` (65536,) uint16
    looked up at each pixel's code (C-contiguous arrays; twice as fast as ``np.take``)."""
    flat_codes = codes.ravel()
    flat_out = out.ravel()
    for k in range(flat_codes.shape[0]):
        flat_out[k] = dn_of_code[np.uint32(flat_codes[k])]


def warm_up() -> None:
    """Compile (or load from the cache) the kernel now, for whole frames and for windows into them."""
    frame = np.zeros((4, 4), np.float32)
    codes = np.zeros((4, 4), np.uint16)
    quantiles = np.zeros(65536, np.float32)
    digitise(frame, codes, quantiles, 1.0, 1.0, 0.0, 4095, np.empty((4, 4), np.uint16))
    digitise(frame[1:3, 1:3], codes[1:3, 1:3], quantiles, 1.0, 1.0, 0.0, 4095, np.empty((2, 2), np.uint16))
    digitise_dark(frame, frame, 1.0, codes, quantiles, 1.0, 1.0, 0.0, 4095, np.empty((4, 4), np.uint16))
    dark_frame(codes, np.zeros(65536, np.uint16), np.empty((4, 4), np.uint16))
