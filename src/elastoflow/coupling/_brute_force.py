"""The classification the paper avoids: every grid point tested against every element.

A staircase code without a boundary map finds the grid points inside a deformable body by
testing each point against each of its triangles ([§3], "every fluid point against every
element of the elastic body"); an obstacle, which has an outline and no triangles, by the
winding number of all its edges along the point's row. The cost is grid points times
elements (or edges), where `classify_points` costs crossings plus solid points. Kept for the
cost comparison of the boundary study (docs/validation/boundary_study.md) and as an
independent check of the map's scanline fill; no step uses it.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from elastoflow.coupling._classify import PointClassification
from elastoflow.grid import Grid2D


@njit(cache=True)
def _classify_family(
    points: np.ndarray, velocities: np.ndarray, triangles: np.ndarray,
    triangle_body: np.ndarray, edges: np.ndarray, edge_body: np.ndarray,
    outline_only: np.ndarray, origin_x: float, origin_y: float, half_h: float, i_start: int,
    j_start: int, solid: np.ndarray, body: np.ndarray, velocity_x: np.ndarray,
    velocity_y: np.ndarray,
) -> None:
    """One family of grid points, point ``[k, l]`` at half-grid index ``(i_start + 2k,
    j_start + 2l)``: test it against every triangle, then against every outline edge of the
    objects without triangles (``outline_only[body]``)."""
    m, n = solid.shape
    scaled = np.empty(points.shape[0])
    for p in range(points.shape[0]):
        # The map's own scaling, so that a row's crossings come out bit for bit the same.
        scaled[p] = (points[p, 1] - origin_y) / half_h
    for k in range(m):
        x = origin_x + (i_start + 2 * k) * half_h
        for l in range(n):
            row = j_start + 2 * l
            y = origin_y + row * half_h
            found = -1
            for t in range(triangles.shape[0]):
                a, b, c = triangles[t, 0], triangles[t, 1], triangles[t, 2]
                ax, ay = points[a, 0], points[a, 1]
                bx, by = points[b, 0], points[b, 1]
                cx, cy = points[c, 0], points[c, 1]
                det = (by - cy) * (ax - cx) + (cx - bx) * (ay - cy)
                if det == 0.0:
                    continue
                wa = ((by - cy) * (x - cx) + (cx - bx) * (y - cy)) / det
                wb = ((cy - ay) * (x - cx) + (ax - cx) * (y - cy)) / det
                wc = 1.0 - wa - wb
                if wa >= 0.0 and wb >= 0.0 and wc >= 0.0:
                    found = triangle_body[t]
                    velocity_x[k, l] = wa * velocities[a, 0] + wb * velocities[b, 0] \
                        + wc * velocities[c, 0]
                    velocity_y[k, l] = wa * velocities[a, 1] + wb * velocities[b, 1] \
                        + wc * velocities[c, 1]
                    break
            if found < 0:
                # The map's rule on this row: the winding of the crossings at or before x;
                # the velocity between the nearest crossings on either side.
                winding = 0
                before, after = -np.inf, np.inf
                before_u = before_v = after_u = after_v = 0.0
                owner = -1
                for e in range(edges.shape[0]):
                    if not outline_only[edge_body[e]]:
                        continue
                    a, b = edges[e, 0], edges[e, 1]
                    sa, sb = scaled[a], scaled[b]
                    if sa == sb or not (min(sa, sb) <= row < max(sa, sb)):
                        continue
                    t = min(max((row - sa) / (sb - sa), 0.0), 1.0)
                    crossing = points[a, 0] + t * (points[b, 0] - points[a, 0])
                    u = (1.0 - t) * velocities[a, 0] + t * velocities[b, 0]
                    v = (1.0 - t) * velocities[a, 1] + t * velocities[b, 1]
                    if crossing <= x:
                        # An edge going down has the body on +x: entering.
                        winding += 1 if sb < sa else -1
                        if crossing > before:
                            before, before_u, before_v = crossing, u, v
                            owner = edge_body[e]
                    elif crossing < after:
                        after, after_u, after_v = crossing, u, v
                if winding != 0:
                    found = owner
                    w = 0.0
                    if after < np.inf and after > before:
                        w = (x - before) / (after - before)
                    velocity_x[k, l] = (1.0 - w) * before_u + w * after_u
                    velocity_y[k, l] = (1.0 - w) * before_v + w * after_v
            if found >= 0:
                solid[k, l] = True
                body[k, l] = found


def classify_points_brute_force(
    grid: Grid2D,
    points: np.ndarray,
    velocities: np.ndarray,
    edges: np.ndarray,
    edge_body: np.ndarray | None = None,
    *,
    triangles: np.ndarray | None = None,
    triangle_body: np.ndarray | None = None,
) -> PointClassification:
    """Classify cell centres, u and v points by testing each against every element.

    Objects that own triangles (their index appears in ``triangle_body``) are tested triangle
    by triangle (inside or on a triangle: solid, velocity barycentric); the others (obstacles)
    by the winding number of their edges along the point's row, with the map's half-open
    rule. Away from ties (a point on an outline) the result equals `classify_points` of the
    same boundary: the same flags and body ids, and the same velocities for affine motion.
    Cost: grid points times (triangles + outline edges).

    Args:
        grid: The MAC grid.
        points: Boundary and interior points [m], shape (P, 2).
        velocities: Their velocities [m/s], shape (P, 2).
        edges: Outline edges (a, b), body on the left, shape (E, 2).
        edge_body: Object index of each edge, shape (E,); all 0 when omitted.
        triangles: Elements (indices into ``points``), shape (T, 3); none: outlines only.
        triangle_body: Object index of each element, shape (T,).

    Returns:
        The classification, as `classify_points` gives it.
    """
    points = np.ascontiguousarray(points, dtype=np.float64)
    velocities = np.ascontiguousarray(velocities, dtype=np.float64)
    edges = np.ascontiguousarray(edges, dtype=np.int64).reshape(-1, 2)
    edge_body = (np.zeros(edges.shape[0], dtype=np.int64) if edge_body is None
                 else np.ascontiguousarray(edge_body, dtype=np.int64))
    if triangles is None or triangle_body is None:
        triangles = np.zeros((0, 3), dtype=np.int64)
        triangle_body = np.zeros(0, dtype=np.int64)
    triangles = np.ascontiguousarray(triangles, dtype=np.int64)
    triangle_body = np.ascontiguousarray(triangle_body, dtype=np.int64)
    if triangle_body.shape != (triangles.shape[0],):
        raise ValueError(f"triangle_body shape {triangle_body.shape}: must be "
                         f"({triangles.shape[0]},), one per triangle")
    object_count = int(max(edge_body.max(initial=-1), triangle_body.max(initial=-1))) + 1
    outline_only = np.ones(max(object_count, 1), dtype=np.bool_)
    outline_only[np.unique(triangle_body)] = False
    nx, ny = grid.nx, grid.ny
    result = PointClassification(
        np.zeros((nx, ny), dtype=np.bool_), np.zeros((nx + 1, ny), dtype=np.bool_),
        np.zeros((nx, ny + 1), dtype=np.bool_), np.full((nx, ny), -1, dtype=np.int32),
        np.full((nx + 1, ny), -1, dtype=np.int32), np.full((nx, ny + 1), -1, dtype=np.int32),
        np.zeros((nx + 1, ny)), np.zeros((nx, ny + 1)),
    )
    common = (points, velocities, triangles, triangle_body, edges, edge_body, outline_only,
              grid.origin[0], grid.origin[1], 0.5 * grid.h)
    # The velocity components the classification keeps: u points x, v points y, cells none.
    scratch_cells = (np.zeros((nx, ny)), np.zeros((nx, ny)))
    scratch_x = np.zeros((nx + 1, ny))
    scratch_y = np.zeros((nx, ny + 1))
    _classify_family(*common, 1, 1, result.solid_cells, result.body_cells, *scratch_cells)
    _classify_family(*common, 0, 1, result.solid_faces_x, result.body_faces_x,
                     result.velocity_faces_x, scratch_x)
    _classify_family(*common, 1, 0, result.solid_faces_y, result.body_faces_y, scratch_y,
                     result.velocity_faces_y)
    return result
