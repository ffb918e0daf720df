"""Exact discrete identities of the level-set free surface on tiny grids."""

from __future__ import annotations

import numpy as np
import pytest

from elastoflow.fluid import (
    DomainBoundaries,
    FluidSolver,
    FreeSurfaceSolver,
    FreeSurfaceState,
    GhostFluidProjection,
    LevelSetTransport,
    RedistanceFastSweeping,
    correct_volume,
    level_set_below,
    level_set_box,
    level_set_from_function,
    liquid_area,
)
from elastoflow.fluid import _level_set_kernels as kernels
from elastoflow.grid import Grid2D
from elastoflow.linalg import apply_operator


def _solver(grid: Grid2D, **options: object) -> FreeSurfaceSolver:
    fluid = FluidSolver(grid, density=1000.0, viscosity=0.0,
                        boundaries=DomainBoundaries.closed_box(), gravity=(0.0, -9.81),
                        advection="maccormack")
    return FreeSurfaceSolver(fluid, **options)  # type: ignore[arg-type]


def _dense(operator) -> np.ndarray:
    m, n = operator.shape
    columns = []
    for k in range(m * n):
        unit = np.zeros(m * n)
        unit[k] = 1.0
        columns.append(apply_operator(operator, unit.reshape(m, n)).ravel())
    return np.array(columns).T


def test_theta_weights_of_a_flat_surface() -> None:
    """A surface at y = 2.3 h: the top liquid cell (centre 1.5 h) is theta = 0.8 from it, so
    its diagonal is exactly 1 / 0.8; liquid cells couple with weight 1; air is inactive."""
    grid = Grid2D(4, 5, 0.1)
    phi = level_set_below(grid, 2.3 * grid.h)
    operator = _solver(grid).pressure_operator(phi)
    top = 1  # cells j = 0, 1 are liquid
    assert np.allclose(operator.diagonal[:, top], 1.0 / 0.8, rtol=0, atol=1e-14)
    assert np.all(operator.diagonal[:, 0] == 0.0)
    assert np.all(operator.diagonal[:, 2:] == 0.0)
    assert np.all(operator.weights_y[:, 0] == 1.0)
    assert np.all(operator.weights_y[:, 1:] == 0.0)
    assert np.all(operator.weights_x[:, :2] == 1.0)
    assert np.all(operator.weights_x[:, 2:] == 0.0)


def test_theta_is_clamped_below() -> None:
    grid = Grid2D(3, 4, 1.0)
    phi = level_set_below(grid, 1.5 + 1e-6)  # surface 1e-6 above the centre of row 1
    operator = GhostFluidProjection(theta_min=1e-3).operator(
        phi, (np.zeros((3, 4)), np.zeros((2, 4)), np.zeros((3, 3))))
    assert np.allclose(operator.diagonal[:, 1], 1e3)
    assert kernels.interface_fraction(-1e-9, 1.0, 1e-3) == 1e-3
    assert kernels.interface_fraction(-0.25, 0.75, 1e-3) == 0.25


def test_operator_is_symmetric_positive_definite_on_the_liquid() -> None:
    grid = Grid2D(6, 6, 1.0 / 6)
    phi = level_set_from_function(grid, lambda x, y: np.hypot(x - 0.45, y - 0.5) - 0.3)
    operator = _solver(grid).pressure_operator(phi)
    matrix = _dense(operator)
    liquid = (phi < 0.0).ravel()
    assert np.allclose(matrix, matrix.T)
    assert np.all(matrix[~liquid] == 0.0)
    eigenvalues = np.linalg.eigvalsh(matrix[np.ix_(liquid, liquid)])
    assert eigenvalues.min() > 0.0


@pytest.mark.parametrize("angle", [0.0, np.pi / 2, np.pi, 3 * np.pi / 2])
@pytest.mark.parametrize("offset", [0.41, 0.4, 0.4371])
def test_redistancing_keeps_a_signed_distance(angle: float, offset: float) -> None:
    """The signed distance of a surface along a grid line is a fixed point to round-off."""
    grid = Grid2D(20, 16, 0.05)
    nx_, ny_ = np.cos(angle), np.sin(angle)
    phi = level_set_from_function(grid, lambda x, y: (x - offset) * nx_ + (y - offset) * ny_)
    out = np.empty_like(phi)
    RedistanceFastSweeping(rounds=1).redistance(phi, grid.h, out,
                                                np.zeros(phi.shape, dtype=np.bool_))
    assert np.max(np.abs(out - phi)) < 1e-13


@pytest.mark.parametrize("angle", [0.3, np.pi / 4, 1.2, 2.5])
def test_redistancing_an_oblique_surface(angle: float) -> None:
    """An oblique straight surface: the cells next to it keep their values to round-off
    (their rescaling by the central-difference gradient is exact for a linear field); the
    others are exact where both upwind neighbours are, and off by up to ~h (0.8 h measured)
    in the domain's corners, where the distance to the part of the line inside the domain
    is not the infinite line's and the one-sided stencil at the domain's edge carries that
    inwards."""
    grid = Grid2D(20, 16, 0.05)
    nx_, ny_ = np.cos(angle), np.sin(angle)
    phi = level_set_from_function(grid, lambda x, y: (x - 0.52) * nx_ + (y - 0.41) * ny_)
    out = np.empty_like(phi)
    fixed = np.zeros(phi.shape, dtype=np.bool_)
    RedistanceFastSweeping(rounds=1).redistance(phi, grid.h, out, fixed)
    assert fixed.sum() > 20
    assert np.max(np.abs(out - phi)[fixed]) < 1e-13
    assert np.max(np.abs(out - phi)) < grid.h


def test_redistancing_rescales_a_stretched_level_set() -> None:
    """3 x (signed distance of a circle) becomes that distance again: exactly at the cells
    next to the surface up to the central differences' error, to first order elsewhere."""
    grid = Grid2D(40, 40, 1.0 / 40)
    distance = level_set_from_function(grid, lambda x, y: np.hypot(x - 0.5, y - 0.5) - 0.3)
    out = np.empty_like(distance)
    RedistanceFastSweeping().redistance(3.0 * distance, grid.h, out,
                                        np.zeros(distance.shape, dtype=np.bool_))
    assert np.all(np.sign(out) == np.sign(distance))
    near = np.abs(distance) < grid.h
    assert np.max(np.abs(out - distance)[near]) < 0.05 * grid.h
    assert np.max(np.abs(out - distance)) < 1.0 * grid.h


def test_redistancing_keeps_a_sheet_one_cell_thick() -> None:
    """A horizontal sheet of liquid 0.6 h thick around a row of cell centres (0.25 h below
    it, 0.35 h above): across it the central differences of phi nearly cancel (|grad phi| =
    0.05), and phi / |grad phi| alone made the row 5 h deep (the sheet thickened to a whole
    cell and more); bounded by the crossing distance (0.25 h) the row keeps its value and
    the sheet its area."""
    grid = Grid2D(12, 10, 0.1)
    _, y = grid.cell_centers()
    centre = (5 + 0.5) * grid.h
    phi = np.maximum(centre - 0.25 * grid.h - y, y - centre - 0.35 * grid.h)
    out = np.empty_like(phi)
    scratch = np.zeros(phi.shape, dtype=np.bool_)
    RedistanceFastSweeping().redistance(phi, grid.h, out, scratch)
    assert np.allclose(out[:, 5], -0.25 * grid.h, rtol=1e-12)
    assert liquid_area(out, grid.h) == pytest.approx(liquid_area(phi, grid.h), rel=1e-12)
    RedistanceFastSweeping(bound_by_crossings=False).redistance(phi, grid.h, out, scratch)
    assert np.allclose(out[:, 5], -5.0 * grid.h, rtol=1e-9)
    assert liquid_area(out, grid.h) > 1.3 * liquid_area(phi, grid.h)


def test_volume_correction_restores_the_area() -> None:
    grid = Grid2D(16, 16, 1.0 / 16)
    phi = level_set_from_function(grid, lambda x, y: np.hypot(x - 0.5, y - 0.4) - 0.25)
    target = liquid_area(phi, grid.h)
    phi += 0.37 * grid.h  # shrink the drop
    assert liquid_area(phi, grid.h) < target
    shift = correct_volume(phi, grid.h, target)
    assert abs(liquid_area(phi, grid.h) - target) <= 1e-14 * target
    assert shift == pytest.approx(-0.37 * grid.h, rel=0.2)


def test_liquid_area_of_a_flat_surface_is_exact() -> None:
    grid = Grid2D(8, 10, 0.1)
    assert liquid_area(level_set_below(grid, 0.437), grid.h) == pytest.approx(0.8 * 0.437,
                                                                              rel=1e-14)


def test_box_level_set_is_the_signed_distance() -> None:
    grid = Grid2D(10, 10, 0.1)
    phi = level_set_box(grid, (0.0, 0.0, 0.4, 0.6))  # in the lower-left corner: two surfaces
    x, y = grid.cell_centers()
    expected = np.where((x < 0.4) & (y < 0.6), np.maximum(x - 0.4, y - 0.6),
                        np.hypot(np.maximum(x - 0.4, 0), np.maximum(y - 0.6, 0)))
    assert np.allclose(phi, expected, atol=1e-15)


def test_advecting_a_flat_surface_along_itself_changes_nothing() -> None:
    """Bilinear sampling is exact for a linear field: a level set y - c carried by a uniform
    horizontal velocity is unchanged, by MacCormack and by the semi-Lagrangian step."""
    grid = Grid2D(12, 10, 0.1)
    for advection in ("maccormack", "semi_lagrangian"):
        solver = _solver(grid, transport=LevelSetTransport(advection=advection,
                                                           redistancing=None,
                                                           volume_correction=False))
        state = solver.state(level_set_below(grid, 0.43))
        before = state.level_set.copy()
        state.fluid.velocity_x[...] = 0.7
        from elastoflow.fluid._level_set import transport_level_set
        transport_level_set(solver.transport, grid, state.level_set, state.fluid.velocity_x,
                            state.fluid.velocity_y, 0.05, 0, None, solver.workspace.level_set)
        assert np.max(np.abs(state.level_set - before)) < 1e-14


def test_extrapolation_extends_a_constant() -> None:
    grid = Grid2D(8, 8, 0.1)
    phi = level_set_below(grid, 0.33)
    solver = _solver(grid, extrapolation_layers=3)
    state = solver.state(phi)
    state.fluid.velocity_x[...] = np.nan
    state.fluid.velocity_x[:, :4] = 0.25  # the liquid's rows (and one above, as faces)
    state.fluid.velocity_x[0, :] = 0.0
    state.fluid.velocity_x[-1, :] = 0.0
    valid_u = np.zeros(grid.shape_faces_x, dtype=np.int32)
    valid_u[1:-1, :4] = 1
    scratch = np.zeros((valid_u.size, 2), dtype=np.int64)
    kernels.extrapolate_faces(state.fluid.velocity_x, valid_u, 3, 0, scratch, scratch.copy())
    assert np.all(state.fluid.velocity_x[1:-1, :7] == 0.25)
    assert np.all(state.fluid.velocity_x[1:-1, 7:] == 0.0)  # beyond the layers
    assert np.all(state.fluid.velocity_x[[0, -1], :] == 0.0)  # walls untouched


def test_water_at_rest_stays_at_rest_with_hydrostatic_pressure() -> None:
    """A flat surface between cell centres: gravity on the faces is balanced by the ghost-fluid
    pressure, which is linear in y and so exact at every liquid cell."""
    grid = Grid2D(8, 12, 0.05)
    solver = _solver(grid)
    depth = 0.3 + 0.2 * grid.h
    state = solver.state(level_set_below(grid, depth))
    for index in range(20):
        report = solver.step(state, 2e-3, index * 2e-3)
    assert report.pressure_converged
    x, y = grid.cell_centers()
    liquid = state.level_set < 0.0
    hydrostatic = 1000.0 * 9.81 * (depth - y)
    assert np.max(np.abs(state.fluid.pressure - hydrostatic)[liquid]) < 1e-6 * 1000 * 9.81 * depth
    assert np.all(state.fluid.pressure[~liquid] == 0.0)
    # The first solve (from p = 0, to rtol 1e-6) leaves ~1e-6 of g dt; later ones start
    # from the hydrostatic pressure and add nothing.
    assert np.max(np.abs(state.fluid.velocity_y)) < 1e-7
    assert np.max(np.abs(state.level_set - (y - depth))) < 1e-9


def test_projection_leaves_the_liquid_divergence_free() -> None:
    grid = Grid2D(16, 16, 1.0 / 16)
    solver = _solver(grid)
    state = solver.state(level_set_from_function(
        grid, lambda x, y: np.minimum(y - 0.3 - 0.05 * np.cos(2 * np.pi * x),
                                      np.hypot(x - 0.5, y - 0.7) - 0.12)))
    rng = np.random.default_rng(3)
    state.fluid.velocity_x[1:-1] = rng.normal(size=(15, 16))
    state.fluid.velocity_y[:, 1:-1] = rng.normal(size=(16, 15))
    report = solver.projection.project(solver.fluid, state.fluid, state.level_set, 1e-3,
                                       solver.workspace)
    assert report.converged
    before = np.abs(rng.normal(size=(16, 16))).max()  # order 1 before the projection
    assert np.max(np.abs(solver.divergence(state))) * grid.h < 1e-5 * before


def test_checkpoint_round_trip_is_bit_exact() -> None:
    grid = Grid2D(10, 8, 0.1)
    solver = _solver(grid)
    state = solver.state(level_set_box(grid, (0.0, 0.0, 0.4, 0.5)))
    for index in range(3):
        solver.step(state, 5e-3, index * 5e-3)
    restored = FreeSurfaceState.from_arrays(state.to_arrays())
    twin = solver.state(level_set_box(grid, (0.0, 0.0, 0.4, 0.5)))
    twin.assign(restored)
    for target in (state, twin):
        solver.step(target, 5e-3, 0.015)
    assert np.array_equal(state.level_set, twin.level_set)
    assert np.array_equal(state.fluid.velocity_x, twin.fluid.velocity_x)
    assert np.array_equal(state.fluid.pressure, twin.fluid.pressure)
    assert state.step_index == twin.step_index == 4


def test_refuses_open_sides() -> None:
    from elastoflow.fluid import Outflow, WallNoSlip

    grid = Grid2D(4, 4, 0.25)
    fluid = FluidSolver(grid, density=1.0, viscosity=0.0,
                        boundaries=DomainBoundaries(WallNoSlip(), WallNoSlip(), WallNoSlip(),
                                                    Outflow()))
    with pytest.raises(ValueError, match="top side"):
        FreeSurfaceSolver(fluid)


def test_stress_free_ghosts_continue_a_shear_free_field() -> None:
    """u = -b y, v = b x has zero shear stress (du/dy + dv/dx = 0): the ghosts of the air
    faces above a flat surface continue it exactly; a pure shear u = a y is continued with
    zero normal gradient (the stress-free condition removes its shear)."""
    grid = Grid2D(6, 6, 0.1)
    phi = level_set_below(grid, 0.33)
    valid_u = np.zeros(grid.shape_faces_x, dtype=np.int32)
    valid_v = np.zeros(grid.shape_faces_y, dtype=np.int32)
    kernels.mark_liquid_faces(phi, valid_u, valid_v)
    xu, yu = grid.faces_x()
    xv, yv = grid.faces_y()
    ghost_u, ghost_v = np.zeros(grid.shape_faces_x), np.zeros(grid.shape_faces_y)
    u, v = -2.0 * yu, 2.0 * xv
    kernels.stress_free_ghosts(u, v, valid_u, valid_v, ghost_u, ghost_v)
    first_air = (valid_u == 0) & np.roll(valid_u == 1, 1, axis=1)
    first_air[[0, -1], :] = False
    assert first_air.sum() == 5
    assert np.allclose(ghost_u[first_air], u[first_air], atol=1e-14)
    shear = 3.0 * yu
    kernels.stress_free_ghosts(shear, np.zeros_like(v), valid_u, valid_v, ghost_u, ghost_v)
    below = np.roll(first_air, -1, axis=1)
    assert np.array_equal(ghost_u[first_air], shear[below])


def test_surface_pressure_moves_to_the_right_hand_side_exactly() -> None:
    """A uniform pressure P held by the surface and no flux: A p = (the Dirichlet terms of P)
    is solved by p = P on every liquid cell (the operator's rows sum to their 1/theta terms)."""
    grid = Grid2D(7, 6, 0.1)
    phi = level_set_from_function(grid, lambda x, y: np.hypot(x - 0.33, y - 0.28) - 0.21)
    operator = _solver(grid).pressure_operator(phi)
    surface = np.where(phi < 0.0, 250.0, 0.0)
    rhs = np.zeros(grid.shape_cells)
    kernels.add_surface_pressure(phi, surface, 1e-3, rhs)
    liquid = phi < 0.0
    assert np.allclose(apply_operator(operator, surface)[liquid], rhs[liquid], rtol=1e-13)


def test_a_tank_full_of_liquid_stays_full() -> None:
    """No surface anywhere: redistancing keeps phi (not an infinite distance), and the
    projection's operator is the closed box's singular one, solved with zero mean."""
    grid = Grid2D(8, 8, 0.125)
    solver = _solver(grid)
    state = solver.state(level_set_below(grid, 2.0))
    for index in range(3):
        report = solver.step(state, 1e-3, index * 1e-3)
    assert report.liquid_cells == 64
    assert np.all(np.isfinite(state.level_set))
    assert np.max(np.abs(state.fluid.velocity_y)) < 1e-7  # rtol 1e-6 of g dt
