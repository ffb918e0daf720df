"""The overview's rasteriser: triangles filled with one colour each behind a depth buffer.

Coordinates are in pixels with x to the right and y down (pixel ``(row, col)`` sampled at its
centre, as in `elastoflow.render._kernels`); depth grows towards the eye.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def fill_triangles_depth(image: np.ndarray, depth: np.ndarray, points: np.ndarray,
                         point_depth: np.ndarray, triangles: np.ndarray,
                         colors: np.ndarray) -> None:
    """Paint triangle ``t`` in ``colors[t]`` where it is nearer the eye than what ``depth``
    (H, W) holds, and keep its depth there (linear across the triangle: an orthographic
    view)."""
    height, width = image.shape[0], image.shape[1]
    for t in range(triangles.shape[0]):
        a, b, c = triangles[t, 0], triangles[t, 1], triangles[t, 2]
        x0, y0 = points[a, 0], points[a, 1]
        x1, y1 = points[b, 0], points[b, 1]
        x2, y2 = points[c, 0], points[c, 1]
        area = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
        if area == 0.0 or not math.isfinite(area):
            continue
        z0, z1, z2 = point_depth[a], point_depth[b], point_depth[c]
        col_min = max(math.floor(min(x0, x1, x2)), 0)
        col_max = min(math.ceil(max(x0, x1, x2)), width - 1)
        row_min = max(math.floor(min(y0, y1, y2)), 0)
        row_max = min(math.ceil(max(y0, y1, y2)), height - 1)
        for row in range(row_min, row_max + 1):
            sy = row + 0.5
            for col in range(col_min, col_max + 1):
                sx = col + 0.5
                w0 = ((x1 - sx) * (y2 - sy) - (x2 - sx) * (y1 - sy)) / area
                w1 = ((x2 - sx) * (y0 - sy) - (x0 - sx) * (y2 - sy)) / area
                w2 = 1.0 - w0 - w1
                if w0 >= 0.0 and w1 >= 0.0 and w2 >= 0.0:
                    z = w0 * z0 + w1 * z1 + w2 * z2
                    if z > depth[row, col]:
                        depth[row, col] = z
                        for k in range(3):
                            image[row, col, k] = colors[t, k]


@njit(cache=True)
def blend_picture(image: np.ndarray, depth: np.ndarray, pixels: np.ndarray, rows: np.ndarray,
                  cols: np.ndarray, pixel_depth: np.ndarray, picture: np.ndarray,
                  opacity: float) -> None:
    """Lay ``picture`` over the flat panel pixels ``pixels`` (row-major indices into
    ``image``), pixel ``k`` showing ``picture[rows[k], cols[k]]`` with ``opacity``, where it
    is not behind what ``depth`` holds (the surfaces in front of the plane stay)."""
    width = image.shape[1]
    for k in range(pixels.shape[0]):
        row, col = pixels[k] // width, pixels[k] % width
        if pixel_depth[k] < depth[row, col]:
            continue
        for c in range(3):
            image[row, col, c] = np.uint8(opacity * picture[rows[k], cols[k], c]
                                          + (1.0 - opacity) * image[row, col, c])
