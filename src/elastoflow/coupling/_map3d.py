"""The 3D boundary map: where the bodies' surface triangles cross the grid lines.

The 2D map (`BoundaryMap`) crosses boundary edges with the half-grid rows and columns; in 3D
the surface is a set of triangles and the lines run along x, y and z through every half-grid
position of the two other axes (cell centres and face centres alike). The map is built by
looping over triangles, each visiting only the lines inside its projected bounding box, so
its cost follows the surface's area (in cells) and the triangle count, not the volume.
Points on a projected edge or vertex are decided by a symbolic perturbation (see
`elastoflow.coupling._kernels3d`), so that a line through a shared edge or vertex crosses a
closed surface exactly as often as a line beside it.

Cells are classified by the winding number along the x lines through their centres (ray
parity, robust to nested and overlapping bodies: inside any body where the sum of entering
minus leaving crossings before the centre is positive).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from elastoflow.coupling import _kernels3d
from elastoflow.grid import Grid3D


@dataclass(frozen=True, eq=False)
class LineCrossings:
    """The crossings of the surface with the half-grid lines parallel to one axis.

    Lines are indexed ``L = U * lines_v + V`` with ``U``, ``V`` their half-grid positions along
    ``u = (axis + 1) % 3`` and ``v = (axis + 2) % 3`` (the line through ``origin_u + U h/2``,
    ``origin_v + V h/2``); a line's crossings are ``offsets[L]:offsets[L + 1]`` of every entry
    array, sorted by coordinate (leaving before entering on ties).

    Attributes:
        axis: 0, 1 or 2 (x, y, z).
        lines_u: Number of half-grid positions along u (``2 n_u + 1``).
        lines_v: Number along v.
        offsets: int64, (lines_u * lines_v + 1,).
        coordinate: Position [m] along the axis of each crossing, (C,).
        triangle: Index into the map's triangles of each crossing, int64, (C,).
        weights: Barycentric weights of the crossing in its triangle, (C, 3).
        sign: +1 where walking towards +axis enters a body, -1 where it leaves, int8, (C,).
    """

    axis: int
    lines_u: int
    lines_v: int
    offsets: np.ndarray
    coordinate: np.ndarray
    triangle: np.ndarray
    weights: np.ndarray
    sign: np.ndarray

    @property
    def count(self) -> int:
        return int(self.coordinate.shape[0])

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(offsets, coordinate, sign, triangle, weights)``: the bundle the line kernels
        (`nearest_crossings`, `inside_along_lines`) take."""
        return (self.offsets, self.coordinate, self.sign, self.triangle, self.weights)

    def line(self, position_u: int, position_v: int) -> slice:
        """The entries of the line at half-grid positions ``(U, V)``."""
        index = position_u * self.lines_v + position_v
        return slice(int(self.offsets[index]), int(self.offsets[index + 1]))


@dataclass(frozen=True, eq=False)
class BoundaryMap3D:
    """Crossings of closed, outward-oriented surface triangles with the grid lines along x,
    y and z.

    Attributes:
        grid: The grid.
        points: Surface vertices [m], (P, 3).
        velocities: Their velocities [m/s], (P, 3).
        triangles: Vertex indices, outward orientation (``(b - a) x (c - a)`` points out of
            the body), int64, (T, 3).
        triangle_body: Body of each triangle, int64, (T,).
        lines: The crossings with the lines along x, y and z.
    """

    grid: Grid3D
    points: np.ndarray
    velocities: np.ndarray
    triangles: np.ndarray
    triangle_body: np.ndarray
    lines: tuple[LineCrossings, LineCrossings, LineCrossings]

    @property
    def crossing_count(self) -> int:
        return sum(crossings.count for crossings in self.lines)

    def crossing_velocities(self, axis: int) -> np.ndarray:
        """Surface velocity [m/s] at each crossing of the lines along ``axis``, (C, 3):
        barycentric in its triangle (exact for rigid motion of the vertices)."""
        crossings = self.lines[axis]
        corners = self.triangles[crossings.triangle]
        return np.einsum("ck,ckd->cd", crossings.weights, self.velocities[corners])


def _line_crossings(grid: Grid3D, points: np.ndarray, triangles: np.ndarray,
                    axis: int) -> LineCrossings:
    u, v = (axis + 1) % 3, (axis + 2) % 3
    counts = (grid.nx, grid.ny, grid.nz)
    lines_u, lines_v = 2 * counts[u] + 1, 2 * counts[v] + 1
    half = 0.5 * grid.h
    origin_u, origin_v = float(grid.origin[u]), float(grid.origin[v])
    per_line = np.zeros(lines_u * lines_v, dtype=np.int64)
    unused_f = np.zeros(0)
    unused_i = np.zeros(0, dtype=np.int64)
    unused_w = np.zeros((0, 3))
    unused_s = np.zeros(0, dtype=np.int8)
    _kernels3d.triangle_crossings(points, triangles, axis, origin_u, origin_v, half, lines_u,
                                  lines_v, False, per_line, unused_i, unused_f, unused_i,
                                  unused_w, unused_s)
    offsets = np.zeros(per_line.shape[0] + 1, dtype=np.int64)
    np.cumsum(per_line, out=offsets[1:])
    total = int(offsets[-1])
    coordinate = np.empty(total)
    triangle = np.empty(total, dtype=np.int64)
    weights = np.empty((total, 3))
    sign = np.empty(total, dtype=np.int8)
    next_slot = offsets[:-1].copy()
    per_line[:] = 0
    _kernels3d.triangle_crossings(points, triangles, axis, origin_u, origin_v, half, lines_u,
                                  lines_v, True, per_line, next_slot, coordinate, triangle,
                                  weights, sign)
    _kernels3d.sort_lines(offsets, coordinate, triangle, weights, sign)
    return LineCrossings(axis, lines_u, lines_v, offsets, coordinate, triangle, weights, sign)


def build_boundary_map_3d(grid: Grid3D, points: np.ndarray, velocities: np.ndarray,
                          triangles: np.ndarray,
                          triangle_body: np.ndarray | None = None) -> BoundaryMap3D:
    """The 3D map of closed surfaces given by outward-oriented triangles.

    Args:
        grid: The grid.
        points: Surface vertices [m], (P, 3), finite.
        velocities: Their velocities [m/s], (P, 3).
        triangles: Vertex indices, int, (T, 3), each surface closed and oriented outwards.
        triangle_body: Body index of each triangle (default: all 0).

    Raises:
        ValueError: On shapes, non-finite values or indices out of range (one line each).
    """
    points = np.ascontiguousarray(points, dtype=np.float64)
    velocities = np.ascontiguousarray(velocities, dtype=np.float64)
    triangles = np.ascontiguousarray(triangles, dtype=np.int64)
    if points.ndim != 2 or points.shape[1] != 3:
        raise ValueError(f"points: shape {points.shape} is not allowed; expected (P, 3)")
    if velocities.shape != points.shape:
        raise ValueError(f"velocities: shape {velocities.shape} is not allowed; "
                         f"expected {points.shape}")
    if triangles.ndim != 2 or triangles.shape[1] != 3:
        raise ValueError(f"triangles: shape {triangles.shape} is not allowed; expected (T, 3)")
    if not (np.isfinite(points).all() and np.isfinite(velocities).all()):
        raise ValueError("points and velocities: values must be finite")
    if triangles.size and (triangles.min() < 0 or triangles.max() >= points.shape[0]):
        raise ValueError(f"triangles: indices must lie in [0, {points.shape[0]}); got "
                         f"[{triangles.min()}, {triangles.max()}]")
    if triangle_body is None:
        triangle_body = np.zeros(triangles.shape[0], dtype=np.int64)
    triangle_body = np.ascontiguousarray(triangle_body, dtype=np.int64)
    if triangle_body.shape != (triangles.shape[0],):
        raise ValueError(f"triangle_body: shape {triangle_body.shape} is not allowed; "
                         f"expected ({triangles.shape[0]},)")
    lines = (_line_crossings(grid, points, triangles, 0),
             _line_crossings(grid, points, triangles, 1),
             _line_crossings(grid, points, triangles, 2))
    return BoundaryMap3D(grid, points, velocities, triangles, triangle_body, lines)


def solid_cells_3d(bmap: BoundaryMap3D, out: np.ndarray | None = None,
                   out_box: tuple[int, ...] | None = None) -> np.ndarray:
    """Cells whose centre lies inside a body (winding number along x > 0), bool,
    (nx, ny, nz).

    ``out``: an earlier result of the same grid that is no longer read, refilled instead of
    allocated: reset inside ``out_box`` (the `bodies_box_3d` of the map it came from,
    outside which it is all False) or everywhere when that is None."""
    grid = bmap.grid
    crossings = bmap.lines[0]
    shape = (grid.nx, grid.ny, grid.nz)
    if out is None:
        solid = np.zeros(shape, dtype=np.bool_)
    else:
        if out.shape != shape or out.dtype != np.bool_:
            raise ValueError(f"out: {out.dtype} array of shape {out.shape} is not allowed; "
                             f"expected bool {shape}")
        solid = out
        if out_box is None:
            solid[...] = False
        else:
            _kernels3d.fill_box(solid, np.asarray(out_box, dtype=np.int64), False)
    _kernels3d.solid_along_lines(crossings.offsets, crossings.coordinate, crossings.sign,
                                 crossings.lines_v, 1, 1, grid.ny, grid.nz,
                                 float(grid.origin[0]), grid.h, grid.nx, solid)
    return solid


def face_open_fractions_3d(
    bmap: BoundaryMap3D,
    out: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
    out_box: tuple[int, int, int, int, int, int] | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The fluid share of every face's square, exactly: ``1 - area(section n square) / h^2``
    with the section the bodies' cross-section in the face's plane (`elastoflow.coupling._area`).

    Continuous in the bodies' positions (a body edge sliding across a face changes it
    linearly), in [0, 1], so the pressure operator weighted by it stays SPD. Overlapping
    bodies count their overlap twice (clipped at 0). Only the faces inside the map's
    `bodies_box_3d` are computed; every other one is 1.

    Args:
        out: An earlier map's fractions of the same grid, no longer read, to refill instead
            of allocating; they are 1 outside ``out_box`` (their map's `bodies_box_3d`; None:
            not known, the whole arrays are reset).

    Returns:
        ``(x faces (nx+1, ny, nz), y faces (nx, ny+1, nz), z faces (nx, ny, nz+1))``.
    """
    grid = bmap.grid
    counts = (grid.nx, grid.ny, grid.nz)
    box = bodies_box_3d(bmap)
    fractions = []
    for axis in range(3):
        u, v = (axis + 1) % 3, (axis + 2) % 3
        planes = counts[axis] + 1
        shape = [counts[0], counts[1], counts[2]]
        shape[axis] = planes
        if out is None:
            open_fraction = np.ones(shape)
        else:
            open_fraction = out[axis]
            if open_fraction.shape != tuple(shape):
                raise ValueError(f"out[{axis}] shape {open_fraction.shape}: must be "
                                 f"{tuple(shape)} for this grid")
            if out_box is None:
                open_fraction[...] = 1.0
            else:
                _kernels3d.fill_box(open_fraction, np.asarray(out_box, dtype=np.int64), 1.0)
        # The faces of the box: the sections lie inside it (it holds every surface point).
        start = np.array(box[:3], dtype=np.int64)
        stop = [min(box[3 + a], shape[a]) for a in range(3)]
        sizes = [max(stop[a] - int(start[a]), 0) for a in range(3)]
        if min(sizes) == 0:
            fractions.append(open_fraction)
            continue
        per_plane = np.zeros(planes, dtype=np.int64)
        no_slots = np.zeros(planes, dtype=np.int64)
        no_segments = np.zeros((0, 4))
        _kernels3d.plane_sections(bmap.points, bmap.triangles, axis, float(grid.origin[axis]),
                                  grid.h, planes, False, per_plane, no_slots, no_segments)
        offsets = np.zeros(planes + 1, dtype=np.int64)
        np.cumsum(per_plane, out=offsets[1:])
        segments = np.empty((int(offsets[-1]), 4))
        next_slot = offsets[:-1].copy()
        per_plane[:] = 0
        _kernels3d.plane_sections(bmap.points, bmap.triangles, axis, float(grid.origin[axis]),
                                  grid.h, planes, True, per_plane, next_slot, segments)
        solid = np.zeros((sizes[axis], sizes[u], sizes[v]))
        _kernels3d.section_areas(
            segments, offsets[start[axis]:stop[axis] + 1],
            float(grid.origin[u]) + int(start[u]) * grid.h,
            float(grid.origin[v]) + int(start[v]) * grid.h, grid.h, solid)
        _kernels3d.open_fractions_from_areas(solid, grid.h**2, axis, start, open_fraction)
        fractions.append(open_fraction)
    return fractions[0], fractions[1], fractions[2]


@dataclass(frozen=True)
class CutDistances3D:
    """For the velocity points of each component, the first body boundary towards each of
    the six neighbours. Directions ``d``: 0 -x, 1 +x, 2 -y, 3 +y, 4 -z, 5 +z.

    Attributes:
        theta: Per component (u, v, w), the fraction of h from the point towards its
            neighbour in direction d at which a boundary is crossed, in (0, 1], ``inf``
            where none lies within one spacing; shapes (6, *shape of the points).
        velocity: The body velocity's own component (x for u points, ...) at that crossing
            [m/s], 0 where none; same shapes.
        box: The map's `bodies_box_3d`: outside it every theta is ``inf`` and every
            velocity 0 (None: not known).
    """

    theta: tuple[np.ndarray, np.ndarray, np.ndarray]
    velocity: tuple[np.ndarray, np.ndarray, np.ndarray]
    box: tuple[int, int, int, int, int, int] | None = None


# Margin [cells] around the bodies' bounding box: a cut distance is written at most one
# spacing from a crossing, a solid point or a partly closed face lies within it.
_BOX_MARGIN = 3


def bodies_box_3d(bmap: BoundaryMap3D) -> tuple[int, int, int, int, int, int]:
    """Index box ``(i0, j0, k0, i1, j1, k1)`` (ends exclusive, clipped to ``[0, n + 1]``)
    outside which no point of any field (cells, u, v, w) is inside a body, next to a
    crossing or on a partly closed face (beyond the rounding of the section areas): the
    map's points' bounding box widened by `_BOX_MARGIN` cells; empty (all zero) without
    points."""
    grid = bmap.grid
    counts = (grid.nx, grid.ny, grid.nz)
    if bmap.points.shape[0] == 0:
        return (0, 0, 0, 0, 0, 0)
    low = (bmap.points.min(axis=0) - np.asarray(grid.origin)) / grid.h
    high = (bmap.points.max(axis=0) - np.asarray(grid.origin)) / grid.h
    start = [min(max(int(np.floor(low[a])) - _BOX_MARGIN, 0), counts[a] + 1) for a in range(3)]
    stop = [min(max(int(np.floor(high[a])) + _BOX_MARGIN + 1, start[a]), counts[a] + 1)
            for a in range(3)]
    return (start[0], start[1], start[2], stop[0], stop[1], stop[2])


def cut_distances_3d(bmap: BoundaryMap3D, out: CutDistances3D | None = None
                     ) -> CutDistances3D:
    """`CutDistances3D` of every u, v and w point, from the crossings on the lines through
    the points (METHOD.md's cut distances, one line per direction). The arrays are filled
    with "none" and only the points next to a crossing are visited; ``out`` (the same grid's
    earlier result, no longer needed) is filled instead of new arrays: only inside its
    ``box`` when it has one (`bodies_box_3d`: nothing was written outside it), so that the
    cost follows the bodies, not the grid."""
    grid = bmap.grid
    counts = (grid.nx, grid.ny, grid.nz)
    thetas = []
    speeds = []
    for component in range(3):
        # The points of this component: integer positions along their own axis, half
        # positions along the two others (in half-grid units: even along it, odd across).
        shape = tuple(counts[a] + (1 if a == component else 0) for a in range(3))
        if out is not None and out.theta[component].shape == (6, *shape):
            theta, velocity = out.theta[component], out.velocity[component]
            if out.box is None:
                theta.fill(np.inf)
                velocity.fill(0.0)
            else:
                i0, j0, k0, i1, j1, k1 = out.box
                theta[:, i0:i1, j0:j1, k0:k1] = np.inf
                velocity[:, i0:i1, j0:j1, k0:k1] = 0.0
        else:
            theta = np.full((6, *shape), np.inf)
            velocity = np.zeros((6, *shape))
        for axis in range(3):
            u, v = (axis + 1) % 3, (axis + 2) % 3
            crossings = bmap.lines[axis]
            half_u = 0 if u == component else 1
            half_v = 0 if v == component else 1
            shift = 0.0 if axis == component else 0.5
            _kernels3d.nearest_crossings(
                crossings.arrays(), (bmap.triangles, bmap.velocities), component,
                (axis, crossings.lines_v, half_u, half_v, shape[u], shape[v]),
                (float(grid.origin[axis]), shift, grid.h, shape[axis]),
                (theta[2 * axis], theta[2 * axis + 1], velocity[2 * axis],
                 velocity[2 * axis + 1]))
        thetas.append(theta)
        speeds.append(velocity)
    return CutDistances3D((thetas[0], thetas[1], thetas[2]), (speeds[0], speeds[1], speeds[2]),
                          bodies_box_3d(bmap))
