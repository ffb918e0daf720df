"""The 3D window's overview: the domain, the slice plane and the surfaces in 3D.

An orthographic view from the front (+z), right (+x) and above (+y), y up::

         +-----------+        box edges grey; the three through the domain's origin corner
        /|    |     /|        x red, y green, z blue; the slice plane with the slice's
       +-----------+ |        picture on it (mostly opaque: what lies behind shows faintly)
       | |    |    | |        and a yellow rim; bodies light and obstacles grey, shaded by
       | +----|----|-+        a light from over the viewer's shoulder, hidden surfaces
       |/     |    |/         removed by a depth buffer
       +-----------+
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import lru_cache
from typing import Any

import numpy as np

from elastoflow.render._kernels import draw_segments, fill_polygon
from elastoflow.viewer._kernels import blend_picture, fill_triangles_depth

BACKGROUND_COLOR = np.array([28, 30, 36], dtype=np.uint8)
BOX_COLOR = np.array([120, 124, 135], dtype=np.uint8)
AXIS_COLORS = np.array([[230, 60, 60], [60, 200, 80], [80, 130, 255]], dtype=np.uint8)
PLANE_FILL_COLOR = np.array([62, 66, 92], dtype=np.uint8)
PLANE_EDGE_COLOR = np.array([250, 210, 40], dtype=np.uint8)
BODY_SURFACE_COLOR = np.array([235, 225, 205], dtype=np.float64)
OBSTACLE_SURFACE_COLOR = np.array([150, 150, 150], dtype=np.float64)
_MARGIN = 0.08
"""Fraction of the panel left free around the domain's picture."""
MAX_ELEVATION = 85.0
"""The eye's highest (and lowest) elevation [degrees]."""
PLANE_OPACITY = 0.85
"""How much of the slice's picture covers what lies behind the plane."""


def _unit(vector: np.ndarray) -> np.ndarray:
    return vector / np.linalg.norm(vector)


class Overview:
    """Draws the overview of a `Grid3D` domain into a square panel.

    Args:
        grid: The `Grid3D`.
        size: The panel's side [pixels].
        azimuth: The eye's turn from +z towards +x [degrees].
        elevation: The eye's height above the x-z plane [degrees].
    """

    def __init__(self, grid: Any, size: int, *, azimuth: float = 35.0,
                 elevation: float = 25.0) -> None:
        self.grid = grid
        self.size = int(size)
        low = np.asarray(grid.origin, dtype=np.float64)
        high = low + np.asarray(grid.shape_cells, dtype=np.float64) * grid.h
        self.low, self.high = low, high
        self.corners = np.array([[(low, high)[i][0], (low, high)[j][1], (low, high)[k][2]]
                                 for i in (0, 1) for j in (0, 1) for k in (0, 1)])
        # The box's circumscribed sphere fills the panel whatever the turn: no zooming.
        self._pixels_per_metre = (1.0 - 2.0 * _MARGIN) * self.size / float(
            np.linalg.norm(high - low))
        # Box edges: corner pairs differing in one coordinate (corner index bits k, j, i).
        self._edges = np.array([(c, c | bit) for bit in (4, 2, 1) for c in range(8)
                                if not c & bit])
        self._depth = np.empty((self.size, self.size))
        self._plane_map = lru_cache(maxsize=8)(self._plane_pixels)
        self.orient(azimuth, elevation)

    def orient(self, azimuth: float, elevation: float) -> None:
        """Turn the eye: ``azimuth`` from +z towards +x and ``elevation`` above the x-z
        plane [degrees] (kept within 85 degrees of level, where "up" stays defined)."""
        self.azimuth = float(azimuth) % 360.0
        self.elevation = float(np.clip(elevation, -MAX_ELEVATION, MAX_ELEVATION))
        a, e = np.radians(self.azimuth), np.radians(self.elevation)
        self.eye = np.array([np.sin(a) * np.cos(e), np.sin(e), np.cos(a) * np.cos(e)])
        self.right = _unit(np.cross([0.0, 1.0, 0.0], self.eye))
        self.up = np.cross(self.eye, self.right)
        self.light = _unit(self.eye + 0.6 * self.up + 0.3 * self.right)
        self._centre = 0.5 * (self.low + self.high) @ np.stack((self.right, self.up), axis=1)
        self._plane_map.cache_clear()

    def to_pixels(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Points [m] (n, 3) to panel pixels (n, 2) (x right, y down) and depth (n,) [m],
        growing towards the eye."""
        points = np.asarray(points, dtype=np.float64)
        flat = points @ np.stack((self.right, self.up), axis=1) - self._centre
        pixels = np.empty((points.shape[0], 2))
        pixels[:, 0] = 0.5 * self.size + flat[:, 0] * self._pixels_per_metre
        pixels[:, 1] = 0.5 * self.size - flat[:, 1] * self._pixels_per_metre
        return pixels, points @ self.eye

    def _shade(self, points: np.ndarray, triangles: np.ndarray,
               base: np.ndarray) -> np.ndarray:
        corners = points[triangles]
        normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
        length = np.linalg.norm(normals, axis=1)
        facing = (normals @ self.light) / np.where(length > 0.0, length, 1.0)
        intensity = 0.35 + 0.65 * np.clip(facing, 0.0, 1.0)
        return (intensity[:, None] * base).astype(np.uint8)

    def _plane_pixels(self, axis: int, position: float, rows: int, cols: int
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
        """The panel pixels the plane ``x[axis] = position`` covers (flat indices), the
        pixel of a (rows, cols) picture of it that each shows (row, col) and the plane's
        depth there; None when the plane is seen edge-on."""
        across, up = [a for a in range(3) if a != axis]
        base = self.low.copy()
        base[axis] = position
        corners = np.stack((base, base, base))
        corners[1, across] = self.high[across]
        corners[2, up] = self.high[up]
        pixels, depth = self.to_pixels(corners)
        matrix = np.stack((pixels[1] - pixels[0], pixels[2] - pixels[0]), axis=1)
        if abs(np.linalg.det(matrix)) < 1.0:
            return None
        centres = np.arange(self.size) + 0.5
        offset = np.stack(np.meshgrid(centres, centres, indexing="xy"), axis=-1).reshape(-1, 2)
        s, t = np.linalg.solve(matrix, (offset - pixels[0]).T)
        inside = np.flatnonzero((s >= 0.0) & (s < 1.0) & (t >= 0.0) & (t < 1.0))
        s, t = s[inside], t[inside]
        row = np.minimum(((1.0 - t) * rows).astype(np.int64), rows - 1)
        col = np.minimum((s * cols).astype(np.int64), cols - 1)
        plane_depth = depth[0] + s * (depth[1] - depth[0]) + t * (depth[2] - depth[0])
        return inside, row, col, plane_depth

    def draw(self, image: np.ndarray, axis: int, position: float,
             bodies: Sequence[tuple[np.ndarray, np.ndarray]] = (),
             obstacles: Sequence[tuple[np.ndarray, np.ndarray]] = (),
             picture: np.ndarray | None = None) -> None:
        """Draw into ``image`` (size, size, 3) uint8, C-contiguous: the box, the plane
        ``x[axis] = position`` [m] with ``picture`` on it (the slice's field, (rows, cols, 3)
        uint8, drawn as `render_slice_3d` draws it; a plain tint when None), the bodies' and
        obstacles' surfaces ``(points (n, 3), triangles (T, 3))`` [m]."""
        image[...] = BACKGROUND_COLOR
        plane = np.array([self.low, self.low, self.high, self.high], dtype=np.float64)
        across, up = [a for a in range(3) if a != axis]
        plane[1, up], plane[3, up] = self.high[up], self.low[up]
        plane[:, axis] = position
        plane_pixels, _ = self.to_pixels(plane)
        if picture is None:
            fill_polygon(image, plane_pixels, PLANE_FILL_COLOR)
        corners, _ = self.to_pixels(self.corners)
        draw_segments(image, corners[self._edges[:, 0]], corners[self._edges[:, 1]], BOX_COLOR)
        for k, bit in enumerate((4, 2, 1)):
            draw_segments(image, corners[:1], corners[bit:bit + 1], AXIS_COLORS[k])
        self._depth[...] = -np.inf
        for surfaces, base in ((bodies, BODY_SURFACE_COLOR),
                               (obstacles, OBSTACLE_SURFACE_COLOR)):
            for points, triangles in surfaces:
                points = np.asarray(points, dtype=np.float64)
                triangles = np.asarray(triangles, dtype=np.int64)
                pixels, depth = self.to_pixels(points)
                fill_triangles_depth(image, self._depth, pixels, depth, triangles,
                                     self._shade(points, triangles, base))
        if picture is not None:
            mapping = self._plane_map(axis, float(position), *picture.shape[:2])
            if mapping is not None:
                inside, row, col, plane_depth = mapping
                blend_picture(image, self._depth, inside, row, col, plane_depth, picture,
                              PLANE_OPACITY)
        draw_segments(image, plane_pixels, np.roll(plane_pixels, -1, axis=0),
                      PLANE_EDGE_COLOR)
