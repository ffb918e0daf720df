"""Tetrahedral meshes: makers' volumes and normals, validation errors, file round trips."""

from __future__ import annotations

import importlib.util

import meshio
import numpy as np
import pytest

from elastoflow.io import write_tetrahedral_mesh
from elastoflow.solid import (
    TetrahedralMesh,
    mesh_box,
    mesh_cylinder,
    mesh_sphere,
    nodes_in_box_3d,
    read_tetrahedral_mesh,
    tetrahedralize_surface,
)
from elastoflow.solid._tet_mesh import signed_volumes

UNIT_TETRAHEDRON = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])


def assert_closed_and_outward(mesh: TetrahedralMesh) -> None:
    """Every boundary edge is used once in each direction (a closed, consistently oriented
    surface), the enclosed volume by the divergence theorem equals the mesh volume (normals
    outward), and each boundary face's own tetrahedron lies behind it."""
    faces = mesh.boundary_triangles
    n = mesh.point_count
    directed = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    forward = np.sort(directed[:, 0] * n + directed[:, 1])
    backward = np.sort(directed[:, 1] * n + directed[:, 0])
    np.testing.assert_array_equal(forward, backward)
    p = mesh.points[faces]
    enclosed = np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2])).sum() / 6.0
    assert enclosed == pytest.approx(mesh.volume, rel=1e-12)


def test_box_counts_volume_quality_and_alternation() -> None:
    mesh = mesh_box((0.3, 0.2, 0.1), counts=(3, 2, 1), origin=(1.0, 2.0, 3.0))
    assert mesh.tetrahedron_count == 5 * 6
    assert mesh.volume == pytest.approx(0.006, rel=1e-12)
    assert np.all(signed_volumes(mesh.points, mesh.tetrahedra) > 0.0)
    assert mesh.boundary_area == pytest.approx(2 * (0.06 + 0.03 + 0.02), rel=1e-12)
    assert_closed_and_outward(mesh)
    np.testing.assert_allclose(mesh.points.min(0), [1.0, 2.0, 3.0])
    # Cubic cells: the central tetrahedron is regular (radius ratio 1), the corner ones 0.73.
    cube = mesh_box((1.0, 1.0, 1.0), counts=(2, 2, 2))
    np.testing.assert_allclose(np.sort(np.unique(np.round(cube.quality, 12))),
                               [np.sqrt(3.0) - 1.0, 1.0])
    # Neighbouring cells are mirror images: the cell at (1, 0, 0) has its central tetrahedron
    # on the other four corners, so both main-diagonal families occur equally often.
    edges = cube.points[cube.tetrahedra[:, [1, 2, 3]]] - cube.points[cube.tetrahedra[:, [0]]]
    directions = np.abs(np.round(edges.reshape(-1, 3) / 0.5)).astype(int)
    face_diagonals = directions[(directions.sum(1) == 2)]
    assert len({tuple(d) for d in face_diagonals}) == 3


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_box_split_is_mirror_symmetric(axis: int) -> None:
    # No preferred direction: with even cell counts, the reflection x_axis -> l - x_axis maps
    # the set of tetrahedra onto itself (a 6-tetrahedron split along one main diagonal, or a
    # 5-tetrahedron split repeated without alternation, does not).
    size = (0.4, 0.2, 0.6)
    mesh = mesh_box(size, counts=(4, 2, 6))
    mirrored = mesh.points.copy()
    mirrored[:, axis] = size[axis] - mirrored[:, axis]
    key = np.round(mesh.points / 0.1).astype(np.int64) @ np.array([10_000, 100, 1])
    mirror_key = np.round(mirrored / 0.1).astype(np.int64) @ np.array([10_000, 100, 1])
    order = np.argsort(key)
    image = order[np.searchsorted(key[order], mirror_key)]
    np.testing.assert_array_equal(key[image], mirror_key)
    original = {tuple(sorted(t)) for t in mesh.tetrahedra.tolist()}
    reflected = {tuple(sorted(t)) for t in image[mesh.tetrahedra].tolist()}
    assert reflected == original


@pytest.mark.parametrize("element_size,tolerance", [(0.5, 0.04), (0.25, 0.01), (0.125, 0.003)])
def test_cylinder_volume_and_area(element_size: float, tolerance: float) -> None:
    # Inscribed polygon of s sides: volume pi r^2 L (1 - O(1/s^2)), second order in h.
    mesh = mesh_cylinder(1.0, 2.0, element_size, center=(0.5, -1.0, 2.0))
    assert mesh.volume == pytest.approx(2.0 * np.pi, rel=tolerance)
    assert mesh.boundary_area == pytest.approx(6.0 * np.pi, rel=tolerance)
    assert mesh.quality.min() > 0.35
    assert_closed_and_outward(mesh)
    np.testing.assert_allclose(mesh.points.mean(0)[2], 2.0, atol=1e-12)


@pytest.mark.parametrize("element_size,tolerance", [(0.5, 0.07), (0.25, 0.017),
                                                    (0.125, 0.006)])
def test_sphere_volume_area_and_quality(element_size: float, tolerance: float) -> None:
    mesh = mesh_sphere(1.0, element_size, center=(1.0, 2.0, 3.0))
    assert mesh.volume == pytest.approx(4.0 / 3.0 * np.pi, rel=tolerance)
    assert mesh.boundary_area == pytest.approx(4.0 * np.pi, rel=tolerance)
    # Boundary nodes lie on the sphere.
    surface = np.unique(mesh.boundary_triangles)
    np.testing.assert_allclose(np.linalg.norm(mesh.points[surface] - [1, 2, 3], axis=1), 1.0,
                               rtol=1e-12)
    assert mesh.quality.min() > 0.19
    assert np.median(mesh.quality) > 0.7
    assert_closed_and_outward(mesh)


def test_outward_normals_of_a_box_point_along_the_axes() -> None:
    mesh = mesh_box((1.0, 1.0, 1.0), counts=(2, 2, 2), center=(0.0, 0.0, 0.0))
    centres = mesh.points[mesh.boundary_triangles].mean(axis=1)
    normals = mesh.boundary_normals
    side = np.argmax(np.abs(centres), axis=1)
    expected = np.zeros_like(normals)
    expected[np.arange(len(side)), side] = np.sign(centres[np.arange(len(side)), side])
    np.testing.assert_allclose(normals, expected, atol=1e-14)


def test_element_heights_of_the_unit_tetrahedron() -> None:
    mesh = TetrahedralMesh(UNIT_TETRAHEDRON, [[0, 1, 2, 3]])
    # Largest face: the slanted one, area sqrt(3)/2; altitude onto it 1/sqrt(3).
    assert mesh.min_element_height == pytest.approx(1.0 / np.sqrt(3.0), rel=1e-14)
    assert mesh.volume == pytest.approx(1.0 / 6.0, rel=1e-14)
    assert mesh.boundary_triangles.shape == (4, 3)


def test_two_tetrahedra_share_an_interior_face() -> None:
    points = np.concatenate([UNIT_TETRAHEDRON, [[1.0, 1.0, 1.0]]])
    mesh = TetrahedralMesh(points, [[0, 1, 2, 3], [1, 2, 3, 4]])
    assert mesh.boundary_triangles.shape == (6, 3)
    assert_closed_and_outward(mesh)


@pytest.mark.parametrize("points,tetrahedra,message", [
    (UNIT_TETRAHEDRON[:, :2], [[0, 1, 2, 3]], r"points shape \(4, 2\): must be \(n >= 4, 3\)"),
    (UNIT_TETRAHEDRON, [[0, 1, 2]], r"tetrahedra shape \(1, 3\)"),
    (UNIT_TETRAHEDRON, [[0.0, 1, 2, 3]], "dtype float64: must be an integer type"),
    (UNIT_TETRAHEDRON, [[0, 1, 2, 4]], r"tetrahedron 0 = \[0, 1, 2, 4\]: node indices must lie"),
    (UNIT_TETRAHEDRON, [[0, 1, 2, 2]], "is degenerate: a node repeats"),
    (UNIT_TETRAHEDRON, [[0, 2, 1, 3]], "is inverted: volume -0.167 m\\^3, must be positively"),
    (np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]]), [[0, 1, 2, 3]],
     "is degenerate: volume 0 m\\^3"),
    (np.concatenate([UNIT_TETRAHEDRON, [[5.0, 5, 5]]]), [[0, 1, 2, 3]],
     "vertex 4 is used by no tetrahedron"),
    (np.concatenate([UNIT_TETRAHEDRON, [[0.2, 0.2, 0.2]]]), [[0, 1, 2, 3], [0, 1, 2, 4]],
     r"face \(0, 2, 1\) is used in the same orientation by tetrahedra 0 and another"),
    (np.concatenate([UNIT_TETRAHEDRON, [[0.2, 0.2, -1], [0.3, 0.3, 2]]]),
     [[0, 1, 2, 3], [0, 2, 1, 4], [0, 1, 2, 5]], r"face \(0, 1, 2\) is non-manifold"),
    (np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, np.nan]]), [[0, 1, 2, 3]],
     "vertex 3 is not finite"),
])
def test_mesh_validation(points: np.ndarray, tetrahedra: list, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        TetrahedralMesh(points, np.array(tetrahedra))


def test_maker_arguments_are_checked() -> None:
    with pytest.raises(ValueError, match="box side y = -1"):
        mesh_box((1.0, -1.0, 1.0), 0.5)
    with pytest.raises(ValueError, match="give exactly one of element_size and counts"):
        mesh_box((1.0, 1.0, 1.0))
    with pytest.raises(ValueError, match=r"counts = \(1, 0, 1\)"):
        mesh_box((1.0, 1.0, 1.0), counts=(1, 0, 1))
    with pytest.raises(ValueError, match="cylinder radius = 0.0"):
        mesh_cylinder(0.0, 1.0, 0.1)
    with pytest.raises(ValueError, match="element_size = nan"):
        mesh_sphere(1.0, float("nan"))
    with pytest.raises(ValueError, match="center = "):
        mesh_sphere(1.0, 0.5, center=(0.0, 0.0))  # type: ignore[arg-type]


@pytest.mark.parametrize("suffix", [".vtu", ".msh", ".vtk"])
def test_meshio_round_trip(tmp_path, suffix: str) -> None:
    mesh = mesh_cylinder(0.1, 0.3, 0.06)
    path = tmp_path / f"body{suffix}"
    write_tetrahedral_mesh(path, mesh)
    again = read_tetrahedral_mesh(path)
    np.testing.assert_allclose(again.points, mesh.points, rtol=1e-12, atol=1e-15)
    np.testing.assert_array_equal(again.tetrahedra, mesh.tetrahedra)


def test_read_orients_ignores_other_cells_and_rejects_no_tetra(tmp_path) -> None:
    # A file with negatively oriented tetrahedra, a surface block and an unused point.
    points = np.concatenate([UNIT_TETRAHEDRON, [[9.0, 9, 9]]])
    path = tmp_path / "flipped.vtu"
    meshio.write(str(path), meshio.Mesh(points, [("triangle", np.array([[0, 1, 2]])),
                                                 ("tetra", np.array([[0, 2, 1, 3]]))]))
    mesh = read_tetrahedral_mesh(path)
    assert mesh.point_count == 4
    assert mesh.volume == pytest.approx(1.0 / 6.0)
    surface = tmp_path / "surface.vtu"
    meshio.write(str(surface), meshio.Mesh(points, [("triangle", np.array([[0, 1, 2]]))]))
    with pytest.raises(ValueError, match=r"has no tetra cells \(found \['triangle'\]\)"):
        read_tetrahedral_mesh(surface)


def test_nodes_in_box_3d() -> None:
    mesh = mesh_box((1.0, 1.0, 1.0), counts=(2, 2, 2))
    end = nodes_in_box_3d(mesh, (0.0, 0.0, 0.0, 0.0, 1.0, 1.0))
    assert end.size == 9 and np.all(mesh.points[end, 0] == 0.0)
    with pytest.raises(ValueError, match="x0 <= x1"):
        nodes_in_box_3d(mesh, (1.0, 0.0, 0.0, 0.0, 1.0, 1.0))


@pytest.mark.skipif(importlib.util.find_spec("pytetwild") is None,
                    reason="optional extra elastoflow[tetwild] not installed")
@pytest.mark.parametrize("suffix", [".stl", ".obj", ".ply"])
def test_tetrahedralize_closed_surface_file(tmp_path, monkeypatch, suffix: str) -> None:
    # The sphere's own boundary as a surface file: fTetWild's solid must have its volume.
    # It leaves no scratch file in the working directory.
    monkeypatch.chdir(tmp_path)
    sphere = mesh_sphere(1.0, 0.4)
    path = tmp_path / f"ball{suffix}"
    surface = meshio.Mesh(sphere.points, [("triangle", sphere.boundary_triangles)])
    if suffix == ".stl":
        meshio.write(str(path), surface, binary=True)
    else:
        meshio.write(str(path), surface)
    mesh = tetrahedralize_surface(path, 0.5)
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name]
    assert mesh.volume == pytest.approx(sphere.volume, rel=0.01)
    assert_closed_and_outward(mesh)
    with pytest.raises(ValueError, match="triangle node indices must lie"):
        tetrahedralize_surface((sphere.points, sphere.boundary_triangles + 10_000), 0.3)
