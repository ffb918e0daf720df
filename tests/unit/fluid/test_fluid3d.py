"""The 3D fluid's exact discrete identities on small grids (16^3 and below)."""

from __future__ import annotations

import numpy as np
import pytest

from elastoflow.fluid import _kernels3d as kernels
from elastoflow.fluid._boundaries import Inflow, Outflow, WallFreeSlip, WallMoving, WallNoSlip
from elastoflow.fluid._boundaries3d import DomainBoundaries3D, WallMoving3D
from elastoflow.fluid._interior3d import InteriorBoundary3D
from elastoflow.fluid._solver3d import FluidSolver3D
from elastoflow.fluid._state3d import FluidState3D
from elastoflow.grid import Grid3D
from elastoflow.linalg import PoissonSolverMGPCG3D, apply_operator_3d

GRID = Grid3D(nx=12, ny=10, nz=8, h=0.1)
OPEN_BOX = DomainBoundaries3D(left=Inflow(0.5), right=Outflow(), bottom=WallNoSlip(),
                              top=WallFreeSlip(), back=WallNoSlip(), front=Outflow())


def random_state(grid: Grid3D, seed: int) -> FluidState3D:
    state = FluidState3D.zeros(grid)
    rng = np.random.default_rng(seed)
    for field in state.velocity():
        field[...] = rng.standard_normal(field.shape)
    return state


def flux_sums(state: FluidState3D) -> np.ndarray:
    """``h div u`` per cell: the sum of the six signed face velocities."""
    u, v, w = state.velocity()
    return (np.diff(u, axis=0) + np.diff(v, axis=1) + np.diff(w, axis=2))


@pytest.mark.parametrize("boundaries", [DomainBoundaries3D.closed_box(), OPEN_BOX])
def test_projection_leaves_divergence_under_the_tolerance(boundaries: DomainBoundaries3D) -> None:
    solver = FluidSolver3D(GRID, density=2.0, viscosity=0.0, boundaries=boundaries,
                           pressure_solver=PoissonSolverMGPCG3D(rtol=1e-8))
    state = random_state(GRID, seed=1)
    solver.apply_side_values(state, time=1.0)
    before = flux_sums(state)
    report = solver.project(state, dt=0.05)
    after = flux_sums(state)
    assert report.converged
    # The new flux sums are the solve's residual divided by rho h / dt: bounded by rtol.
    assert np.linalg.norm(after) <= 1e-8 * np.linalg.norm(before) * (1 + 1e-6)
    np.testing.assert_allclose(solver.divergence(state), after / GRID.h, atol=1e-12)


@pytest.mark.parametrize("boundaries", [DomainBoundaries3D.closed_box(), OPEN_BOX])
def test_divergence_of_gradient_is_the_seven_point_operator(
        boundaries: DomainBoundaries3D) -> None:
    solver = FluidSolver3D(GRID, density=1.0, viscosity=0.0, boundaries=boundaries)
    state = FluidState3D.zeros(GRID)
    p = np.random.default_rng(2).standard_normal(GRID.shape_cells)
    kernels.subtract_pressure_gradient_3d(state.velocity(), p, 1.0, solver._outflow, False,
                                          solver._no_faces, solver._no_faces)
    # u = -grad p (times h), so the flux sums are -h^2 div grad p = A p exactly.
    np.testing.assert_allclose(flux_sums(state), apply_operator_3d(solver.pressure_operator(), p),
                               atol=1e-12)


def test_viscosity_operator_stencils() -> None:
    solver = FluidSolver3D(GRID, density=1.0, viscosity=0.3, boundaries=OPEN_BOX)
    dt = 0.01
    c = 0.3 * dt / GRID.h**2
    state = random_state(GRID, seed=3)
    u = state.velocity_x
    operator, rhs = solver.viscosity_system(u, axis=0, dt=dt)
    # (A x)_P = diagonal_P x_P + sum w (x_P - x_nb): the diagonal holds 1 plus the boundary
    # terms. An interior point couples to its six neighbours with c.
    assert operator.diagonal[5, 5, 4] == 1.0
    assert operator.weights_x[5, 5, 4] == operator.weights_y[5, 5, 4] == c
    assert operator.weights_z[5, 5, 3] == operator.weights_x[4, 5, 4] == c
    assert rhs[5, 5, 4] == u[5, 5, 4]
    # Next to the no-slip bottom (j = 0): the mirror ghost (wall velocity 0) adds 2c.
    assert operator.diagonal[5, 0, 4] == pytest.approx(1 + 2 * c)
    # Next to the free-slip top: zero gradient, nothing added.
    assert operator.diagonal[5, -1, 4] == 1.0
    # The inflow face (i = 0) is held: an identity row; its neighbour gets c on the diagonal
    # and c u_0 on the right-hand side instead of a coupling.
    assert operator.diagonal[0, 5, 4] == 1.0 and operator.weights_x[0, 5, 4] == 0.0
    assert operator.weights_y[0, 5, 4] == 0.0 and operator.weights_z[0, 5, 4] == 0.0
    assert operator.diagonal[1, 5, 4] == pytest.approx(1 + c)
    assert rhs[1, 5, 4] == pytest.approx(u[1, 5, 4] + c * u[0, 5, 4])
    # The outflow face (i = nx) is an unknown with a zero-gradient end.
    assert operator.diagonal[-1, 5, 4] == 1.0 and operator.weights_x[-1, 5, 4] == c
    # The cached operator's right-hand side is the freshly assembled one.
    again, rhs_again = solver.viscosity_system(u, axis=0, dt=dt)
    assert again is operator
    fresh = FluidSolver3D(GRID, density=1.0, viscosity=0.3, boundaries=OPEN_BOX)
    np.testing.assert_array_equal(rhs_again, fresh.viscosity_system(u, axis=0, dt=dt)[1])


@pytest.mark.parametrize("advection", ["semi_lagrangian", "maccormack"])
def test_advecting_a_constant_changes_nothing(advection: str) -> None:
    solver = FluidSolver3D(GRID, density=1.0, viscosity=0.0,
                           boundaries=DomainBoundaries3D.closed_box(), advection=advection)
    state = random_state(GRID, seed=4)
    solver.apply_side_values(state, 0.0)
    solver.project(state, 0.1)
    state.dye[...] = 0.75
    solver.advect(state, 0.05)
    assert np.all(state.dye == 0.75)


def test_maccormack_makes_no_new_extrema() -> None:
    solver = FluidSolver3D(GRID, density=1.0, viscosity=0.0,
                           boundaries=DomainBoundaries3D.closed_box(), advection="maccormack")
    state = random_state(GRID, seed=5)
    solver.apply_side_values(state, 0.0)
    solver.project(state, 0.1)
    state.dye[...] = (np.random.default_rng(6).random(GRID.shape_cells) > 0.5)
    solver.advect(state, 0.05)
    assert state.dye.min() >= 0.0 and state.dye.max() <= 1.0


def test_uniform_flow_in_a_free_slip_channel_stays_uniform() -> None:
    boundaries = DomainBoundaries3D.channel(Inflow(0.8), walls=WallFreeSlip())
    solver = FluidSolver3D(GRID, density=1.0, viscosity=0.01, boundaries=boundaries)
    state = FluidState3D.zeros(GRID)
    state.velocity_x[...] = 0.8
    for step in range(3):
        report = solver.step(state, 0.02, time=0.02 * step)
        assert report.pressure_converged
    np.testing.assert_allclose(state.velocity_x, 0.8, atol=1e-12)
    assert np.abs(state.velocity_y).max() < 1e-12 and np.abs(state.velocity_z).max() < 1e-12


def test_fluid_at_rest_under_gravity_stays_at_rest() -> None:
    solver = FluidSolver3D(GRID, density=1000.0, viscosity=1e-3,
                           boundaries=DomainBoundaries3D.closed_box(), gravity=(0.0, -9.81, 0.0),
                           pressure_solver=PoissonSolverMGPCG3D(rtol=1e-10))
    state = solver.rest_state()
    # Hydrostatic: dp/dy = rho g between cell centres.
    np.testing.assert_allclose(np.diff(state.pressure, axis=1) / GRID.h, -9810.0, rtol=1e-8)
    for _ in range(3):
        solver.step(state, 0.01)
    assert max(np.abs(f).max() for f in state.velocity()) < 1e-12
    np.testing.assert_allclose(np.diff(state.pressure, axis=1) / GRID.h, -9810.0, rtol=1e-8)
    # From zero pressure the first step's viscosity meets dt g at the walls (measured
    # 2.9e-4 m/s here, 0.3 % of g dt); the paper's non-incremental form lets it grow.
    zero = FluidState3D.zeros(GRID)
    solver.step(zero, 0.01)
    first = max(np.abs(f).max() for f in zero.velocity())
    solver.step(zero, 0.01)
    assert first < 5e-4 and max(np.abs(f).max() for f in zero.velocity()) <= first


def test_inflow_profile_and_outflow_side_values() -> None:
    boundaries = DomainBoundaries3D(
        left=Inflow(2.0, profile="parabolic", ramp_time=1.0), right=WallNoSlip(),
        bottom=WallNoSlip(), top=WallNoSlip(), back=WallNoSlip(), front=Outflow())
    solver = FluidSolver3D(GRID, density=1.0, viscosity=0.0, boundaries=boundaries)
    state = random_state(GRID, seed=7)
    solver.apply_side_values(state, time=0.5)
    inflow = state.velocity_x[0]
    # Half the ramp at t = T/2; peak 2 at the centre, zero at the edges.
    assert inflow.max() <= 1.0 and inflow.max() > 0.9 and inflow.min() > 0.0
    np.testing.assert_allclose(inflow, inflow[::-1, :])
    assert not state.velocity_x[-1].any() and not state.velocity_y[:, 0].any()
    np.testing.assert_array_equal(state.velocity_z[:, :, -1], state.velocity_z[:, :, -2])


def test_invalid_input_is_refused() -> None:
    with pytest.raises(ValueError, match="WallMoving3D"):
        DomainBoundaries3D(left=WallMoving(1.0), right=WallNoSlip(), bottom=WallNoSlip(),
                           top=WallNoSlip(), back=WallNoSlip(), front=WallNoSlip())
    with pytest.raises(ValueError, match="y component must be 0"):
        DomainBoundaries3D(left=WallNoSlip(), right=WallNoSlip(), bottom=WallNoSlip(),
                           top=WallMoving3D((1.0, 0.5, 0.0)), back=WallNoSlip(),
                           front=WallNoSlip())
    box = DomainBoundaries3D.closed_box()
    with pytest.raises(ValueError, match="Grid3D"):
        FluidSolver3D(None, density=1.0, viscosity=0.0, boundaries=box)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="advection"):
        FluidSolver3D(GRID, density=1.0, viscosity=0.0, boundaries=box, advection="upwind")
    solver = FluidSolver3D(GRID, density=1.0, viscosity=0.0, boundaries=box)
    with pytest.raises(ValueError, match="dt"):
        solver.step(FluidState3D.zeros(GRID), 0.0)
    with pytest.raises(ValueError, match="shape"):
        solver.step(FluidState3D.zeros(Grid3D(nx=12, ny=10, nz=9, h=0.1)), 0.1)


def test_jet_sets_the_faces_and_cells_inside_its_box() -> None:
    from elastoflow.fluid._boundaries3d import Jet3D

    jet = Jet3D(region=(0.3, 0.0, 0.25, 0.5, 0.2, 0.55), velocity=(0.0, 2.0, -1.0), dye=0.5)
    solver = FluidSolver3D(GRID, density=1.0, viscosity=0.0,
                           boundaries=DomainBoundaries3D.closed_box(), jets=(jet,))
    state = FluidState3D.zeros(GRID)
    solver.apply_forces(state, 0.01, 0.0)
    # v points (i + 1/2, j, k + 1/2) h inside: i = 3, 4; j = 1, 2 (j = 0 is the wall, set to
    # 0 by the side values after the jet); k = 2 .. 5 (z = 0.25 and 0.55 on the box's faces).
    expected = np.zeros(GRID.shape_faces_y)
    expected[3:5, 1:3, 2:6] = 2.0
    np.testing.assert_array_equal(state.velocity_y, expected)
    # w points k h: k = 3, 4, 5; cell centres: k = 2 .. 5.
    assert np.count_nonzero(state.velocity_z == -1.0) == 2 * 2 * 3
    assert np.count_nonzero(state.dye == 0.5) == 2 * 2 * 4
    with pytest.raises(ValueError, match="z0 < z1"):
        Jet3D(region=(0.0, 0.0, 0.5, 1.0, 1.0, 0.5), velocity=(0.0, 0.0, 0.0))


def test_couette_flow_between_a_moving_lid_and_a_wall_is_linear() -> None:
    # Lid at y = H moving along x and z, still wall at y = 0, outflow on the four other
    # sides: the steady u(y) and w(y) are linear, which the 7-point operator with mirror
    # ghosts represents exactly. nu = 1, H = 1: the slowest start-up mode decays as
    # exp(-pi^2 t), 1e-13 by t = 3.
    grid = Grid3D(nx=4, ny=8, nz=4, h=0.125)
    boundaries = DomainBoundaries3D(left=Outflow(), right=Outflow(), bottom=WallNoSlip(),
                                    top=WallMoving3D((0.2, 0.0, -0.1)), back=Outflow(),
                                    front=Outflow())
    solver = FluidSolver3D(grid, density=1.0, viscosity=1.0, boundaries=boundaries,
                           pressure_solver=PoissonSolverMGPCG3D(rtol=1e-12),
                           viscosity_solver=PoissonSolverMGPCG3D(rtol=1e-12))
    state = FluidState3D.zeros(grid)
    for step in range(30):
        solver.step(state, 0.1, time=0.1 * step)
    y = (np.arange(8) + 0.5) / 8
    np.testing.assert_allclose(state.velocity_x, 0.2 * y[None, :, None] * np.ones((5, 8, 4)),
                               atol=1e-10)
    np.testing.assert_allclose(state.velocity_z, -0.1 * y[None, :, None] * np.ones((4, 8, 5)),
                               atol=1e-10)
    assert np.abs(state.velocity_y).max() < 1e-10


def test_dye_buoyancy_pushes_the_y_faces_between_dyed_cells_upwards() -> None:
    solver = FluidSolver3D(GRID, density=1.0, viscosity=0.0,
                           boundaries=DomainBoundaries3D.closed_box(), buoyancy=2.0)
    state = FluidState3D.zeros(GRID)
    state.dye[4, 3, 2] = 1.0
    solver.apply_forces(state, 0.1, 0.0)
    expected = np.zeros(GRID.shape_faces_y)
    expected[4, 3:5, 2] = 0.1 * 2.0 * 0.5
    np.testing.assert_allclose(state.velocity_y, expected)
    assert not state.velocity_x.any() and not state.velocity_z.any()


@pytest.mark.parametrize("advection", ["semi_lagrangian", "maccormack"])
def test_an_empty_interior_steps_exactly_as_no_bodies(advection: str) -> None:
    # One kernel per phase serves both: with bodies nowhere, the body path (open fractions 1,
    # no solid point, no cut) must give the plain path's numbers.
    steps = []
    for interior in (None, InteriorBoundary3D.empty(GRID)):
        solver = FluidSolver3D(GRID, density=1.0, viscosity=0.05, boundaries=OPEN_BOX,
                               gravity=(0.0, -1.0, 0.5), buoyancy=0.3, advection=advection)
        state = random_state(GRID, seed=7)
        state.dye[...] = np.random.default_rng(8).random(GRID.shape_cells)
        for index in range(3):
            solver.step(state, 0.02, 0.02 * index, interior)
        steps.append((*state.velocity(), state.dye, state.pressure,
                      solver.divergence(state, interior)))
    for plain, empty in zip(*steps, strict=True):
        np.testing.assert_array_equal(plain, empty)


@pytest.mark.parametrize("advection", ["semi_lagrangian", "maccormack"])
def test_advecting_from_a_source_state_equals_advecting_in_place(advection: str) -> None:
    # The coupled schemes transport state_in into state_out without copying it first: every
    # velocity and dye value of the target must be written, none read.
    solver = FluidSolver3D(GRID, density=1.0, viscosity=0.0, boundaries=OPEN_BOX,
                           advection=advection)
    source = random_state(GRID, seed=11)
    source.dye[...] = np.random.default_rng(12).random(GRID.shape_cells)
    kept = source.copy()
    in_place = source.copy()
    solver.advect(in_place, 0.05)
    target = FluidState3D.zeros(GRID)
    for name in FluidSolver3D.ADVECTED_FIELDS:
        getattr(target, name)[...] = np.nan
    solver.advect(target, 0.05, source=source)
    for name in FluidSolver3D.ADVECTED_FIELDS:
        np.testing.assert_array_equal(getattr(target, name), getattr(in_place, name))
        np.testing.assert_array_equal(getattr(source, name), getattr(kept, name))


@pytest.mark.parametrize("dyed", [False, True])
def test_dye_that_is_zero_everywhere_stays_zero_without_a_pass(dyed: bool) -> None:
    """Without dye and without a dyed inflow the advection leaves the dye 0 (the kernel is
    not called for it), in place and into a target whose dye held anything; with one dyed
    cell it is carried as before."""
    solver = FluidSolver3D(GRID, density=1.0, viscosity=0.0, boundaries=OPEN_BOX)
    source = random_state(GRID, seed=14)
    source.dye[...] = 0.0
    if dyed:
        source.dye[3, 4, 5] = 1.0
    calls: list[int] = []
    original = kernels.advect_3d

    def counted(*arguments):  # type: ignore[no-untyped-def]
        calls.append(arguments[4])
        return original(*arguments)

    kernels.advect_3d = counted
    try:
        target = FluidState3D.zeros(GRID)
        target.dye[...] = np.nan
        solver.advect(target, 0.05, source=source)
        in_place = source.copy()
        solver.advect(in_place, 0.05)
    finally:
        kernels.advect_3d = original
    assert (kernels.FIELD_CELLS in calls) == dyed
    np.testing.assert_array_equal(target.dye, in_place.dye)
    if dyed:
        assert target.dye[3, 4, 5] > 0.0
    else:
        assert not np.any(target.dye) and not np.any(in_place.dye)


def test_update_into_counts_the_changed_values() -> None:
    old = np.random.default_rng(13).random((20, 18, 17))
    new = old.copy()
    new[3, 4, 5] += 1.0
    new[19, 0, 16] = np.nan
    assert kernels.update_into_3d(new, old) == 2
    np.testing.assert_array_equal(old, new)
    assert kernels.update_into_3d(new[:2, :2, :2].copy(), old[:2, :2, :2].copy()) == 0


def test_solid_box_bounds_the_solid_points_read_inside_a_region() -> None:
    """`solid_box` finds the inclusive bounds of the True entries; read only inside a region
    that holds them all, it finds the same; with none, an empty box."""
    rng = np.random.default_rng(3)
    solid = np.zeros((9, 7, 8), dtype=np.bool_)
    solid[3:6, 2:5, 1:7] = rng.random((3, 3, 6)) < 0.5
    solid[4, 3, 6] = solid[3, 2, 1] = solid[5, 4, 1] = True
    expected = np.array([3, 5, 2, 4, 1, 6])
    out = np.empty(6, dtype=np.int64)
    kernels.solid_box(solid, out, kernels.WHOLE_REGION)
    np.testing.assert_array_equal(out, expected)
    kernels.solid_box(solid, out, np.array([3, 2, 1, 6, 5, 7], dtype=np.int64))
    np.testing.assert_array_equal(out, expected)
    kernels.solid_box(solid, out, np.array([0, 0, 0, 3, 7, 8], dtype=np.int64))
    assert out[0] > out[1] and out[2] > out[3] and out[4] > out[5]


@pytest.mark.parametrize("dt", [0.05, 0.3])
def test_the_trace_is_exact_for_a_linear_flow(dt: float) -> None:
    """In a linear flow u = a + B (x - c) the midpoint trace's departure point is
    x - dt u + dt^2 B u / 2, whether the midpoint's velocity is sampled or taken from the
    point's neighbours (u - dt (u . grad) u / 2, exact here too), and trilinear sampling of a
    linear field is exact: every point away from the sides lands on the analytic value. At
    dt = 0.3 the midpoints of the faster points lie more than a cell away, which the
    neighbours do not reach: those are sampled."""
    grid = Grid3D(nx=16, ny=16, nz=16, h=1.0 / 16)
    solver = FluidSolver3D(grid, density=1.0, viscosity=0.0,
                           boundaries=DomainBoundaries3D.closed_box(),
                           advection="semi_lagrangian")
    a = np.array([0.3, -0.2, 0.1])
    b = np.array([[0.2, -0.4, 0.1], [0.3, -0.1, 0.25], [-0.2, 0.15, -0.1]])
    centre = np.full(3, 0.5)
    dye_gradient = np.array([0.7, -0.3, 0.5])
    state = FluidState3D.zeros(grid)
    h = grid.h
    offsets = ((0.0, 0.5, 0.5), (0.5, 0.0, 0.5), (0.5, 0.5, 0.0), (0.5, 0.5, 0.5))
    fields = (*state.velocity(), state.dye)

    def positions(field: np.ndarray, offset: tuple[float, float, float]) -> np.ndarray:
        axes = [(np.arange(size) + shift) * h for size, shift in zip(field.shape, offset,
                                                                       strict=True)]
        return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1)

    def velocity(x: np.ndarray) -> np.ndarray:
        return a + (x - centre) @ b.T

    for component, (field, offset) in enumerate(zip(fields[:3], offsets, strict=False)):
        field[...] = velocity(positions(field, offset))[..., component]
    state.dye[...] = 1.0 + (positions(state.dye, offsets[3]) - centre) @ dye_gradient
    before = [field.copy() for field in fields]
    solver.advect(state, dt)
    assert not np.array_equal(before[0], state.velocity_x)
    inner = (slice(5, -5),) * 3
    for component, (field, offset) in enumerate(zip(fields, offsets, strict=True)):
        x = positions(field, offset)[inner]
        u = velocity(x)
        departure = x - dt * u + 0.5 * dt * dt * (u @ b.T)
        if component < 3:
            expected = velocity(departure)[..., component]
        else:
            expected = 1.0 + (departure - centre) @ dye_gradient
        np.testing.assert_allclose(field[inner], expected, rtol=0, atol=1e-13)


@pytest.mark.parametrize("field", [kernels.FIELD_U, kernels.FIELD_V, kernels.FIELD_W,
                                   kernels.FIELD_CELLS])
def test_the_neighbour_trace_stops_at_any_solid_point_it_reads(field: int) -> None:
    """`_taylor_motion` reads a point's neighbours only where none of them is solid: every
    entry whose change moves its result (found by perturbing each entry around the point)
    turns it off when it is the one solid point of its array, and a solid point two
    points away does not."""
    grid = Grid3D(nx=10, ny=10, nz=10, h=0.1)
    state = random_state(grid, seed=8)
    arrays = state.velocity()
    point = (5, 5, 5)

    def motion(boxes: np.ndarray, has_interior: bool = True) -> tuple:
        return kernels._taylor_motion(*arrays, *point, field, 1.0 / grid.h, has_interior,
                                      boxes)

    base = motion(kernels.NO_BODIES_BOXES, has_interior=False)
    assert base[0]
    for row, array in enumerate(arrays):
        read = []
        for index in np.ndindex(*(5,) * 3):
            entry = tuple(p - 2 + d for p, d in zip(point, index, strict=True))
            saved = array[entry]
            array[entry] = saved + 1.0
            if motion(kernels.NO_BODIES_BOXES, has_interior=False) != base:
                read.append(entry)
            array[entry] = saved
        assert read
        for entry in read:
            boxes = kernels.NO_BODIES_BOXES.copy()
            boxes[row] = [entry[0], entry[0], entry[1], entry[1], entry[2], entry[2]]
            assert not motion(boxes)[0], (row, entry)
        far = tuple(p + 2 for p in point)
        boxes = kernels.NO_BODIES_BOXES.copy()
        boxes[row] = [far[0], far[0], far[1], far[1], far[2], far[2]]
        assert motion(boxes)[0]
