"""Tetrahedral meshes of 3D elastic bodies: the mesh, built-in shapes, files, surface meshing.

Node and face conventions of one linear tetrahedron ``(a, b, c, d)``, positively oriented
(``det[b - a, c - a, d - a] > 0``, i.e. d lies on the side of triangle abc that its
counter-clockwise normal points to)::

                d
               /|\\          faces with outward normals (counter-clockwise seen from
              / | \\         outside), each the one opposite the vertex named:
             /  |  \\          a: (b, c, d)    b: (a, d, c)
            a---|---c         c: (a, b, d)    d: (a, c, b)
             \\  |  /
              \\ | /
               \\|/
                b

A face used by one tetrahedron is on the boundary; it keeps that tetrahedron's orientation,
so boundary triangles point outwards.
"""

from __future__ import annotations

import contextlib
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from elastoflow.solid._mesh import mesh_from_polygon

# Local vertex triples of the four faces, outward for a positive tetrahedron (picture above).
TETRAHEDRON_FACES = np.array([[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]], dtype=np.int64)


@dataclass(frozen=True, eq=False)
class TetrahedralMesh:
    """A 3D linear-tetrahedron mesh in its rest (material) configuration.

    Several disjoint bodies may live in one mesh. Construction validates the mesh and raises a
    one-line ``ValueError`` naming the bad element, face or vertex: degenerate (zero-volume) or
    inverted (negatively oriented) tetrahedra, faces shared by more than two tetrahedra or by
    two with the same orientation (overlap), and vertices used by no tetrahedron. The boundary
    triangles are derived from the tetrahedra (not an argument). The arrays are made
    read-only; meshes compare by identity.

    Attributes:
        points: Rest positions [m], float64, shape (n, 3).
        tetrahedra: Node indices of each element, positively oriented, int64, shape (m, 4).
        boundary_triangles: Faces used by one element, counter-clockwise seen from outside
            (outward normal ``(p1 - p0) x (p2 - p0)``), int64, shape (k, 3).
    """

    points: np.ndarray
    tetrahedra: np.ndarray
    boundary_triangles: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        points = np.ascontiguousarray(self.points, dtype=np.float64)
        tetrahedra = np.ascontiguousarray(self.tetrahedra)
        if points.ndim != 2 or points.shape[1] != 3 or points.shape[0] < 4:
            raise ValueError(f"mesh points shape {points.shape}: must be (n >= 4, 3)")
        if not np.all(np.isfinite(points)):
            raise ValueError(f"mesh points: vertex {int(np.argmin(np.isfinite(points).all(1)))} "
                             "is not finite")
        if tetrahedra.ndim != 2 or tetrahedra.shape[1] != 4 or tetrahedra.shape[0] < 1:
            raise ValueError(f"mesh tetrahedra shape {tetrahedra.shape}: must be (m >= 1, 4)")
        if not np.issubdtype(tetrahedra.dtype, np.integer):
            raise ValueError(f"mesh tetrahedra dtype {tetrahedra.dtype}: must be an integer type")
        tetrahedra = tetrahedra.astype(np.int64)
        n = points.shape[0]
        bad = np.flatnonzero((tetrahedra < 0).any(1) | (tetrahedra >= n).any(1))
        if bad.size:
            raise ValueError(f"mesh tetrahedron {bad[0]} = {tetrahedra[bad[0]].tolist()}: node "
                             f"indices must lie in [0, {n})")
        ordered = np.sort(tetrahedra, axis=1)
        repeated = np.flatnonzero((ordered[:, 1:] == ordered[:, :-1]).any(1))
        if repeated.size:
            e = repeated[0]
            raise ValueError(f"mesh tetrahedron {e} = {tetrahedra[e].tolist()} is degenerate: "
                             "a node repeats")
        volumes = signed_volumes(points, tetrahedra)
        scale = float(np.max(np.ptp(points, axis=0))) ** 3
        degenerate = np.flatnonzero(np.abs(volumes) <= 1e-14 * scale)
        if degenerate.size:
            e = degenerate[0]
            raise ValueError(f"mesh tetrahedron {e} = {tetrahedra[e].tolist()} is degenerate: "
                             f"volume {volumes[e]:.3g} m^3")
        inverted = np.flatnonzero(volumes < 0.0)
        if inverted.size:
            e = inverted[0]
            raise ValueError(f"mesh tetrahedron {e} = {tetrahedra[e].tolist()} is inverted: "
                             f"volume {volumes[e]:.3g} m^3, must be positively oriented")
        unused = np.setdiff1d(np.arange(n), tetrahedra.ravel())
        if unused.size:
            raise ValueError(f"mesh vertex {unused[0]} is used by no tetrahedron")
        boundary = _boundary_triangles_from_tetrahedra(tetrahedra, n)
        points.setflags(write=False)
        tetrahedra.setflags(write=False)
        boundary.setflags(write=False)
        object.__setattr__(self, "points", points)
        object.__setattr__(self, "tetrahedra", tetrahedra)
        object.__setattr__(self, "boundary_triangles", boundary)

    @property
    def point_count(self) -> int:
        """Number of nodes ``n``."""
        return int(self.points.shape[0])

    @property
    def tetrahedron_count(self) -> int:
        """Number of elements ``m``."""
        return int(self.tetrahedra.shape[0])

    @property
    def tetrahedron_volumes(self) -> np.ndarray:
        """Rest volume of each element [m^3], shape (m,)."""
        return signed_volumes(self.points, self.tetrahedra)

    @property
    def volume(self) -> float:
        """Total rest volume [m^3]."""
        return float(self.tetrahedron_volumes.sum())

    @property
    def boundary_normals(self) -> np.ndarray:
        """Outward unit normal of each boundary triangle, shape (k, 3)."""
        normals = _face_cross(self.points, self.boundary_triangles)
        return normals / np.linalg.norm(normals, axis=1, keepdims=True)

    @property
    def boundary_area(self) -> float:
        """Total rest area of the boundary triangles [m^2]."""
        return float(0.5 * np.linalg.norm(_face_cross(self.points, self.boundary_triangles),
                                          axis=1).sum())

    @property
    def element_size(self) -> float:
        """Mean edge length of the elements [m]."""
        p = self.points[self.tetrahedra]
        pairs = ((0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3))
        lengths = np.stack([np.linalg.norm(p[:, a] - p[:, b], axis=1) for a, b in pairs])
        return float(lengths.mean())

    @property
    def element_heights(self) -> np.ndarray:
        """Smallest altitude of each element ``3 V / (largest face area)`` [m], shape (m,)."""
        areas = np.stack([
            0.5 * np.linalg.norm(_face_cross(self.points, self.tetrahedra[:, face]), axis=1)
            for face in TETRAHEDRON_FACES
        ])
        return 3.0 * self.tetrahedron_volumes / areas.max(axis=0)

    @property
    def min_element_height(self) -> float:
        """Smallest altitude of any element [m]: the length that bounds the stable substep."""
        return float(self.element_heights.min())

    @property
    def quality(self) -> np.ndarray:
        """Radius ratio ``3 r_in / r_circ`` of each element, shape (m,): 1 for the regular
        tetrahedron, towards 0 for slivers and needles."""
        p = self.points[self.tetrahedra]
        volume = self.tetrahedron_volumes
        area = sum(
            0.5 * np.linalg.norm(_face_cross(self.points, self.tetrahedra[:, face]), axis=1)
            for face in TETRAHEDRON_FACES
        )
        inradius = 3.0 * volume / area
        # Circumcentre c - p0 solves 2 (pk - p0) . (c - p0) = |pk - p0|^2, k = 1, 2, 3.
        edges = p[:, 1:] - p[:, :1]
        rhs = 0.5 * np.sum(edges * edges, axis=2)
        centre = np.linalg.solve(edges, rhs[..., None])[..., 0]
        circumradius = np.linalg.norm(centre, axis=1)
        return 3.0 * inradius / circumradius


def signed_volumes(points: np.ndarray, tetrahedra: np.ndarray) -> np.ndarray:
    """Signed volume of each tetrahedron [m^3] (positive when positively oriented), (m,)."""
    p0 = points[tetrahedra[:, 0]]
    d1 = points[tetrahedra[:, 1]] - p0
    d2 = points[tetrahedra[:, 2]] - p0
    d3 = points[tetrahedra[:, 3]] - p0
    return np.einsum("ij,ij->i", np.cross(d1, d2), d3) / 6.0


def _face_cross(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    p0 = points[faces[:, 0]]
    return np.cross(points[faces[:, 1]] - p0, points[faces[:, 2]] - p0)


def _boundary_triangles_from_tetrahedra(tetrahedra: np.ndarray, n: int) -> np.ndarray:
    """Faces used by one tetrahedron, in its orientation; validates that no face is used by
    more than two, nor twice in the same orientation."""
    faces = tetrahedra[:, TETRAHEDRON_FACES].reshape(-1, 3)
    ordered = np.sort(faces, axis=1)
    _, inverse, counts = np.unique(ordered, axis=0, return_inverse=True, return_counts=True)
    inverse = inverse.ravel()
    shared = np.flatnonzero(counts > 2)
    if shared.size:
        k = int(np.flatnonzero(inverse == shared[0])[0])
        raise ValueError(f"mesh face {tuple(ordered[k].tolist())} is non-manifold: shared by "
                         f"{counts[shared[0]]} tetrahedra, at most 2 allowed")
    # Rotate each face so that its smallest index comes first: two uses of one face in the
    # same orientation then give equal rows, i.e. both tetrahedra lie on the same side.
    first = np.argmin(faces, axis=1)
    rotation = (first[:, None] + np.arange(3)[None, :]) % 3
    canonical = np.take_along_axis(faces, rotation, axis=1)
    _, same_counts = np.unique(canonical, axis=0, return_counts=True)
    if np.any(same_counts > 1):
        rows, first_index, same_counts = np.unique(canonical, axis=0, return_index=True,
                                                   return_counts=True)
        k = int(first_index[np.flatnonzero(same_counts > 1)[0]])
        raise ValueError(f"mesh face {tuple(faces[k].tolist())} is used in the same orientation "
                         f"by tetrahedra {k // 4} and another: they overlap")
    return np.ascontiguousarray(faces[counts[inverse] == 1])


def _orient(points: np.ndarray, tetrahedra: np.ndarray) -> np.ndarray:
    """The tetrahedra with negatively oriented ones made positive (two nodes swapped)."""
    tetrahedra = np.array(tetrahedra, dtype=np.int64)
    negative = signed_volumes(points, tetrahedra) < 0.0
    tetrahedra[negative] = tetrahedra[negative][:, [0, 2, 1, 3]]
    return tetrahedra


def _check_length(name: str, value: float) -> float:
    if not (np.isfinite(value) and value > 0.0):
        raise ValueError(f"{name} = {value!r}: must be a finite positive length")
    return float(value)


def _check_point(name: str, value: Sequence[float] | np.ndarray) -> np.ndarray:
    array = np.asarray(value, dtype=np.float64)
    if array.shape != (3,) or not np.all(np.isfinite(array)):
        raise ValueError(f"{name} = {value!r}: must be three finite numbers [m]")
    return array


def _structured_hexahedra(counts: tuple[int, int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Unit-spaced lattice points (n, 3) and the 5-tetrahedron split of each lattice cell.

    Each cell is cut into the central tetrahedron on its four corners of even lattice parity
    ``(i + j + k) % 2 == 0`` and four corner tetrahedra, one on each odd corner with its three
    neighbours. The choice by *global* parity alternates the split from cell to cell (mirror
    images), so the face diagonals of neighbouring cells meet (a conforming mesh) and no
    direction is favoured, unlike the 6-tetrahedron split along one main diagonal.
    """
    cx, cy, cz = counts
    i, j, k = np.meshgrid(np.arange(cx + 1), np.arange(cy + 1), np.arange(cz + 1),
                          indexing="ij")
    points = np.stack([i.ravel(), j.ravel(), k.ravel()], axis=1).astype(np.float64)

    def node(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
        return (a * (cy + 1) + b) * (cz + 1) + c

    ci, cj, ck = (a.ravel() for a in np.meshgrid(np.arange(cx), np.arange(cy), np.arange(cz),
                                                 indexing="ij"))
    corners = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0],
                        [0, 0, 1], [1, 0, 1], [0, 1, 1], [1, 1, 1]])
    # Corner indices of each cell's two alternatives: even corners central (cell parity 0)
    # or odd corners central (cell parity 1); each list is central, then four corner tets.
    split_even = [[0, 3, 5, 6], [1, 0, 3, 5], [2, 0, 3, 6], [4, 0, 5, 6], [7, 3, 5, 6]]
    split_odd = [[1, 2, 4, 7], [0, 1, 2, 4], [3, 1, 2, 7], [5, 1, 4, 7], [6, 2, 4, 7]]
    cell_nodes = np.stack([node(ci + a, cj + b, ck + c) for a, b, c in corners], axis=1)
    odd = ((ci + cj + ck) % 2 == 1)[:, None, None]
    tetrahedra = np.where(odd, cell_nodes[:, split_odd], cell_nodes[:, split_even])
    return points, tetrahedra.reshape(-1, 4)


def mesh_box(
    size: tuple[float, float, float],
    element_size: float | None = None,
    *,
    counts: tuple[int, int, int] | None = None,
    origin: tuple[float, float, float] | None = None,
    center: tuple[float, float, float] | None = None,
) -> TetrahedralMesh:
    """Structured tetrahedral mesh of a box, five tetrahedra per cell, alternating.

    The box ``[0, lx] x [0, ly] x [0, lz]`` is cut into ``counts = (cx, cy, cz)`` cells, each
    split into five tetrahedra whose diagonals alternate from cell to cell like a chequerboard
    (no preferred direction), then placed with its low corner at ``origin`` or its centre at
    ``center``.

    Args:
        size: Sides ``(lx, ly, lz)`` [m].
        element_size: Target cell side [m]; gives ``counts = ceil(side / element_size)``.
        counts: Cells along x, y, z (instead of ``element_size``).
        origin: World position of the low corner [m]; default (0, 0, 0).
        center: World position of the centre [m]; exclusive with ``origin``.

    Returns:
        The mesh, ``5 cx cy cz`` elements; node ``(i (cy + 1) + j) (cz + 1) + k`` is the lattice
        corner ``(i, j, k)``.
    """
    if len(size) != 3:
        raise ValueError(f"box size = {size!r}: must be three lengths (lx, ly, lz) [m]")
    sides = np.array([_check_length(f"box side {axis}", s) for axis, s in zip("xyz", size)])
    if (element_size is None) == (counts is None):
        raise ValueError("mesh_box: give exactly one of element_size and counts")
    if element_size is not None:
        _check_length("element_size", element_size)
        cells = tuple(max(1, int(np.ceil(s / element_size - 1e-9))) for s in sides)
    else:
        assert counts is not None
        if len(counts) != 3 or any(int(c) != c or c < 1 for c in counts):
            raise ValueError(f"counts = {counts!r}: must be three integers >= 1")
        cells = tuple(int(c) for c in counts)
    if origin is not None and center is not None:
        raise ValueError("mesh_box: give at most one of origin and center")
    lattice, tetrahedra = _structured_hexahedra((cells[0], cells[1], cells[2]))
    points = lattice * (sides / np.array(cells))
    if center is not None:
        points += _check_point("center", center) - 0.5 * sides
    elif origin is not None:
        points += _check_point("origin", origin)
    return TetrahedralMesh(points, _orient(points, tetrahedra))


def mesh_cylinder(
    radius: float,
    length: float,
    element_size: float,
    *,
    center: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> TetrahedralMesh:
    """Tetrahedral mesh of a solid circular cylinder along z.

    A quality triangulation of the disc (Shewchuk's Triangle, angles >= 30 degrees, boundary
    vertices on the circle) is extruded in ``ceil(length / element_size)`` layers and each
    prism cut into three tetrahedra. The cut of each side face joins the bottom of its
    lower-numbered vertex to the top of the other, a rule both prisms sharing the face follow,
    so the mesh is conforming.

    Args:
        radius: Radius [m].
        length: Length along z [m].
        element_size: Target edge length [m], both across and along the axis.
        center: World position of the cylinder's centre [m].
    """
    _check_length("cylinder radius", radius)
    _check_length("cylinder length", length)
    _check_length("element_size", element_size)
    centre = _check_point("center", center)
    sides = max(12, int(np.ceil(2.0 * np.pi * radius / element_size)))
    angle = 2.0 * np.pi * np.arange(sides) / sides
    outline = radius * np.stack([np.cos(angle), np.sin(angle)], axis=1)
    disc = mesh_from_polygon(outline, element_size=element_size)
    layers = max(1, int(np.ceil(length / element_size - 1e-9)))
    z = np.linspace(-0.5 * length, 0.5 * length, layers + 1)
    q = disc.point_count
    points = np.concatenate([
        np.column_stack([disc.points, np.full(q, zk)]) for zk in z
    ])
    # Each prism's three vertices in increasing global order (a < b < c): the rule above.
    a, b, c = np.sort(disc.triangles, axis=1).T
    blocks = []
    for layer in range(layers):
        lo, hi = layer * q, (layer + 1) * q
        blocks.append(np.stack([
            np.stack([lo + a, lo + b, lo + c, hi + c], axis=1),
            np.stack([lo + a, lo + b, hi + b, hi + c], axis=1),
            np.stack([lo + a, hi + a, hi + b, hi + c], axis=1),
        ], axis=1).reshape(-1, 4))
    tetrahedra = np.concatenate(blocks)
    points = points + centre
    return TetrahedralMesh(points, _orient(points, tetrahedra))


def mesh_sphere(
    radius: float,
    element_size: float,
    *,
    center: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> TetrahedralMesh:
    """Tetrahedral mesh of a solid ball: a cube inside six blocks that reach the sphere.

    An "O-grid": the inner cube of half-side ``0.4 radius`` is a structured lattice of ``n``
    cells a side (``n`` even, about a quarter circumference over ``element_size``); on each of
    its six faces stands a block of ``n x n x L`` cells whose layers go from the cube face to
    the sphere (equal-angle on the sphere, blended linearly in between). Every cell is split
    like :func:`mesh_box` by the parity of its lattice corners, which agrees across the blocks'
    shared faces because ``n`` is even, so the mesh is conforming. A plain lattice mapped onto
    the ball would flatten the cells along the cube's edges more and more with refinement
    (smallest radius ratio 0.09 at element size r/2, 7e-4 at r/8); here it measured 0.24 at
    r/2.5 and 0.20 at r/20, the median 0.73 (tests/unit/solid/test_tet_mesh.py checks 0.19).

    Args:
        radius: Radius [m].
        element_size: Target edge length [m].
        center: World position of the centre [m].
    """
    _check_length("sphere radius", radius)
    _check_length("element_size", element_size)
    centre = _check_point("center", center)
    cells = max(2, int(np.ceil(0.5 * np.pi * radius / element_size)))
    cells += cells % 2
    inner = 0.4 * radius
    layers = max(1, int(round((radius - inner) / element_size)))
    lattice, tetrahedra = _structured_hexahedra((cells, cells, cells))
    points = [inner * (2.0 * lattice / cells - 1.0)]
    blocks = [tetrahedra]
    block_lattice, block_tetrahedra = _structured_hexahedra((cells, cells, layers))
    u = 2.0 * block_lattice[:, 0] / cells - 1.0
    v = 2.0 * block_lattice[:, 1] / cells - 1.0
    t = (block_lattice[:, 2] / layers)[:, None]
    offset = lattice.shape[0]
    for axis in range(3):
        for sign in (-1.0, 1.0):
            face = np.empty((u.size, 3))
            face[:, axis] = sign
            face[:, (axis + 1) % 3] = u
            face[:, (axis + 2) % 3] = v
            # Equal-angle spacing on the sphere keeps its cells near the cube's corners
            # about as large as those at the face centres.
            angle = face.copy()
            angle[:, (axis + 1) % 3] = np.tan(0.25 * np.pi * u)
            angle[:, (axis + 2) % 3] = np.tan(0.25 * np.pi * v)
            on_sphere = radius * angle / np.linalg.norm(angle, axis=1, keepdims=True)
            points.append((1.0 - t) * inner * face + t * on_sphere)
            blocks.append(block_tetrahedra + offset)
            offset += block_lattice.shape[0]
    all_points = np.concatenate(points)
    # The blocks repeat the nodes of their shared faces; merge them by position.
    key = np.round(all_points / (1e-9 * radius)).astype(np.int64)
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    merged = all_points[first] + centre
    tetrahedra = inverse.ravel()[np.concatenate(blocks)]
    return TetrahedralMesh(merged, _orient(merged, tetrahedra))


def read_tetrahedral_mesh(path: str | Path) -> TetrahedralMesh:
    """Read a tetrahedral mesh with meshio (.vtu, .vtk, .msh, .xdmf, .med, ...).

    Only ``tetra`` cells are used (other cells, such as the surface triangles a Gmsh file also
    holds, are ignored); negatively oriented tetrahedra are turned positive (tools differ in
    their convention); points used by no tetrahedron are dropped.
    """
    import meshio

    data = meshio.read(str(path))
    blocks = [cells.data for cells in data.cells if cells.type == "tetra"]
    if not blocks:
        kinds = sorted({cells.type for cells in data.cells})
        raise ValueError(f"mesh file {path}: has no tetra cells (found {kinds})")
    tetrahedra = np.concatenate(blocks).astype(np.int64)
    points = np.asarray(data.points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 3:
        raise ValueError(f"mesh file {path}: points shape {points.shape}, must be (n, 3)")
    used = np.unique(tetrahedra)
    if used.size < points.shape[0]:
        new_index = np.full(points.shape[0], -1, np.int64)
        new_index[used] = np.arange(used.size)
        points, tetrahedra = points[used], new_index[tetrahedra]
    return TetrahedralMesh(points, _orient(points, tetrahedra))


def _read_surface(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    import meshio

    data = meshio.read(str(path))
    blocks = [cells.data for cells in data.cells if cells.type == "triangle"]
    if not blocks:
        kinds = sorted({cells.type for cells in data.cells})
        raise ValueError(f"surface file {path}: has no triangle cells (found {kinds})")
    return np.asarray(data.points, dtype=np.float64), np.concatenate(blocks).astype(np.int64)


def tetrahedralize_surface(
    surface: str | Path | tuple[np.ndarray, np.ndarray],
    element_size: float,
    *,
    envelope: float = 1e-3,
    threads: int = 1,
) -> TetrahedralMesh:
    """Tetrahedral mesh of the solid a closed triangle surface bounds (fTetWild).

    Uses ``pytetwild`` (the optional extra ``elastoflow[tetwild]``; fTetWild, MPL-2.0), which
    meshes robustly even surfaces with small defects: its boundary lies within ``envelope``
    times the bounding-box diagonal of the input surface, not exactly on it. fTetWild runs in
    a temporary working directory (it writes a scratch file): the process's working directory
    changes for the duration of the call.

    Args:
        surface: A file meshio reads with triangle cells (.stl, .obj, .ply, .off, .vtk, ...),
            or ``(points (p, 3) [m], triangles (t, 3) int)``.
        element_size: Target edge length [m].
        envelope: Largest distance of the output's boundary from the surface, relative to the
            bounding-box diagonal.
        threads: Threads fTetWild may use (0: all cores).

    Raises:
        ImportError: ``pytetwild`` is not installed (the message says how to install it).
        ValueError: bad input, or fTetWild returned no tetrahedra.
    """
    try:
        import pytetwild
    except ImportError as error:  # pragma: no cover - depends on the environment
        raise ImportError("tetrahedralize_surface needs pytetwild: pip install "
                          "'elastoflow[tetwild]'") from error
    if isinstance(surface, tuple):
        vertices = np.asarray(surface[0], dtype=np.float64)
        faces = np.asarray(surface[1], dtype=np.int64)
        name = "surface"
    else:
        vertices, faces = _read_surface(surface)
        name = f"surface file {surface}"
    if vertices.ndim != 2 or vertices.shape[1] != 3 or not np.all(np.isfinite(vertices)):
        raise ValueError(f"{name}: points shape {vertices.shape}, must be finite (p, 3)")
    if faces.ndim != 2 or faces.shape[1] != 3 or faces.size == 0:
        raise ValueError(f"{name}: triangles shape {faces.shape}, must be (t >= 1, 3)")
    if faces.min() < 0 or faces.max() >= vertices.shape[0]:
        raise ValueError(f"{name}: triangle node indices must lie in [0, {vertices.shape[0]})")
    _check_length("element_size", element_size)
    # fTetWild writes a scratch file (__tracked_surface.stl) into the working directory; run
    # it in a temporary one, which goes with the file. Writable C-ordered copies: the binding
    # refuses read-only arrays (a mesh's own points).
    with tempfile.TemporaryDirectory() as folder, contextlib.chdir(folder):
        raw_points, raw_tetrahedra = pytetwild.tetrahedralize(
            np.array(vertices, dtype=np.float64, order="C"), np.array(faces, dtype=np.int32),
            edge_length_abs=float(element_size), epsilon=float(envelope),
            num_threads=int(threads), quiet=True,
        )
    if len(raw_tetrahedra) == 0:
        raise ValueError(f"{name}: fTetWild returned no tetrahedra (is the surface closed?)")
    points = np.asarray(raw_points, dtype=np.float64)
    tetrahedra = np.asarray(raw_tetrahedra, dtype=np.int64)
    used = np.unique(tetrahedra)
    if used.size < points.shape[0]:
        new_index = np.full(points.shape[0], -1, np.int64)
        new_index[used] = np.arange(used.size)
        points, tetrahedra = points[used], new_index[tetrahedra]
    return TetrahedralMesh(points, _orient(points, tetrahedra))


def nodes_in_box_3d(mesh: TetrahedralMesh,
                    box: tuple[float, float, float, float, float, float],
                    positions: np.ndarray | None = None) -> np.ndarray:
    """Indices of the nodes inside the closed box ``(x0, y0, z0, x1, y1, z1)`` [m], int64
    (sorted).

    Uses the rest points unless ``positions`` (n, 3) is given. Bounds are widened by a relative
    1e-9 so that nodes lying exactly on the box are included.
    """
    if len(box) != 6:
        raise ValueError(f"box = {box!r}: must be (x0, y0, z0, x1, y1, z1)")
    low = np.array(box[:3], dtype=np.float64)
    high = np.array(box[3:], dtype=np.float64)
    if not np.all(low <= high):
        raise ValueError(f"box = {box!r}: must be (x0, y0, z0, x1, y1, z1) with x0 <= x1, ...")
    p = mesh.points if positions is None else np.asarray(positions)
    tolerance = 1e-9 * max(1.0, float(np.abs(p).max()))
    inside = np.all((p >= low - tolerance) & (p <= high + tolerance), axis=1)
    return np.flatnonzero(inside).astype(np.int64)
