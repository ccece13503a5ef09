"""The plume's compiled optical depth: the array formula it replaced, to the last bit, over random lines of sight."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from universe.camera.plume_depth import depth_outside

STEPS = 16


def tan_multiples(angle: np.ndarray, frac: np.ndarray) -> np.ndarray:
    """tan(frac[j] * angle) for equally spaced ``frac``, (cos, sin) rotated from the first multiple in equal steps."""
    step = (frac[1] - frac[0]) * angle
    c, s = np.cos(frac[0] * angle), np.sin(frac[0] * angle)
    cs, sn = np.cos(step), np.sin(step)
    out = np.empty((len(frac),) + angle.shape)
    for j in range(len(frac)):
        out[j] = s / c
        c, s = c * cs - s * sn, s * cs + c * sn
    return out


def test_tan_multiples_match_tan() -> None:
    """The rotation recurrence gives tan(frac_j * angle) for angles up to 89.9 deg."""
    angle = np.linspace(0.0, math.radians(89.9), 500)
    frac = (np.arange(8) + 0.5) / 8
    assert np.allclose(tan_multiples(angle, frac), np.tan(frac[:, None] * angle[None]), rtol=1e-9, atol=1e-12)


def reference_depth(b: np.ndarray, b_eff: np.ndarray, phi_max: np.ndarray, q_axis: np.ndarray, d_axis: np.ndarray,
                    t_c: np.ndarray, radius_m: float, c_out: float, ramp: float, scale: float) -> np.ndarray:
    """The whole-array NumPy formula: tangents by the rotation recurrence, samples stacked, summed over axis 0."""
    ell = b_eff[None] * tan_multiples(phi_max, (np.arange(STEPS // 2) + 0.5) / (STEPS // 2))
    rr = np.sqrt(b[None] * b[None] + ell * ell)
    inv_rr = 1.0 / np.maximum(rr, 1e-9)
    along = ell * d_axis[None]

    def in_cone(x: np.ndarray) -> np.ndarray:
        return np.clip((x - c_out) * ramp, 0.0, 1.0)

    weight = in_cone((q_axis[None] + along) * inv_rr) + in_cone((q_axis[None] - along) * inv_rr)
    inside = (weight * (rr >= radius_m)).sum(axis=0)
    tau = scale * inside * (2.0 * phi_max / STEPS) / b_eff
    return np.where(t_c > 0.0, tau, 0.0)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), rows=st.integers(1, 40), cols=st.integers(1, 40),
       half_angle_deg=st.floats(1.0, 85.0))
def test_depth_equals_the_array_formula_bit_for_bit(seed: int, rows: int, cols: int, half_angle_deg: float) -> None:
    """Every node's depth is the array formula's, to the last bit (rays through, beside and behind the source)."""
    rng = np.random.default_rng(seed)
    radius = rng.uniform(50.0, 500.0)
    big_r = radius * rng.uniform(1.1, 200.0)
    b = rng.uniform(0.0, 1.5 * big_r, (rows, cols))
    b_eff = np.maximum(b, 0.5 * radius)
    phi_max = np.arctan(np.sqrt(np.maximum(big_r * big_r - b * b, 0.0)) / b_eff)
    d_axis = rng.uniform(-1.0, 1.0, (rows, cols))
    q_axis = b * rng.uniform(-1.0, 1.0, (rows, cols))
    t_c = rng.uniform(-1e4, 1e5, (rows, cols))
    c_out = math.cos(math.radians(min(half_angle_deg + 5.0, 90.0)))
    c_in = math.cos(math.radians(max(half_angle_deg - 5.0, 0.0)))
    scale = rng.uniform(1.0, 1e4) / big_r
    frac = (np.arange(STEPS // 2) + 0.5) / (STEPS // 2)
    got = depth_outside(b, b_eff, phi_max, q_axis, d_axis, t_c, frac, radius, c_out, 1.0 / (c_in - c_out), scale,
                        STEPS)
    want = reference_depth(b, b_eff, phi_max, q_axis, d_axis, t_c, radius, c_out, 1.0 / (c_in - c_out), scale)
    assert got.dtype == want.dtype and got.shape == want.shape
    assert np.array_equal(got.view(np.uint64), want.view(np.uint64))


def test_depth_of_a_uniform_cone_through_its_axis_is_the_closed_form() -> None:
    """A line of sight through the cone's axis region, wholly inside the cone, away from the source: the sampled
    depth is scale * 2 phi_max / b (the 1/r^2 density integrated exactly by uniform steps in angle)."""
    b = np.array([[1000.0]])
    big_r = 20_000.0
    phi = np.arctan(np.sqrt(big_r**2 - b**2) / b)
    frac = (np.arange(STEPS // 2) + 0.5) / (STEPS // 2)
    # the cone's axis along the closest point: cos to the axis = b / r > c_out for every sample with c_out = -1
    tau = depth_outside(b, b, phi, b, np.zeros((1, 1)), np.ones((1, 1)), frac, 10.0, -1.0, 1e9, 3.0, STEPS)
    assert math.isclose(float(tau[0, 0]), 3.0 * 2.0 * float(phi[0, 0]) / 1000.0, rel_tol=1e-12)
