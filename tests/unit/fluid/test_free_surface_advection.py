"""The free surface's MacCormack velocity advection: the semi-Lagrangian value where the
forward and backward steps do not see the same field (side ghosts, air)."""

from __future__ import annotations

import numpy as np
import pytest

from elastoflow.fluid import DomainBoundaries, FluidSolver, FreeSurfaceSolver, FreeSurfaceState
from elastoflow.grid import Grid2D


def _shear_onto_the_floor(fallback: str, liquid_top: float = 2.0,
                          ) -> tuple[FreeSurfaceState, np.ndarray, FreeSurfaceSolver]:
    """u growing with height, v uniform towards the no-slip floor; returns the state after
    one advection, the semi-Lagrangian result, and the solver."""
    grid = Grid2D(16, 16, 1.0 / 16)
    results = []
    for advection in ("semi_lagrangian", "maccormack"):
        fluid = FluidSolver(grid, density=1000.0, viscosity=0.0,
                            boundaries=DomainBoundaries.closed_box(), advection=advection)
        solver = FreeSurfaceSolver(fluid, maccormack_fallback=fallback)
        _, y = grid.cell_centers()
        state = solver.state(y - liquid_top)
        _, yu = grid.faces_x()
        state.fluid.velocity_x[...] = 1.0 + 4.0 * yu
        state.fluid.velocity_y[...] = -0.5
        solver.advect(state, 0.05)
        results.append((state, solver))
    return results[1][0], results[0][0].fluid.velocity_x, results[1][1]


def test_the_correction_is_dropped_where_the_backward_step_reads_the_floor() -> None:
    """Liquid moving down onto a no-slip floor: the backward step reads the floor's ghost
    (-u) in the lowest row, its forward step does not. The fluid's own MacCormack step
    ("none") makes those faces faster than the semi-Lagrangian step; with the fallback they
    keep the semi-Lagrangian value, and the rows above keep MacCormack's."""
    state, semi_lagrangian, _ = _shear_onto_the_floor("walls")
    inner = slice(6, 11)  # departures 4 cells left, arrivals 4 right: no side reached
    np.testing.assert_array_equal(state.fluid.velocity_x[inner, 0], semi_lagrangian[inner, 0])
    clamped, _, _ = _shear_onto_the_floor("none")
    assert np.all(clamped.fluid.velocity_x[inner, 0] > semi_lagrangian[inner, 0] + 1e-3)
    # Away from the floor the field is linear in y: MacCormack transports it exactly
    # (u(y + 0.5 dt)), where the semi-Lagrangian step's interpolation is exact too.
    np.testing.assert_allclose(state.fluid.velocity_x[inner, 4:-3],
                               clamped.fluid.velocity_x[inner, 4:-3], rtol=0, atol=1e-12)


def test_air_faces_keep_the_semi_lagrangian_value() -> None:
    """With "walls_and_air" the faces with no liquid on a side, and those whose forward
    stencil reads one, keep the semi-Lagrangian value; deep in the liquid nothing changes
    against "walls"."""
    state, semi_lagrangian, _ = _shear_onto_the_floor("walls_and_air", liquid_top=0.5)
    walls, _, _ = _shear_onto_the_floor("walls", liquid_top=0.5)
    u = state.fluid.velocity_x
    air_rows = slice(8, -1)   # cells 8.. are air (centres above 0.5 m)
    np.testing.assert_array_equal(u[6:11, air_rows], semi_lagrangian[6:11, air_rows])
    np.testing.assert_array_equal(u[6:11, 1:6], walls.fluid.velocity_x[6:11, 1:6])


def test_maccormack_fallback_is_checked() -> None:
    grid = Grid2D(8, 8, 1.0 / 8)
    fluid = FluidSolver(grid, density=1.0, viscosity=0.0,
                        boundaries=DomainBoundaries.closed_box(), advection="maccormack")
    with pytest.raises(ValueError, match="maccormack_fallback = 'air'"):
        FreeSurfaceSolver(fluid, maccormack_fallback="air")
