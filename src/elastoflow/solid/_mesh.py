from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from elastoflow.solid import _kernels


@dataclass(frozen=True, eq=False)
class TriangleMesh:
    """A 2D linear-triangle mesh in its rest (material) configuration.

    Several disjoint bodies may live in one mesh. Construction validates the mesh and raises a
    one-line ``ValueError`` naming the bad element, edge or vertex: degenerate (zero-area) or
    inverted (clockwise) triangles, edges shared by more than two triangles or by two triangles
    with the same orientation, vertices used by no triangle, and boundary loops that are not
    closed. When ``boundary_loops`` is not given it is derived from the triangles. The arrays
    are made read-only; meshes compare by identity.

    Attributes:
        points: Rest positions [m], float64, shape (n, 2).
        triangles: Node indices of each element, counter-clockwise, int64, shape (m, 3).
        boundary_loops: One int64 array of node indices per closed boundary loop, consecutive
            nodes (and last to first) joined by a boundary edge with the body on the left:
            outer outlines counter-clockwise, holes clockwise.
    """

    points: np.ndarray
    triangles: np.ndarray
    boundary_loops: tuple[np.ndarray, ...] = None  # type: ignore[assignment]

    def __post_init__(self) -> None:
        points = np.ascontiguousarray(self.points, dtype=np.float64)
        triangles = np.ascontiguousarray(self.triangles)
        if points.ndim != 2 or points.shape[1] != 2 or points.shape[0] < 3:
            raise ValueError(f"mesh points shape {points.shape}: must be (n >= 3, 2)")
        if not np.all(np.isfinite(points)):
            raise ValueError(f"mesh points: vertex {int(np.argmin(np.isfinite(points).all(1)))} "
                             "is not finite")
        if triangles.ndim != 2 or triangles.shape[1] != 3 or triangles.shape[0] < 1:
            raise ValueError(f"mesh triangles shape {triangles.shape}: must be (m >= 1, 3)")
        if not np.issubdtype(triangles.dtype, np.integer):
            raise ValueError(f"mesh triangles dtype {triangles.dtype}: must be an integer type")
        triangles = triangles.astype(np.int64)
        n = points.shape[0]
        bad = np.flatnonzero((triangles < 0).any(1) | (triangles >= n).any(1))
        if bad.size:
            raise ValueError(f"mesh triangle {bad[0]} = {triangles[bad[0]].tolist()}: node "
                             f"indices must lie in [0, {n})")
        repeated = np.flatnonzero((triangles[:, 0] == triangles[:, 1])
                                  | (triangles[:, 1] == triangles[:, 2])
                                  | (triangles[:, 2] == triangles[:, 0]))
        if repeated.size:
            raise ValueError(f"mesh triangle {repeated[0]} = {triangles[repeated[0]].tolist()} "
                             "is degenerate: a node repeats")
        signed = signed_areas(points, triangles)
        scale = np.max(np.ptp(points, axis=0)) ** 2
        degenerate = np.flatnonzero(np.abs(signed) <= 1e-12 * scale)
        if degenerate.size:
            e = degenerate[0]
            raise ValueError(f"mesh triangle {e} = {triangles[e].tolist()} is degenerate: "
                             f"area {signed[e]:.3g} m^2")
        inverted = np.flatnonzero(signed < 0.0)
        if inverted.size:
            e = inverted[0]
            raise ValueError(f"mesh triangle {e} = {triangles[e].tolist()} is inverted: "
                             f"clockwise (area {signed[e]:.3g} m^2), must be counter-clockwise")
        unused = np.setdiff1d(np.arange(n), triangles.ravel())
        if unused.size:
            raise ValueError(f"mesh vertex {unused[0]} is used by no triangle")
        boundary = _boundary_edges_from_triangles(triangles, n)
        if self.boundary_loops is None:
            loops = _loops_from_edges(boundary, n)
        else:
            loops = tuple(np.asarray(loop, dtype=np.int64) for loop in self.boundary_loops)
            _check_loops(loops, boundary, n)
        points.setflags(write=False)
        triangles.setflags(write=False)
        for loop in loops:
            loop.setflags(write=False)
        object.__setattr__(self, "points", points)
        object.__setattr__(self, "triangles", triangles)
        object.__setattr__(self, "boundary_loops", loops)

    @property
    def point_count(self) -> int:
        """Number of nodes ``n``."""
        return int(self.points.shape[0])

    @property
    def triangle_count(self) -> int:
        """Number of elements ``m``."""
        return int(self.triangles.shape[0])

    @property
    def boundary_edges(self) -> np.ndarray:
        """Boundary edges ``(a, b)`` with the body on the left of a -> b, int64, shape (k, 2).

        Edges are listed loop after loop, in the order of ``boundary_loops``.
        """
        if not self.boundary_loops:
            return np.zeros((0, 2), dtype=np.int64)
        return np.concatenate(
            [np.stack([loop, np.roll(loop, -1)], axis=1) for loop in self.boundary_loops]
        )

    @property
    def triangle_areas(self) -> np.ndarray:
        """Rest area of each element [m^2], shape (m,)."""
        return signed_areas(self.points, self.triangles)

    @property
    def area(self) -> float:
        """Total rest area [m^2]."""
        return float(self.triangle_areas.sum())

    @property
    def element_size(self) -> float:
        """Mean edge length of the elements [m]."""
        p = self.points[self.triangles]
        lengths = np.linalg.norm(p - np.roll(p, -1, axis=1), axis=2)
        return float(lengths.mean())

    @property
    def min_element_height(self) -> float:
        """Smallest altitude of any element [m]: the length that bounds the stable substep."""
        p = self.points[self.triangles]
        lengths = np.linalg.norm(p - np.roll(p, -1, axis=1), axis=2)
        heights = 2.0 * self.triangle_areas[:, None] / lengths
        return float(heights.min())


def signed_areas(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Signed area of each triangle [m^2] (positive when counter-clockwise), shape (m,)."""
    p0, p1, p2 = points[triangles[:, 0]], points[triangles[:, 1]], points[triangles[:, 2]]
    d1, d2 = p1 - p0, p2 - p0
    return 0.5 * (d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0])


def _boundary_edges_from_triangles(triangles: np.ndarray, n: int) -> np.ndarray:
    """Directed edges (a, b) used by exactly one triangle; validates manifoldness."""
    directed = np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]])
    low = np.minimum(directed[:, 0], directed[:, 1])
    high = np.maximum(directed[:, 0], directed[:, 1])
    _, inverse, counts = np.unique(low * n + high, return_inverse=True, return_counts=True)
    shared = np.flatnonzero(counts > 2)
    if shared.size:
        k = int(np.flatnonzero(inverse == shared[0])[0])
        raise ValueError(f"mesh edge ({low[k]}, {high[k]}) is non-manifold: shared by "
                         f"{counts[shared[0]]} triangles, at most 2 allowed")
    _, directed_counts = np.unique(directed[:, 0] * n + directed[:, 1], return_counts=True)
    if np.any(directed_counts > 1):
        _keys, first, directed_counts = np.unique(
            directed[:, 0] * n + directed[:, 1], return_index=True, return_counts=True
        )
        k = int(first[np.flatnonzero(directed_counts > 1)[0]])
        raise ValueError(f"mesh edge ({directed[k, 0]}, {directed[k, 1]}) is used in the same "
                         "direction by two triangles: they overlap")
    return directed[counts[inverse] == 1]


def _loops_from_edges(boundary: np.ndarray, n: int) -> tuple[np.ndarray, ...]:
    order, offsets, code, vertex = _kernels.chain_boundary_loops(
        np.ascontiguousarray(boundary[:, 0]), np.ascontiguousarray(boundary[:, 1]), n
    )
    if code == 1:
        raise ValueError(f"mesh vertex {vertex} is pinched: two boundary loops touch there "
                         "(bodies must meet along edges, not at a single vertex)")
    if code == 2:
        raise ValueError(f"mesh boundary loop through vertex {vertex} is open: no boundary edge "
                         "continues it")
    return tuple(order[offsets[k]:offsets[k + 1]].copy() for k in range(offsets.size - 1))


def _check_loops(loops: tuple[np.ndarray, ...], boundary: np.ndarray, n: int) -> None:
    boundary_keys = np.sort(boundary[:, 0] * n + boundary[:, 1])
    given: list[np.ndarray] = []
    for k, loop in enumerate(loops):
        if loop.ndim != 1 or loop.size < 3:
            raise ValueError(f"boundary loop {k}: must be a 1D array of >= 3 node indices")
        if np.any(loop < 0) or np.any(loop >= n):
            raise ValueError(f"boundary loop {k}: node indices must lie in [0, {n})")
        keys = loop * n + np.roll(loop, -1)
        missing = np.flatnonzero(~np.isin(keys, boundary_keys))
        if missing.size:
            i = int(missing[0])
            a, b = int(loop[i]), int(loop[(i + 1) % loop.size])
            what = "closing edge" if i == loop.size - 1 else "edge"
            raise ValueError(f"boundary loop {k} is open: its {what} ({a}, {b}) is not a "
                             "boundary edge with the body on its left")
        given.append(keys)
    all_keys = np.concatenate(given) if given else np.zeros(0, np.int64)
    uncovered = np.setdiff1d(boundary_keys, all_keys)
    if uncovered.size or all_keys.size != np.unique(all_keys).size:
        edge = (uncovered[0] // n, uncovered[0] % n) if uncovered.size else "repeated"
        raise ValueError(f"boundary loops do not cover each boundary edge exactly once: "
                         f"edge {edge}")


def _polygon_signed_area(polygon: np.ndarray) -> float:
    x, y = polygon[:, 0], polygon[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def _as_polygon(name: str, polygon: np.ndarray | Sequence) -> np.ndarray:
    array = np.asarray(polygon, dtype=np.float64)
    if array.ndim != 2 or array.shape[1] != 2 or array.shape[0] < 3:
        raise ValueError(f"{name} shape {array.shape}: must be (k >= 3, 2) vertices")
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{name}: vertices must be finite")
    if np.allclose(array[0], array[-1]):
        array = array[:-1]
    if abs(_polygon_signed_area(array)) <= 1e-14 * np.max(np.ptp(array, axis=0)) ** 2:
        raise ValueError(f"{name}: polygon has zero area")
    return array


def check_simple_polygons(polygons: Sequence[np.ndarray], names: Sequence[str]) -> None:
    """Raise ValueError when an outline repeats a vertex or intersects itself or another
    outline."""
    for polygon, name in zip(polygons, names):
        # A repeated vertex makes a zero-length edge, which the crossing test would report as
        # two other edges crossing; name the vertex instead.
        _, first_seen, counts = np.unique(polygon, axis=0, return_index=True,
                                          return_counts=True)
        if np.any(counts > 1):
            twice = np.flatnonzero(np.all(polygon == polygon[first_seen[counts > 1][0]], axis=1))
            x, y = polygon[twice[0]]
            raise ValueError(f"{name} repeats a vertex: vertices {int(twice[0])} and "
                             f"{int(twice[1])} are both ({x:g}, {y:g})")
    starts = np.concatenate(polygons)
    ends = np.concatenate([np.roll(p, -1, axis=0) for p in polygons])
    loop_id = np.concatenate([np.full(len(p), k, np.int64) for k, p in enumerate(polygons)])
    first = np.concatenate([[0], np.cumsum([len(p) for p in polygons])[:-1]])
    local = np.concatenate([np.arange(len(p)) for p in polygons])
    sizes = np.array([len(p) for p in polygons])[loop_id]
    base = first[loop_id]
    previous = base + (local - 1) % sizes
    following = base + (local + 1) % sizes
    i, j = _kernels.first_segment_intersection(starts, ends, loop_id, previous, following)
    if i >= 0:
        li, lj = int(loop_id[i]), int(loop_id[j])
        ei, ej = int(local[i]), int(local[j])
        if li == lj:
            raise ValueError(f"{names[li]} is self-intersecting: edge {ei} crosses edge {ej}")
        raise ValueError(f"{names[li]} edge {ei} crosses {names[lj]} edge {ej}")


def _interior_point(polygon: np.ndarray) -> np.ndarray:
    """A point strictly inside a simple polygon: centroid of one of its triangles."""
    import triangle

    count = len(polygon)
    segments = np.stack([np.arange(count), (np.arange(count) + 1) % count], axis=1)
    result = triangle.triangulate({"vertices": polygon, "segments": segments}, "pQ")
    tri = result["triangles"]
    areas = np.abs(signed_areas(result["vertices"], tri))
    return result["vertices"][tri[int(np.argmax(areas))]].mean(axis=0)


def mesh_from_polygon(
    outer: np.ndarray | Sequence,
    holes: Sequence[np.ndarray | Sequence] = (),
    element_size: float | None = None,
    *,
    extra_points: np.ndarray | Sequence = (),
    min_angle: float = 30.0,
) -> TriangleMesh:
    """Quality triangulation of a polygon with holes (Shewchuk's Triangle).

    Args:
        outer: Outline vertices [m], shape (k, 2), either orientation, not repeated at the end.
        holes: Outlines of holes, each shape (k_h, 2), inside ``outer`` and disjoint.
        element_size: Target edge length [m]; triangles get at most the area of the equilateral
            triangle of that side. ``None``: no area bound (only the angle bound).
        extra_points: Points [m], shape (q, 2), that must become nodes, numbered first after the
            outline vertices (``outer`` first, then ``holes`` in order, then these).
        min_angle: Smallest triangle angle [degrees] Triangle must reach, in (0, 34].

    Returns:
        The mesh; its first nodes are the given vertices in the order above.
    """
    import triangle

    outer_polygon = _as_polygon("outer polygon", outer)
    hole_polygons = [_as_polygon(f"hole {k}", h) for k, h in enumerate(holes)]
    check_simple_polygons(
        [outer_polygon, *hole_polygons], ["outer polygon"] + [f"hole {k}" for k in range(len(
            hole_polygons))]
    )
    if element_size is not None and not (element_size > 0.0 and np.isfinite(element_size)):
        raise ValueError(f"element_size = {element_size!r}: must be a finite positive length")
    if not 0.0 < min_angle <= 34.0:
        raise ValueError(f"min_angle = {min_angle!r}: must lie in (0, 34] degrees")
    extra = np.asarray(extra_points, dtype=np.float64).reshape(-1, 2)
    vertices = np.concatenate([outer_polygon, *hole_polygons, extra])
    segments = []
    offset = 0
    for polygon in [outer_polygon, *hole_polygons]:
        count = len(polygon)
        local = np.arange(count)
        segments.append(np.stack([offset + local, offset + (local + 1) % count], axis=1))
        offset += count
    geometry: dict[str, np.ndarray] = {"vertices": vertices, "segments": np.concatenate(segments)}
    if hole_polygons:
        geometry["holes"] = np.array([_interior_point(h) for h in hole_polygons])
    flags = f"pq{min_angle:g}Q"
    if element_size is not None:
        # Positional digits: Triangle reads a switch's number up to the first letter, so
        # "a9.7e-05" would bound the area by 9.7 (and turn on the -e switch).
        area = np.sqrt(3.0) / 4.0 * element_size**2
        flags += "a" + np.format_float_positional(area, precision=17, unique=True, trim="-")
    result = triangle.triangulate(geometry, flags)
    points = np.asarray(result["vertices"], dtype=np.float64)
    triangles = np.asarray(result["triangles"], dtype=np.int64)
    if points.shape[0] > vertices.shape[0] and not np.allclose(
        points[: vertices.shape[0]], vertices
    ):
        raise ValueError("mesh_from_polygon: Triangle renumbered the input vertices")
    clockwise = signed_areas(points, triangles) < 0.0
    triangles[clockwise] = triangles[clockwise][:, ::-1]
    return TriangleMesh(points, triangles)


def _placement(points: np.ndarray, angle: float, shift: np.ndarray) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    rotation = np.array([[c, -s], [s, c]])
    return points @ rotation.T + shift


def mesh_rectangle(
    width: float,
    height: float,
    element_size: float | None = None,
    *,
    counts: tuple[int, int] | None = None,
    center: tuple[float, float] | None = None,
    origin: tuple[float, float] | None = None,
    angle: float = 0.0,
    pattern: str = "alternating",
) -> TriangleMesh:
    """Structured triangle mesh of a rectangle.

    The rectangle ``[0, width] x [0, height]`` is cut into ``counts = (cx, cy)`` cells, each
    split into triangles, then rotated by ``angle`` about its lower-left corner (``origin``) or
    its centre (``center``) and placed there.

    Args:
        width: Side along the rectangle's own x axis [m].
        height: Side along its own y axis [m].
        element_size: Target cell side [m]; gives ``counts = ceil(side / element_size)``.
        counts: Cells along x and y (instead of ``element_size``).
        center: World position of the rectangle's centre [m]; exclusive with ``origin``.
        origin: World position of the rectangle's lower-left corner [m]; default (0, 0).
        angle: Rotation [rad], counter-clockwise.
        pattern: ``"alternating"``: two triangles per cell, diagonals alternating like a
            chequerboard (2 cx cy elements); ``"crossed"``: four triangles per cell around a
            centre node (4 cx cy elements), which locks less in bending.

    Returns:
        The mesh; node ``i + j (cx + 1)`` is the corner at column ``i``, row ``j`` of the cells
        (for ``"crossed"`` the cell centres follow the corners).
    """
    for name, value in (("width", width), ("height", height)):
        if not (value > 0.0 and np.isfinite(value)):
            raise ValueError(f"rectangle {name} = {value!r}: must be a finite positive length")
    if (element_size is None) == (counts is None):
        raise ValueError("mesh_rectangle: give exactly one of element_size and counts")
    if element_size is not None:
        if not (element_size > 0.0 and np.isfinite(element_size)):
            raise ValueError(f"element_size = {element_size!r}: must be a finite positive length")
        cx = max(1, int(np.ceil(width / element_size - 1e-9)))
        cy = max(1, int(np.ceil(height / element_size - 1e-9)))
    elif counts is not None:
        cx, cy = (int(c) for c in counts)
        if cx < 1 or cy < 1 or (cx, cy) != tuple(counts):
            raise ValueError(f"counts = {counts!r}: must be two integers >= 1")
    if center is not None and origin is not None:
        raise ValueError("mesh_rectangle: give at most one of center and origin")
    if pattern not in ("alternating", "crossed"):
        raise ValueError(f"pattern = {pattern!r}: must be 'alternating' or 'crossed'")
    xs = np.linspace(0.0, width, cx + 1)
    ys = np.linspace(0.0, height, cy + 1)
    gx, gy = np.meshgrid(xs, ys, indexing="xy")
    points = np.stack([gx.ravel(), gy.ravel()], axis=1)
    column, row = np.meshgrid(np.arange(cx), np.arange(cy), indexing="xy")
    i, j = column.ravel(), row.ravel()
    a = i + j * (cx + 1)
    b, c, d = a + 1, a + cx + 2, a + cx + 1
    if pattern == "alternating":
        flip = (i + j) % 2 == 1
        first = np.where(flip[:, None], np.stack([a, b, d], 1), np.stack([a, b, c], 1))
        second = np.where(flip[:, None], np.stack([b, c, d], 1), np.stack([a, c, d], 1))
        triangles = np.concatenate([first, second])
    else:
        centres = np.stack([(i + 0.5) * width / cx, (j + 0.5) * height / cy], axis=1)
        m = points.shape[0] + np.arange(i.size)
        points = np.concatenate([points, centres])
        triangles = np.concatenate([
            np.stack([a, b, m], 1), np.stack([b, c, m], 1), np.stack([c, d, m], 1),
            np.stack([d, a, m], 1),
        ])
    if center is not None:
        shift = np.asarray(center, dtype=np.float64)
        points = points - np.array([width / 2.0, height / 2.0])
    else:
        shift = np.asarray((0.0, 0.0) if origin is None else origin, dtype=np.float64)
    return TriangleMesh(_placement(points, angle, shift), triangles)


def mesh_windmill(
    hub_radius: float,
    blade_count: int,
    blade_length: float,
    blade_width: float,
    center: tuple[float, float] = (0.0, 0.0),
    element_size: float | None = None,
    *,
    angle: float = 0.0,
    arc_points: int = 4,
) -> TriangleMesh:
    """One connected body: a round hub with ``blade_count`` straight blades.

    Blade ``k`` points along ``angle + 2 pi k / blade_count`` and reaches
    ``hub_radius + blade_length`` from the centre. Node 0 is the hub centre (the natural pivot).

    Args:
        hub_radius: Radius of the hub [m].
        blade_count: Number of blades, >= 1.
        blade_length: Length of each blade beyond the hub [m].
        blade_width: Width of each blade [m]; blades must not overlap at the hub.
        center: Hub centre [m].
        element_size: Target edge length [m] (default: blade_width / 2).
        angle: Direction of blade 0 [rad].
        arc_points: Outline vertices on each stretch of hub between two blades.
    """
    if not (hub_radius > 0.0 and np.isfinite(hub_radius)):
        raise ValueError(f"hub_radius = {hub_radius!r}: must be a finite positive length")
    if not (blade_length > 0.0 and np.isfinite(blade_length)):
        raise ValueError(f"blade_length = {blade_length!r}: must be a finite positive length")
    if int(blade_count) != blade_count or blade_count < 1:
        raise ValueError(f"blade_count = {blade_count!r}: must be an integer >= 1")
    half = 0.5 * blade_width
    # Half the angle a blade root takes on the hub circle; roots must leave room between them.
    root = np.arcsin(half / hub_radius) if 0.0 < half < hub_radius else np.inf
    if not (blade_width > 0.0 and 2.0 * root * blade_count < 2.0 * np.pi * 0.9):
        raise ValueError(f"blade_width = {blade_width!r}: must be positive and leave a gap "
                         f"between {blade_count} blade roots on a hub of radius {hub_radius}")
    if int(arc_points) != arc_points or arc_points < 1:
        raise ValueError(f"arc_points = {arc_points!r}: must be an integer >= 1")
    root_x = np.sqrt(hub_radius**2 - half**2)
    tip = hub_radius + blade_length
    outline = []
    step = 2.0 * np.pi / blade_count
    for k in range(int(blade_count)):
        direction = angle + k * step
        c, s = np.cos(direction), np.sin(direction)
        local = np.array([[root_x, -half], [tip, -half], [tip, half], [root_x, half]])
        outline.append(local @ np.array([[c, s], [-s, c]]))
        arc = direction + root + (step - 2.0 * root) * np.arange(1, arc_points + 1) / (
            arc_points + 1
        )
        outline.append(hub_radius * np.stack([np.cos(arc), np.sin(arc)], axis=1))
    polygon = np.concatenate(outline) + np.asarray(center, dtype=np.float64)
    size = 0.5 * blade_width if element_size is None else element_size
    mesh = mesh_from_polygon(polygon, element_size=size, extra_points=[center])
    # Put the hub centre first so that node 0 is the pivot.
    hub = polygon.shape[0]
    permutation = np.arange(mesh.point_count)
    permutation[[0, hub]] = permutation[[hub, 0]]
    return _renumber(mesh, permutation)


def _renumber(mesh: TriangleMesh, order: np.ndarray) -> TriangleMesh:
    """The same mesh with node ``order[k]`` renamed ``k``."""
    new_index = np.empty_like(order)
    new_index[order] = np.arange(order.size)
    return TriangleMesh(
        mesh.points[order], new_index[mesh.triangles],
        tuple(new_index[loop] for loop in mesh.boundary_loops),
    )


def read_mesh(path: str | Path) -> TriangleMesh:
    """Read a triangle mesh with meshio (.msh, .vtk, .vtu, .obj, .ply, ...).

    Only triangle cells are used; points must be 2D or 3D with z = 0. Clockwise triangles are
    turned counter-clockwise (3D tools often store the opposite normal); points used by no
    triangle are dropped.
    """
    import meshio

    data = meshio.read(str(path))
    blocks = [cells.data for cells in data.cells if cells.type == "triangle"]
    if not blocks:
        kinds = sorted({cells.type for cells in data.cells})
        raise ValueError(f"mesh file {path}: has no triangle cells (found {kinds})")
    triangles = np.concatenate(blocks).astype(np.int64)
    points = np.asarray(data.points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] not in (2, 3):
        raise ValueError(f"mesh file {path}: points shape {points.shape}, must be (n, 2 or 3)")
    if points.shape[1] == 3:
        off_plane = np.flatnonzero(np.abs(points[:, 2]) > 1e-12 * max(1.0, np.abs(points).max()))
        if off_plane.size:
            raise ValueError(f"mesh file {path}: vertex {off_plane[0]} has z = "
                             f"{points[off_plane[0], 2]!r}, must be 0 (2D meshes only)")
        points = points[:, :2]
    used = np.unique(triangles)
    if used.size < points.shape[0]:
        new_index = np.full(points.shape[0], -1, np.int64)
        new_index[used] = np.arange(used.size)
        points, triangles = points[used], new_index[triangles]
    clockwise = signed_areas(points, triangles) < 0.0
    triangles[clockwise] = triangles[clockwise][:, ::-1]
    return TriangleMesh(points, triangles)


def nodes_in_box(mesh: TriangleMesh, box: tuple[float, float, float, float],
                 positions: np.ndarray | None = None) -> np.ndarray:
    """Indices of the nodes inside the closed box ``(x0, y0, x1, y1)`` [m], int64 (sorted).

    Uses the rest points unless ``positions`` (n, 2) is given. Bounds are widened by a relative
    1e-9 so that nodes lying exactly on the box are included.
    """
    x0, y0, x1, y1 = (float(v) for v in box)
    if not (x0 <= x1 and y0 <= y1):
        raise ValueError(f"box = {box!r}: must be (x0, y0, x1, y1) with x0 <= x1, y0 <= y1")
    p = mesh.points if positions is None else np.asarray(positions)
    tolerance = 1e-9 * max(1.0, float(np.abs(p).max()))
    inside = ((p[:, 0] >= x0 - tolerance) & (p[:, 0] <= x1 + tolerance)
              & (p[:, 1] >= y0 - tolerance) & (p[:, 1] <= y1 + tolerance))
    return np.flatnonzero(inside).astype(np.int64)


def nearest_node(mesh: TriangleMesh, point: tuple[float, float]) -> int:
    """Index of the rest node nearest to ``point`` [m]."""
    return int(np.argmin(np.linalg.norm(mesh.points - np.asarray(point, float), axis=1)))
