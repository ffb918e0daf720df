"""A 3D state seen through a plane: the field on the cells the plane cuts, with the bodies'
cross-sections drawn on top, through the 2D frame's colouring, colour bar and time stamp.

What a user can look at without ParaView (issue 16, item 5): a slice per frame makes a video
of a 3D run with the same look as the 2D ones.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import math

import numpy as np
from numba import njit

from elastoflow.grid import Grid2D, Grid3D
from elastoflow.render._frame import (
    BODY_EDGE_COLOR,
    BODY_FILL_COLOR,
    OBSTACLE_EDGE_COLOR,
    OBSTACLE_FILL_COLOR,
    default_scale,
    render_frame,
)
from elastoflow.render._kernels import draw_segments, fill_triangles

AXES = {"x": 0, "y": 1, "z": 2}
VIEWS_3D = ("speed", "vorticity", "pressure", "dye")
SILHOUETTE_COLOR = np.array([230, 0, 230], dtype=np.uint8)
"""The outline of a surface seen along the slice's normal (what lies off the plane): magenta,
a colour none of the field's colour maps uses."""


def slice_values(grid: Grid3D, state: Any, axis: int, index: int, view: str) -> np.ndarray:
    """The view's values on cell layer ``index`` across ``axis``, as a 2D field indexed by
    the two other axes in order ((ny, nz) for x, (nx, nz) for y, (nx, ny) for z). Vorticity
    is its component along ``axis`` (the one in the plane's normal: the swirl seen in it)."""
    if view not in VIEWS_3D:
        raise ValueError(f"view = {view!r}: must be one of {', '.join(VIEWS_3D)}")
    if not 0 <= index < grid.shape_cells[axis]:
        raise ValueError(f"slice index {index}: must be in 0..{grid.shape_cells[axis] - 1}")
    if view == "pressure":
        return np.take(state.pressure, index, axis=axis)
    if view == "dye":
        return np.take(state.dye, index, axis=axis)
    return layer_values(grid, state, axis, index, view)


def _layers(array: np.ndarray, axis: int, start: int, stop: int) -> np.ndarray:
    index = [slice(None)] * 3
    index[axis] = slice(start, stop)
    return array[tuple(index)]


def _centre_velocity_layers(state: Any, axis: int, start: int, stop: int) -> np.ndarray:
    """`_centre_velocity` on the cell layers ``start .. stop - 1`` across ``axis`` alone,
    shape (..., 3) with ``stop - start`` along ``axis``."""
    parts = []
    for component, faces in enumerate((state.velocity_x, state.velocity_y,
                                       state.velocity_z)):
        faces = _layers(faces, axis, start, stop + (component == axis))
        parts.append(0.5 * (_layers(faces, component, 1, faces.shape[component])
                            + _layers(faces, component, 0, faces.shape[component] - 1)))
    return np.stack(parts, axis=-1)


def layer_values(grid: Grid3D, state: Any, axis: int, index: int, view: str) -> np.ndarray:
    """`slice_values`' speed and vorticity, with the cell-centre velocity computed on the
    layer (and its two neighbours for the vorticity, along ``axis``: d(b)/d(a) - d(a)/d(b)
    for the in-plane axes) alone instead of the whole volume: what a frame per step can
    afford at 64^3 and beyond (0.1 ms instead of 30 ms there)."""
    if view not in ("speed", "vorticity") or not 0 <= index < grid.shape_cells[axis]:
        return slice_values(grid, state, axis, index, view)
    if view == "speed":
        velocity = _centre_velocity_layers(state, axis, index, index + 1)
        return np.take(np.sqrt((velocity**2).sum(axis=-1)), 0, axis=axis)
    start, stop = max(index - 1, 0), min(index + 2, grid.shape_cells[axis])
    local = _centre_velocity_layers(state, axis, start, stop)
    a, b = [k for k in range(3) if k != axis]
    h = grid.h
    db_da = np.gradient(local[..., b], h, axis=a) if local.shape[a] > 1 else 0.0 * local[..., b]
    da_db = np.gradient(local[..., a], h, axis=b) if local.shape[b] > 1 else 0.0 * local[..., a]
    return np.take(db_da - da_db, index - start, axis=axis)


def tetrahedra_section(points: np.ndarray, tetrahedra: np.ndarray, axis: int,
                       position: float) -> tuple[np.ndarray, np.ndarray]:
    """The cross-section of a tetrahedral mesh with the plane ``x[axis] = position``: points
    (in the plane's two other coordinates, in order) and triangles; a tetrahedron cut into a
    quadrilateral gives two."""
    others = [k for k in range(3) if k != axis]
    distance = points[tetrahedra, axis] - position  # (m, 4)
    above = distance > 0.0
    count = above.sum(axis=1)
    pieces_points: list[np.ndarray] = []
    pieces_triangles: list[np.ndarray] = []
    offset = 0

    def crossing(tets: np.ndarray, i: np.ndarray, j: np.ndarray) -> np.ndarray:
        """Where edge (i, j) of each tetrahedron meets the plane, in-plane coordinates."""
        pi = points[tetrahedra[tets, i]]
        pj = points[tetrahedra[tets, j]]
        di = distance[tets, i]
        dj = distance[tets, j]
        t = (di / (di - dj))[:, None]
        return (pi + t * (pj - pi))[:, others]

    for lonely_above in (True, False):
        # One vertex alone on its side: a triangle.
        tets = np.flatnonzero(count == (1 if lonely_above else 3))
        if tets.size:
            side = above[tets] if lonely_above else ~above[tets]
            alone = np.argmax(side, axis=1)
            rest = np.array([[k for k in range(4) if k != a] for a in range(4)])[alone]
            corners = np.stack([crossing(tets, alone, rest[:, c]) for c in range(3)], axis=1)
            pieces_points.append(corners.reshape(-1, 2))
            pieces_triangles.append(offset + np.arange(3 * tets.size).reshape(-1, 3))
            offset += 3 * tets.size
    tets = np.flatnonzero(count == 2)
    if tets.size:
        order = np.argsort(~above[tets], axis=1, kind="stable")  # the two above first
        a0, a1, b0, b1 = order[:, 0], order[:, 1], order[:, 2], order[:, 3]
        # The quadrilateral a0-b0, a0-b1, a1-b1, a1-b0 in order around its boundary.
        quad = np.stack([crossing(tets, a0, b0), crossing(tets, a0, b1),
                         crossing(tets, a1, b1), crossing(tets, a1, b0)], axis=1)
        pieces_points.append(quad.reshape(-1, 2))
        base = offset + 4 * np.arange(tets.size)
        pieces_triangles.append(np.concatenate([np.stack([base, base + 1, base + 2], axis=1),
                                                np.stack([base, base + 2, base + 3], axis=1)]))
        offset += 4 * tets.size
    if not pieces_points:
        return np.zeros((0, 2)), np.zeros((0, 3), dtype=np.int64)
    return np.concatenate(pieces_points), np.concatenate(pieces_triangles).astype(np.int64)


def surface_section(points: np.ndarray, triangles: np.ndarray, axis: int,
                    position: float) -> tuple[np.ndarray, np.ndarray]:
    """Where a triangle surface meets the plane ``x[axis] = position``: segments (starts,
    ends), each shape (s, 2) in the plane's two other coordinates [m], in order.

    A vertex on the plane counts as below it (as in `tetrahedra_section`) and each crossing is
    computed from its edge's lower-numbered vertex, so the two triangles of an edge give the
    same point to the bit: the section of a closed surface is a set of closed loops (what
    `fill_segments` fills by the even-odd rule), each segment's end the next one's start.
    With outward triangles the loops run counter-clockwise around the solid in the plane's
    coordinates (the first to the right, the second up, as the slice is drawn).
    """
    points = np.asarray(points, dtype=np.float64)
    triangles = np.asarray(triangles, dtype=np.int64)
    others = [k for k in range(3) if k != axis]
    distance = points[:, axis] - position
    above = distance[triangles] > 0.0  # (T, 3)
    count = above.sum(axis=1)
    cut = np.flatnonzero((count == 1) | (count == 2))
    if not cut.size:
        return np.zeros((0, 2)), np.zeros((0, 2))
    side = above[cut]
    # The vertex alone on its side: the one above when one is, else the one below.
    alone = np.where(count[cut] == 1, np.argmax(side, axis=1), np.argmin(side, axis=1))
    ends = []
    for step in (1, 2):
        i = triangles[cut, alone]
        j = triangles[cut, (alone + step) % 3]
        low, high = np.minimum(i, j), np.maximum(i, j)
        d_low, d_high = distance[low], distance[high]
        t = (d_low / (d_low - d_high))[:, None]
        ends.append((points[low] + t * (points[high] - points[low]))[:, others])
    corners = points[triangles[cut]]
    normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    # Along (the picture's normal) x (the triangle's): the solid on the left.
    facing = np.cross(np.eye(3)[others[0]], np.eye(3)[others[1]])
    along = np.cross(facing, normal)[:, others]
    backwards = ((ends[1] - ends[0]) * along).sum(axis=1) < 0.0
    starts = np.where(backwards[:, None], ends[1], ends[0])
    return starts, np.where(backwards[:, None], ends[0], ends[1])


def surface_silhouette(points: np.ndarray, triangles: np.ndarray,
                       axis: int) -> tuple[np.ndarray, np.ndarray]:
    """The outline of a triangle surface seen along ``axis``: the edges between a triangle
    facing +axis and one that does not (and the edges of an open surface's rim), as segments
    (starts, ends), each shape (s, 2) in the two other coordinates [m], in order."""
    points = np.asarray(points, dtype=np.float64)
    triangles = np.asarray(triangles, dtype=np.int64)
    others = [k for k in range(3) if k != axis]
    if not triangles.shape[0]:
        return np.zeros((0, 2)), np.zeros((0, 2))
    corners = points[triangles]
    normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])[:, axis]
    front = normal > 0.0
    edges = np.concatenate((triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]))
    owner = np.tile(np.arange(triangles.shape[0]), 3)
    low, high = edges.min(axis=1), edges.max(axis=1)
    order = np.lexsort((high, low))
    low, high, owner = low[order], high[order], owner[order]
    pair = (low[:-1] == low[1:]) & (high[:-1] == high[1:])
    first = np.flatnonzero(pair)
    outline = first[front[owner[first]] != front[owner[first + 1]]]
    paired = np.zeros(low.size, dtype=np.bool_)
    paired[first] = True
    paired[first + 1] = True
    rim = np.flatnonzero(~paired)
    chosen = np.concatenate((outline, rim))
    return points[low[chosen]][:, others], points[high[chosen]][:, others]


@njit(cache=True)
def fill_segments(image: np.ndarray, starts: np.ndarray, ends: np.ndarray,
                  color: np.ndarray) -> None:
    """Paint the pixels whose centre lies inside closed loops given as loose segments [pixels]
    (even-odd rule, scanlines): the section of a closed surface, whatever order its pieces
    come in."""
    height, width = image.shape[0], image.shape[1]
    count_segments = starts.shape[0]
    if count_segments == 0:
        return
    low = min(starts[:, 1].min(), ends[:, 1].min())
    high = max(starts[:, 1].max(), ends[:, 1].max())
    if not (math.isfinite(low) and math.isfinite(high)):
        return
    row_min = max(math.floor(low), 0)
    row_max = min(math.ceil(high), height - 1)
    crossings = np.empty(count_segments)
    for row in range(row_min, row_max + 1):
        sy = row + 0.5
        count = 0
        for e in range(count_segments):
            xa, ya = starts[e, 0], starts[e, 1]
            xb, yb = ends[e, 0], ends[e, 1]
            # Half-open rule so that a loop's vertex on the scanline is counted once.
            if (ya <= sy) != (yb <= sy):
                crossings[count] = xa + (sy - ya) * (xb - xa) / (yb - ya)
                count += 1
        xs = np.sort(crossings[:count])
        for pair in range(0, count - 1, 2):
            col_start = max(math.ceil(xs[pair] - 0.5), 0)
            col_end = min(math.floor(xs[pair + 1] - 0.5), width - 1)
            for col in range(col_start, col_end + 1):
                for c in range(3):
                    image[row, col, c] = color[c]


def render_slice_3d(
    grid: Grid3D,
    state: Any,
    *,
    axis: str = "z",
    position: float | None = None,
    view: str = "speed",
    bodies: Sequence[tuple[np.ndarray, np.ndarray]] = (),
    time: float | None = None,
    value_range: tuple[float, float] | None = None,
    scale: int | None = None,
    colorbar: bool = True,
    out: np.ndarray | None = None,
    obstacles: Sequence[tuple[np.ndarray, np.ndarray]] = (),
    surfaces: Sequence[tuple[np.ndarray, np.ndarray]] = (),
    values: np.ndarray | None = None,
) -> np.ndarray:
    """Draw ``view`` on the cell layer that the plane ``axis = position`` [m] (default: the
    domain's middle) cuts, with the bodies' cross-sections filled (the time stamp may sit
    under a section that reaches the top-left corner); the picture's horizontal
    axis is the first of the two other axes (y for an x-slice, x otherwise), as `render_frame`
    draws a 2D run.

    Args:
        grid: The `Grid3D`.
        state: A `FluidState3D` (``velocity_x/_y/_z``, ``pressure``, ``dye``).
        axis: "x", "y" or "z": the plane's normal.
        position: Where the plane cuts that axis [m].
        view: "speed", "vorticity" (its component along ``axis``), "pressure" or "dye".
        bodies: ``(positions (n, 3), tetrahedra (m, 4))`` pairs [m].
        time, value_range, scale, colorbar, out: As `render_frame`.
        obstacles: Closed triangle surfaces ``(points (k, 3), triangles (T, 3))`` [m] (e.g.
            an `Obstacle3D`'s ``points_at(t)`` and ``triangles``): their section is filled and
            outlined in the obstacle colours, their outline seen along ``axis`` drawn in
            `SILHOUETTE_COLOR`.
        surfaces: The bodies' surfaces ``(positions (n, 3), triangles (T, 3))`` [m] (what
            `Simulation.body_geometry` gives): their outline seen along ``axis`` is drawn in
            `SILHOUETTE_COLOR` under the sections (where a body lies off the plane) and the
            edge of their section in the bodies' edge colour.
        values: The layer's values (`slice_values` or `layer_values` of the layer the plane
            cuts), if the caller has them; computed by `slice_values` when None.

    Returns:
        RGB image (H, W, 3) uint8.
    """
    if axis not in AXES:
        raise ValueError(f"axis = {axis!r}: must be one of x, y, z")
    k = AXES[axis]
    low_edge = grid.origin[k]
    extent = grid.shape_cells[k] * grid.h
    if position is None:
        position = low_edge + 0.5 * extent
    if not low_edge <= position <= low_edge + extent:
        raise ValueError(f"position = {position!r}: the plane must cut the domain "
                         f"[{low_edge}, {low_edge + extent}] m along {axis}")
    index = min(int((position - low_edge) / grid.h), grid.shape_cells[k] - 1)
    if values is None:
        values = slice_values(grid, state, k, index, view)
    others = [a for a in range(3) if a != k]
    plane = Grid2D(grid.shape_cells[others[0]], grid.shape_cells[others[1]], grid.h,
                   origin=(grid.origin[others[0]], grid.origin[others[1]]))
    scale = default_scale(plane) if scale is None else int(scale)
    image = render_frame(plane, None, (), (), view, time, value_range=value_range, scale=scale,
                         colorbar=colorbar, values=values, out=out)
    height, width = plane.ny * scale, plane.nx * scale
    field = image[:height, :width]

    def to_pixels(in_plane: np.ndarray) -> np.ndarray:
        pixels = np.empty_like(in_plane)
        pixels[:, 0] = (in_plane[:, 0] - plane.origin[0]) * scale / grid.h
        pixels[:, 1] = height - (in_plane[:, 1] - plane.origin[1]) * scale / grid.h
        return pixels

    for points, triangles in (*surfaces, *obstacles):
        starts, ends = surface_silhouette(points, triangles, k)
        draw_segments(field, to_pixels(starts), to_pixels(ends), SILHOUETTE_COLOR)
    for points, triangles in obstacles:
        starts, ends = surface_section(points, triangles, k, position)
        starts, ends = to_pixels(starts), to_pixels(ends)
        fill_segments(field, starts, ends, OBSTACLE_FILL_COLOR)
        draw_segments(field, starts, ends, OBSTACLE_EDGE_COLOR)
    for points, tetrahedra in bodies:
        section, triangles = tetrahedra_section(np.asarray(points, dtype=np.float64),
                                                np.asarray(tetrahedra, dtype=np.int64), k,
                                                position)
        if not triangles.shape[0]:
            continue
        # Filled only: the section's triangles are pieces of tetrahedra, their edges noise.
        pixels = np.empty_like(section)
        pixels[:, 0] = (section[:, 0] - plane.origin[0]) * scale / grid.h
        pixels[:, 1] = height - (section[:, 1] - plane.origin[1]) * scale / grid.h
        fill_triangles(field, pixels, triangles, BODY_FILL_COLOR)
    for points, triangles in surfaces:
        starts, ends = surface_section(points, triangles, k, position)
        draw_segments(field, to_pixels(starts), to_pixels(ends), BODY_EDGE_COLOR)
    return image
