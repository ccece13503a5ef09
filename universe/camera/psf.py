"""Optics and motion: a Gaussian point-spread function convolved with the line the image moves along in the
exposure (closed form), as kernels and as the blur of an image."""

from __future__ import annotations

import math

import cv2
import numpy as np
from scipy.special import erf


_POINT_SMEAR_PX = 1e-3  # smear lengths up to this (px) use the plain Gaussian


def smeared_psf(dx: np.ndarray, dy: np.ndarray, sigma_px: float, lx: np.ndarray, ly: np.ndarray) -> np.ndarray:
    """Unit-integral Gaussian PSF (sigma) convolved with a centred line segment (lx, ly) px, at offsets (dx, dy).

    Closed form: Gaussian across the segment times a difference of error functions along it.
    ``lx, ly`` broadcast against ``dx, dy`` (one segment per star, for instance).
    """
    length = np.hypot(lx, ly)
    safe = np.maximum(length, 1e-9)
    ex, ey = lx / safe, ly / safe
    s = dx * ex + dy * ey
    p = -dx * ey + dy * ex
    two_s2 = 2.0 * sigma_px * sigma_px
    point = np.exp(-(dx * dx + dy * dy) / two_s2) / (np.pi * two_s2)
    k = 1.0 / (math.sqrt(2.0) * sigma_px)
    line = (
        np.exp(-p * p / two_s2)
        / (math.sqrt(2.0 * np.pi) * sigma_px)
        * 0.5
        * (erf((s + 0.5 * length) * k) - erf((s - 0.5 * length) * k))
        / safe
    )
    return np.where(length > _POINT_SMEAR_PX, line, point)


def psf_half_size_px(sigma_px: float, smear_px: float) -> int:
    """Half-size of a kernel holding the PSF and its smear: 3.5 sigma (99.8 % of the light) beyond half the smear."""
    return int(math.ceil(3.5 * sigma_px + 0.5 * smear_px))


def psf_kernel(sigma_px: float, smear_px: tuple[float, float]) -> np.ndarray:
    """Odd square float32 kernel of the smeared PSF, centred, summing to 1."""
    h = psf_half_size_px(sigma_px, math.hypot(*smear_px))
    o = np.arange(-h, h + 1, dtype=np.float64)
    k = smeared_psf(o[None, :], o[:, None], sigma_px, np.float64(smear_px[0]), np.float64(smear_px[1]))
    return (k / k.sum()).astype(np.float32)


def blurred(image: np.ndarray, sigma_px: float, smear_px: tuple[float, float]) -> tuple[int, np.ndarray]:
    """``image`` convolved with the smeared PSF over itself grown by the kernel's half-size m: (m, result).

    Without smear, or with a smear along an image axis, the kernel is exactly separable (a Gaussian across the smear
    times the smeared Gaussian along it): two 1-D passes instead of one 2-D pass.
    """
    kernel = psf_kernel(sigma_px, smear_px)
    m = kernel.shape[0] // 2
    padded = cv2.copyMakeBorder(image, m, m, m, m, cv2.BORDER_CONSTANT, value=0.0)
    if min(abs(smear_px[0]), abs(smear_px[1])) <= _POINT_SMEAR_PX:
        # the kernel sums to 1, so it is the outer product of its row and column sums
        return m, cv2.sepFilter2D(padded, -1, kernel.sum(axis=0), kernel.sum(axis=1), borderType=cv2.BORDER_CONSTANT)
    return m, cv2.filter2D(padded, -1, kernel, borderType=cv2.BORDER_CONSTANT)

