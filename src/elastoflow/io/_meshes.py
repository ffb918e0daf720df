"""Body meshes extruded to 3D prisms (pseudo-3D, paper Fig. 7), as OBJ or PLY surfaces.

A rod (a body without triangles) becomes a ribbon: its polyline swept along z, a sheet of
zero thickness as the fluid sees it, in the same files and formats, so that Blender or
ParaView shows reeds and triangle bodies alike.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from elastoflow.io._atomic import atomic_path, write_text_atomic
from elastoflow.solid import TetrahedralMesh


def boundary_edges_of(triangles: np.ndarray) -> np.ndarray:
    """Edges used by one triangle only, oriented as in that triangle (body on the left for
    counter-clockwise triangles), shape (k, 2) int."""
    edges = np.concatenate((triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]))
    keys = np.sort(edges, axis=1)
    _, inverse, counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    return edges[counts[inverse.ravel()] == 1]


def _two_layers(points: np.ndarray, thickness: float) -> np.ndarray:
    """The nodes at z = -thickness/2 (first n) and at +thickness/2 (next n), (2n, 3)."""
    n = points.shape[0]
    vertices = np.empty((2 * n, 3))
    vertices[:n, :2] = points
    vertices[:n, 2] = -0.5 * thickness
    vertices[n:, :2] = points
    vertices[n:, 2] = 0.5 * thickness
    return vertices


def _quads(a: np.ndarray, b: np.ndarray, n: int) -> np.ndarray:
    """Two triangles a, b, b' and a, b', a' per segment a -> b (primes: the top layer)."""
    return np.concatenate((np.column_stack((a, b, b + n)), np.column_stack((a, b + n, a + n))))


def extrude_surface(points: np.ndarray, triangles: np.ndarray,
                    thickness: float) -> tuple[np.ndarray, np.ndarray]:
    """Closed surface of the prism ``mesh x [-thickness/2, thickness/2]``.

    Args:
        points: Node positions (n, 2) [m].
        triangles: Counter-clockwise triangles (m, 3).
        thickness: Extent along z [m].

    Returns:
        ``(vertices (2n, 3), faces (2m + 2k, 3))`` with outward normals: bottom nodes first,
        then top nodes; k is the number of boundary edges.
    """
    points = np.asarray(points, dtype=np.float64)
    triangles = np.asarray(triangles, dtype=np.int64)
    n = points.shape[0]
    vertices = _two_layers(points, thickness)
    top = triangles + n
    bottom = triangles[:, ::-1]
    edges = boundary_edges_of(triangles)
    a, b = edges[:, 0], edges[:, 1]
    # Body on the left of a -> b: the outward side quad is a, b, b', a' seen from outside.
    return vertices, np.concatenate((bottom, top, _quads(a, b, n)))


def extrude_polyline(points: np.ndarray, thickness: float) -> tuple[np.ndarray, np.ndarray]:
    """The ribbon ``polyline x [-thickness/2, thickness/2]``: two triangles per segment.

    Args:
        points: The polyline's nodes in order (n, 2) [m].
        thickness: Extent along z [m].

    Returns:
        ``(vertices (2n, 3), faces (2(n - 1), 3))``: bottom nodes first, then top nodes; the
        faces' normals point to the polyline's right (an open sheet has no outside).
    """
    points = np.asarray(points, dtype=np.float64)
    n = points.shape[0]
    vertices = _two_layers(points, thickness)
    a = np.arange(n - 1, dtype=np.int64)
    b = a + 1
    return vertices, _quads(a, b, n)


def write_obj(path: str | Path, vertices: np.ndarray, faces: np.ndarray) -> None:
    """Wavefront OBJ (vertices and triangular faces), written atomically."""
    lines = ["# elastoflow extruded body mesh"]
    lines += [f"v {x:.9g} {y:.9g} {z:.9g}" for x, y, z in vertices]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces]
    write_text_atomic(path, "\n".join(lines) + "\n")


def write_ply(path: str | Path, vertices: np.ndarray, faces: np.ndarray) -> None:
    """ASCII PLY (vertices and triangular faces), written atomically."""
    header = [
        "ply", "format ascii 1.0", "comment elastoflow extruded body mesh",
        f"element vertex {len(vertices)}", "property float x", "property float y",
        "property float z", f"element face {len(faces)}", "property list uchar int vertex_indices",
        "end_header",
    ]
    lines = header + [f"{x:.9g} {y:.9g} {z:.9g}" for x, y, z in vertices]
    lines += [f"3 {a} {b} {c}" for a, b, c in faces]
    write_text_atomic(path, "\n".join(lines) + "\n")


MESH_WRITERS = {"obj": write_obj, "ply": write_ply}


def write_extruded_meshes(folder: str | Path, frame: int, meshes: list[tuple[np.ndarray, np.ndarray]],
                          thickness: float, file_format: str = "obj") -> list[Path]:
    """One file per body, ``folder/body{k}_{frame:06d}.{format}``: a triangle body's
    prism, a rod's ribbon (a body whose triangles are (0, 3)); returns the paths."""
    writer = MESH_WRITERS[file_format]
    paths = []
    for index, (points, triangles) in enumerate(meshes):
        path = Path(folder) / f"body{index}_{frame:06d}.{file_format}"
        if len(triangles):
            writer(path, *extrude_surface(points, triangles, thickness))
        else:
            writer(path, *extrude_polyline(points, thickness))
        paths.append(path)
    return paths


def write_surface_meshes(folder: str | Path, frame: int,
                         meshes: list[tuple[np.ndarray, np.ndarray]],
                         file_format: str = "obj") -> list[Path]:
    """One file per 3D body, ``folder/body{k}_{frame:06d}.{format}``: its surface triangles
    (``(positions (n, 3), triangles (t, 3))`` pairs, unused nodes dropped); the paths."""
    writer = MESH_WRITERS[file_format]
    paths = []
    for index, (points, triangles) in enumerate(meshes):
        used, faces = np.unique(np.asarray(triangles), return_inverse=True)
        path = Path(folder) / f"body{index}_{frame:06d}.{file_format}"
        writer(path, np.asarray(points)[used], faces.reshape(-1, 3))
        paths.append(path)
    return paths


def write_tetrahedral_mesh(path: str | Path, mesh: TetrahedralMesh,
                           positions: np.ndarray | None = None,
                           point_data: dict[str, np.ndarray] | None = None) -> None:
    """Write a tetrahedral body (at ``positions`` (n, 3) [m] when given, with ``point_data``
    arrays of one row per node) with meshio, the format from the file suffix (.vtu for
    ParaView, .msh, ...), atomically (a temporary file beside it, then a rename)."""
    import meshio

    points = mesh.points if positions is None else np.asarray(positions, dtype=np.float64)
    if points.shape != mesh.points.shape:
        raise ValueError(f"positions shape {points.shape}: must be {mesh.points.shape}")
    with atomic_path(path) as temporary:
        meshio.write(str(temporary), meshio.Mesh(points, [("tetra", mesh.tetrahedra)],
                                                 point_data=point_data or {}))
