"""A 3D state seen through a plane: the field on the cells the plane cuts, with the bodies'
cross-sections drawn on top, through the 2D frame's colouring, colour bar and time stamp.

What a user can look at without ParaView (issue 16, item 5): a slice per frame makes a video
of a 3D run with the same look as the 2D ones.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from elastoflow.grid import Grid2D, Grid3D
from elastoflow.render._frame import BODY_FILL_COLOR, default_scale, render_frame
from elastoflow.render._kernels import fill_triangles

AXES = {"x": 0, "y": 1, "z": 2}
VIEWS_3D = ("speed", "vorticity", "pressure", "dye")


def _centre_velocity(state: Any) -> np.ndarray:
    u, v, w = state.velocity_x, state.velocity_y, state.velocity_z
    return np.stack((0.5 * (u[1:] + u[:-1]), 0.5 * (v[:, 1:] + v[:, :-1]),
                     0.5 * (w[:, :, 1:] + w[:, :, :-1])), axis=-1)


def slice_values(grid: Grid3D, state: Any, axis: int, index: int, view: str) -> np.ndarray:
    """The view's values on cell layer ``index`` across ``axis``, as a 2D field indexed by
    the two other axes in order ((ny, nz) for x, (nx, nz) for y, (nx, ny) for z). Vorticity
    is its component along ``axis`` (the one in the plane's normal: the swirl seen in it)."""
    if view not in VIEWS_3D:
        raise ValueError(f"view = {view!r}: must be one of {', '.join(VIEWS_3D)}")
    if not 0 <= index < grid.shape_cells[axis]:
        raise ValueError(f"slice index {index}: must be in 0..{grid.shape_cells[axis] - 1}")
    take = [slice(None)] * 3
    if view == "pressure":
        return np.take(state.pressure, index, axis=axis)
    if view == "dye":
        return np.take(state.dye, index, axis=axis)
    velocity = _centre_velocity(state)
    if view == "speed":
        return np.take(np.sqrt((velocity**2).sum(axis=-1)), index, axis=axis)
    # Vorticity along ``axis``: d(b)/d(a) - d(a)/d(b) for the in-plane axes (a, b).
    a, b = [k for k in range(3) if k != axis]
    take[axis] = slice(max(index - 1, 0), index + 2)
    local = velocity[tuple(take)]
    position = index - max(index - 1, 0)
    h = grid.h
    db_da = np.gradient(local[..., b], h, axis=a) if local.shape[a] > 1 else 0.0 * local[..., b]
    da_db = np.gradient(local[..., a], h, axis=b) if local.shape[b] > 1 else 0.0 * local[..., a]
    return np.take(db_da - da_db, position, axis=axis)


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
    values = slice_values(grid, state, k, index, view)
    others = [a for a in range(3) if a != k]
    plane = Grid2D(grid.shape_cells[others[0]], grid.shape_cells[others[1]], grid.h,
                   origin=(grid.origin[others[0]], grid.origin[others[1]]))
    scale = default_scale(plane) if scale is None else int(scale)
    image = render_frame(plane, None, (), (), view, time, value_range=value_range, scale=scale,
                         colorbar=colorbar, values=values, out=out)
    height, width = plane.ny * scale, plane.nx * scale
    field = image[:height, :width]
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
    return image
