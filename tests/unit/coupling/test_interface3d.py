"""The 3D body flux ``W`` and its transpose, the pressure's nodal force: the discrete
identities that make the coupled pressure operator right."""

from __future__ import annotations

import numpy as np
import pytest

from elastoflow.coupling import (
    InterfaceFlux3D,
    build_boundary_map_3d,
    interface_flux_3d,
    interior_boundary_3d,
)
from elastoflow.coupling import _kernels3d
from elastoflow.coupling._area import segment_moments
from elastoflow.fluid import OPEN_MIN
from elastoflow.grid import Grid3D
from elastoflow.solid._tet_mesh import TetrahedralMesh, mesh_box, mesh_sphere, signed_volumes

GRID = Grid3D(nx=16, ny=16, nz=16, h=1.0 / 16)
DENSITY = 1000.0
GRAVITY = 9.81
# 8 cells per diameter, off the grid's symmetry.
SPHERE_RADIUS = 0.25
SPHERE_CENTRE = (0.503, 0.517, 0.489)
# A box whose faces lie on grid planes: 6 x 4 x 5 cells from cell (4, 4, 5).
BOX_SIZE = (0.375, 0.25, 0.3125)
BOX_ORIGIN = (0.25, 0.25, 0.3125)
ROTATION_CENTRE = np.array([0.41, 0.55, 0.47])


@pytest.fixture(scope="module")
def sphere() -> TetrahedralMesh:
    return mesh_sphere(SPHERE_RADIUS, 0.06, center=SPHERE_CENTRE)


@pytest.fixture(scope="module")
def box() -> TetrahedralMesh:
    return mesh_box(BOX_SIZE, counts=(3, 2, 3), origin=BOX_ORIGIN)


def _flux(mesh: TetrahedralMesh, use_tetrahedra: bool = True
          ) -> tuple[InterfaceFlux3D, object]:
    points = mesh.points
    bmap = build_boundary_map_3d(GRID, points, np.zeros_like(points), mesh.boundary_triangles)
    interior = interior_boundary_3d(bmap)
    if use_tetrahedra:
        flux = interface_flux_3d(GRID, bmap, interior, mesh.tetrahedra,
                                 np.array([0, mesh.tetrahedra.shape[0]]))
    else:
        flux = interface_flux_3d(GRID, bmap, interior)
    return flux, interior


def _open_fractions(interior, flux: InterfaceFlux3D) -> np.ndarray:
    return np.concatenate([interior.open_fraction(axis).reshape(-1)
                           for axis in range(3)])[flux.faces]


def _rigid(points: np.ndarray, translation=(0.1, 0.2, -0.3),
           spin=(0.3, -0.7, 0.5)) -> np.ndarray:
    return np.asarray(translation) + np.cross(np.asarray(spin), points - ROTATION_CENTRE)


def _face_centres(flux: InterfaceFlux3D) -> np.ndarray:
    """(x, y, z) of each row's face centre."""
    grid = flux.grid
    counts = np.array([grid.nx, grid.ny, grid.nz])
    sizes = [int(np.prod(counts + np.eye(3, dtype=np.int64)[a])) for a in range(3)]
    offsets = np.concatenate(([0], np.cumsum(sizes)))
    centres = np.empty((flux.faces.shape[0], 3))
    for axis in range(3):
        mine = flux.axis == axis
        shape = tuple(counts + np.eye(3, dtype=np.int64)[axis])
        index = np.array(np.unravel_index(flux.faces[mine] - offsets[axis], shape)).T
        centre = np.asarray(grid.origin) + (index + 0.5) * grid.h
        centre[:, axis] -= 0.5 * grid.h
        centres[mine] = centre
    return centres


def _covered_centroids(mesh: TetrahedralMesh, flux: InterfaceFlux3D) -> np.ndarray:
    """Centroid of each row's covered part from the surface's cross-sections (Green's
    theorem on the section segments: independent of the tetrahedra)."""
    grid = flux.grid
    counts = (grid.nx, grid.ny, grid.nz)
    centres = _face_centres(flux)
    centroids = centres.copy()
    for axis in range(3):
        u, v = (axis + 1) % 3, (axis + 2) % 3
        planes = counts[axis] + 1
        per_plane = np.zeros(planes, dtype=np.int64)
        _kernels3d.plane_sections(mesh.points, mesh.boundary_triangles, axis,
                                  float(grid.origin[axis]), grid.h, planes, False, per_plane,
                                  np.zeros(planes, dtype=np.int64), np.zeros((0, 4)))
        offsets = np.concatenate(([0], np.cumsum(per_plane)))
        segments = np.empty((offsets[-1], 4))
        per_plane[:] = 0
        _kernels3d.plane_sections(mesh.points, mesh.boundary_triangles, axis,
                                  float(grid.origin[axis]), grid.h, planes, True, per_plane,
                                  offsets[:-1].copy(), segments)
        for r in np.flatnonzero(flux.axis == axis):
            centre = centres[r]
            plane = int(round((centre[axis] - grid.origin[axis]) / grid.h))
            moments = np.zeros((1, 1, 3))
            segment_moments(segments[offsets[plane]:offsets[plane + 1]],
                            centre[u] - 0.5 * grid.h, centre[v] - 0.5 * grid.h, grid.h, 1, 1,
                            moments)
            area, first_u, first_v = moments[0, 0]
            if area > 0.0:
                centroids[r, u] = centre[u] + first_u / area
                centroids[r, v] = centre[v] + first_v / area
    return centroids


@pytest.mark.parametrize("shape", ["sphere", "box"])
@pytest.mark.parametrize("use_tetrahedra", [True, False])
def test_translation_gives_the_covered_fraction(shape, use_tetrahedra, request):
    mesh = request.getfixturevalue(shape)
    flux, interior = _flux(mesh, use_tetrahedra)
    fraction = _open_fractions(interior, flux)
    for axis in range(3):
        velocity = np.zeros_like(mesh.points)
        velocity[:, axis] = 1.0
        face_flux = flux.face_flux(velocity)
        mine = flux.axis == axis
        # Faces the fluid closes carry the whole face's flux.
        expected = np.where(fraction[mine] < OPEN_MIN, 1.0, 1.0 - fraction[mine])
        np.testing.assert_allclose(face_flux[mine], expected, rtol=0, atol=1e-12)
        np.testing.assert_allclose(face_flux[~mine], 0.0, rtol=0, atol=1e-12)


@pytest.mark.parametrize("use_tetrahedra", [True, False])
def test_rotation_gives_the_flux_at_the_covered_centroid(sphere, use_tetrahedra):
    """``W v = (1 - A) v_n(c)`` with c the covered part's centroid from the surface sections
    (the face centre where the fluid closes the face and it carries all of it)."""
    flux, interior = _flux(sphere, use_tetrahedra)
    fraction = _open_fractions(interior, flux)
    velocity = _rigid(sphere.points)
    closed = fraction < OPEN_MIN
    where = np.where(closed[:, None], _face_centres(flux), _covered_centroids(sphere, flux))
    rigid = _rigid(where)[np.arange(flux.faces.shape[0]), flux.axis]
    expected = np.where(closed, 1.0, 1.0 - fraction) * rigid
    np.testing.assert_allclose(flux.face_flux(velocity), expected, rtol=0, atol=1e-12)


def test_tetrahedra_and_cones_agree_for_affine_motion(sphere):
    with_tetrahedra, _ = _flux(sphere, True)
    with_cones, _ = _flux(sphere, False)
    np.testing.assert_array_equal(with_tetrahedra.faces, with_cones.faces)
    strain = np.array([[0.2, 0.1, -0.3], [0.05, -0.4, 0.2], [0.3, 0.0, 0.1]])
    velocity = _rigid(sphere.points) + (sphere.points - ROTATION_CENTRE) @ strain.T
    np.testing.assert_allclose(with_tetrahedra.face_flux(velocity),
                               with_cones.face_flux(velocity), rtol=0, atol=1e-12)


@pytest.mark.parametrize("shape", ["sphere", "box"])
@pytest.mark.parametrize("use_tetrahedra", [True, False])
def test_uniform_pressure_exerts_no_force_and_no_torque(shape, use_tetrahedra, request):
    mesh = request.getfixturevalue(shape)
    flux, _ = _flux(mesh, use_tetrahedra)
    forces = flux.pressure_forces(np.full(GRID.shape_cells, 1.0e5))
    # Scale: 1e5 Pa on a face of h^2.
    scale = 1.0e5 * GRID.h**2
    np.testing.assert_allclose(forces.sum(axis=0), 0.0, rtol=0, atol=1e-12 * scale)
    torque = np.cross(mesh.points - ROTATION_CENTRE, forces).sum(axis=0)
    np.testing.assert_allclose(torque, 0.0, rtol=0, atol=1e-12 * scale)


@pytest.mark.parametrize("shape, tolerance", [("box", 1e-12), ("sphere", 0.01)])
def test_hydrostatic_pressure_gives_archimedes(shape, tolerance, request):
    """``p = -rho g y`` pushes the body up by rho g V (V the mesh's volume): exactly for a
    box on the grid, within 1 % (0.33 % measured) for a sphere 8 cells across."""
    mesh = request.getfixturevalue(shape)
    flux, _ = _flux(mesh)
    y = GRID.origin[1] + (np.arange(GRID.ny) + 0.5) * GRID.h
    pressure = np.broadcast_to(-DENSITY * GRAVITY * y[None, :, None], GRID.shape_cells)
    force = flux.pressure_forces(pressure).sum(axis=0)
    weight = DENSITY * GRAVITY * signed_volumes(mesh.points, mesh.tetrahedra).sum()
    assert force[1] == pytest.approx(weight, rel=tolerance)
    np.testing.assert_allclose(force[[0, 2]], 0.0, rtol=0, atol=1e-9 * weight)


@pytest.mark.parametrize("use_tetrahedra", [True, False])
def test_rigid_flux_out_of_every_closed_set_of_cells_is_zero(sphere, use_tetrahedra):
    flux, _ = _flux(sphere, use_tetrahedra)
    velocity = _rigid(sphere.points)
    everywhere = np.ones(GRID.shape_cells, dtype=np.bool_)
    assert abs(flux.cell_flux(velocity, everywhere).sum()) < 1e-12
    # Over the cells the pressure equation has: the cells it drops keep a rigid flux of 0.
    assert abs(flux.cell_flux(velocity).sum()) < 1e-12


def test_uniform_expansion_leaves_the_cells_it_fills_at_their_divergence(sphere):
    """``v = e (x - x0)``: the cells the pressure equation drops lie inside the body, closed
    all round, each with a net outflow ``div v h^3 = 3 e h^3``, so the cells it has take in
    exactly their sum (a rigid motion: 0)."""
    flux, _ = _flux(sphere)
    rate = 0.7
    expanding = rate * (sphere.points - ROTATION_CENTRE)
    dropped = int((~flux.active).sum())
    assert dropped > 10
    total = flux.cell_flux(expanding).sum()
    assert total == pytest.approx(-3.0 * rate * GRID.h * dropped, rel=1e-12)


def test_force_is_the_transpose_of_the_flux(sphere):
    flux, _ = _flux(sphere)
    generator = np.random.default_rng(3)
    pressure = generator.normal(size=GRID.shape_cells)
    velocity = generator.normal(size=sphere.points.shape)
    power = (flux.pressure_forces(pressure) * velocity).sum()
    work = GRID.h**2 * (np.where(flux.active, pressure, 0.0) * flux.cell_flux(velocity)).sum()
    assert power == pytest.approx(work, rel=1e-12)


def test_cell_rows_are_d_w_on_the_pressure_cells(sphere):
    flux, _ = _flux(sphere)
    cells, rows = flux.cell_rows()
    assert np.all(np.diff(cells) > 0)
    assert flux.active.reshape(-1)[cells].all()
    generator = np.random.default_rng(5)
    velocity = generator.normal(size=sphere.points.shape)
    pressure = generator.normal(size=GRID.shape_cells)
    flux_by_cell = flux.cell_flux(velocity).reshape(-1)
    np.testing.assert_allclose(rows.times(velocity), flux_by_cell[cells], atol=1e-12)
    others = np.setdiff1d(np.arange(flux_by_cell.shape[0]), cells)
    np.testing.assert_array_equal(flux_by_cell[others], 0.0)
    forces = GRID.h**2 * rows.transpose_times(pressure.reshape(-1)[cells]).reshape(-1, 3)
    np.testing.assert_allclose(forces, flux.pressure_forces(pressure), atol=1e-14)


def test_a_body_with_tetrahedra_beside_an_obstacle(sphere, box):
    """Body 0 by its tetrahedra, body 1 (no tetrahedra: an obstacle) by signed cones."""
    shift = np.array([0.0, 0.0, 0.0])
    points = np.concatenate((box.points - np.array([0.125, 0.125, 0.0]),
                             0.5 * (sphere.points - SPHERE_CENTRE) + [0.75, 0.7, 0.5] + shift))
    count = box.points.shape[0]
    triangles = np.concatenate((box.boundary_triangles, sphere.boundary_triangles + count))
    owner = np.repeat([0, 1], [box.boundary_triangles.shape[0],
                               sphere.boundary_triangles.shape[0]])
    bmap = build_boundary_map_3d(GRID, points, np.zeros_like(points), triangles, owner)
    interior = interior_boundary_3d(bmap)
    flux = interface_flux_3d(GRID, bmap, interior, box.tetrahedra,
                             np.array([0, box.tetrahedra.shape[0]]))
    forces = flux.pressure_forces(np.full(GRID.shape_cells, 1.0))
    np.testing.assert_allclose(forces[:count].sum(axis=0), 0.0, atol=1e-14)
    np.testing.assert_allclose(forces[count:].sum(axis=0), 0.0, atol=1e-14)
    fraction = _open_fractions(interior, flux)
    velocity = np.zeros_like(points)
    velocity[:, 2] = 1.0
    mine = flux.axis == 2
    np.testing.assert_allclose(flux.face_flux(velocity)[mine],
                               np.where(fraction[mine] < OPEN_MIN, 1.0, 1.0 - fraction[mine]),
                               atol=1e-12)


def test_bad_input_is_refused_in_one_line(box):
    points = box.points
    bmap = build_boundary_map_3d(GRID, points, np.zeros_like(points), box.boundary_triangles)
    interior = interior_boundary_3d(bmap)
    offsets = np.array([0, box.tetrahedra.shape[0]])
    other = Grid3D(nx=8, ny=8, nz=8, h=1.0 / 8)
    cases = [
        ((other, bmap, interior), "must be the grid"),
        ((GRID, bmap, "interior"), "must be an InteriorBoundary3D"),
        ((GRID, "map", interior), "must be a BoundaryMap3D"),
        ((GRID, bmap, interior, box.tetrahedra, None), "give both or neither"),
        ((GRID, bmap, interior, box.tetrahedra[:, :3], offsets), "expected integers"),
        ((GRID, bmap, interior, box.tetrahedra + points.shape[0], offsets), "must lie in"),
        ((GRID, bmap, interior, box.tetrahedra, np.array([0, 5])), "must rise from 0"),
    ]
    for arguments, message in cases:
        with pytest.raises(ValueError, match=message) as raised:
            interface_flux_3d(*arguments)
        assert "\n" not in str(raised.value)
