"""The operators as SciPy matrices: Lap = Div∘Grad on linear fields (thesis eq. 4.23–4.28)."""

import numpy as np
import pytest

import sphcover
from conftest import fibonacci_sphere

scipy = pytest.importorskip("scipy", reason="the operators are scipy.sparse matrices")


@pytest.fixture(scope="module")
def cover():
    points, normals = fibonacci_sphere(2000)
    return sphcover.cover(points, normals, eps=5e-3)


@pytest.mark.parametrize(
    "variant, mass, flux",
    [
        ("thesis", "thesis", "neighbour"),
        ("thesis", "moment", "central"),
        ("consistent", "thesis", "neighbour"),
    ],
)
def test_lap_is_div_of_grad_on_a_linear_field(cover, variant, mass, flux):
    ops = sphcover.operators(cover, variant=variant, mass=mass, flux=flux)
    n = len(cover)
    assert ops.grad.shape == (3 * n, n) and ops.div.shape == (n, 3 * n)
    assert ops.lap.shape == (n, n) and isinstance(ops.lap, scipy.sparse.csr_matrix)
    c = cover.centres
    u = c @ np.array([0.3, -1.2, 2.0]) + 0.7
    gradient = (ops.grad @ u).reshape(-1, 3)
    # The gradient of a linear field is exact wherever the neighbours span space.
    np.testing.assert_allclose(gradient, np.tile([0.3, -1.2, 2.0], (n, 1)), atol=1e-8)
    composed = ops.div @ (ops.grad @ u)
    lap = ops.lap @ u
    scale = max(np.abs(lap).max(), np.abs(composed).max(), 1.0)
    np.testing.assert_allclose(composed, lap, atol=1e-8 * scale)


def test_lap_of_a_constant_vanishes(cover):
    ops = sphcover.operators(cover)
    row_size = np.asarray(abs(ops.lap).sum(axis=1)).ravel()
    # Zero to the rounding of the row's sum (the diagonal is the negated sum of the row).
    assert np.all(np.abs(ops.lap @ np.ones(len(cover))) <= 1e-13 * row_size)


def test_unknown_variants_are_bad_input(cover):
    with pytest.raises(sphcover.BadInputError, match="variant"):
        sphcover.operators(cover, variant="exact")
