"""The staircase boundary: cells by their centres, faces fully open or closed, no cut data;
its interface operator carries the body's whole flux through every closed face."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from elastoflow.coupling import (
    BoundaryCutCell,
    BoundaryStaircase,
    PressureCoupledBodies,
    StaircaseInteriorBoundary,
    build_boundary_map,
    classify_points,
    interface_flux,
    interior_boundary_from_map,
    interior_boundary_staircase,
    obstacle_circle,
    obstacle_rectangle,
)
from elastoflow.fluid import InteriorBoundary
from elastoflow.grid import Grid2D
from elastoflow.solid import mesh_from_polygon

GRID = Grid2D(48, 40, 1.0 / 48.0)
VELOCITY = np.array([0.37, -1.21])


def _outlines():
    yield obstacle_circle((0.47, 0.41), 0.173, segments=61)
    yield obstacle_rectangle((0.2031, 0.3117), (0.6452, 0.4483))


def _map(obstacle, velocity=VELOCITY, shift=(0.0, 0.0)):
    points = obstacle.points_at(0.0) + np.asarray(shift)
    velocities = np.tile(velocity, (points.shape[0], 1))
    return build_boundary_map(GRID, points, velocities, obstacle.edges)


def _expected_faces(solid_cells):
    """Closed when a solid cell touches the face, from the cell flags alone."""
    nx, ny = solid_cells.shape
    closed_x = np.zeros((nx + 1, ny), dtype=bool)
    closed_x[:-1] |= solid_cells
    closed_x[1:] |= solid_cells
    closed_y = np.zeros((nx, ny + 1), dtype=bool)
    closed_y[:, :-1] |= solid_cells
    closed_y[:, 1:] |= solid_cells
    return closed_x, closed_y


@pytest.mark.parametrize("index", [0, 1])
def test_faces_are_open_or_closed_by_the_cell_flags(index: int) -> None:
    bmap = _map(list(_outlines())[index])
    interior = interior_boundary_staircase(GRID, bmap)
    assert isinstance(interior, StaircaseInteriorBoundary)
    np.testing.assert_array_equal(interior.solid_cells, classify_points(GRID, bmap).solid_cells)
    closed_x, closed_y = _expected_faces(interior.solid_cells)
    np.testing.assert_array_equal(interior.solid_faces_x, closed_x)
    np.testing.assert_array_equal(interior.solid_faces_y, closed_y)
    np.testing.assert_array_equal(interior.open_fraction_x, np.where(closed_x, 0.0, 1.0))
    np.testing.assert_array_equal(interior.open_fraction_y, np.where(closed_y, 0.0, 1.0))
    assert np.isinf(interior.cut_theta_x).all() and np.isinf(interior.cut_theta_y).all()
    assert not interior.cut_velocity_x.any() and not interior.cut_velocity_y.any()
    # Rigid translation: every closed face holds the body's velocity, open ones nothing.
    np.testing.assert_allclose(interior.velocity_faces_x, np.where(closed_x, VELOCITY[0], 0.0),
                               atol=1e-12)
    np.testing.assert_allclose(interior.velocity_faces_y, np.where(closed_y, VELOCITY[1], 0.0),
                               atol=1e-12)
    # The cut-cell interior of the same map has fractional faces; this one none.
    cut = interior_boundary_from_map(GRID, bmap)
    fractional = (cut.open_fraction_x > 0.0) & (cut.open_fraction_x < 1.0)
    assert fractional.any()


def test_everything_outside_the_regions_is_empty() -> None:
    bmap = _map(list(_outlines())[0])
    interior = interior_boundary_staircase(GRID, bmap)
    assert interior.regions is not None and interior.regions.shape[0] == 1
    i0, i1, j0, j1 = interior.regions[0]
    empty = InteriorBoundary.empty(GRID)
    for item in dataclasses.fields(InteriorBoundary):
        if item.name == "regions":
            continue
        value = getattr(interior, item.name).copy()
        value[..., i0:i1, j0:j1] = getattr(empty, item.name)[..., i0:i1, j0:j1]
        np.testing.assert_array_equal(value, getattr(empty, item.name), err_msg=item.name)


def test_reusing_the_arrays_gives_the_fresh_result() -> None:
    """A body that moves between steps: rebuilding into the last step's arrays resets the old
    body's faces and gives what a fresh build gives."""
    obstacle = list(_outlines())[0]
    first = interior_boundary_staircase(GRID, _map(obstacle))
    moved = _map(obstacle, shift=(0.21, 0.07))
    again = interior_boundary_staircase(GRID, moved, out=first)
    assert again is first
    fresh = interior_boundary_staircase(GRID, moved)
    for item in dataclasses.fields(InteriorBoundary):
        np.testing.assert_array_equal(getattr(again, item.name), getattr(fresh, item.name),
                                      err_msg=item.name)
    # A plain InteriorBoundary given as ``out`` comes back as a staircase one, same arrays.
    plain = InteriorBoundary.empty(GRID)
    wrapped = interior_boundary_staircase(GRID, moved, out=plain)
    assert isinstance(wrapped, StaircaseInteriorBoundary)
    assert wrapped.solid_cells is plain.solid_cells


def test_the_treatments_build_their_interiors() -> None:
    bmap = _map(list(_outlines())[1])
    assert BoundaryStaircase().name == "staircase" and BoundaryCutCell().name == "cut_cell"
    assert isinstance(BoundaryStaircase().interior(GRID, bmap), StaircaseInteriorBoundary)
    cut = BoundaryCutCell().interior(GRID, bmap)
    reference = interior_boundary_from_map(GRID, bmap)
    assert not isinstance(cut, StaircaseInteriorBoundary)
    for item in dataclasses.fields(InteriorBoundary):
        np.testing.assert_array_equal(getattr(cut, item.name), getattr(reference, item.name))


def _active_cells(interior):
    open_x = interior.open_fraction_x > 0.0
    open_y = interior.open_fraction_y > 0.0
    active = np.zeros(GRID.shape_cells, dtype=bool)
    active[1:, :] |= open_x[1:-1, :]
    active[:-1, :] |= open_x[1:-1, :]
    active[:, 1:] |= open_y[:, 1:-1]
    active[:, :-1] |= open_y[:, 1:-1]
    return active


@pytest.mark.parametrize("index", [0, 1])
def test_closed_faces_carry_the_whole_flux_of_a_rigid_motion(index: int) -> None:
    """Every closed face between a fluid cell and a solid one has a row, which gives the
    body's whole velocity (translation) and its velocity at the solid cell's centre
    (rotation); no other face has one."""
    obstacle = list(_outlines())[index]
    bmap = _map(obstacle)
    interior = interior_boundary_staircase(GRID, bmap)
    flux = interface_flux(GRID, bmap, interior)
    velocities = bmap.velocities
    u_faces = (GRID.nx + 1) * GRID.ny
    is_u = flux.axis == 0
    np.testing.assert_allclose(flux.face_flux(velocities),
                               np.where(is_u, VELOCITY[0], VELOCITY[1]), atol=1e-12)
    active = _active_cells(interior).reshape(-1)
    low_active = np.where(flux.low_cell >= 0, active[np.maximum(flux.low_cell, 0)], False)
    high_active = np.where(flux.high_cell >= 0, active[np.maximum(flux.high_cell, 0)], False)
    assert np.all(low_active ^ high_active)
    closed_x, closed_y = _expected_faces(interior.solid_cells)
    boundary_faces = 0
    for closed, shape, offset in ((closed_x, GRID.shape_faces_x, 0),
                                  (closed_y, GRID.shape_faces_y, u_faces)):
        faces = flux.faces[(flux.faces >= offset) & (flux.faces < offset + closed.size)]
        assert closed.reshape(-1)[faces - offset].all()
        boundary_faces += faces.shape[0]
    assert boundary_faces == flux.faces.shape[0]
    # A meshed body rotating about its centre: the row takes the body's velocity at the
    # solid cell's centre (an obstacle, without triangles, that of its nearest outline point).
    mesh = mesh_from_polygon(obstacle.points_at(0.0), element_size=0.05)
    centre = mesh.points.mean(axis=0)
    omega = 2.3
    arm = mesh.points - centre
    rotating = omega * np.column_stack((-arm[:, 1], arm[:, 0]))
    bmap = build_boundary_map(GRID, mesh.points, rotating, mesh.boundary_edges)
    interior = interior_boundary_staircase(GRID, bmap)
    flux = interface_flux(GRID, bmap, interior, mesh.triangles,
                          np.array([0, mesh.triangle_count]))
    is_u = flux.axis == 0
    active = _active_cells(interior).reshape(-1)
    low_active = np.where(flux.low_cell >= 0, active[np.maximum(flux.low_cell, 0)], False)
    solid_cell = np.where(low_active, flux.high_cell, flux.low_cell)
    x, y = GRID.cell_centers()
    cx, cy = x.reshape(-1)[solid_cell], y.reshape(-1)[solid_cell]
    expected = np.where(is_u, -omega * (cy - centre[1]), omega * (cx - centre[0]))
    np.testing.assert_allclose(flux.face_flux(rotating), expected, atol=1e-12)
    # ... which is the velocity the staircase interior gives those faces.
    u_faces = (GRID.nx + 1) * GRID.ny
    given = np.where(is_u, interior.velocity_faces_x.reshape(-1)[np.minimum(flux.faces,
                                                                            u_faces - 1)],
                     interior.velocity_faces_y.reshape(-1)[np.maximum(flux.faces - u_faces, 0)])
    np.testing.assert_allclose(given, expected, atol=1e-12)


class _Held:
    def velocity_change(self, forces, out=None):
        if out is not None:
            out[...] = 0.0
            return out
        return np.zeros_like(forces)

    def compliance(self, dofs):
        return np.zeros((len(dofs), len(dofs)))

    def compliance_factor(self, dofs):
        return None


@pytest.mark.parametrize("index", [0, 1])
def test_uniform_pressure_exerts_no_net_force_or_torque(index: int) -> None:
    obstacle = list(_outlines())[index]
    mesh = mesh_from_polygon(obstacle.points_at(0.0), element_size=0.05)
    zeros = np.zeros_like(mesh.points)
    bmap = build_boundary_map(GRID, mesh.points, zeros, mesh.boundary_edges)
    interior = interior_boundary_staircase(GRID, bmap)
    flux = interface_flux(GRID, bmap, interior, mesh.triangles,
                          np.array([0, mesh.triangle_count]))
    active = _active_cells(interior)
    coupled = PressureCoupledBodies(flux, zeros, [_Held()], [0, mesh.points.shape[0]], 1000.0,
                                    0.01)
    coupled.add_to_rhs(np.zeros(GRID.shape_cells), 1.0, active)
    coupled.respond(np.full(GRID.shape_cells, 1.0e4), active, np.zeros(GRID.shape_faces_x),
                    np.zeros(GRID.shape_faces_y))
    forces = coupled.pressure_forces
    arm = mesh.points - np.array([0.3, 0.5])
    torque = np.sum(arm[:, 0] * forces[:, 1] - arm[:, 1] * forces[:, 0])
    scale = 1.0e4 * 0.173
    assert np.abs(forces.sum(axis=0)).max() < 1e-10 * scale
    assert abs(torque) < 1e-9 * scale * 0.173
    assert np.abs(forces).sum() > scale


@pytest.mark.parametrize("index", [0, 1])
def test_momentum_exchange_reads_the_first_open_face_beyond_the_staircase(index: int) -> None:
    """Fluid at u = v = 1 on every open face, the body's velocity (0) on the closed ones: with
    the staircase interior every crossing feels the fluid (alpha rho h^2 / dt (1 - 0) per
    crossing on its line's component); the fluid point next to the crossing would often be a
    closed face and give 0. With cut cells the interior changes nothing."""
    from elastoflow.coupling import force_momentum_exchange

    bmap = _map(list(_outlines())[index], velocity=np.zeros(2))
    staircase = interior_boundary_staircase(GRID, bmap)
    u = np.where(staircase.solid_faces_x, 0.0, 1.0)
    v = np.where(staircase.solid_faces_y, 0.0, 1.0)
    density, dt, alpha = 1000.0, 0.01, 0.5
    coefficient = alpha * density * GRID.h**2 / dt
    force = force_momentum_exchange(GRID, bmap, u, v, density, dt, alpha, staircase)
    crossings_x = sum(int(bmap.x_offsets[line + 1] - bmap.x_offsets[line])
                      for line in range(1, bmap.x_offsets.shape[0] - 1, 2))
    crossings_y = sum(int(bmap.y_offsets[line + 1] - bmap.y_offsets[line])
                      for line in range(1, bmap.y_offsets.shape[0] - 1, 2))
    assert force.sum(axis=0) == pytest.approx([coefficient * crossings_x,
                                              coefficient * crossings_y], rel=1e-12)
    blind = force_momentum_exchange(GRID, bmap, u, v, density, dt, alpha)
    assert blind.sum(axis=0)[0] < 0.9 * force.sum(axis=0)[0]
    cut = interior_boundary_from_map(GRID, bmap)
    u_cut = np.where(cut.solid_faces_x, 0.0, 1.0)
    v_cut = np.where(cut.solid_faces_y, 0.0, 1.0)
    np.testing.assert_array_equal(
        force_momentum_exchange(GRID, bmap, u_cut, v_cut, density, dt, alpha, cut),
        force_momentum_exchange(GRID, bmap, u_cut, v_cut, density, dt, alpha))
