"""The compiled readout turns electrons and normal codes into DN by the camera's noise model, pixel by pixel."""

from __future__ import annotations

import numpy as np
import pytest

from universe.camera import NORMAL_QUANTILES, normal_codes
from universe.camera.readout import dark_frame, digitise, digitise_dark


def reference_dn(signal_e: np.ndarray, codes: np.ndarray, var0: float, inv_g: float, bias: float, max_dn: int):
    """The model in double precision with NumPy: offset + (s + sqrt(s + var0) z) / g, rounded, clipped."""
    s = np.maximum(signal_e.astype(np.float64), 0.0)
    v = (s + np.sqrt(s + var0) * NORMAL_QUANTILES[codes].astype(np.float64)) * inv_g + bias
    return np.clip(np.rint(v), 0, max_dn)


@pytest.mark.parametrize("layout", ["full", "window"])
def test_digitise_matches_the_noise_model(layout: str) -> None:
    """Every pixel's DN is the model's, to one DN where single precision lands on the other side of a half."""
    rng = np.random.default_rng(7)
    signal = rng.uniform(-50.0, 60_000.0, (300, 400)).astype(np.float32)  # negative: clamped; bright: clipped
    codes = normal_codes(rng, signal.shape)
    var0, inv_g, bias, max_dn = 25.0 + 12.0**2, 1 / 9.0, 100.0 + 25.0 / 9.0, 4095
    if layout == "window":  # a view into a frame, as the camera passes the boxes holding bodies
        signal, codes = signal[20:250, 30:333], codes[20:250, 30:333]
    out = np.empty(signal.shape, dtype=np.uint16)
    digitise(signal, codes, NORMAL_QUANTILES, var0, inv_g, bias, max_dn, out)
    expected = reference_dn(signal, codes, var0, inv_g, bias, max_dn)
    diff = np.abs(out.astype(np.int64) - expected)
    assert diff.max() <= 1 and np.count_nonzero(diff) <= 1e-3 * diff.size
    assert out.max() == max_dn and out.min() > 0  # the brightest pixels saturate; the bias keeps dark ones above 0


def test_digitise_clips_at_zero_below_the_offset() -> None:
    """A negative total (large negative bias) reads 0 DN, never wraps around."""
    codes = np.zeros((4, 4), dtype=np.uint16)  # the most negative deviate
    out = np.empty((4, 4), dtype=np.uint16)
    digitise(np.zeros((4, 4), np.float32), codes, NORMAL_QUANTILES, 100.0, 1.0, 0.0, 4095, out)
    assert np.all(out == 0)


def test_digitise_dark_reads_the_dark_charge_with_the_signal() -> None:
    """A non-uniform dark current read in the pass equals the signal plus its dark charge (NumPy, single precision)
    digitised, bit for bit."""
    rng = np.random.default_rng(11)
    signal = rng.uniform(-20.0, 5_000.0, (200, 300)).astype(np.float32)
    dark = rng.lognormal(1.0, 0.5, signal.shape).astype(np.float32)
    codes = normal_codes(rng, signal.shape)
    args = (NORMAL_QUANTILES, 144.0, 1 / 9.0, 100.0, 4095)
    out, expected = np.empty(signal.shape, np.uint16), np.empty(signal.shape, np.uint16)
    digitise_dark(signal, dark, 0.37, codes, *args, out)
    digitise(signal + dark * np.float32(0.37), codes, *args, expected)
    assert np.array_equal(out, expected)
    assert not np.array_equal(out, _without_dark(signal, codes, args))  # the dark charge is read


def _without_dark(signal: np.ndarray, codes: np.ndarray, args: tuple) -> np.ndarray:
    """The same pixels digitised without their dark charge."""
    out = np.empty(signal.shape, np.uint16)
    digitise(signal, codes, *args, out)
    return out


def test_dark_frame_is_the_table_at_each_code() -> None:
    """Pixels without signal read the per-code DN table, as numpy's take would give."""
    rng = np.random.default_rng(3)
    codes = normal_codes(rng, (64, 96))
    table = rng.integers(0, 4096, 65536).astype(np.uint16)
    out = np.empty(codes.shape, dtype=np.uint16)
    dark_frame(codes, table, out)
    assert np.array_equal(out, np.take(table, codes))
