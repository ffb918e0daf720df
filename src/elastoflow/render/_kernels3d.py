"""The 3D picture's rasterisers: a perspective camera's triangles, lines and a field's plane,
each behind one depth buffer.

Coordinates are in pixels with x to the right and y down (pixel ``(row, col)`` sampled at its
centre, as in `elastoflow.render._kernels`). The depth buffer holds the inverse distance along
the camera's viewing direction, 1/z [1/m], larger nearer and 0 for nothing: 1/z is linear
in screen space under perspective, so it is interpolated across a triangle or line exactly.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

DEPTH_BIAS = 1e-3
"""Relative lead a line keeps over a surface at the same depth (the plane's rim over the
plane, a box edge over a body touching the wall)."""


@njit(cache=True)
def fill_triangles_perspective(image: np.ndarray, depth: np.ndarray, pixels: np.ndarray,
                               inverse_depth: np.ndarray, triangles: np.ndarray,
                               colors: np.ndarray) -> None:
    """Paint triangle ``t`` in ``colors[t]`` (T, 3) uint8 where it is nearer than what
    ``depth`` (H, W) holds, and keep its 1/z there.

    ``pixels`` (n, 2) and ``inverse_depth`` (n,) are the vertices' projections; a triangle
    with a vertex at or behind the eye (1/z <= 0) is skipped.
    """
    height, width = image.shape[0], image.shape[1]
    for t in range(triangles.shape[0]):
        a, b, c = triangles[t, 0], triangles[t, 1], triangles[t, 2]
        w0_, w1_, w2_ = inverse_depth[a], inverse_depth[b], inverse_depth[c]
        if not (w0_ > 0.0 and w1_ > 0.0 and w2_ > 0.0):
            continue
        x0, y0 = pixels[a, 0], pixels[a, 1]
        x1, y1 = pixels[b, 0], pixels[b, 1]
        x2, y2 = pixels[c, 0], pixels[c, 1]
        area = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
        if area == 0.0 or not math.isfinite(area):
            continue
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
                    inverse = w0 * w0_ + w1 * w1_ + w2 * w2_
                    if inverse > depth[row, col]:
                        depth[row, col] = inverse
                        for k in range(3):
                            image[row, col, k] = colors[t, k]


@njit(cache=True)
def draw_segments_perspective(image: np.ndarray, depth: np.ndarray, starts: np.ndarray,
                              ends: np.ndarray, inverse_starts: np.ndarray,
                              inverse_ends: np.ndarray, color: np.ndarray) -> None:
    """One-pixel segments from ``starts[k]`` to ``ends[k]`` (pixels, (s, 2)) where they are
    not behind what ``depth`` holds (within `DEPTH_BIAS`); the buffer is left as it is, so
    lines never hide one another or a later surface."""
    height, width = image.shape[0], image.shape[1]
    for k in range(starts.shape[0]):
        xa, ya, xb, yb = starts[k, 0], starts[k, 1], ends[k, 0], ends[k, 1]
        wa, wb = inverse_starts[k], inverse_ends[k]
        dx, dy = xb - xa, yb - ya
        if not (math.isfinite(dx) and math.isfinite(dy) and wa > 0.0 and wb > 0.0):
            continue
        # The picture is a few hundred pixels wide: a longer segment lies mostly outside.
        samples = min(int(max(abs(dx), abs(dy))) + 1, 8 * (height + width))
        for s in range(samples + 1):
            f = s / samples
            col = math.floor(xa + f * dx)
            row = math.floor(ya + f * dy)
            if 0 <= row < height and 0 <= col < width:
                if (wa + f * (wb - wa)) * (1.0 + DEPTH_BIAS) >= depth[row, col]:
                    for c in range(3):
                        image[row, col, c] = color[c]


@njit(cache=True, parallel=True)
def draw_plane_field(image: np.ndarray, depth: np.ndarray, eye: np.ndarray,
                     forward: np.ndarray, right: np.ndarray, up: np.ndarray,
                     camera: np.ndarray, axis: int, position: float, plane_low: np.ndarray,
                     h: float, values: np.ndarray, low: float, high: float, lut: np.ndarray,
                     bounds: np.ndarray) -> None:
    """The plane ``x[axis] = position`` [m] coloured by ``values`` (n_a, n_b), the cells of
    the plane's two other axes in order, cell ``(i, j)`` covering ``plane_low + h (i, j) ..
    + h (i + 1, j + 1)``: each pixel's ray from ``eye`` meets the plane, the cell there is
    coloured through ``lut`` (256, 3) between ``low`` and ``high`` (clipped, NaN the first
    entry, as `color_field`) where the plane is nearer than ``depth``, and its 1/z kept.

    ``camera`` is (focal [pixels], centre column, centre row); ``forward``, ``right``, ``up``
    the camera's unit axes (picture rows run down, against ``up``); ``bounds`` (row_min,
    row_max, col_min, col_max) the pixels to try, inclusive. Rows in parallel: each pixel is
    written by one thread alone, so the picture does not depend on the thread count.
    """
    focal, centre_col, centre_row = camera[0], camera[1], camera[2]
    first = 1 if axis == 0 else 0
    second = 1 if axis == 2 else 2
    count_a, count_b = values.shape
    span = high - low if high > low else 1.0
    factor = 255.0 / span
    row_min, row_max, col_min, col_max = bounds[0], bounds[1], bounds[2], bounds[3]
    for row in prange(row_min, row_max + 1):
        v = (row + 0.5 - centre_row) / focal
        for col in range(col_min, col_max + 1):
            u = (col + 0.5 - centre_col) / focal
            # The ray eye + t d with d . forward = 1: t is the distance along forward.
            d_axis = forward[axis] + u * right[axis] - v * up[axis]
            if d_axis == 0.0:
                continue
            t = (position - eye[axis]) / d_axis
            if not t > 0.0:
                continue
            inverse = 1.0 / t
            if inverse <= depth[row, col]:
                continue
            a = eye[first] + t * (forward[first] + u * right[first] - v * up[first])
            b = eye[second] + t * (forward[second] + u * right[second] - v * up[second])
            fa = (a - plane_low[0]) / h
            fb = (b - plane_low[1]) / h
            if not (0.0 <= fa < count_a and 0.0 <= fb < count_b):
                continue
            x = (values[int(fa), int(fb)] - low) * factor
            if not x >= 0.0:
                index = 0
            elif x > 255.0:
                index = 255
            else:
                index = int(x)
            depth[row, col] = inverse
            for c in range(3):
                image[row, col, c] = lut[index, c]
