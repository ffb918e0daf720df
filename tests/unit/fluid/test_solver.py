"""Projection, advection, viscosity and body hooks of FluidSolver on small grids."""

from __future__ import annotations

import numpy as np
import pytest

from elastoflow.fluid import (
    DomainBoundaries,
    FluidSolver,
    FluidState,
    Inflow,
    Jet,
    Outflow,
    WallFreeSlip,
    WallMoving,
    WallNoSlip,
)
from elastoflow.grid import Grid2D
from elastoflow.linalg import PoissonSolverJacobi, PoissonSolverMGPCG

CLOSED = DomainBoundaries.closed_box()
CHANNEL = DomainBoundaries(left=Inflow(1.0), right=Outflow(), bottom=WallFreeSlip(),
                           top=WallFreeSlip())


def _random_state(grid: Grid2D, rng: np.random.Generator) -> FluidState:
    state = FluidState.zeros(grid)
    state.velocity_x[...] = rng.standard_normal(grid.shape_faces_x)
    state.velocity_y[...] = rng.standard_normal(grid.shape_faces_y)
    return state


@pytest.mark.parametrize("incremental", [False, True])
@pytest.mark.parametrize("boundaries", [CLOSED, CHANNEL], ids=["closed", "channel"])
def test_projection_removes_divergence(rng, boundaries, incremental):
    grid = Grid2D(24, 20, 0.05)
    solver = FluidSolver(grid, density=1000.0, viscosity=1e-3, boundaries=boundaries,
                         pressure_solver=PoissonSolverMGPCG(rtol=1e-10, max_iterations=500),
                         incremental_pressure=incremental)
    state = _random_state(grid, rng)
    state.pressure[...] = rng.standard_normal(grid.shape_cells)
    solver.apply_side_values(state, 1.0)
    before = np.abs(solver.divergence(state)).max()
    report = solver.project(state, 0.01)
    after = np.abs(solver.divergence(state)).max()
    assert report.converged
    assert after < 1e-8 * before


def test_incremental_pressure_matches_plain_pressure(rng):
    # Same divergent field, once solved for the whole pressure and once for the increment
    # over a previous pressure: the projected velocity and final pressure (up to the constant
    # of the closed box) must agree.
    grid = Grid2D(16, 12, 0.1)
    results = []
    previous = rng.standard_normal(grid.shape_cells)
    field = _random_state(grid, rng)
    for incremental in (False, True):
        solver = FluidSolver(grid, density=2.0, viscosity=0.0, boundaries=CLOSED,
                             pressure_solver=PoissonSolverMGPCG(rtol=1e-11, max_iterations=500),
                             incremental_pressure=incremental)
        state = FluidState(field.velocity_x.copy(), field.velocity_y.copy(), previous.copy(),
                           np.zeros(grid.shape_cells))
        solver.diffuse(state, 0.05)
        solver.apply_side_values(state, 0.0)
        solver.project(state, 0.05)
        results.append(state)
    np.testing.assert_allclose(results[0].velocity_x, results[1].velocity_x, atol=1e-9)
    np.testing.assert_allclose(results[0].velocity_y, results[1].velocity_y, atol=1e-9)
    pressures = [r.pressure - r.pressure.mean() for r in results]
    np.testing.assert_allclose(pressures[0], pressures[1], atol=1e-8)


@pytest.mark.parametrize("incremental", [False, True])
def test_water_at_rest_between_viscous_walls_stays_at_rest(incremental):
    """Gravity and the pressure gradient must meet in the same phase: the plain form adds
    gravity after the viscosity (the projection then takes it out whole); the incremental
    form subtracts the last pressure gradient before it, so gravity goes there too (with it
    after the viscosity the no-slip walls held back part of the uniform upward correction
    and the water started to flow along the side walls: 0.016 m/s after 5 steps at
    nu = 1e-2 in this box; 3e-11 m/s after 60 steps now). The first step, with no pressure
    yet, is the plain one."""
    grid = Grid2D(32, 32, 4.0 / 32)
    solver = FluidSolver(grid, density=1000.0, viscosity=1e-2, boundaries=CLOSED,
                         gravity=(0.0, -9.81), incremental_pressure=incremental)
    state = FluidState.zeros(grid)
    for k in range(20):
        solver.step(state, 0.01, 0.01 * k)
    assert np.abs(state.velocity_x).max() < 1e-6
    assert np.abs(state.velocity_y).max() < 1e-6
    x, y = grid.cell_centers()
    hydrostatic = -1000.0 * 9.81 * y
    np.testing.assert_allclose(state.pressure - state.pressure.mean(),
                               hydrostatic - hydrostatic.mean(), atol=1e-6 * 1000.0 * 9.81 * 4.0)


def test_projection_with_block_removes_weighted_divergence(rng, make_block):
    grid = Grid2D(24, 20, 0.05)
    interior = make_block(grid, 0.42, 0.33, 0.71, 0.62, velocity=(0.3, -0.2))
    solver = FluidSolver(grid, density=1.0, viscosity=0.0, boundaries=CHANNEL,
                         pressure_solver=PoissonSolverMGPCG(rtol=1e-10, max_iterations=500))
    state = _random_state(grid, rng)
    solver.apply_side_values(state, 1.0)
    before = np.abs(solver.divergence(state, interior)).max()
    report = solver.project(state, 0.01, interior)
    after = np.abs(solver.divergence(state, interior)).max()
    assert report.converged
    assert after < 1e-8 * before
    closed_x = interior.open_fraction_x == 0.0
    closed_y = interior.open_fraction_y == 0.0
    np.testing.assert_array_equal(state.velocity_x[closed_x], 0.3)
    np.testing.assert_array_equal(state.velocity_y[closed_y], -0.2)


def test_jacobi_and_mgpcg_give_the_same_pressure(rng):
    grid = Grid2D(16, 12, 0.1)
    pressures = []
    for pressure_solver in (PoissonSolverJacobi(rtol=1e-10, max_iterations=200000),
                            PoissonSolverMGPCG(rtol=1e-10, max_iterations=500)):
        solver = FluidSolver(grid, density=1.0, viscosity=0.0, boundaries=CLOSED,
                             pressure_solver=pressure_solver)
        state = _random_state(grid, np.random.default_rng(7))
        solver.apply_side_values(state, 0.0)
        report = solver.project(state, 0.05)
        assert report.converged
        pressures.append(state.pressure.copy())
    scale = np.abs(pressures[1]).max()
    np.testing.assert_allclose(pressures[0], pressures[1], rtol=0, atol=1e-7 * scale)


def _divergence_free_state(grid: Grid2D, solver: FluidSolver, rng) -> FluidState:
    state = _random_state(grid, rng)
    solver.apply_side_values(state, 0.0)
    solver.project(state, 0.1)
    return state


@pytest.mark.parametrize("advection", ["semi_lagrangian", "maccormack"])
def test_advecting_constant_dye_changes_nothing(rng, advection):
    grid = Grid2D(20, 16, 0.1)
    solver = FluidSolver(grid, density=1.0, viscosity=0.0, boundaries=CLOSED,
                         advection=advection)
    state = _divergence_free_state(grid, solver, rng)
    state.dye[...] = 0.37
    solver.advect(state, 0.7 * grid.h / np.abs(state.velocity_x).max())
    np.testing.assert_array_equal(state.dye, 0.37)


@pytest.mark.parametrize("advection", ["semi_lagrangian", "maccormack"])
def test_advecting_uniform_flow_changes_nothing(advection):
    grid = Grid2D(20, 16, 0.1)
    solver = FluidSolver(grid, density=1.0, viscosity=0.0, boundaries=CHANNEL,
                         advection=advection)
    state = FluidState.zeros(grid)
    state.velocity_x[...] = 1.0
    state.dye[...] = 0.0
    solver.advect(state, 0.37)
    np.testing.assert_array_equal(state.velocity_x, 1.0)
    np.testing.assert_array_equal(state.velocity_y, 0.0)


def test_inflow_dye_enters_and_moving_lid_drags_fluid():
    grid = Grid2D(16, 16, 1.0 / 16)
    lid = DomainBoundaries(left=Inflow(1.0, dye=1.0), right=Outflow(), bottom=WallNoSlip(),
                           top=WallMoving(0.5))
    solver = FluidSolver(grid, density=1.0, viscosity=0.01, boundaries=lid)
    state = FluidState.zeros(grid)
    for k in range(5):
        solver.step(state, 0.02, k * 0.02)
    assert state.dye[0].min() > 0.5
    assert state.velocity_x[1:-1, -1].mean() > state.velocity_x[1:-1, 0].mean() + 0.1


def test_fluid_at_rest_around_block_stays_at_rest(make_block):
    grid = Grid2D(20, 20, 0.05)
    interior = make_block(grid, 0.31, 0.42, 0.63, 0.58)
    for gravity in ((0.0, 0.0), (0.0, -9.81)):
        solver = FluidSolver(grid, density=1000.0, viscosity=1e-3, boundaries=CLOSED,
                             gravity=gravity,
                             pressure_solver=PoissonSolverMGPCG(rtol=1e-10, max_iterations=500))
        state = FluidState.zeros(grid)
        for k in range(4):
            solver.step(state, 0.01, 0.01 * k, interior)
        speed = max(np.abs(state.velocity_x).max(), np.abs(state.velocity_y).max())
        assert speed < 1e-9
        if gravity[1] != 0.0:
            # Hydrostatic: p falls by rho g h per cell upwards in a fluid column.
            column = state.pressure[2]
            np.testing.assert_allclose(-np.diff(column), 1000.0 * 9.81 * grid.h, rtol=1e-6)


def test_uniform_flow_past_block_is_divergence_free(make_block):
    grid = Grid2D(32, 16, 1.0 / 16)
    interior = make_block(grid, 0.7, 0.37, 1.1, 0.66)
    solver = FluidSolver(grid, density=1.0, viscosity=1e-3, boundaries=CHANNEL,
                         pressure_solver=PoissonSolverMGPCG(rtol=1e-10, max_iterations=500))
    state = FluidState.zeros(grid)
    state.velocity_x[...] = 1.0
    for k in range(5):
        report = solver.step(state, 0.02, 0.02 * k, interior)
        assert report.pressure_converged
    divergence = np.abs(solver.divergence(state, interior)).max()
    assert divergence < 1e-7 / grid.h
    # Closed faces hold the body velocity; partly open ones carry the flux of their open part.
    np.testing.assert_array_equal(state.velocity_x[interior.open_fraction_x == 0.0], 0.0)
    np.testing.assert_array_equal(state.velocity_y[interior.open_fraction_y == 0.0], 0.0)
    assert np.isfinite(state.velocity_x).all()
    assert np.abs(state.velocity_x).max() < 3.0
    np.testing.assert_array_equal(state.dye[interior.solid_cells], 0.0)


def test_viscosity_cut_term_pulls_towards_body_velocity(make_block):
    # A uniform stream next to a block moving with the stream feels no viscous change,
    # so the cut-cell stencil must reproduce the uniform field exactly.
    grid = Grid2D(16, 16, 0.1)
    interior = make_block(grid, 0.53, 0.47, 1.01, 0.96, velocity=(0.8, 0.0))
    solver = FluidSolver(grid, density=1.0, viscosity=0.5,
                         boundaries=DomainBoundaries(Inflow(0.8), Outflow(), WallFreeSlip(),
                                                     WallFreeSlip()),
                         viscosity_solver=PoissonSolverMGPCG(rtol=1e-12, max_iterations=500))
    state = FluidState.zeros(grid)
    state.velocity_x[...] = 0.8
    solver.diffuse(state, 0.1, interior)
    np.testing.assert_allclose(state.velocity_x, 0.8, rtol=0, atol=1e-10)
    np.testing.assert_allclose(state.velocity_y, 0.0, rtol=0, atol=1e-10)


def test_jet_sets_velocity_and_dye():
    grid = Grid2D(16, 16, 0.1)
    jet = Jet(region=(0.7, 0.0, 0.9, 0.3), velocity=(0.0, 2.0), dye=1.0)
    solver = FluidSolver(grid, density=1.0, viscosity=0.0, boundaries=CLOSED, jets=(jet,))
    state = FluidState.zeros(grid)
    solver.apply_forces(state, 0.01, 0.0)
    xv, yv = grid.faces_y()
    inside = (xv >= 0.7) & (xv <= 0.9) & (yv > 0.0) & (yv <= 0.3)
    np.testing.assert_array_equal(state.velocity_y[inside], 2.0)
    assert state.dye.sum() > 0.0


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"density": -1.0}, "density"),
        ({"density": float("nan")}, "density"),
        ({"viscosity": -0.1}, "viscosity"),
        ({"boundaries": "walls"}, "boundaries"),
        ({"jets": (1,)}, "jets"),
        ({"gravity": (1.0,)}, "gravity"),
        ({"buoyancy": float("inf")}, "buoyancy"),
        ({"pressure_solver": object()}, "pressure_solver"),
        ({"viscosity_solver": 3}, "viscosity_solver"),
        ({"advection": "upwind"}, "advection"),
        ({"pressure_guess": "zero"}, "pressure_guess"),
    ],
)
def test_bad_constructor_input_names_the_field(kwargs, field):
    arguments = {"density": 1.0, "viscosity": 0.1, "boundaries": CLOSED} | kwargs
    with pytest.raises(ValueError, match=field):
        FluidSolver(Grid2D(4, 4, 1.0), **arguments)


def test_bad_side_and_jet_input_names_the_field():
    with pytest.raises(ValueError, match="profile"):
        Inflow(1.0, profile="cubic")
    with pytest.raises(ValueError, match="ramp_time"):
        Inflow(1.0, ramp_time=-1.0)
    with pytest.raises(ValueError, match="region"):
        Jet(region=(1.0, 0.0, 0.0, 1.0), velocity=(0.0, 1.0))
    with pytest.raises(ValueError, match="left"):
        DomainBoundaries(left="wall", right=WallNoSlip(), bottom=WallNoSlip(), top=WallNoSlip())
    with pytest.raises(ValueError, match="velocity"):
        WallMoving(float("nan"))


def test_bad_state_and_time_step_are_rejected():
    grid = Grid2D(4, 4, 1.0)
    solver = FluidSolver(grid, density=1.0, viscosity=0.1, boundaries=CLOSED)
    state = FluidState.zeros(Grid2D(5, 4, 1.0))
    with pytest.raises(ValueError, match="velocity_x"):
        solver.step(state, 0.1)
    with pytest.raises(ValueError, match="dt"):
        solver.step(FluidState.zeros(grid), -0.1)


def test_advection_ghosts_keep_flow_that_moves_with_the_body(make_block):
    # Fluid moving with the body's own velocity: every cut-distance ghost equals that
    # velocity, so advection must reproduce the uniform field exactly.
    grid = Grid2D(24, 16, 0.1)
    interior = make_block(grid, 0.93, 0.51, 1.37, 1.02, velocity=(0.6, -0.25))
    solver = FluidSolver(grid, density=1.0, viscosity=0.0,
                         boundaries=DomainBoundaries(*(WallFreeSlip(),) * 4))
    state = FluidState.zeros(grid)
    state.velocity_x[...] = 0.6
    state.velocity_y[...] = -0.25
    solver.advect(state, 0.15, interior)
    np.testing.assert_allclose(state.velocity_x[1:-1], 0.6, rtol=0, atol=1e-14)
    np.testing.assert_allclose(state.velocity_y[:, 1:-1], -0.25, rtol=0, atol=1e-14)


def test_inflow_profile_and_ramp():
    grid = Grid2D(8, 10, 0.1)
    inflow = Inflow(2.0, profile="parabolic", ramp_time=1.0)
    solver = FluidSolver(grid, density=1.0, viscosity=0.0,
                         boundaries=DomainBoundaries(inflow, Outflow(), WallNoSlip(),
                                                     WallNoSlip()))
    state = FluidState.zeros(grid)
    solver.apply_side_values(state, 0.5)
    y = (np.arange(grid.ny) + 0.5) * grid.h
    expected = 0.5 * 4.0 * 2.0 * (y / grid.ly) * (1.0 - y / grid.ly)
    np.testing.assert_allclose(state.velocity_x[0], expected, rtol=1e-14)
    solver.apply_side_values(state, 2.0)
    np.testing.assert_allclose(state.velocity_x[0], 2.0 * expected, rtol=1e-14)
    np.testing.assert_array_equal(state.velocity_y[:, 0], 0.0)


def test_velocity_does_not_leak_through_a_thin_plate(make_block):
    # A fixed plate thinner than a cell between the u points x = 0.9 and x = 1.0: what is
    # advected to the right of it must not depend on the velocity on its left.
    grid = Grid2D(20, 10, 0.1)
    interior = make_block(grid, 0.93, -1.0, 0.97, 2.0)
    solver = FluidSolver(grid, density=1.0, viscosity=0.0,
                         boundaries=DomainBoundaries(*(WallFreeSlip(),) * 4))
    results = []
    for left_speed in (1.0, 5.0):
        state = FluidState.zeros(grid)
        state.velocity_x[:10] = left_speed
        state.velocity_x[10:] = 0.5
        solver.advect(state, 0.05, interior)
        results.append(state.velocity_x[10:].copy())
    np.testing.assert_array_equal(results[0], results[1])


@pytest.mark.parametrize("advection", ["semi_lagrangian", "maccormack"])
def test_sides_are_consistent_under_transposition(advection):
    # Swapping x and y maps left/right onto bottom/top and u onto v: the transposed set-up
    # must give the transposed flow (up to the solver tolerance).
    grid = Grid2D(12, 12, 1.0 / 12)
    setups = (
        DomainBoundaries(Inflow(1.0, profile="parabolic", dye=1.0), Outflow(), WallNoSlip(),
                         WallMoving(0.3)),
        DomainBoundaries(WallNoSlip(), WallMoving(0.3),
                         Inflow(1.0, profile="parabolic", dye=1.0), Outflow()),
    )
    states = []
    for boundaries in setups:
        solver = FluidSolver(grid, density=1.0, viscosity=0.01, boundaries=boundaries,
                             gravity=(0.0, 0.0), advection=advection,
                             pressure_solver=PoissonSolverMGPCG(rtol=1e-12, max_iterations=500),
                             viscosity_solver=PoissonSolverMGPCG(rtol=1e-12, max_iterations=500))
        state = FluidState.zeros(grid)
        for k in range(6):
            solver.step(state, 0.03, 0.03 * k)
        states.append(state)
    first, second = states
    np.testing.assert_allclose(second.velocity_y, first.velocity_x.T, atol=1e-9)
    np.testing.assert_allclose(second.velocity_x, first.velocity_y.T, atol=1e-9)
    np.testing.assert_allclose(second.dye, first.dye.T, atol=1e-9)
    np.testing.assert_allclose(second.pressure, first.pressure.T, atol=1e-8)


def test_dye_buoyancy_lifts_dyed_fluid():
    grid = Grid2D(16, 16, 1.0 / 16)
    solver = FluidSolver(grid, density=1.0, viscosity=0.001, boundaries=CLOSED, buoyancy=2.0)
    state = FluidState.zeros(grid)
    state.dye[6:10, 2:6] = 1.0
    solver.step(state, 0.01, 0.0)
    assert state.velocity_y[6:10, 3:6].min() > 0.0
    # Fluid away from the blob moves down to make room: no net vertical flux through any row.
    np.testing.assert_allclose(state.velocity_y[:, 1:-1].sum(axis=0), 0.0, atol=1e-8)


def test_sides_are_consistent_under_mirroring():
    # x -> Lx - x maps left onto right and u onto -u: an inflow from the right into an outflow
    # on the left must give the mirrored flow of the left-to-right channel.
    grid = Grid2D(12, 10, 0.1)
    setups = (
        DomainBoundaries(Inflow(1.0, profile="parabolic", dye=1.0), Outflow(), WallNoSlip(),
                         WallMoving(0.3)),
        DomainBoundaries(Outflow(), Inflow(1.0, profile="parabolic", dye=1.0), WallNoSlip(),
                         WallMoving(-0.3)),
    )
    states = []
    for boundaries in setups:
        solver = FluidSolver(grid, density=1.0, viscosity=0.01, boundaries=boundaries,
                             pressure_solver=PoissonSolverMGPCG(rtol=1e-12, max_iterations=500),
                             viscosity_solver=PoissonSolverMGPCG(rtol=1e-12, max_iterations=500))
        state = FluidState.zeros(grid)
        for k in range(6):
            solver.step(state, 0.03, 0.03 * k)
        states.append(state)
    first, second = states
    np.testing.assert_allclose(second.velocity_x, -first.velocity_x[::-1], atol=1e-9)
    np.testing.assert_allclose(second.velocity_y, first.velocity_y[::-1], atol=1e-9)
    np.testing.assert_allclose(second.dye, first.dye[::-1], atol=1e-9)
    np.testing.assert_allclose(second.pressure, first.pressure[::-1], atol=1e-8)


def test_extrapolated_pressure_guess_gives_the_same_flow_in_fewer_iterations():
    """A channel whose inflow ramps up: the pressure grows smoothly, so starting each solve
    from the pressure extrapolated from the last two steps cuts the iterations, and the flow
    is the same to the solver's tolerance. The state keeps the pressure before the last one."""
    grid = Grid2D(64, 24, 1.0 / 24)
    boundaries = DomainBoundaries(left=Inflow(1.0, profile="parabolic", ramp_time=1.0),
                                  right=Outflow(), bottom=WallNoSlip(), top=WallNoSlip())
    runs = {}
    for guess in ("previous", "extrapolated"):
        solver = FluidSolver(grid, density=1.0, viscosity=0.01, boundaries=boundaries,
                             pressure_solver=PoissonSolverMGPCG(rtol=1e-8),
                             pressure_guess=guess)
        state = FluidState.zeros(grid)
        iterations = 0
        for step in range(30):
            iterations += solver.step(state, 0.01, time=0.01 * step).pressure_iterations
        runs[guess] = (state, iterations)
    previous, extrapolated = runs["previous"][0], runs["extrapolated"][0]
    assert previous.previous_pressure is None
    assert extrapolated.previous_pressure is not None
    assert extrapolated.previous_pressure_dt == 0.01
    assert runs["extrapolated"][1] < 0.8 * runs["previous"][1]
    scale = np.abs(previous.velocity_x).max()
    assert np.abs(extrapolated.velocity_x - previous.velocity_x).max() < 1e-6 * scale
    assert np.allclose(extrapolated.pressure, previous.pressure, rtol=0.0,
                       atol=1e-5 * np.abs(previous.pressure).max())


def test_pressure_is_extended_two_cells_into_the_cells_the_equation_leaves_out():
    """`extend_into_inactive`: each layer takes the mean of its known neighbours; the
    equation's own cells and cells beyond the layers keep their values."""
    from elastoflow.fluid import _kernels

    grid = Grid2D(7, 5, 0.1)
    open_x = np.ones(grid.shape_faces_x)
    open_y = np.ones(grid.shape_faces_y)
    # Columns 3.. are covered: faces at and right of x = 3 h closed, and their y faces.
    open_x[3:, :] = 0.0
    open_y[3:, :] = 0.0
    solver = FluidSolver(grid, density=1.0, viscosity=0.0, boundaries=CLOSED)
    operator = solver._assemble_pressure_operator(open_x, open_y)
    values = np.full(grid.shape_cells, -7.0)
    values[:3, :] = np.arange(15.0).reshape(3, 5)
    _kernels.extend_into_inactive(values, operator.diagonal, operator.weights_x,
                                  operator.weights_y, 2)
    np.testing.assert_array_equal(values[:3, :], np.arange(15.0).reshape(3, 5))
    np.testing.assert_array_equal(values[3, :], values[2, :])
    np.testing.assert_array_equal(values[4, :], values[2, :])
    np.testing.assert_array_equal(values[5:, :], -7.0)
