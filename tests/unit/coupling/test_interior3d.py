"""The 3D fluid with bodies inside (`InteriorBoundary3D` from the 3D map) and the traction
force on surface triangles: exact discrete identities on small grids."""

from __future__ import annotations

import numpy as np
import pytest
from coupling_surfaces import icosphere

from elastoflow.coupling import build_boundary_map_3d
from elastoflow.coupling._interior3d import force_traction_3d, interior_boundary_3d
from elastoflow.fluid._boundaries import Inflow, Outflow, WallFreeSlip
from elastoflow.fluid._boundaries3d import DomainBoundaries3D
from elastoflow.fluid._interior3d import InteriorBoundary3D
from elastoflow.fluid._kernels import OPEN_MIN
from elastoflow.fluid._solver3d import FluidSolver3D
from elastoflow.fluid._state3d import FluidState3D
from elastoflow.grid import Grid3D
from elastoflow.linalg import PoissonSolverMGPCG3D, apply_operator_3d

GRID = Grid3D(nx=16, ny=12, nz=12, h=0.1)
CENTRE = np.array([0.73, 0.61, 0.58])


def sphere(radius: float = 0.33, subdivisions: int = 3, centre: np.ndarray = CENTRE,
           velocity: tuple[float, float, float] = (0.0, 0.0, 0.0),
           spin: tuple[float, float, float] = (0.0, 0.0, 0.0)
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """An icosphere off the grid's lines: points, rigid velocities (translation plus spin
    about the centre), outward triangles."""
    unit, triangles = icosphere(subdivisions)
    points = centre + radius * unit
    velocities = np.asarray(velocity) + np.cross(np.asarray(spin), points - centre)
    return points, velocities, triangles


def interior_of(points: np.ndarray, velocities: np.ndarray, triangles: np.ndarray,
                grid: Grid3D = GRID) -> InteriorBoundary3D:
    return interior_boundary_3d(build_boundary_map_3d(grid, points, velocities, triangles))


def test_points_inside_carry_the_rigid_velocity_exactly() -> None:
    """Inside flags of every velocity point agree with the exact polyhedron test along a
    second axis, and the body velocity there (linear between the crossings) is the rigid
    motion's own, to rounding."""
    points, velocities, triangles = sphere(velocity=(0.3, -0.2, 0.1), spin=(0.5, -1.0, 2.0))
    interior = interior_of(points, velocities, triangles)
    interior.check(GRID)
    for axis, faces in enumerate((GRID.faces_x(), GRID.faces_y(), GRID.faces_z())):
        position = np.stack(faces, axis=-1)
        solid = interior.solid_faces(axis)
        # Inside the polyhedron: within the inscribed radius surely, beyond the circumradius
        # surely not.
        distance = np.linalg.norm(position - CENTRE, axis=-1)
        assert solid[distance < 0.33 * 0.99].all() and not solid[distance > 0.33].any()
        rigid = (np.asarray((0.3, -0.2, 0.1))
                 + np.cross(np.asarray((0.5, -1.0, 2.0)), position - CENTRE))[..., axis]
        np.testing.assert_allclose(interior.velocity_faces(axis)[solid], rigid[solid],
                                   atol=1e-12)
        assert not interior.velocity_faces(axis)[~solid].any()


def test_cells_covered_by_the_body_are_inactive_and_the_operator_is_spd() -> None:
    points, velocities, triangles = sphere()
    interior = interior_of(points, velocities, triangles)
    solver = FluidSolver3D(GRID, density=1.0, viscosity=0.0,
                           boundaries=DomainBoundaries3D.closed_box())
    operator = solver.pressure_operator(interior)
    weights = (operator.weights_x, operator.weights_y, operator.weights_z)
    for axis, w in enumerate(weights):
        fraction = interior.open_fraction(axis)
        inner = fraction[(slice(None),) * axis + (slice(1, -1),)]
        expected = np.where(inner < OPEN_MIN, 0.0, inner)
        np.testing.assert_array_equal(w, expected)
        assert w.min() >= 0.0 and w.max() <= 1.0
    total = operator.diagonal.copy()
    for axis, w in enumerate(weights):
        low = [slice(None)] * 3
        high = [slice(None)] * 3
        low[axis] = slice(0, -1)
        high[axis] = slice(1, None)
        total[tuple(low)] += w
        total[tuple(high)] += w
    # Cells whose six faces are all closed are out of the system; the deep inside is.
    assert (total[interior.solid_cells] == 0.0).sum() > 0
    i, j, k = np.floor((CENTRE - GRID.origin) / GRID.h).astype(int)
    assert total[i, j, k] == 0.0
    # Symmetric by construction (weights per face); positive semi-definite: x.Ax >= 0.
    rng = np.random.default_rng(3)
    for _ in range(3):
        x = rng.standard_normal(GRID.shape_cells)
        assert float(np.sum(x * apply_operator_3d(operator, x))) >= 0.0


def test_projection_with_a_moving_body_makes_the_weighted_divergence_vanish() -> None:
    """After the projection ``div(A u + (1 - A) u_s)`` is zero to the tolerance and the
    faces closed inside the body hold its velocity (a spinning, translating sphere; an
    outflow side takes up the volume it sweeps)."""
    points, velocities, triangles = sphere(velocity=(0.3, -0.2, 0.1), spin=(0.4, 0.0, 1.5))
    interior = interior_of(points, velocities, triangles)
    sides = DomainBoundaries3D(left=Inflow(0.5), right=Outflow(), bottom=WallFreeSlip(),
                               top=WallFreeSlip(), back=WallFreeSlip(), front=Outflow())
    solver = FluidSolver3D(GRID, density=1.0, viscosity=0.0, boundaries=sides,
                           pressure_solver=PoissonSolverMGPCG3D(rtol=1e-10))
    state = FluidState3D.zeros(GRID)
    rng = np.random.default_rng(5)
    for field in state.velocity():
        field[...] = rng.standard_normal(field.shape)
    solver.apply_side_values(state, 0.0)
    before = np.abs(solver.divergence(state, interior)).max()
    report = solver.project(state, 0.1, interior)
    assert report.converged
    after = np.abs(solver.divergence(state, interior)).max()
    assert after < 1e-8 * before
    for axis in range(3):
        closed_solid = (interior.open_fraction(axis) < OPEN_MIN) & interior.solid_faces(axis)
        assert closed_solid.any()
        np.testing.assert_array_equal(state.velocity()[axis][closed_solid],
                                      interior.velocity_faces(axis)[closed_solid])


@pytest.mark.parametrize("advection", ["semi_lagrangian", "maccormack"])
def test_a_body_moving_with_a_uniform_stream_leaves_it_unchanged(advection: str) -> None:
    """A sphere carried by a uniform stream at the stream's own velocity: every ghost of the
    advection and of the viscosity is the stream's velocity and the body's faces carry it,
    so a whole step (advection, viscosity, projection) leaves the stream as it was."""
    speed = 0.4
    points, velocities, triangles = sphere(velocity=(speed, 0.0, 0.0))
    interior = interior_of(points, velocities, triangles)
    sides = DomainBoundaries3D(left=Inflow(speed), right=Outflow(), bottom=WallFreeSlip(),
                               top=WallFreeSlip(), back=WallFreeSlip(), front=WallFreeSlip())
    solver = FluidSolver3D(GRID, density=1.0, viscosity=0.05, boundaries=sides,
                           advection=advection,
                           pressure_solver=PoissonSolverMGPCG3D(rtol=1e-10),
                           viscosity_solver=PoissonSolverMGPCG3D(rtol=1e-12))
    state = FluidState3D.zeros(GRID)
    state.velocity_x[...] = speed
    report = solver.step(state, 0.05, 0.0, interior)
    assert report.pressure_converged
    np.testing.assert_allclose(state.velocity_x, speed, atol=1e-10)
    np.testing.assert_allclose(state.velocity_y, 0.0, atol=1e-10)
    np.testing.assert_allclose(state.velocity_z, 0.0, atol=1e-10)


def test_viscosity_with_a_fixed_body_is_symmetric_and_holds_the_inside() -> None:
    points, velocities, triangles = sphere()
    interior = interior_of(points, velocities, triangles)
    solver = FluidSolver3D(GRID, density=1.0, viscosity=0.1,
                           boundaries=DomainBoundaries3D.closed_box())
    rng = np.random.default_rng(2)
    for axis, shape in enumerate((GRID.shape_faces_x, GRID.shape_faces_y, GRID.shape_faces_z)):
        field = rng.standard_normal(shape)
        field[interior.solid_faces(axis)] = 0.0
        operator, rhs = solver.viscosity_system(field, axis, 0.2, interior)
        solid = interior.solid_faces(axis)
        assert (operator.diagonal >= 1.0).all()
        # Held points: diagonal 1, no connection, right-hand side their (body) value.
        np.testing.assert_array_equal(operator.diagonal[solid], 1.0)
        np.testing.assert_array_equal(rhs[solid], 0.0)
        # A cut neighbour adds c / theta to the diagonal: more than the plain 1 near the
        # body.
        cut = np.isfinite(interior.cut_theta(axis)).any(axis=0) & ~solid
        assert (operator.diagonal[cut] > 1.0).all()


def test_constant_pressure_gives_no_force_and_hydrostatic_pressure_archimedes() -> None:
    grid = Grid3D(nx=16, ny=16, nz=16, h=0.0625)
    centre = np.array([0.52, 0.47, 0.51])
    points, velocities, triangles = sphere(radius=0.3, subdivisions=4, centre=centre)
    bmap = build_boundary_map_3d(grid, points, velocities, triangles)
    interior = interior_boundary_3d(bmap)
    state = FluidState3D.zeros(grid)
    state.pressure[...] = 7.0
    force = force_traction_3d(grid, bmap, *state.velocity(), state.pressure, 1000.0, 1e-3,
                              interior)
    assert np.abs(force.sum(axis=0)).max() < 1e-10
    gravity = (0.0, -9.81, 0.0)
    _, y, _ = grid.cell_centers()
    state.pressure[...] = 1000.0 * 9.81 * (1.0 - y)
    force = force_traction_3d(grid, bmap, *state.velocity(), state.pressure, 1000.0, 1e-3,
                              interior, gravity=gravity)
    a, b, c = (points[triangles[:, k]] for k in range(3))
    volume = float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)
    total = force.sum(axis=0)
    np.testing.assert_allclose(total[1], 1000.0 * 9.81 * volume, rtol=1e-2)
    assert abs(total[0]) < 1e-3 * total[1] and abs(total[2]) < 1e-3 * total[1]


def test_uniform_stream_through_a_co_moving_surface_has_no_viscous_traction() -> None:
    """A uniform velocity equal to the surface's own: no shear, so with zero pressure the
    traction vanishes (every sample's difference to the wall velocity is 0)."""
    stream = (0.2, 0.1, -0.3)
    points, velocities, triangles = sphere(velocity=stream)
    bmap = build_boundary_map_3d(GRID, points, velocities, triangles)
    interior = interior_boundary_3d(bmap)
    state = FluidState3D.zeros(GRID)
    for field, value in zip(state.velocity(), stream, strict=True):
        field[...] = value
    force = force_traction_3d(GRID, bmap, *state.velocity(), state.pressure, 1.0, 0.1, interior)
    assert np.abs(force).max() < 1e-12


def test_bad_interior_is_refused_in_one_line() -> None:
    empty = InteriorBoundary3D.empty(Grid3D(nx=4, ny=4, nz=4, h=0.1))
    with pytest.raises(ValueError, match="solid_cells"):
        empty.check(GRID)
    solver = FluidSolver3D(GRID, density=1.0, viscosity=0.0,
                           boundaries=DomainBoundaries3D.closed_box())
    with pytest.raises(ValueError, match="InteriorBoundary3D"):
        solver.project(FluidState3D.zeros(GRID), 0.1, empty)
    with pytest.raises(ValueError, match="grid"):
        force_traction_3d(GRID, build_boundary_map_3d(Grid3D(nx=4, ny=4, nz=4, h=0.1),
                                                      *sphere()[:2], sphere()[2]),
                          *FluidState3D.zeros(GRID).velocity(), np.zeros(GRID.shape_cells),
                          1.0, 0.0)
