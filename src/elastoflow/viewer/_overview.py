"""The 3D window's overview: the domain, the slice plane and the surfaces in 3D.

An orthographic view from the front (+z), right (+x) and above (+y), y up::

         +-----------+        box edges grey; the three through the domain's origin corner
        /|    |     /|        x red, y green, z blue; the slice plane tinted with a yellow
       +-----------+ |        rim; bodies light and obstacles grey, shaded by a light from
       | |    |    | |        over the viewer's shoulder, hidden surfaces removed by a depth
       | +----|----|-+        buffer
       |/     |    |/
       +-----------+
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from elastoflow.render._kernels import draw_segments, fill_polygon
from elastoflow.viewer._kernels import fill_triangles_depth

BACKGROUND_COLOR = np.array([28, 30, 36], dtype=np.uint8)
BOX_COLOR = np.array([120, 124, 135], dtype=np.uint8)
AXIS_COLORS = np.array([[230, 60, 60], [60, 200, 80], [80, 130, 255]], dtype=np.uint8)
PLANE_FILL_COLOR = np.array([62, 66, 92], dtype=np.uint8)
PLANE_EDGE_COLOR = np.array([250, 210, 40], dtype=np.uint8)
BODY_SURFACE_COLOR = np.array([235, 225, 205], dtype=np.float64)
OBSTACLE_SURFACE_COLOR = np.array([150, 150, 150], dtype=np.float64)
_MARGIN = 0.08
"""Fraction of the panel left free around the domain's picture."""


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
        a, e = np.radians(azimuth), np.radians(elevation)
        self.eye = np.array([np.sin(a) * np.cos(e), np.sin(e), np.cos(a) * np.cos(e)])
        self.right = _unit(np.cross([0.0, 1.0, 0.0], self.eye))
        self.up = np.cross(self.eye, self.right)
        self.light = _unit(self.eye + 0.6 * self.up + 0.3 * self.right)
        low = np.asarray(grid.origin, dtype=np.float64)
        high = low + np.asarray(grid.shape_cells, dtype=np.float64) * grid.h
        self.low, self.high = low, high
        self.corners = np.array([[(low, high)[i][0], (low, high)[j][1], (low, high)[k][2]]
                                 for i in (0, 1) for j in (0, 1) for k in (0, 1)])
        flat = self.corners @ np.stack((self.right, self.up), axis=1)
        lowest, highest = flat.min(axis=0), flat.max(axis=0)
        self._pixels_per_metre = (1.0 - 2.0 * _MARGIN) * self.size / float(
            (highest - lowest).max())
        self._centre = 0.5 * (lowest + highest)
        # Box edges: corner pairs differing in one coordinate (corner index bits k, j, i).
        self._edges = np.array([(c, c | bit) for bit in (4, 2, 1) for c in range(8)
                                if not c & bit])
        self._depth = np.empty((self.size, self.size))

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

    def draw(self, image: np.ndarray, axis: int, position: float,
             bodies: Sequence[tuple[np.ndarray, np.ndarray]] = (),
             obstacles: Sequence[tuple[np.ndarray, np.ndarray]] = ()) -> None:
        """Draw into ``image`` (size, size, 3) uint8: the box, the plane ``x[axis] =
        position`` [m], the bodies' and obstacles' surfaces ``(points (n, 3), triangles (T,
        3))`` [m]."""
        image[...] = BACKGROUND_COLOR
        plane = np.array([self.low, self.low, self.high, self.high], dtype=np.float64)
        across, up = [a for a in range(3) if a != axis]
        plane[1, up], plane[3, up] = self.high[up], self.low[up]
        plane[:, axis] = position
        plane_pixels, _ = self.to_pixels(plane)
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
        draw_segments(image, plane_pixels, np.roll(plane_pixels, -1, axis=0),
                      PLANE_EDGE_COLOR)
