"""The body side of the projection, ``W``: exact fluxes for rigid motion, and its transpose
gives the pressure's force (zero for a uniform pressure, Archimedes for a hydrostatic one);
for both the cut-cell and the dual-cell face weights."""

from __future__ import annotations

import numpy as np
import pytest

from elastoflow.coupling import (
    PressureCoupledBodies,
    build_boundary_map,
    interface_flux,
    interior_boundary_dual_cell,
    interior_boundary_from_map,
    obstacle_circle,
    obstacle_rectangle,
)
from elastoflow.fluid import OPEN_MIN
from elastoflow.grid import Grid2D
from elastoflow.solid import mesh_from_polygon

GRID = Grid2D(48, 40, 1.0 / 48.0)

INTERIORS = {"cut_cell": interior_boundary_from_map, "dual_cell": interior_boundary_dual_cell}
treatments = pytest.mark.parametrize("treatment", list(INTERIORS))


def _outlines():
    yield obstacle_circle((0.47, 0.41), 0.173, segments=61)
    yield obstacle_rectangle((0.2031, 0.3117), (0.6452, 0.4483))


@treatments
@pytest.mark.parametrize("index", [0, 1])
def test_rigid_translation_gives_the_solid_part_of_every_face(index: int, treatment: str) -> None:
    obstacle = list(_outlines())[index]
    points = obstacle.points_at(0.0)
    velocity = np.array([0.37, -1.21])
    velocities = np.tile(velocity, (points.shape[0], 1))
    bmap = build_boundary_map(GRID, points, velocities, obstacle.edges)
    interior = INTERIORS[treatment](GRID, bmap)
    flux = interface_flux(GRID, bmap, interior)
    face_flux = flux.face_flux(velocities)
    u_faces = (GRID.nx + 1) * GRID.ny
    is_u = flux.axis == 0
    open_fraction = np.where(
        is_u, interior.open_fraction_x.reshape(-1)[np.minimum(flux.faces, u_faces - 1)],
        interior.open_fraction_y.reshape(-1)[np.maximum(flux.faces - u_faces, 0)])
    component = np.where(is_u, velocity[0], velocity[1])
    solid = np.where(open_fraction < OPEN_MIN, 1.0, 1.0 - open_fraction)
    assert np.allclose(face_flux, solid * component, atol=1e-12)
    # Every partly covered face has a row (faces deep inside, between cells the pressure
    # equation does not have, are left out).
    partly = np.count_nonzero((interior.open_fraction_x < 1.0)
                              & (interior.open_fraction_x >= OPEN_MIN)) + np.count_nonzero(
        (interior.open_fraction_y < 1.0) & (interior.open_fraction_y >= OPEN_MIN))
    assert np.count_nonzero(solid < 1.0) == partly
    covered = np.count_nonzero(interior.open_fraction_x < 1.0) + np.count_nonzero(
        interior.open_fraction_y < 1.0)
    assert partly < flux.faces.shape[0] < covered


class _Held:
    """A body that does not move (zero compliance)."""

    def velocity_change(self, forces, out=None):
        if out is not None:
            out[...] = 0.0
            return out
        return np.zeros_like(forces)

    def compliance(self, dofs):
        return np.zeros((len(dofs), len(dofs)))

    def compliance_factor(self, dofs):
        return None


def _active_cells(grid, interior):
    """Active as in the pressure operator: a cell with an interior face open by OPEN_MIN."""
    open_x = interior.open_fraction_x >= OPEN_MIN
    open_y = interior.open_fraction_y >= OPEN_MIN
    active = np.zeros(grid.shape_cells, dtype=bool)
    active[1:, :] |= open_x[1:-1, :]
    active[:-1, :] |= open_x[1:-1, :]
    active[:, 1:] |= open_y[:, 1:-1]
    active[:, :-1] |= open_y[:, 1:-1]
    return active


def _pressure_forces(obstacle, pressure_of, gravity=(0.0, 0.0), treatment="cut_cell"):
    """Nodal forces of a cell pressure field on the outline, meshed, as a held body."""
    mesh = mesh_from_polygon(obstacle.points_at(0.0), element_size=0.05)
    points = mesh.points
    zeros = np.zeros_like(points)
    bmap = build_boundary_map(GRID, points, zeros, mesh.boundary_edges)
    interior = INTERIORS[treatment](GRID, bmap)
    flux = interface_flux(GRID, bmap, interior, mesh.triangles,
                          np.array([0, mesh.triangle_count]))
    active = _active_cells(GRID, interior)
    x, y = GRID.cell_centers()
    coupled = PressureCoupledBodies(flux, zeros, [_Held()], [0, points.shape[0]], 1000.0, 0.01,
                                    bmap=bmap, gravity=gravity)
    coupled.add_to_rhs(np.zeros(GRID.shape_cells), 1.0, active)
    coupled.respond(pressure_of(x, y), active, np.zeros(GRID.shape_faces_x),
                    np.zeros(GRID.shape_faces_y))
    return points, coupled.pressure_forces


@treatments
@pytest.mark.parametrize("index", [0, 1])
def test_flux_pressure_forces_are_what_the_coupled_answer_applies(index: int,
                                                                  treatment: str) -> None:
    """``InterfaceFlux.pressure_forces`` (the last pressure's force the incremental form
    holds on the bodies) is the force `PressureCoupledBodies.respond` applies for the same
    pressure, on the same active cells; inactive cells' values do not count."""
    obstacle = list(_outlines())[index]
    x, y = GRID.cell_centers()
    field = 1.0e3 * np.sin(3.0 * x + 1.0) * np.cos(2.0 * y) + 40.0 * x * y

    points, expected = _pressure_forces(obstacle, lambda x, y: field, treatment=treatment)
    mesh = mesh_from_polygon(obstacle.points_at(0.0), element_size=0.05)
    bmap = build_boundary_map(GRID, points, np.zeros_like(points), mesh.boundary_edges)
    interior = INTERIORS[treatment](GRID, bmap)
    flux = interface_flux(GRID, bmap, interior, mesh.triangles,
                          np.array([0, mesh.triangle_count]))
    forces = flux.pressure_forces(field, interior.open_fraction_x, interior.open_fraction_y)
    assert forces.shape == points.shape
    assert np.abs(expected).max() > 1.0
    assert np.allclose(forces, expected, rtol=1e-12, atol=1e-9 * np.abs(expected).max())
    garbage = np.where(_active_cells(GRID, interior), field, 1.0e9)
    assert np.array_equal(
        flux.pressure_forces(garbage, interior.open_fraction_x, interior.open_fraction_y),
        forces)


@treatments
@pytest.mark.parametrize("index", [0, 1])
def test_uniform_pressure_exerts_no_net_force_or_torque(index: int, treatment: str) -> None:
    obstacle = list(_outlines())[index]
    points, forces = _pressure_forces(obstacle, lambda x, y: np.full(x.shape, 1.0e4),
                                      treatment=treatment)
    centre = np.array([0.3, 0.5])
    arm = points - centre
    torque = np.sum(arm[:, 0] * forces[:, 1] - arm[:, 1] * forces[:, 0])
    scale = 1.0e4 * 0.173
    assert np.abs(forces.sum(axis=0)).max() < 1e-10 * scale
    assert abs(torque) < 1e-9 * scale * 0.173
    # ... while it does push on every part of the outline (inwards).
    assert np.abs(forces).sum() > scale


@treatments
@pytest.mark.parametrize("index", [0, 1])
def test_hydrostatic_pressure_gives_archimedes(index: int, treatment: str) -> None:
    """With the fluid's gravity named, the hydrostatic pressure's force is the exact
    Archimedes force of the polygon, whatever the cut cells; without it ``W`` alone is off by
    up to half a cell of height per straight edge lying inside a row (7 % on the rectangle)."""
    obstacle = list(_outlines())[index]
    rho_g = 1000.0 * 9.81
    _, forces = _pressure_forces(obstacle, lambda x, y: rho_g * (1.0 - y), (0.0, -9.81),
                                 treatment)
    outline = obstacle.points_at(0.0)
    area = 0.5 * np.sum(outline[:, 0] * np.roll(outline[:, 1], -1)
                        - np.roll(outline[:, 0], -1) * outline[:, 1])
    assert abs(forces[:, 0].sum()) < 1e-9 * rho_g * area
    assert forces[:, 1].sum() == pytest.approx(rho_g * area, rel=1e-9)
    _, plain = _pressure_forces(obstacle, lambda x, y: rho_g * (1.0 - y), treatment=treatment)
    assert plain[:, 1].sum() == pytest.approx(rho_g * area, rel=0.1)


def _exact_force_and_torque(points, edges, pressure_of, centre):
    """``-∮ p n ds`` and its torque about ``centre``, 8-point Gauss on every edge."""
    nodes, weights = np.polynomial.legendre.leggauss(8)
    start, step = points[edges[:, 0]], points[edges[:, 1]] - points[edges[:, 0]]
    normal = np.column_stack((step[:, 1], -step[:, 0]))  # outward, times the edge length
    force, torque = np.zeros(2), 0.0
    for node, weight in zip(nodes, weights):
        at = start + 0.5 * (node + 1.0) * step
        piece = -(0.5 * weight * pressure_of(at[:, 0], at[:, 1]))[:, None] * normal
        force += piece.sum(axis=0)
        arm = at - centre
        torque += float(np.sum(arm[:, 0] * piece[:, 1] - arm[:, 1] * piece[:, 0]))
    return force, torque


@treatments
@pytest.mark.parametrize("field", ["linear", "swirl"])
def test_pressure_force_and_torque_on_a_slender_body_match_the_boundary_integral(
        field: str, treatment: str) -> None:
    """The windmill (four blades 3.5 cm wide, 9 cells at 256^2) in a smooth pressure field:
    ``h (DW)^T p`` gives the exact ``-∮ p n ds`` and its torque about the hub within 1 %
    (measured 0.0 % and 0.5 %). The coupled scheme moves the body with this force, so its
    lever arms matter as much as its sum."""
    from elastoflow.solid import mesh_windmill

    grid = Grid2D(256, 256, 1.0 / 256)
    # The windmill scene's body: hub radius 4 cm, blades to 20 cm.
    centre = np.array([0.62, 0.5])
    mesh = mesh_windmill(0.04, 4, 0.16, 0.035, center=(0.62, 0.5), element_size=0.05)
    points = mesh.points
    zeros = np.zeros_like(points)
    bmap = build_boundary_map(grid, points, zeros, mesh.boundary_edges)
    interior = INTERIORS[treatment](grid, bmap)
    flux = interface_flux(grid, bmap, interior, mesh.triangles,
                          np.array([0, mesh.triangle_count]))
    active = _active_cells(grid, interior)

    def pressure_of(x, y):
        if field == "linear":
            return 1.0e3 * x
        return 1.0e3 * np.hypot(x - 0.62, y - 0.5) * np.sin(4.0 * np.arctan2(y - 0.5, x - 0.62))

    x, y = grid.cell_centers()
    coupled = PressureCoupledBodies(flux, zeros, [_Held()], [0, points.shape[0]], 1000.0, 0.01)
    coupled.add_to_rhs(np.zeros(grid.shape_cells), 1.0, active)
    coupled.respond(pressure_of(x, y), active, np.zeros(grid.shape_faces_x),
                    np.zeros(grid.shape_faces_y))
    forces = coupled.pressure_forces
    arm = points - centre
    torque = float(np.sum(arm[:, 0] * forces[:, 1] - arm[:, 1] * forces[:, 0]))
    exact_force, exact_torque = _exact_force_and_torque(points, mesh.boundary_edges,
                                                        pressure_of, centre)
    scale = np.abs(exact_force).max() if field == "linear" else abs(exact_torque) / 0.2
    assert np.abs(forces.sum(axis=0) - exact_force).max() <= 0.01 * scale
    if field == "swirl":
        assert torque == pytest.approx(exact_torque, rel=0.01)


@treatments
def test_each_covered_face_takes_the_velocity_of_the_body_that_covers_it(treatment: str) -> None:
    """An elastic disc below a wall (as the windmill below its pipe): rows of faces that
    cross the disc come before rows that cross only the wall. Every face row must use the
    nodes of the body whose outline covers the face; a winding left over from the disc's
    rows once handed the wall's faces, and their pressure, to a node of the disc."""
    grid = Grid2D(64, 64, 1.0 / 64)
    angles = np.linspace(0.0, 2.0 * np.pi, 40, endpoint=False)
    disc = mesh_from_polygon(np.column_stack((0.5 + 0.15 * np.cos(angles),
                                              0.35 + 0.15 * np.sin(angles))), element_size=0.05)
    wall = obstacle_rectangle((0.1011, 0.7043), (0.8937, 0.7791))
    nb = disc.points.shape[0]
    points = np.concatenate([disc.points, wall.points_at(0.0)])
    edges = np.concatenate([disc.boundary_edges, wall.edges + nb])
    edge_body = np.concatenate([np.zeros(len(disc.boundary_edges), dtype=np.int64),
                                np.ones(len(wall.edges), dtype=np.int64)])
    bmap = build_boundary_map(grid, points, np.zeros_like(points), edges, edge_body)
    interior = INTERIORS[treatment](grid, bmap)
    flux = interface_flux(grid, bmap, interior, disc.triangles,
                          np.array([0, disc.triangle_count]))
    u_faces = (grid.nx + 1) * grid.ny
    is_u = flux.faces < u_faces
    face_y = np.where(is_u, (flux.faces % grid.ny + 0.5) * grid.h,
                      ((flux.faces - u_faces) % (grid.ny + 1)) * grid.h)
    matrix = flux.matrix.tocsr()
    for row, y in enumerate(face_y):
        nodes = matrix.indices[matrix.indptr[row]:matrix.indptr[row + 1]] // 2
        nodes = nodes[matrix.data[matrix.indptr[row]:matrix.indptr[row + 1]] != 0.0]
        if y > 0.6:
            assert (nodes >= nb).all(), (row, y, nodes)
        else:
            assert (nodes < nb).all(), (row, y, nodes)
