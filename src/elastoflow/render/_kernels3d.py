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

from elastoflow import _numba  # noqa: F401  (starts Numba's threads: see _numba)

DEPTH_BIAS = 1e-3
"""Relative lead a line keeps over a surface at the same depth (the plane's rim over the
plane, a box edge over a body touching the wall)."""


@njit(cache=True)
def fill_triangles_perspective(image: np.ndarray, depth: np.ndarray, pixels: np.ndarray,
                               inverse_depth: np.ndarray, triangles: np.ndarray,
                               colors: np.ndarray) -> None:
    """Paint triangle ``t`` in ``colors[t]`` (T, 3) uint8 where it is nearer than what
    ``depth`` (H, W) holds (or as near: a surface on the slice shows), and keep its 1/z
    there.

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
        # Barycentric weights are affine in the pixel: w = base + dx * col + dy * row.
        scale = 1.0 / area
        dx0, dy0 = (y1 - y2) * scale, (x2 - x1) * scale
        dx1, dy1 = (y2 - y0) * scale, (x0 - x2) * scale
        base0 = (x1 * y2 - x2 * y1) * scale + 0.5 * (dx0 + dy0)
        base1 = (x2 * y0 - x0 * y2) * scale + 0.5 * (dx1 + dy1)
        for row in range(row_min, row_max + 1):
            for col in range(col_min, col_max + 1):
                w0 = base0 + dx0 * col + dy0 * row
                w1 = base1 + dx1 * col + dy1 * row
                w2 = 1.0 - w0 - w1
                if w0 >= 0.0 and w1 >= 0.0 and w2 >= 0.0:
                    inverse = w0 * w0_ + w1 * w1_ + w2 * w2_
                    if inverse >= depth[row, col]:
                        depth[row, col] = inverse
                        for k in range(3):
                            image[row, col, k] = colors[t, k]


@njit(cache=True)
def project_points(points: np.ndarray, eye: np.ndarray, forward: np.ndarray,
                   right: np.ndarray, up: np.ndarray, focal: float, centre_col: float,
                   centre_row: float, pixels: np.ndarray, inverse_depth: np.ndarray) -> None:
    """Points [m] (n, 3) seen by a pinhole camera at ``eye`` to ``pixels`` (n, 2) (x right,
    y down) and ``inverse_depth`` (n,): 1/z along ``forward`` [1/m], -1 at or behind the
    eye (the pixel is then meaningless)."""
    for p in range(points.shape[0]):
        rx = points[p, 0] - eye[0]
        ry = points[p, 1] - eye[1]
        rz = points[p, 2] - eye[2]
        z = rx * forward[0] + ry * forward[1] + rz * forward[2]
        inverse = 1.0 / z if z > 0.0 else -1.0
        pixels[p, 0] = centre_col + focal * (rx * right[0] + ry * right[1]
                                             + rz * right[2]) * inverse
        pixels[p, 1] = centre_row - focal * (rx * up[0] + ry * up[1] + rz * up[2]) * inverse
        inverse_depth[p] = inverse


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
def plane_cells(eye: np.ndarray, forward: np.ndarray, right: np.ndarray, up: np.ndarray,
                camera: np.ndarray, axis: int, position: float, plane_low: np.ndarray,
                h: float, counts: np.ndarray, cells: np.ndarray,
                inverse_depth: np.ndarray) -> None:
    """Which cell of the plane ``x[axis] = position`` [m] each pixel sees: ``cells`` (H, W)
    the flat index ``i * counts[1] + j`` of cell ``(i, j)`` of the plane's two other axes in
    order (covering ``plane_low + h (i, j) .. + h (i + 1, j + 1)``), -1 where the pixel's ray
    misses the plane, and ``inverse_depth`` (H, W) the plane's 1/z there [1/m].

    ``camera`` is (focal [pixels], centre column, centre row); ``forward``, ``right``, ``up``
    the camera's unit axes (picture rows run down, against ``up``). Computed once per camera
    and plane; rows in parallel, each pixel written by one thread.
    """
    focal, centre_col, centre_row = camera[0], camera[1], camera[2]
    first = 1 if axis == 0 else 0
    second = 1 if axis == 2 else 2
    count_a, count_b = counts[0], counts[1]
    height, width = cells.shape
    # The ray eye + t d, d = forward + u right - v up (so d . forward = 1 and t is the
    # distance along forward), meets the plane at t = gap / d[axis].
    gap = position - eye[axis]
    for row in prange(height):
        v = (row + 0.5 - centre_row) / focal
        for col in range(width):
            cells[row, col] = -1
            inverse_depth[row, col] = 0.0
            if gap == 0.0:
                continue
            u = (col + 0.5 - centre_col) / focal
            d_axis = forward[axis] + u * right[axis] - v * up[axis]
            inverse = d_axis / gap  # 1/t
            if not inverse > 0.0:
                continue
            t = 1.0 / inverse
            fa = (eye[first] + t * (forward[first] + u * right[first] - v * up[first])
                  - plane_low[0]) / h
            fb = (eye[second] + t * (forward[second] + u * right[second] - v * up[second])
                  - plane_low[1]) / h
            if 0.0 <= fa < count_a and 0.0 <= fb < count_b:
                cells[row, col] = int(fa) * count_b + int(fb)
                inverse_depth[row, col] = inverse


@njit(cache=True)
def draw_plane_cells(image: np.ndarray, depth: np.ndarray, cells: np.ndarray,
                     inverse_depth: np.ndarray, values: np.ndarray, low: float, high: float,
                     lut: np.ndarray, background: np.ndarray) -> None:
    """Start a picture (H, W, 3) and its ``depth`` (H, W): each pixel that sees a plane cell
    (`plane_cells`) takes the cell's value in ``values`` (flat, the cells' order) through
    ``lut`` (256, 3) between ``low`` and ``high`` (clipped, NaN the first entry, as
    `color_field`) and the plane's 1/z; every other pixel ``background`` (3,) and 0 (nothing).
    The surfaces are drawn after it, where nearer.

    Serial: a threaded loop waits for a thread that ffmpeg or another job has descheduled
    (measured 4.3 ms threaded against 2.8 ms serial for 640x480 at load 8 on 2 cores).
    """
    span = high - low if high > low else 1.0
    factor = 255.0 / span
    height, width = cells.shape
    for row in range(height):
        for col in range(width):
            cell = cells[row, col]
            if cell < 0:
                depth[row, col] = 0.0
                for c in range(3):
                    image[row, col, c] = background[c]
                continue
            x = (values[cell] - low) * factor
            if not x >= 0.0:
                index = 0
            elif x > 255.0:
                index = 255
            else:
                index = int(x)
            depth[row, col] = inverse_depth[row, col]
            for c in range(3):
                image[row, col, c] = lut[index, c]


@njit(cache=True)
def lit_triangle_colors(points: np.ndarray, triangles: np.ndarray, light: np.ndarray,
                        color: np.ndarray, ambient: float, out: np.ndarray) -> None:
    """``out[t]`` (T, 3) uint8: ``color`` (3,) times ``ambient + (1 - ambient) |cos|`` of the
    angle between triangle ``t``'s normal and the unit vector ``light`` (both sides lit
    alike); a degenerate triangle gets the ambient share."""
    for t in range(triangles.shape[0]):
        a, b, c = triangles[t, 0], triangles[t, 1], triangles[t, 2]
        e1x = points[b, 0] - points[a, 0]
        e1y = points[b, 1] - points[a, 1]
        e1z = points[b, 2] - points[a, 2]
        e2x = points[c, 0] - points[a, 0]
        e2y = points[c, 1] - points[a, 1]
        e2z = points[c, 2] - points[a, 2]
        nx = e1y * e2z - e1z * e2y
        ny = e1z * e2x - e1x * e2z
        nz = e1x * e2y - e1y * e2x
        length = math.sqrt(nx * nx + ny * ny + nz * nz)
        facing = 0.0
        if length > 0.0:
            facing = abs(nx * light[0] + ny * light[1] + nz * light[2]) / length
        intensity = ambient + (1.0 - ambient) * facing
        for k in range(3):
            out[t, k] = np.uint8(min(round(intensity * color[k]), 255.0))
