"""The coupling schemes take the fluid's BDF2 step (`FluidSolver.predict` then a projection
over its ``projection_dt``) exactly as `FluidSolver.step` does."""

from __future__ import annotations

import math

import numpy as np

from elastoflow import fluid
from elastoflow.grid import Grid2D
from elastoflow.simulation import Simulation


def _solver(grid: Grid2D) -> fluid.FluidSolver:
    boundaries = fluid.DomainBoundaries(left=fluid.Inflow(1.0), right=fluid.Outflow(),
                                        bottom=fluid.WallNoSlip(), top=fluid.WallNoSlip())
    return fluid.FluidSolver(grid, density=1.0, viscosity=1e-2, boundaries=boundaries,
                             advection="maccormack", viscosity_scheme="bdf2")


def _perturbed(grid: Grid2D) -> fluid.FluidState:
    state = fluid.FluidState.zeros(grid)
    xu, yu = grid.faces_x()
    state.velocity_x[...] = 1.0 + 0.1 * np.sin(2.0 * math.pi * xu) * np.sin(math.pi * yu)
    return state


def test_simulation_without_bodies_takes_the_fluid_solvers_bdf2_steps() -> None:
    grid = Grid2D(nx=32, ny=16, h=1.0 / 16)
    dt = 0.01
    direct_solver = _solver(grid)
    direct = _perturbed(grid)
    for index in range(6):
        direct_solver.step(direct, dt, index * dt)
    simulation = Simulation(grid, _solver(grid), dt=dt)
    simulation.state.fluid.velocity_x[...] = _perturbed(grid).velocity_x
    for _ in range(6):
        simulation.step()
    assert np.array_equal(simulation.state.fluid.velocity_x, direct.velocity_x)
    assert np.array_equal(simulation.state.fluid.velocity_y, direct.velocity_y)
    assert np.array_equal(simulation.state.fluid.pressure, direct.pressure)
    # The BDF2 history was used (the projection took 2 dt / 3 from the second step on):
    # backward Euler steps give other fields.
    plain = _perturbed(grid)
    solver = fluid.FluidSolver(grid, density=1.0, viscosity=1e-2,
                               boundaries=direct_solver.boundaries, advection="maccormack")
    for index in range(6):
        solver.step(plain, dt, index * dt)
    assert not np.allclose(plain.velocity_x, direct.velocity_x, rtol=0.0, atol=1e-9)
