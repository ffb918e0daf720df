"""The ghost-fluid pressure solved on the liquid's bounding box: the whole grid's solution."""

from __future__ import annotations

import numpy as np
import pytest
from numba.np.ufunc import parallel

from elastoflow.fluid import (
    DomainBoundaries,
    FluidSolver,
    FreeSurfaceSolver,
    GhostFluidProjection,
    level_set_from_function,
)
from elastoflow.fluid import _level_set_kernels as kernels
from elastoflow.fluid._free_surface import LIQUID_BOX_QUANTUM, _rounded_range
from elastoflow.grid import Grid2D


@pytest.mark.parametrize("size", [7, 16, 40, 128, 256])
def test_the_rounded_range_holds_the_liquid_in_few_shapes(size: int) -> None:
    quantum = max(LIQUID_BOX_QUANTUM, -(-size // 4))
    widths = set()
    for low in range(size):
        for high in range(low + 1, size + 1):
            start, stop = _rounded_range(low, high, size)
            assert 0 <= start <= low and high <= stop <= size
            width = stop - start
            assert width == size or width % quantum == 0
            widths.add(width)
    assert len(widths) <= 4


def test_liquid_bounds() -> None:
    phi = np.ones((9, 7))
    assert kernels.liquid_bounds(phi) == (0, 0, 0, 0)
    phi[2, 5] = -1.0
    phi[6, 1] = -0.1
    assert kernels.liquid_bounds(phi) == (2, 7, 1, 6)


def _projected(liquid_box: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray, int,
                                          FreeSurfaceSolver]:
    """A drop and a pool, both off the grid's centre, in a 96 x 64 box, with a random
    velocity projected once."""
    # With a warm Numba cache, a cached kernel that can branch to a threaded one
    # (`pressure_rhs`) segfaulted when it was the process's first threaded call (the threads
    # not started yet); projecting before any step does that, so start them first.
    parallel._launch_threads()
    grid = Grid2D(96, 64, 1.0 / 64)
    fluid = FluidSolver(grid, density=1000.0, viscosity=0.0,
                        boundaries=DomainBoundaries.closed_box(), gravity=(0.0, -9.81))
    solver = FreeSurfaceSolver(fluid, projection=GhostFluidProjection(liquid_box=liquid_box))
    phi = level_set_from_function(
        grid, lambda x, y: np.minimum(np.hypot(x - 0.4, y - 0.33) - 0.1, y - 0.2))
    state = solver.state(phi)
    rng = np.random.default_rng(5)
    state.fluid.velocity_x[1:-1] = rng.standard_normal(state.fluid.velocity_x[1:-1].shape)
    state.fluid.velocity_y[:, 1:-1] = rng.standard_normal(state.fluid.velocity_y[:, 1:-1].shape)
    report = solver.projection.project(fluid, state.fluid, state.level_set, 1e-3,
                                       solver.workspace)
    return (state.fluid.pressure.copy(), state.fluid.velocity_x.copy(),
            solver.divergence(state), int(report.iterations), solver)


def test_the_box_solve_gives_the_whole_grid_solution() -> None:
    """The liquid spans 96 x 28 of 96 x 64 cells: solved on a 96 x 32 box, the pressure is
    the whole grid's to the solver's tolerance, 0 outside the box, and the liquid
    divergence-free."""
    whole, u_whole, _, _, _ = _projected(False)
    boxed, u_boxed, divergence, iterations, solver = _projected(True)
    assert list(solver.workspace.boxes) == [(96, 32)]
    assert 0 < iterations < 30
    scale = np.max(np.abs(whole))
    assert np.max(np.abs(boxed - whole)) < 1e-5 * scale
    assert np.max(np.abs(u_boxed - u_whole)) < 1e-5 * np.max(np.abs(u_whole))
    assert np.all(boxed[:, 32:] == 0.0)
    assert np.max(np.abs(divergence)) < 1e-4 * np.max(np.abs(u_whole)) * 64
