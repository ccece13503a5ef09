"""The star-shaped asteroid surfaces: radius, irregularity, normals and their tables."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from universe.shapes import ShapeModel, fibonacci_sphere

SPHERE = ShapeModel(irregularity=0.0)


def test_zero_irregularity_unit_axes_is_a_sphere() -> None:
    """With no bumps and equal axes the radius is 1 everywhere and the normal is radial."""
    u = fibonacci_sphere(500)
    r, n = SPHERE.radius_and_normal(u)
    assert np.allclose(r, 1.0) and np.allclose(n, u)


def test_shape_irregularity_is_the_rms_radius_perturbation() -> None:
    """For equal axes, the RMS of r - 1 over the sphere equals the requested irregularity."""
    shape = ShapeModel(seed=5, irregularity=0.1)
    r = shape.radius(fibonacci_sphere(30000))
    assert np.sqrt(np.mean((r - 1.0) ** 2)) == pytest.approx(0.1, rel=0.03)
    assert r.min() >= shape.min_radius() and r.max() <= shape.max_radius()


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 1000), irr=st.floats(0.0, 0.2))
def test_shape_normal_is_orthogonal_to_the_surface(seed: int, irr: float) -> None:
    """The analytic normal is orthogonal to finite-difference tangents of the surface r(u) u."""
    shape = ShapeModel(seed=seed, irregularity=irr, axis_ratios=(1.2, 1.0, 0.9))
    u = fibonacci_sphere(50)
    u = u[np.abs(u[:, 2]) < 0.95]
    r, n = shape.radius_and_normal(u)
    t1 = np.cross(u, [0.0, 0.0, 1.0])
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(u, t1)
    eps = 1e-6
    for t in (t1, t2):
        ua = (u + eps * t) / np.linalg.norm(u + eps * t, axis=1, keepdims=True)
        ub = (u - eps * t) / np.linalg.norm(u - eps * t, axis=1, keepdims=True)
        tangent = shape.radius(ua)[:, None] * ua - shape.radius(ub)[:, None] * ub
        tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
        assert np.all(np.abs(np.sum(tangent * n, axis=1)) < 1e-5)


def test_shape_table_lookup_matches_direct_evaluation() -> None:
    """The interpolated table radius agrees with the analytic radius to 1e-3 of the mean radius."""
    shape = ShapeModel(seed=2, irregularity=0.12, axis_ratios=(1.1, 1.0, 0.95))
    u = fibonacci_sphere(5000)
    look = shape.lookup(u[:, 0].reshape(50, 100), u[:, 1].reshape(50, 100), u[:, 2].reshape(50, 100))
    assert np.max(np.abs(look[..., 0].ravel() - shape.radius(u))) < 1e-3


def test_each_direction_is_evaluated_as_if_alone() -> None:
    """A direction's radius and normal do not depend on how many directions are evaluated with it (the shape is
    evaluated in passes), to 1e-12 (the matrix products' rounding may differ in the last bit)."""
    shape = ShapeModel(seed=9, axis_ratios=(1.12, 1.0, 0.88))
    u = fibonacci_sphere(10_001)
    r, n = shape.radius_and_normal(u)
    for i in (0, 4095, 4096, 10_000):
        r1, n1 = shape.radius_and_normal(u[i:i + 1])
        assert abs(r1[0] - r[i]) <= 1e-12 and np.allclose(n1[0], n[i], rtol=0.0, atol=1e-12)
    grid = u.reshape(1, -1, 3)  # any leading shape is kept
    r2, n2 = shape.radius_and_normal(grid)
    assert r2.shape == (1, 10_001) and n2.shape == (1, 10_001, 3) and np.array_equal(r2[0], r)


def test_models_of_the_same_parameters_share_their_tables_and_nothing_else_does() -> None:
    """Equal parameters give the same cached table (built once); a different seed gives its own; shared arrays are
    read-only; a table served from the shared cache equals one built afresh with no cache."""
    import universe.shapes as shapes

    a = ShapeModel(seed=91, irregularity=0.1, axis_ratios=(1.2, 1.0, 0.9))
    b = ShapeModel(seed=91, irregularity=0.1, axis_ratios=(1.2, 1.0, 0.9))
    other = ShapeModel(seed=92, irregularity=0.1, axis_ratios=(1.2, 1.0, 0.9))
    assert a.surface_table() is b.surface_table()
    assert a.max_radius() == b.max_radius()
    assert other.surface_table() is not a.surface_table()
    assert not np.array_equal(other.surface_table(), a.surface_table())
    assert all(not arr.flags.writeable for arr in (*a._bumps, a.surface_table()))
    shared = a.surface_table()
    shapes._shared.clear()
    fresh = ShapeModel(seed=91, irregularity=0.1, axis_ratios=(1.2, 1.0, 0.9))
    assert fresh.surface_table() is not shared and np.array_equal(fresh.surface_table(), shared)


def test_the_shared_cache_keeps_a_bounded_number_of_parameter_sets() -> None:
    """Many distinct shapes (a campaign dispersing them) keep at most the bound's number of caches."""
    import universe.shapes as shapes

    for seed in range(3 * shapes._SHARED_MODELS):
        ShapeModel(seed=1000 + seed, irregularity=0.05).max_radius()
    assert len(shapes._shared) == shapes._SHARED_MODELS
