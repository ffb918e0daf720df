"""Exact discrete identities of the fluid operators on tiny grids."""

from __future__ import annotations

import numpy as np

from elastoflow.fluid import (
    DomainBoundaries,
    FluidSolver,
    divergence_faces_to_cells,
    gradient_cells_to_faces,
)
from elastoflow.grid import Grid2D
from elastoflow.linalg import apply_operator


def _matrices(nx: int, ny: int, h: float, ax: np.ndarray, ay: np.ndarray):
    """Dense matrices of div(A .) (cells x faces) and grad (faces x cells)."""
    n_u, n_v = (nx + 1) * ny, nx * (ny + 1)
    div = np.zeros((nx * ny, n_u + n_v))
    for k in range(n_u + n_v):
        w = np.zeros(n_u + n_v)
        w[k] = 1.0
        u, v = w[:n_u].reshape(nx + 1, ny), w[n_u:].reshape(nx, ny + 1)
        div[:, k] = divergence_faces_to_cells(u, v, h, ax, ay).ravel()
    grad = np.zeros((n_u + n_v, nx * ny))
    for k in range(nx * ny):
        p = np.zeros(nx * ny)
        p[k] = 1.0
        gx, gy = gradient_cells_to_faces(p.reshape(nx, ny), h)
        grad[:, k] = np.concatenate([gx.ravel(), gy.ravel()])
    return div, grad


def test_weighted_divergence_is_minus_transpose_of_weighted_gradient(rng):
    nx, ny, h = 5, 4, 0.3
    # Fractions below OPEN_MIN count as closed faces; keep the random weights above it.
    ax = rng.uniform(0.05, 1.0, (nx + 1, ny))
    ay = rng.uniform(0.05, 1.0, (nx, ny + 1))
    div, grad = _matrices(nx, ny, h, ax, ay)
    weights = np.concatenate([ax.ravel(), ay.ravel()])
    interior = np.concatenate([
        np.pad(np.ones((nx - 1, ny), dtype=bool), ((1, 1), (0, 0))).ravel(),
        np.pad(np.ones((nx, ny - 1), dtype=bool), ((0, 0), (1, 1))).ravel(),
    ])
    # On interior faces div(A .) = -(A grad)^T; side faces carry no gradient.
    np.testing.assert_array_equal(div[:, interior], -(weights[:, None] * grad).T[:, interior])
    assert not grad[~interior].any()


def test_pressure_operator_is_minus_h2_weighted_laplacian(rng, make_block):
    grid = Grid2D(12, 10, 0.25)
    solver = FluidSolver(grid, density=1.0, viscosity=0.0,
                         boundaries=DomainBoundaries.closed_box())
    interior = make_block(grid, 0.9, 0.8, 1.9, 1.6)
    p = rng.standard_normal(grid.shape_cells)
    for body in (None, interior):
        operator = solver.pressure_operator(body)
        gx, gy = gradient_cells_to_faces(p, grid.h)
        ax = None if body is None else body.open_fraction_x
        ay = None if body is None else body.open_fraction_y
        expected = -grid.h**2 * divergence_faces_to_cells(gx, gy, grid.h, ax, ay)
        np.testing.assert_allclose(apply_operator(operator, p), expected, rtol=0, atol=1e-12)
