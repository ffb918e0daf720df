"""Random polygons and brute-force references for the coupling tests (not a test module)."""

from __future__ import annotations

import numpy as np
from hypothesis import strategies as st

# Powers of two keep half-grid coordinates exact in binary, so snapped vertices lie exactly on
# the lines.
H = 1.0 / 32.0
ORIGINS = [(0.0, 0.0), (-0.25, 0.5), (0.125, -0.375)]


def segments_intersect(polygon: np.ndarray) -> bool:
    """True if two non-adjacent edges of the closed polygon touch or cross."""
    k = polygon.shape[0]
    a = polygon
    b = np.roll(polygon, -1, axis=0)

    def orientation(p, q, r):
        return np.sign((q[..., 0] - p[..., 0]) * (r[..., 1] - p[..., 1])
                       - (q[..., 1] - p[..., 1]) * (r[..., 0] - p[..., 0]))

    for e in range(k):
        for f in range(e + 2, k):
            if e == 0 and f == k - 1:
                continue
            o1 = orientation(a[e], b[e], a[f])
            o2 = orientation(a[e], b[e], b[f])
            o3 = orientation(a[f], b[f], a[e])
            o4 = orientation(a[f], b[f], b[e])
            if o1 * o2 <= 0 and o3 * o4 <= 0:
                return True
    return False


@st.composite
def star_polygon(draw, center_x, center_y, radius_min, radius_max, grid_origin, snap=True):
    """A simple star-shaped polygon, counter-clockwise, some vertex coordinates snapped onto
    half-grid lines of a grid with spacing ``H`` and origin ``grid_origin``."""
    n = draw(st.integers(3, 20))
    cx = draw(st.floats(*center_x))
    cy = draw(st.floats(*center_y))
    jitter = np.array(draw(st.lists(st.floats(0.0, 0.8), min_size=n, max_size=n)))
    radii = np.array(draw(st.lists(st.floats(radius_min, radius_max), min_size=n, max_size=n)))
    angle = 2.0 * np.pi * (np.arange(n) + jitter) / n
    polygon = np.stack([cx + radii * np.cos(angle), cy + radii * np.sin(angle)], axis=1)
    if snap:
        mode = np.array(draw(st.lists(st.integers(0, 3), min_size=n, max_size=n)))
        half = 0.5 * H
        for axis, bit in ((0, 1), (1, 2)):
            chosen = (mode & bit) > 0
            o = grid_origin[axis]
            polygon[chosen, axis] = o + np.round((polygon[chosen, axis] - o) / half) * half
    return polygon


def polygon_edges(count: int, start: int = 0) -> np.ndarray:
    first = np.arange(count, dtype=np.int64)
    return np.stack([first, (first + 1) % count], axis=1) + start


def inside_even_odd(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Brute-force ray cast towards +x, crossing rule y_lo <= y < y_hi; shape (N,) bool."""
    px = points[:, 0][:, None]
    py = points[:, 1][:, None]
    a = polygon[None, :, :]
    b = np.roll(polygon, -1, axis=0)[None, :, :]
    straddle = (a[..., 1] > py) != (b[..., 1] > py)
    with np.errstate(divide="ignore", invalid="ignore"):
        x_cross = a[..., 0] + (py - a[..., 1]) * (b[..., 0] - a[..., 0]) / (b[..., 1] - a[..., 1])
    return (np.sum(straddle & (px < x_cross), axis=1) % 2) == 1


def distance_to_polygon(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Distance from each point (N, 2) to the closed polygon's boundary, shape (N,)."""
    a = polygon[None, :, :]
    b = np.roll(polygon, -1, axis=0)[None, :, :]
    p = points[:, None, :]
    ab = b - a
    t = np.clip(np.sum((p - a) * ab, axis=2) / np.maximum(np.sum(ab * ab, axis=2), 1e-300),
                0.0, 1.0)
    nearest = a + t[..., None] * ab
    return np.min(np.linalg.norm(p - nearest, axis=2), axis=1)
