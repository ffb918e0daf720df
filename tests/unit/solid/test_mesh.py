"""Mesh makers, boundary loops, validation errors and file reading."""

from __future__ import annotations

import meshio
import numpy as np
import pytest

from elastoflow.solid import (
    TriangleMesh,
    mesh_from_polygon,
    mesh_rectangle,
    mesh_windmill,
    nearest_node,
    nodes_in_box,
    read_mesh,
)
from elastoflow.solid._mesh import signed_areas

SQUARE = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])


def polygon_area(points: np.ndarray, loop: np.ndarray) -> float:
    p = points[loop]
    return 0.5 * float(np.sum(p[:, 0] * np.roll(p[:, 1], -1) - np.roll(p[:, 0], -1) * p[:, 1]))


def assert_body_on_left(mesh: TriangleMesh) -> None:
    """Every boundary edge a->b has the third vertex of its triangle on its left."""
    edges = mesh.boundary_edges
    tri = mesh.triangles
    directed = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    third = np.concatenate([tri[:, 2], tri[:, 0], tri[:, 1]])
    n = mesh.point_count
    lookup = dict(zip((directed[:, 0] * n + directed[:, 1]).tolist(), third.tolist()))
    p = mesh.points
    for a, b in edges:
        c = lookup[int(a) * n + int(b)]
        cross = (p[b, 0] - p[a, 0]) * (p[c, 1] - p[a, 1]) - (p[b, 1] - p[a, 1]) * (p[c, 0] - p[a, 0])
        assert cross > 0.0


@pytest.mark.parametrize("pattern,per_cell", [("alternating", 2), ("crossed", 4)])
def test_rectangle_counts_area_and_loop(pattern: str, per_cell: int) -> None:
    mesh = mesh_rectangle(0.3, 0.1, counts=(6, 2), origin=(1.0, 2.0), pattern=pattern)
    assert mesh.triangle_count == per_cell * 12
    assert mesh.area == pytest.approx(0.03, rel=1e-12)
    assert np.all(signed_areas(mesh.points, mesh.triangles) > 0.0)
    assert len(mesh.boundary_loops) == 1
    assert polygon_area(mesh.points, mesh.boundary_loops[0]) == pytest.approx(0.03, rel=1e-12)
    assert mesh.boundary_edges.shape == (16, 2)
    assert_body_on_left(mesh)
    np.testing.assert_allclose(mesh.points.min(axis=0), [1.0, 2.0])


def test_rectangle_rotated_about_center() -> None:
    mesh = mesh_rectangle(0.4, 0.1, element_size=0.05, center=(1.0, 1.0), angle=np.pi / 2)
    np.testing.assert_allclose(mesh.points.mean(axis=0), [1.0, 1.0], atol=1e-12)
    np.testing.assert_allclose(np.ptp(mesh.points, axis=0), [0.1, 0.4], atol=1e-12)
    assert mesh.triangle_count == 2 * 8 * 2


def test_polygon_with_hole_orientation_and_area() -> None:
    hole = np.array([[0.3, 0.3], [0.3, 0.6], [0.6, 0.6], [0.6, 0.3]])
    mesh = mesh_from_polygon(SQUARE, holes=[hole], element_size=0.1)
    assert mesh.area == pytest.approx(1.0 - 0.09, rel=1e-12)
    areas = sorted(polygon_area(mesh.points, loop) for loop in mesh.boundary_loops)
    assert areas == pytest.approx([-0.09, 1.0])
    assert_body_on_left(mesh)
    # Area bound from the element size: equilateral triangle of that side.
    assert mesh.triangle_areas.max() <= np.sqrt(3) / 4 * 0.1**2 * (1 + 1e-9)
    np.testing.assert_allclose(mesh.points[:4], SQUARE)


def test_clockwise_polygon_is_accepted() -> None:
    mesh = mesh_from_polygon(SQUARE[::-1], element_size=0.5)
    assert mesh.area == pytest.approx(1.0)


def test_windmill_is_one_body_with_hub_node_zero() -> None:
    mesh = mesh_windmill(0.05, 4, 0.2, 0.04, center=(0.5, 0.5), element_size=0.03)
    assert len(mesh.boundary_loops) == 1
    np.testing.assert_allclose(mesh.points[0], [0.5, 0.5])
    assert nearest_node(mesh, (0.5, 0.5)) == 0
    # Hub polygon plus four rectangular blades (hub chords make the hub slightly smaller).
    assert 0.7 * np.pi * 0.05**2 + 4 * 0.2 * 0.04 < mesh.area < np.pi * 0.05**2 + 4 * 0.21 * 0.04
    assert_body_on_left(mesh)
    tip = np.linalg.norm(mesh.points - 0.5, axis=1).max()
    assert tip == pytest.approx(np.hypot(0.25, 0.02))


def test_two_bodies_in_one_mesh() -> None:
    a = mesh_rectangle(1.0, 1.0, counts=(2, 2))
    b = mesh_rectangle(1.0, 1.0, counts=(2, 2), origin=(3.0, 0.0))
    mesh = TriangleMesh(np.concatenate([a.points, b.points]),
                        np.concatenate([a.triangles, b.triangles + a.point_count]))
    assert len(mesh.boundary_loops) == 2
    assert_body_on_left(mesh)


def test_nodes_in_box() -> None:
    mesh = mesh_rectangle(1.0, 2.0, counts=(2, 4))
    top = nodes_in_box(mesh, (0.0, 2.0, 1.0, 2.0))
    np.testing.assert_array_equal(mesh.points[top, 1], [2.0, 2.0, 2.0])


POINTS = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [2.0, 0.5]])


@pytest.mark.parametrize(
    "points,triangles,message",
    [
        (POINTS[:4], [[0, 1, 2], [0, 2, 3]], None),
        (np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [0.0, 1.0]]), [[0, 1, 2], [0, 1, 3]],
         "triangle 0 .* degenerate"),
        (POINTS[:4], [[0, 1, 2], [0, 3, 2]], "triangle 1 .* inverted"),
        (POINTS[:4], [[0, 1, 1], [0, 2, 3]], "triangle 0 .* degenerate"),
        (POINTS, [[0, 1, 2], [0, 2, 3]], "vertex 4 is used by no triangle"),
        (np.array([[0, 0], [1, 0], [0.5, 1], [0.5, -1], [0.4, 0.5]]),
         [[0, 1, 2], [0, 3, 1], [0, 1, 4]], r"edge \(0, 1\) is non-manifold"),
        (np.array([[0, 0], [1, 0], [0.5, 1], [2, 1], [2, -1]]), [[0, 1, 2], [1, 4, 3]],
         "vertex 1 is pinched"),
        (POINTS[:4], [[0, 1, 2], [0, 1, 3]], "same direction"),
    ],
)
def test_mesh_validation(points: np.ndarray, triangles: list, message: str | None) -> None:
    if message is None:
        TriangleMesh(points, np.array(triangles))
        return
    with pytest.raises(ValueError, match=message):
        TriangleMesh(points, np.array(triangles))


def test_open_boundary_loop_is_rejected() -> None:
    points, triangles = POINTS[:4], np.array([[0, 1, 2], [0, 2, 3]])
    TriangleMesh(points, triangles, (np.array([0, 1, 2, 3]),))
    with pytest.raises(ValueError, match=r"boundary loop 0 is open: its closing edge \(2, 0\)"):
        TriangleMesh(points, triangles, (np.array([0, 1, 2]),))
    with pytest.raises(ValueError, match="boundary loop 0 is open"):
        TriangleMesh(points, triangles, (np.array([3, 2, 1, 0]),))


def test_self_intersecting_outline_is_rejected() -> None:
    bowtie = np.array([[0.0, 0.0], [1.0, 1.0], [1.0, 0.0], [0.0, 2.0]])
    with pytest.raises(ValueError, match="outer polygon is self-intersecting: edge 0 crosses edge 2"):
        mesh_from_polygon(bowtie, element_size=0.5)
    sticking_out = np.array([[0.5, 0.5], [1.5, 0.5], [1.5, 0.6], [0.5, 0.6]])
    with pytest.raises(ValueError, match="outer polygon edge 1 crosses hole 0 edge 0"):
        mesh_from_polygon(SQUARE, holes=[sticking_out], element_size=0.5)


@pytest.mark.parametrize("suffix", [".vtu", ".msh", ".obj", ".ply"])
def test_meshio_round_trip(tmp_path, suffix: str) -> None:
    mesh = mesh_from_polygon(SQUARE, element_size=0.3)
    points3 = np.column_stack([mesh.points, np.zeros(mesh.point_count)])
    path = tmp_path / f"mesh{suffix}"
    kwargs = {"file_format": "gmsh22", "binary": False} if suffix == ".msh" else {}
    meshio.write(str(path), meshio.Mesh(points3, [("triangle", mesh.triangles)]), **kwargs)
    back = read_mesh(path)
    np.testing.assert_allclose(back.points, mesh.points, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(back.triangles, mesh.triangles)


def test_read_mesh_flips_clockwise_and_rejects_3d(tmp_path) -> None:
    mesh = mesh_rectangle(1.0, 1.0, counts=(2, 2))
    path = tmp_path / "cw.vtu"
    meshio.write(str(path), meshio.Mesh(mesh.points, [("triangle", mesh.triangles[:, ::-1])]))
    assert read_mesh(path).area == pytest.approx(1.0)
    bent = np.column_stack([mesh.points, mesh.points[:, 0] * 0.1])
    meshio.write(str(path), meshio.Mesh(bent, [("triangle", mesh.triangles)]))
    with pytest.raises(ValueError, match="vertex 1 has z"):
        read_mesh(path)


@pytest.mark.parametrize("element_size", [0.02, 0.015, 0.01, 0.005, 0.001])
def test_polygon_mesh_honours_every_element_size(element_size: float) -> None:
    """Every triangle within the equilateral area of the requested side, at sizes whose area
    bound Python writes with an exponent (0.015 and below gave 2 triangles when the bound
    reached Triangle as "a9.7e-05", which it reads as 9.7)."""
    square = np.array([[0.0, 0.0], [0.2, 0.0], [0.2, 0.2], [0.0, 0.2]])
    mesh = mesh_from_polygon(square, element_size=element_size)
    bound = np.sqrt(3.0) / 4.0 * element_size**2
    assert mesh.triangle_areas.max() <= bound * (1.0 + 1e-9)
    assert mesh.triangle_count >= 0.04 / bound


def test_repeated_vertex_is_named_as_such() -> None:
    with pytest.raises(ValueError, match=r"outer polygon repeats a vertex: vertices 1 and 2 are "
                                         r"both \(1, 0\)"):
        mesh_from_polygon(np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 0.0], [0.0, 1.0]]))
