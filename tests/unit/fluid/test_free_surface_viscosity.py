"""The free surface's viscosity with the full stress tensor (`ViscosityStressFree`, form
"stress"): exact discrete identities on tiny grids."""

from __future__ import annotations

import numpy as np
import pytest

from elastoflow.fluid import (
    DomainBoundaries,
    FluidSolver,
    FreeSurfaceSolver,
    ViscosityStressFree,
    WallFreeSlip,
    WallMoving,
    WallNoSlip,
    level_set_below,
    level_set_from_function,
)
from elastoflow.fluid import _level_set_kernels as kernels
from elastoflow.grid import Grid2D


def _weights(phi: np.ndarray, h: float, slips=(1.0, 1.0, 1.0, 1.0)):
    nx, ny = phi.shape
    w_cell, w_node = np.zeros((nx, ny)), np.zeros((nx + 1, ny + 1))
    mass_u, mass_v = np.zeros((nx + 1, ny)), np.zeros((nx, ny + 1))
    kernels.stress_viscosity_weights(phi, h, *slips, 1e-3, w_cell, w_node, mass_u, mass_v)
    return w_cell, w_node, mass_u, mass_v


def _divergence_free(nx: int, ny: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """A discretely divergence-free face field from a stream function at the corners that
    is zero on the sides (so the walls' normal velocities are zero)."""
    psi = np.zeros((nx + 1, ny + 1))
    psi[1:-1, 1:-1] = np.random.default_rng(seed).normal(size=(nx - 1, ny - 1))
    return psi[:, 1:] - psi[:, :-1], -(psi[1:, :] - psi[:-1, :])


def _laplacian_no_slip(f: np.ndarray) -> np.ndarray:
    """Each component's 5-point Laplacian (times h^2) on a u-like array (nx+1, ny), the ends
    of the second index reflected (no-slip walls at rest); rows 0 and -1 left 0."""
    padded = np.pad(f, ((0, 0), (1, 1)))
    padded[:, 0], padded[:, -1] = -f[:, 0], -f[:, -1]
    out = np.zeros_like(f)
    out[1:-1] = (f[2:] + f[:-2] - 2 * f[1:-1]
                 + padded[1:-1, 2:] + padded[1:-1, :-2] - 2 * f[1:-1])
    return out


def test_full_stress_is_the_laplacian_of_a_divergence_free_field() -> None:
    """In a tank full of liquid (no-slip walls) the divergence of 2 e of a discretely
    divergence-free field is each component's Laplacian, to round-off, walls included."""
    nx, ny = 9, 7
    u, v = _divergence_free(nx, ny, 1)
    w_cell, w_node, _, _ = _weights(-10.0 * np.ones((nx, ny)), 1.0)
    gradient_u, gradient_v = np.zeros_like(u), np.zeros_like(v)
    kernels._strain_gradient(u, v, w_cell, w_node, np.zeros(4), gradient_u, gradient_v)
    assert np.max(np.abs(-gradient_u[1:-1] - _laplacian_no_slip(u)[1:-1])) < 1e-12
    assert np.max(np.abs(-gradient_v[:, 1:-1] - _laplacian_no_slip(v.T).T[:, 1:-1])) < 1e-12


def test_the_operator_is_symmetric_and_positive_on_a_surface() -> None:
    """x . K y = y . K x and x . K x >= 0 with the fractions of a wavy surface (the energy's
    Hessian), so conjugate gradients applies."""
    grid = Grid2D(10, 8, 0.1)
    phi = level_set_below(grid, lambda x: 0.41 + 0.1 * np.cos(2 * np.pi * x))
    w_cell, w_node, _, _ = _weights(phi, grid.h, (1.0, 0.0, 1.0, 0.0))
    rng = np.random.default_rng(2)
    x = (rng.normal(size=grid.shape_faces_x), rng.normal(size=grid.shape_faces_y))
    y = (rng.normal(size=grid.shape_faces_x), rng.normal(size=grid.shape_faces_y))
    kx = (np.zeros(grid.shape_faces_x), np.zeros(grid.shape_faces_y))
    ky = (np.zeros(grid.shape_faces_x), np.zeros(grid.shape_faces_y))
    kernels._strain_gradient(*x, w_cell, w_node, np.zeros(4), *kx)
    kernels._strain_gradient(*y, w_cell, w_node, np.zeros(4), *ky)

    def dot(a, b) -> float:
        return float(np.sum(a[0] * b[0]) + np.sum(a[1] * b[1]))

    assert dot(x, ky) == pytest.approx(dot(y, kx), rel=1e-12)
    assert dot(x, kx) > 0.0


def _viscous_solver(grid: Grid2D, boundaries: DomainBoundaries, viscosity: float = 0.5,
                    form: str = "stress") -> FreeSurfaceSolver:
    fluid = FluidSolver(grid, density=1.0, viscosity=viscosity, boundaries=boundaries,
                        gravity=(0.0, 0.0))
    return FreeSurfaceSolver(fluid, viscosity=ViscosityStressFree(form=form))


def test_a_rotating_drop_keeps_its_rigid_rotation() -> None:
    """A rigid rotation has no strain: the viscous step leaves a spinning drop's velocity
    unchanged on every face (air faces around it included), however large nu dt / h^2."""
    grid = Grid2D(16, 16, 1.0 / 16)
    solver = _viscous_solver(grid, DomainBoundaries.closed_box(), viscosity=2.0)
    state = solver.state(level_set_from_function(
        grid, lambda x, y: np.hypot(x - 0.5, y - 0.5) - 0.3))
    xu, yu = grid.faces_x()
    xv, yv = grid.faces_y()
    state.fluid.velocity_x[...] = -(yu - 0.5)
    state.fluid.velocity_y[...] = xv - 0.5
    before_u, before_v = state.fluid.velocity_x.copy(), state.fluid.velocity_y.copy()
    solver.viscosity.diffuse(solver.fluid, state.fluid, state.level_set, 0.01, solver.workspace)
    assert np.max(np.abs(state.fluid.velocity_x - before_u)) < 1e-12
    assert np.max(np.abs(state.fluid.velocity_y - before_v)) < 1e-12


def test_the_step_dissipates_and_converges() -> None:
    """A random liquid velocity under a flat surface: the solve reaches its tolerance, the
    kinetic energy falls, and the result satisfies the backward-Euler equations (checked
    with the operator, not the solver)."""
    grid = Grid2D(12, 10, 0.1)
    boundaries = DomainBoundaries(WallNoSlip(), WallFreeSlip(), WallMoving(0.3), WallNoSlip())
    solver = _viscous_solver(grid, boundaries)
    state = solver.state(level_set_below(grid, 0.57))
    rng = np.random.default_rng(4)
    u, v = state.fluid.velocity_x, state.fluid.velocity_y
    u[1:-1] = rng.normal(size=(11, 10))
    v[:, 1:-1] = rng.normal(size=(12, 9))
    old_u, old_v = u.copy(), v.copy()
    dt = 0.01
    iterations = solver.viscosity.diffuse(solver.fluid, state.fluid, state.level_set, dt,
                                          solver.workspace)
    assert 0 < iterations < 200
    w_cell, w_node, mass_u, mass_v, _ = solver.workspace.stress_arrays(grid)
    c = 0.5 * dt / grid.h ** 2
    gradient_u, gradient_v = np.zeros_like(u), np.zeros_like(v)
    kernels._strain_gradient(u, v, w_cell, w_node, np.array([0.0, 0.0, 0.3, 0.0]),
                             gradient_u, gradient_v)
    residual_u = np.where(mass_u >= 0.0, mass_u * (u - old_u) + c * gradient_u, 0.0)
    residual_v = np.where(mass_v >= 0.0, mass_v * (v - old_v) + c * gradient_v, 0.0)
    assert max(np.abs(residual_u).max(), np.abs(residual_v).max()) < 1e-6
    assert np.all(u[mass_u < 0.0] == old_u[mass_u < 0.0])
    energy = (np.sum(np.where(mass_u > 0, mass_u * u * u, 0.0))
              + np.sum(np.where(mass_v > 0, mass_v * v * v, 0.0)))
    energy_before = (np.sum(np.where(mass_u > 0, mass_u * old_u ** 2, 0.0))
                     + np.sum(np.where(mass_v > 0, mass_v * old_v ** 2, 0.0)))
    assert energy < 0.5 * energy_before


def test_form_is_checked() -> None:
    with pytest.raises(ValueError, match="form"):
        ViscosityStressFree(form="tensor")
