"""Exact area of closed polygons inside every square of a grid.

The face weights a boundary map gives today are fractions of a face's *segment* (2D) that lie
in fluid; they jump when a body edge parallel to the face crosses it (docs/method_notes.md
item 9). Fractions of *areas* — of a face's dual cell in 2D, of a face's square in 3D (the
body's cross-section in the face's plane) — change continuously with the body's position.
This module computes them exactly.

For polygons oriented counter-clockwise (inside on the left; holes clockwise), Green's
theorem in the form

    area(P n R) = - sum over edges e of  int_e (clamp(y, y0, y1) - y0) dx

holds for every square ``R = [x0, x1] x [y0, y1]`` once each edge is clipped to the square's
x-range: an edge above the square counts its whole height ``y1 - y0``, one below counts
nothing, and the contributions of the parts of the outline that do not bound ``P n R`` cancel
in pairs. Per column of squares each edge therefore adds an exact integral to the squares its
y-range meets and a constant ``-h dx`` to every square below it; the constants are gathered by
one running sum per column. Cost: the squares the edges pass through plus the squares below
them up to the polygon's lowest point, i.e. the polygon's area in cells, not the grid's.
"""

from __future__ import annotations

import numpy as np
from numba import njit



@njit(cache=True)
def polygon_areas(points, edges, origin_x, origin_y, h, nx, ny, out):
    """``out[i, j]`` += area [m^2] of the polygons inside square ``[origin_x + i h, ... +
    h] x [origin_y + j h, ... + h]``.

    Args:
        points: Vertices (P, 2) [m].
        edges: Directed edges (E, 2) into ``points``; closed loops, inside on the left.
        origin_x, origin_y: Corner of square (0, 0) [m].
        h: Square side [m].
        nx, ny: Number of squares along x and y.
        out: Accumulator, (nx, ny); parts of polygons outside the squares are ignored.
    """
    segments = np.empty((edges.shape[0], 4))
    for e in range(edges.shape[0]):
        segments[e, 0] = points[edges[e, 0], 0]
        segments[e, 1] = points[edges[e, 0], 1]
        segments[e, 2] = points[edges[e, 1], 0]
        segments[e, 3] = points[edges[e, 1], 1]
    segment_areas(segments, origin_x, origin_y, h, nx, ny, out)


@njit(cache=True)
def segment_areas(segments, origin_x, origin_y, h, nx, ny, out):
    """`polygon_areas` for the edges given as segments ``(ax, ay, bx, by)``, (E, 4)."""
    moments = np.zeros((nx, ny, 3))
    segment_moments(segments, origin_x, origin_y, h, nx, ny, moments)
    out += moments[:, :, 0]


@njit(cache=True, inline="always")
def _clamped_moments(xa: float, ya: float, xb: float, yb: float, low: float, high: float,
                     xc: float, yc: float) -> tuple[float, float, float]:
    """The three Green integrals of `segment_moments` along one clipped edge: ``int P dx``
    for ``P = clamp(y) - low``, ``(x - xc)(clamp(y) - low)`` and ``((clamp(y) - yc)^2 -
    (low - yc)^2) / 2``; clamp(y) is linear on each piece between the crossings of the two
    levels, so Simpson's rule is exact on it."""
    area = 0.0
    first = 0.0
    second = 0.0
    if xa == xb:
        return area, first, second
    ts = np.empty(4)
    ts[0] = 0.0
    count = 1
    dy = yb - ya
    if dy != 0.0:
        for level in (low, high):
            t = (level - ya) / dy
            if 0.0 < t < 1.0:
                ts[count] = t
                count += 1
    ts[count] = 1.0
    count += 1
    for i in range(1, count):
        k = i
        while k > 0 and ts[k - 1] > ts[k]:
            ts[k - 1], ts[k] = ts[k], ts[k - 1]
            k -= 1
    dx = xb - xa
    base = 0.5 * (low - yc) ** 2
    for i in range(count - 1):
        t0, t1 = ts[i], ts[i + 1]
        if t1 <= t0:
            continue
        width = (t1 - t0) * dx
        for weight, t in ((1.0, t0), (4.0, 0.5 * (t0 + t1)), (1.0, t1)):
            x = xa + t * dx
            y = min(max(ya + t * dy, low), high)
            area += weight * width * (y - low) / 6.0
            first += weight * width * (x - xc) * (y - low) / 6.0
            second += weight * width * (0.5 * (y - yc) ** 2 - base) / 6.0
    return area, first, second


@njit(cache=True)
def segment_moments(segments, origin_x, origin_y, h, nx, ny, out):
    """``out[i, j]`` += (area [m^2], int (x - xc) dA, int (y - yc) dA [m^3]) of the polygons
    inside square (i, j), ``(xc, yc)`` its centre; edges as `segment_areas`.

    The centroid of the covered part is ``(xc + out[..., 1] / A, yc + out[..., 2] / A)``.
    """
    below_area = np.zeros((nx, ny + 1))
    below_first = np.zeros((nx, ny + 1))
    for e in range(segments.shape[0]):
        ax, ay, bx, by = segments[e, 0], segments[e, 1], segments[e, 2], segments[e, 3]
        if ax == bx:
            continue
        left, right = min(ax, bx), max(ax, bx)
        first = max(int(np.floor((left - origin_x) / h)), 0)
        last = min(int(np.floor((right - origin_x) / h)), nx - 1)
        for i in range(first, last + 1):
            x0 = origin_x + i * h
            xc = x0 + 0.5 * h
            ta = (max(x0, left) - ax) / (bx - ax)
            tb = (min(x0 + h, right) - ax) / (bx - ax)
            if ta > tb:
                ta, tb = tb, ta
            if tb <= ta:
                continue
            pxa, pya = ax + ta * (bx - ax), ay + ta * (by - ay)
            pxb, pyb = ax + tb * (bx - ax), ay + tb * (by - ay)
            j_low = int(np.floor((min(pya, pyb) - origin_y) / h))
            j_high = int(np.floor((max(pya, pyb) - origin_y) / h))
            for j in range(max(j_low, 0), min(j_high, ny - 1) + 1):
                y0 = origin_y + j * h
                area, moment_x, moment_y = _clamped_moments(pxa, pya, pxb, pyb, y0, y0 + h, xc,
                                                            y0 + 0.5 * h)
                out[i, j, 0] -= area
                out[i, j, 1] -= moment_x
                out[i, j, 2] -= moment_y
            top_below = min(j_low - 1, ny - 1)
            if top_below >= 0:
                # Above a square the edge counts its full height: area h dx, x-moment
                # h (x - xc) dx, y-moment 0 (symmetric about yc).
                below_area[i, top_below] -= h * (pxb - pxa)
                below_first[i, top_below] -= h * 0.5 * ((pxb - xc) ** 2 - (pxa - xc) ** 2)
    for i in range(nx):
        running_area = 0.0
        running_first = 0.0
        for j in range(ny - 1, -1, -1):
            running_area += below_area[i, j]
            running_first += below_first[i, j]
            out[i, j, 0] += running_area
            out[i, j, 1] += running_first
