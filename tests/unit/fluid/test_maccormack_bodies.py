"""The cut-distance boundary treatment with MacCormack advection (the scene default): the
same guarantees the plain semi-Lagrangian scheme's tests in test_solver.py check."""

from __future__ import annotations

import numpy as np

from elastoflow.fluid import DomainBoundaries, FluidSolver, FluidState, WallFreeSlip
from elastoflow.grid import Grid2D


def _solver(grid: Grid2D) -> FluidSolver:
    return FluidSolver(grid, density=1.0, viscosity=0.0,
                       boundaries=DomainBoundaries(*(WallFreeSlip(),) * 4),
                       advection="maccormack")


def test_maccormack_keeps_flow_that_moves_with_the_body(make_block) -> None:
    # Every cut-distance ghost equals the body velocity, in the forward and the backward
    # pass: the correction is zero and the uniform field survives exactly.
    grid = Grid2D(24, 16, 0.1)
    interior = make_block(grid, 0.93, 0.51, 1.37, 1.02, velocity=(0.6, -0.25))
    state = FluidState.zeros(grid)
    state.velocity_x[...] = 0.6
    state.velocity_y[...] = -0.25
    _solver(grid).advect(state, 0.15, interior)
    np.testing.assert_allclose(state.velocity_x[1:-1], 0.6, rtol=0, atol=1e-14)
    np.testing.assert_allclose(state.velocity_y[:, 1:-1], -0.25, rtol=0, atol=1e-14)


def test_maccormack_does_not_leak_through_a_thin_plate(make_block) -> None:
    # A fixed plate thinner than a cell between the u points x = 0.9 and 1.0: what is
    # advected right of it must not depend on the velocity left of it (the backward pass
    # and the clamp read the same ghosts as the forward pass).
    grid = Grid2D(20, 10, 0.1)
    interior = make_block(grid, 0.93, -1.0, 0.97, 2.0)
    solver = _solver(grid)
    results = []
    for left_speed in (1.0, 5.0):
        state = FluidState.zeros(grid)
        state.velocity_x[:10] = left_speed
        state.velocity_x[10:] = 0.5
        solver.advect(state, 0.05, interior)
        results.append(state.velocity_x[10:].copy())
    np.testing.assert_array_equal(results[0], results[1])


def test_maccormack_dye_stays_out_of_a_body_and_in_range(make_block) -> None:
    grid = Grid2D(32, 32, 1.0 / 32)
    interior = make_block(grid, 0.4, 0.4, 0.6, 0.6)
    state = FluidState.zeros(grid)
    state.velocity_x[...] = 1.0
    x, y = grid.cell_centers()
    state.dye[...] = np.exp(-((x - 0.25) ** 2 + (y - 0.5) ** 2) / 0.08**2)
    solver = _solver(grid)
    for _ in range(10):
        solver.advect(state, 0.01, interior)
    assert np.all(state.dye[interior.solid_cells] == 0.0)
    assert state.dye.min() >= 0.0 and state.dye.max() <= 1.0
