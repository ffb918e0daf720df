"""Plane geometry for the scene checks: polygons, segments, point sets (NumPy, set-up time only).

Every function works on outlines of at most a few thousand vertices and point sets of at most a
few million points, in chunks so that no temporary exceeds a few tens of MB.
"""

from __future__ import annotations

import numpy as np

_CHUNK = 1 << 20
"""Most pairwise entries computed at once (8 MB per float64 temporary)."""


def _orientation(ax: np.ndarray, ay: np.ndarray, bx: np.ndarray, by: np.ndarray,
                 cx: np.ndarray, cy: np.ndarray) -> np.ndarray:
    """Sign of the turn a -> b -> c: +1 left, -1 right, 0 collinear."""
    return np.sign((bx - ax) * (cy - ay) - (by - ay) * (cx - ax))


def first_crossing(starts_a: np.ndarray, ends_a: np.ndarray, starts_b: np.ndarray,
                   ends_b: np.ndarray, *, one_loop: bool = False) -> tuple[int, int] | None:
    """First pair ``(i, j)`` of segments, ``i`` from set a and ``j`` from set b, that cross
    properly (each separates the other's end points strictly); touching is not crossing.

    Args:
        starts_a, ends_a: Segments of set a [m], shape (k, 2).
        starts_b, ends_b: Segments of set b [m], shape (l, 2).
        one_loop: Both sets are the edges of one closed polygon: an edge is not compared with
            itself or its two neighbours (they share a vertex).
    """
    k, count_b = len(starts_a), len(starts_b)
    if k == 0 or count_b == 0:
        return None
    rows = max(1, _CHUNK // count_b)
    bx0, by0 = starts_b[:, 0][None, :], starts_b[:, 1][None, :]
    bx1, by1 = ends_b[:, 0][None, :], ends_b[:, 1][None, :]
    low_b = np.minimum(starts_b, ends_b)
    high_b = np.maximum(starts_b, ends_b)
    columns = np.arange(count_b)[None, :]
    for begin in range(0, k, rows):
        stop = min(k, begin + rows)
        ax0, ay0 = starts_a[begin:stop, 0][:, None], starts_a[begin:stop, 1][:, None]
        ax1, ay1 = ends_a[begin:stop, 0][:, None], ends_a[begin:stop, 1][:, None]
        low_a = np.minimum(starts_a[begin:stop], ends_a[begin:stop])
        high_a = np.maximum(starts_a[begin:stop], ends_a[begin:stop])
        near = ((low_a[:, None, 0] <= high_b[None, :, 0]) & (low_b[None, :, 0] <= high_a[:, None, 0])
                & (low_a[:, None, 1] <= high_b[None, :, 1])
                & (low_b[None, :, 1] <= high_a[:, None, 1]))
        if one_loop:
            gap = np.abs(np.arange(begin, stop)[:, None] - columns)
            near &= (gap > 1) & (gap != count_b - 1)
        if not near.any():
            continue
        crossing = near & (
            (_orientation(ax0, ay0, ax1, ay1, bx0, by0)
             * _orientation(ax0, ay0, ax1, ay1, bx1, by1) < 0)
            & (_orientation(bx0, by0, bx1, by1, ax0, ay0)
               * _orientation(bx0, by0, bx1, by1, ax1, ay1) < 0)
        )
        hits = np.argwhere(crossing)
        if hits.size:
            return int(hits[0, 0]) + begin, int(hits[0, 1])
    return None


def polygon_edges(polygon: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Edge start and end points of a closed polygon, shapes (k, 2)."""
    return polygon, np.roll(polygon, -1, axis=0)


def self_crossing(polygon: np.ndarray) -> tuple[int, int] | None:
    """First pair of non-adjacent edges ``(i, j)``, ``i < j``, of a polygon that cross, or a
    vertex and an edge it lies on without being its end (touching), or None when the polygon
    is simple."""
    count = len(polygon)
    starts, ends = polygon_edges(polygon)
    hit = first_crossing(starts, ends, starts, ends, one_loop=True)
    if hit is not None:
        return (min(hit), max(hit))
    tolerance = 1e-12 * max(1.0, float(np.abs(polygon).max()))
    rows = max(1, _CHUNK // count)
    edges = np.arange(count)[None, :]
    for begin in range(0, count, rows):
        stop = min(count, begin + rows)
        vertices = np.arange(begin, stop)[:, None]
        on_edge = _point_segment_distances(polygon[begin:stop], starts, ends) <= tolerance
        # A vertex is the end of its own edge and of the one before.
        on_edge &= (edges != vertices) & (edges != (vertices - 1) % count)
        touching = np.argwhere(on_edge)
        if touching.size:
            vertex, edge = int(touching[0, 0]) + begin, int(touching[0, 1])
            return (min(vertex, edge), max(vertex, edge))
    return None


def _point_segment_distances(points: np.ndarray, starts: np.ndarray,
                             ends: np.ndarray) -> np.ndarray:
    """Distance of every point to every segment, shape (p, k) (at most a chunk of pairs)."""
    dx, dy = (ends - starts)[:, 0][None, :], (ends - starts)[:, 1][None, :]
    length2 = np.maximum(dx * dx + dy * dy, 1e-300)
    rx = points[:, 0][:, None] - starts[:, 0][None, :]
    ry = points[:, 1][:, None] - starts[:, 1][None, :]
    t = np.clip((rx * dx + ry * dy) / length2, 0.0, 1.0)
    rx -= t * dx
    ry -= t * dy
    return np.sqrt(rx * rx + ry * ry)


def distance_to_segments(points: np.ndarray, starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """Distance [m] of each point to the nearest of the segments, shape (p,)."""
    result = np.empty(len(points))
    rows = max(1, _CHUNK // max(1, len(starts)))
    for begin in range(0, len(points), rows):
        stop = min(len(points), begin + rows)
        result[begin:stop] = _point_segment_distances(points[begin:stop], starts, ends).min(1)
    return result


def points_in_polygons(points: np.ndarray, starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """Whether each point lies inside the region the closed loops of segments bound (even-odd
    rule over all the loops together), shape (p,) bool. Points on an edge may go either way."""
    inside = np.zeros(len(points), dtype=bool)
    rows = max(1, _CHUNK // max(1, len(starts)))
    x0, y0 = starts[:, 0][None, :], starts[:, 1][None, :]
    x1, y1 = ends[:, 0][None, :], ends[:, 1][None, :]
    for begin in range(0, len(points), rows):
        stop = min(len(points), begin + rows)
        px = points[begin:stop, 0][:, None]
        py = points[begin:stop, 1][:, None]
        spans = (y0 > py) != (y1 > py)
        with np.errstate(divide="ignore", invalid="ignore"):
            x_cross = x0 + (py - y0) * (x1 - x0) / (y1 - y0)
        crossings = spans & (px < x_cross)
        inside[begin:stop] = (np.count_nonzero(crossings, axis=1) % 2) == 1
    return inside


def cell_centres_inside(starts: np.ndarray, ends: np.ndarray, nx: int, ny: int,
                        h: float, origin: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
    """Mask (nx, ny) of the cell centres ``origin + ((i + 1/2) h, (j + 1/2) h)`` inside the
    closed loops of segments (even-odd rule), found row by row (scanlines)."""
    shift = np.asarray(origin, dtype=np.float64)
    starts, ends = starts - shift, ends - shift
    mask = np.zeros((nx, ny), dtype=bool)
    low = float(min(starts[:, 1].min(), ends[:, 1].min()))
    high = float(max(starts[:, 1].max(), ends[:, 1].max()))
    first = max(0, int(np.floor(low / h - 0.5)))
    last = min(ny - 1, int(np.ceil(high / h - 0.5)))
    centres_x = (np.arange(nx) + 0.5) * h
    for j in range(first, last + 1):
        y = (j + 0.5) * h
        spans = (starts[:, 1] > y) != (ends[:, 1] > y)
        if not spans.any():
            continue
        s, e = starts[spans], ends[spans]
        crossings = np.sort(s[:, 0] + (y - s[:, 1]) * (e[:, 0] - s[:, 0]) / (e[:, 1] - s[:, 1]))
        # Cells right of an odd number of crossings are inside.
        count = np.searchsorted(crossings, centres_x, side="right")
        mask[:, j] = (count % 2) == 1
    return mask


def ray_thickness(starts: np.ndarray, ends: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Width of a region across each of its boundary edges.

    From the midpoint of each edge (the region on its left) a ray goes along the inward normal
    to the first other boundary edge it meets; its length is the region's width there.

    Returns:
        The midpoints (k, 2) [m] and the widths (k,) [m] (inf where the ray meets nothing).
    """
    middle = 0.5 * (starts + ends)
    direction = ends - starts
    length = np.maximum(np.linalg.norm(direction, axis=1), 1e-300)
    normal = np.stack([-direction[:, 1], direction[:, 0]], axis=1) / length[:, None]
    widths = np.full(len(starts), np.inf)
    rows = max(1, _CHUNK // max(1, len(starts)))
    e = ends - starts
    for begin in range(0, len(starts), rows):
        stop = min(len(starts), begin + rows)
        origin = middle[begin:stop][:, None, :]
        ray = normal[begin:stop][:, None, :]
        # Solve origin + t ray = start + u e for t > 0, u in [0, 1].
        rel = starts[None, :, :] - origin
        denominator = ray[..., 0] * e[None, :, 1] - ray[..., 1] * e[None, :, 0]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (rel[..., 0] * e[None, :, 1] - rel[..., 1] * e[None, :, 0]) / denominator
            u = (rel[..., 0] * ray[..., 1] - rel[..., 1] * ray[..., 0]) / denominator
        valid = (np.abs(denominator) > 0) & (t > 1e-12 * length[begin:stop, None]) & (
            u >= 0.0) & (u <= 1.0)
        valid[np.arange(stop - begin), np.arange(begin, stop)] = False
        widths[begin:stop] = np.where(valid, t, np.inf).min(axis=1)
    return middle, widths
