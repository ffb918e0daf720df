"""Small rasterisers for frames: triangles, polygons and line segments into an RGB array.

Coordinates are in pixels with x to the right and y down; pixel ``(row, col)`` covers
``[col, col+1) x [row, row+1)`` and is sampled at its centre.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from elastoflow import _numba  # noqa: F401  (starts Numba's threads: see _numba)


@njit(cache=True)
def fill_triangles(image: np.ndarray, points: np.ndarray, triangles: np.ndarray,
                   color: np.ndarray) -> None:
    """Paint every pixel whose centre lies in a triangle (edges inclusive)."""
    height, width = image.shape[0], image.shape[1]
    for t in range(triangles.shape[0]):
        x0, y0 = points[triangles[t, 0], 0], points[triangles[t, 0], 1]
        x1, y1 = points[triangles[t, 1], 0], points[triangles[t, 1], 1]
        x2, y2 = points[triangles[t, 2], 0], points[triangles[t, 2], 1]
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
                    for c in range(3):
                        image[row, col, c] = color[c]


@njit(cache=True)
def fill_polygon(image: np.ndarray, polygon: np.ndarray, color: np.ndarray) -> None:
    """Paint the pixels whose centre is inside a closed polygon (even-odd scanlines)."""
    height, width = image.shape[0], image.shape[1]
    k = polygon.shape[0]
    row_min = max(math.floor(polygon[:, 1].min()), 0)
    row_max = min(math.ceil(polygon[:, 1].max()), height - 1)
    crossings = np.empty(k)
    for row in range(row_min, row_max + 1):
        sy = row + 0.5
        count = 0
        for e in range(k):
            xa, ya = polygon[e, 0], polygon[e, 1]
            xb, yb = polygon[(e + 1) % k, 0], polygon[(e + 1) % k, 1]
            # Half-open rule so that a vertex on the scanline is counted once.
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


@njit(cache=True, inline="always")
def _clip(p: float, q: float, t0: float, t1: float) -> tuple[float, float, bool]:
    """One side of Liang-Barsky clipping: the part of [t0, t1] where q - p t >= 0."""
    if p == 0.0:
        return t0, t1, q >= 0.0
    r = q / p
    if p < 0.0:
        return max(t0, r), t1, r <= t1
    return t0, min(t1, r), r >= t0


@njit(cache=True, inline="always")
def _draw_segment(image: np.ndarray, xa: float, ya: float, xb: float, yb: float,
                  color: np.ndarray) -> None:
    """One-pixel segment from (xa, ya) to (xb, yb) in pixel coordinates (DDA), clipped to a
    pixel around the image first (a segment far outside, from a damaged file, would otherwise
    take as many samples as it is long)."""
    height, width = image.shape[0], image.shape[1]
    dx, dy = xb - xa, yb - ya
    if not (math.isfinite(dx) and math.isfinite(dy)):
        return
    if not (0.0 <= xa <= width and 0.0 <= xb <= width and 0.0 <= ya <= height
            and 0.0 <= yb <= height):
        t0, t1, left = _clip(-dx, xa + 1.0, 0.0, 1.0)
        t0, t1, right = _clip(dx, width + 1.0 - xa, t0, t1)
        t0, t1, below = _clip(-dy, ya + 1.0, t0, t1)
        t0, t1, above = _clip(dy, height + 1.0 - ya, t0, t1)
        if not (left and right and below and above) or t1 < t0:
            return
        xa, ya, xb, yb = xa + t0 * dx, ya + t0 * dy, xa + t1 * dx, ya + t1 * dy
        dx, dy = xb - xa, yb - ya
    samples = int(max(abs(dx), abs(dy))) + 1
    for s in range(samples + 1):
        f = s / samples
        col = math.floor(xa + f * dx)
        row = math.floor(ya + f * dy)
        if 0 <= row < height and 0 <= col < width:
            for c in range(3):
                image[row, col, c] = color[c]


@njit(cache=True)
def draw_segments(image: np.ndarray, starts: np.ndarray, ends: np.ndarray,
                  color: np.ndarray) -> None:
    """Draw one-pixel line segments from ``starts[k]`` to ``ends[k]`` (DDA)."""
    for k in range(starts.shape[0]):
        _draw_segment(image, starts[k, 0], starts[k, 1], ends[k, 0], ends[k, 1], color)


@njit(cache=True)
def draw_triangle_edges(image: np.ndarray, points: np.ndarray, triangles: np.ndarray,
                        color: np.ndarray) -> None:
    """Draw every edge of a triangle mesh as a one-pixel segment (DDA).

    Each edge runs from its lower to its higher node index, so an edge shared by two triangles
    lands on the same pixels both times and the picture equals drawing each edge once.
    """
    for t in range(triangles.shape[0]):
        for corner in range(3):
            a = triangles[t, corner]
            b = triangles[t, (corner + 1) % 3]
            if a > b:
                a, b = b, a
            _draw_segment(image, points[a, 0], points[a, 1], points[b, 0], points[b, 1], color)


@njit(cache=True, parallel=True)
def color_field(image: np.ndarray, values: np.ndarray, low: float, high: float,
                lut: np.ndarray, scale: int) -> None:
    """Colour cell values (nx, ny) through ``lut`` (256, 3) into the top-left
    (ny * scale, nx * scale) pixels of ``image``, each cell a ``scale`` x ``scale`` block, y up.

    Values map linearly from [low, high] to the table's 256 entries, clipped; NaN takes the
    first entry (as `apply_colormap` does).
    """
    nx, ny = values.shape
    span = high - low if high > low else 1.0
    factor = 255.0 / span
    for j in prange(ny):
        row = (ny - 1 - j) * scale
        for i in range(nx):
            x = (values[i, j] - low) * factor
            if not x >= 0.0:
                index = 0
            elif x > 255.0:
                index = 255
            else:
                index = int(x)
            col = i * scale
            for s in range(scale):
                for c in range(3):
                    image[row, col + s, c] = lut[index, c]
        for r in range(1, scale):
            for col in range(nx * scale):
                for c in range(3):
                    image[row + r, col, c] = image[row, col, c]


@njit(cache=True, parallel=True)
def rgb_to_yuv420(image: np.ndarray, out: np.ndarray) -> None:
    """Convert an RGB frame (H, W, 3) uint8, H and W even, to planar YUV 4:2:0 in ``out``
    (H * W * 3 // 2,) uint8: the Y plane, then U and V at half resolution (2x2 means).

    BT.601 limited range (the conversion ffmpeg applies to RGB input by default, so the video
    looks the same) in 16-bit fixed point; done here it halves the bytes piped
    to the encoder and spares it the conversion.
    """
    height, width = image.shape[0], image.shape[1]
    half_width = width // 2
    u_start = height * width
    v_start = u_start + (height // 2) * half_width
    for pair in prange(height // 2):
        # Row views and plain loops: Numba compiles these ~20 % faster than 2x2 blocks with
        # computed flat indices.
        top = image[2 * pair]
        bottom = image[2 * pair + 1]
        y_top = out[2 * pair * width:(2 * pair + 1) * width]
        y_bottom = out[(2 * pair + 1) * width:(2 * pair + 2) * width]
        u_row = out[u_start + pair * half_width:u_start + (pair + 1) * half_width]
        v_row = out[v_start + pair * half_width:v_start + (pair + 1) * half_width]
        for col in range(width):
            y_top[col] = np.uint8(((16829 * np.int32(top[col, 0]) + 33039 * np.int32(top[col, 1])
                                    + 6416 * np.int32(top[col, 2]) + 32768) >> 16) + 16)
            y_bottom[col] = np.uint8(((16829 * np.int32(bottom[col, 0])
                                       + 33039 * np.int32(bottom[col, 1])
                                       + 6416 * np.int32(bottom[col, 2]) + 32768) >> 16) + 16)
        for half_col in range(half_width):
            col = 2 * half_col
            r_sum = (np.int32(top[col, 0]) + np.int32(top[col + 1, 0])
                     + np.int32(bottom[col, 0]) + np.int32(bottom[col + 1, 0]))
            g_sum = (np.int32(top[col, 1]) + np.int32(top[col + 1, 1])
                     + np.int32(bottom[col, 1]) + np.int32(bottom[col + 1, 1]))
            b_sum = (np.int32(top[col, 2]) + np.int32(top[col + 1, 2])
                     + np.int32(bottom[col, 2]) + np.int32(bottom[col + 1, 2]))
            # Sums of four pixels: the extra factor 4 goes into the shift (16 + 2).
            u_row[half_col] = np.uint8(
                ((-9714 * r_sum - 19070 * g_sum + 28784 * b_sum + 131072) >> 18) + 128)
            v_row[half_col] = np.uint8(
                ((28784 * r_sum - 24103 * g_sum - 4681 * b_sum + 131072) >> 18) + 128)


@njit(cache=True)
def finite_range(values: np.ndarray) -> tuple[int, float, float, float]:
    """(count, min, max, max |value|) of the finite entries of ``values`` (any shape); the
    extremes are NaN when there are none. One pass, without the masked copy NumPy needs.

    Serial: ~40 us at 256^2, and a threaded region waits for a thread that ffmpeg (which
    runs beside a run writing video) has descheduled; measured slower threaded in that case.
    """
    flat = values.ravel()
    count = 0
    low = math.inf
    high = -math.inf
    for k in range(flat.size):
        value = flat[k]
        if math.isfinite(value):
            count += 1
            low = min(low, value)
            high = max(high, value)
    if count == 0:
        return 0, math.nan, math.nan, math.nan
    return count, low, high, max(abs(low), abs(high))


@njit(cache=True)
def speed_from_faces(velocity_x: np.ndarray, velocity_y: np.ndarray, out: np.ndarray) -> None:
    """Velocity magnitude at cell centres from MAC face velocities: ``out`` (nx, ny) from
    ``velocity_x`` (nx + 1, ny) and ``velocity_y`` (nx, ny + 1) [m/s]."""
    nx, ny = out.shape
    for i in range(nx):
        for j in range(ny):
            ux = 0.5 * (velocity_x[i, j] + velocity_x[i + 1, j])
            vy = 0.5 * (velocity_y[i, j] + velocity_y[i, j + 1])
            out[i, j] = math.sqrt(ux * ux + vy * vy)


@njit(cache=True, parallel=True)
def draw_liquid(image: np.ndarray, phi: np.ndarray, scale: int, line_width: float,
                air_color: np.ndarray, line_color: np.ndarray) -> None:
    """Blank the air and draw the free surface over the field coloured by `color_field`.

    ``phi`` (nx, ny) is the level set at the cell centres (liquid where negative), in cells
    of ``scale`` pixels; each pixel of the top-left (ny * scale, nx * scale) block samples it
    bilinearly at its centre (clamped at the ends): pixels with ``|phi| <= line_width`` (in
    the level set's unit) take ``line_color``, the other air pixels (``phi >= 0``)
    ``air_color``, the liquid keeps its colour.
    """
    nx, ny = phi.shape
    height = ny * scale
    width = nx * scale
    inverse = 1.0 / scale
    for row in prange(height):
        y = (height - row - 0.5) * inverse - 0.5
        y = min(max(y, 0.0), ny - 1.0)
        j = min(int(y), max(ny - 2, 0))
        ty = y - j
        j1 = min(j + 1, ny - 1)
        for col in range(width):
            x = (col + 0.5) * inverse - 0.5
            x = min(max(x, 0.0), nx - 1.0)
            i = min(int(x), max(nx - 2, 0))
            tx = x - i
            i1 = min(i + 1, nx - 1)
            low = phi[i, j] + tx * (phi[i1, j] - phi[i, j])
            high = phi[i, j1] + tx * (phi[i1, j1] - phi[i, j1])
            value = low + ty * (high - low)
            if abs(value) <= line_width:
                for c in range(3):
                    image[row, col, c] = line_color[c]
            elif value >= 0.0:
                for c in range(3):
                    image[row, col, c] = air_color[c]
