"""iLQR's box-constrained QP (rmac_mj.solvers.ilqr)."""

from __future__ import annotations

import numpy as np
import pytest

from rmac_mj.solvers.ilqr import box_qp


@pytest.mark.parametrize("seed", range(6))
def test_box_qp_against_a_dense_search(seed):
    rng = np.random.default_rng(seed)
    root = rng.normal(size=(2, 2))
    hessian = root @ root.T + 0.1 * np.eye(2)
    gradient = rng.normal(size=2) * 3
    lower, upper = -rng.uniform(0.1, 1, 2), rng.uniform(0.1, 1, 2)
    d, free = box_qp(hessian, gradient, lower, upper)
    grid = np.stack(
        np.meshgrid(
            np.linspace(lower[0], upper[0], 401),
            np.linspace(lower[1], upper[1], 401),
            indexing="ij",
        ),
        axis=-1,
    ).reshape(-1, 2)
    values = 0.5 * np.einsum("ni,ij,nj->n", grid, hessian, grid) + grid @ gradient
    assert 0.5 * d @ hessian @ d + gradient @ d <= values.min() + 1e-12
    assert np.all(d >= lower) and np.all(d <= upper)
    np.testing.assert_array_equal(free, (d > lower) & (d < upper))
