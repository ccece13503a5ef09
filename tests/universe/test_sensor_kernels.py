"""The compiled sensor sampling gives the bits of the NumPy expressions it replaced, on the same drawn noise."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.numerics import assert_within_ulps
from universe.sensor_kernels import gyro_and_tachometers, star_tracker_q

_values = st.floats(-10.0, 10.0, allow_nan=False)


def _vector(n: int) -> st.SearchStrategy[np.ndarray]:
    return st.lists(_values, min_size=n, max_size=n).map(np.array)


@settings(max_examples=200, deadline=None)
@given(omega=_vector(3), speeds=_vector(4), bias=_vector(3), noise=_vector(10), step=_vector(3),
       stepped=st.booleans(), scales=st.lists(st.floats(0.0, 1e-2), min_size=3, max_size=3))
def test_the_gyro_and_tachometers_are_the_numpy_expressions(omega: np.ndarray, speeds: np.ndarray, bias: np.ndarray,
                                                            noise: np.ndarray, step: np.ndarray, stepped: bool,
                                                            scales: list[float]) -> None:
    """Bias walk, gyro (with and without a fault's step) and tachometers, bit for bit as NumPy computes them."""
    walk, white, wheel = scales
    expected_bias = bias + walk * noise[0:3]
    expected_gyro = omega + expected_bias + white * noise[3:6]
    if stepped:
        expected_gyro = expected_gyro + step
    expected_wheels = speeds + wheel * noise[6:]
    gyro, wheels = np.empty(3), np.empty(4)
    gyro_and_tachometers(omega, speeds, bias, noise, walk, white, wheel, step, stepped, gyro, wheels)
    assert bias.tobytes() == expected_bias.tobytes()
    assert gyro.tobytes() == expected_gyro.tobytes()
    assert wheels.tobytes() == expected_wheels.tobytes()


def _multiply(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    px, py, pz, pw = p
    qx, qy, qz, qw = q
    return np.array([pw * qx + px * qw + py * qz - pz * qy, pw * qy - px * qz + py * qw + pz * qx,
                     pw * qz + px * qy - py * qx + pz * qw, pw * qw - px * qx - py * qy - pz * qz])


def _from_rotvec(r: np.ndarray) -> np.ndarray:
    angle = math.sqrt(float(r.dot(r)))
    if angle < 1e-12:
        return np.array([0.5 * r[0], 0.5 * r[1], 0.5 * r[2], 1.0]) / math.sqrt(1.0 + 0.25 * angle**2)
    s = math.sin(0.5 * angle) / angle
    return np.array([s * r[0], s * r[1], s * r[2], math.cos(0.5 * angle)])


@settings(max_examples=200, deadline=None)
@given(q=_vector(4), bias=st.lists(st.floats(-1e-4, 1e-4), min_size=3, max_size=3).map(np.array),
       sigma=st.lists(st.floats(0.0, 1e-4), min_size=3, max_size=3).map(np.array), z=_vector(3))
def test_the_star_tracker_quaternion_is_the_numpy_expression(q: np.ndarray, bias: np.ndarray, sigma: np.ndarray,
                                                             z: np.ndarray) -> None:
    """True attitude times the rotation of bias + sigma z, normalised, as the NumPy code computed it (zero and tiny
    errors included), within 4 ulps of 1 (bit for bit where NumPy sums its small products in index order,
    ``tests.numerics``)."""
    q_true = q / np.linalg.norm(q) if np.linalg.norm(q) > 1e-3 else np.array([0.0, 0.0, 0.0, 1.0])
    product = _multiply(q_true, _from_rotvec(bias + sigma * z))
    expected = product / math.sqrt(float(product.dot(product)))
    out = np.empty(4)
    star_tracker_q(q_true, bias, sigma, z, out)
    assert_within_ulps(out, expected)
