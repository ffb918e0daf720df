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


@njit(cache=True, inline="always")
def _clamped_integral(xa: float, ya: float, xb: float, yb: float, low: float,
                      high: float) -> float:
    """``int_xa^xb (clamp(y(x), low, high) - low) dx`` for y linear from (xa, ya) to
    (xb, yb) (signed: negative when xb < xa)."""
    if xa == xb:
        return 0.0
    # Split the segment where y crosses low and high; on each piece the integrand is
    # linear (between) or constant (outside).
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
    # At most two interior split points: sort the short list.
    for i in range(1, count):
        k = i
        while k > 0 and ts[k - 1] > ts[k]:
            ts[k - 1], ts[k] = ts[k], ts[k - 1]
            k -= 1
    total = 0.0
    for i in range(count - 1):
        t0, t1 = ts[i], ts[i + 1]
        if t1 <= t0:
            continue
        y0 = min(max(ya + t0 * dy, low), high) - low
        y1 = min(max(ya + t1 * dy, low), high) - low
        total += 0.5 * (y0 + y1) * (t1 - t0) * (xb - xa)
    return total


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
    # below[i, j]: the constant each edge adds to squares (i, j') with j' <= j (those wholly
    # below it), summed from the top by the running sum at the end.
    below = np.zeros((nx, ny + 1))
    for e in range(segments.shape[0]):
        ax, ay, bx, by = segments[e, 0], segments[e, 1], segments[e, 2], segments[e, 3]
        if ax == bx:
            continue  # a vertical edge sweeps no x: it adds nothing
        left, right = min(ax, bx), max(ax, bx)
        first = max(int(np.floor((left - origin_x) / h)), 0)
        last = min(int(np.floor((right - origin_x) / h)), nx - 1)
        for i in range(first, last + 1):
            x0 = origin_x + i * h
            x1 = x0 + h
            # The part of the edge over this column, in the edge's own direction.
            ta = (max(x0, left) - ax) / (bx - ax)
            tb = (min(x1, right) - ax) / (bx - ax)
            if ta > tb:
                ta, tb = tb, ta
            if tb <= ta:
                continue
            # From the end nearer a to the one nearer b: the edge's direction, which gives the
            # integrals their sign.
            pxa, pya = ax + ta * (bx - ax), ay + ta * (by - ay)
            pxb, pyb = ax + tb * (bx - ax), ay + tb * (by - ay)
            lowest = min(pya, pyb)
            highest = max(pya, pyb)
            j_low = int(np.floor((lowest - origin_y) / h))
            j_high = int(np.floor((highest - origin_y) / h))
            # Squares the edge's y-range meets: the exact clamped integral.
            for j in range(max(j_low, 0), min(j_high, ny - 1) + 1):
                y0 = origin_y + j * h
                out[i, j] -= _clamped_integral(pxa, pya, pxb, pyb, y0, y0 + h)
            # Squares wholly below it: the full height over its x-extent.
            top_below = min(j_low - 1, ny - 1)
            if top_below >= 0:
                below[i, top_below] -= h * (pxb - pxa)
    for i in range(nx):
        running = 0.0
        for j in range(ny - 1, -1, -1):
            running += below[i, j]
            out[i, j] += running
