"""A free surface as lines: the zero contour of the level set, for the field files (a polyline
per piece) and for Blender (an extruded ribbon per frame, beside the bodies' meshes).

The contour comes from contourpy (matplotlib's own contouring library, BSD-3), which follows
the level set's bilinear interpolation between the cell centres: where the level set is a
distance function this is the sub-cell surface the projection sees.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np


def surface_polylines(grid: Any, level_set: np.ndarray) -> list[np.ndarray]:
    """The pieces of the zero contour of ``level_set`` (nx, ny) [m], sampled at the cell
    centres of ``grid``: each an (n, 2) array of points [m] in order, a closed piece with its
    first point repeated at the end. Pieces end where they leave the cell centres' box (half
    a cell inside the walls)."""
    import contourpy

    phi = np.asarray(level_set, dtype=np.float64)
    if phi.shape != grid.shape_cells:
        raise ValueError(f"level_set shape {phi.shape}: must be {grid.shape_cells}")
    if phi.min() >= 0.0 or phi.max() <= 0.0:
        return []
    ox, oy = grid.origin
    x = ox + (np.arange(grid.nx) + 0.5) * grid.h
    y = oy + (np.arange(grid.ny) + 0.5) * grid.h
    # contourpy takes z indexed [row = y, column = x].
    generator = contourpy.contour_generator(x, y, phi.T, line_type="Separate")
    return [np.asarray(line, dtype=np.float64) for line in generator.lines(0.0)
            if len(line) >= 2]


def pack_polylines(lines: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """``lines`` as one (k, 2) point array and offsets (n + 1,): piece i is
    ``points[offsets[i]:offsets[i + 1]]`` (the field files' ``surface_points`` and
    ``surface_offsets``)."""
    if not lines:
        return np.zeros((0, 2)), np.zeros(1, dtype=np.int64)
    offsets = np.concatenate([[0], np.cumsum([len(line) for line in lines])]).astype(np.int64)
    return np.concatenate(lines), offsets


def write_surface_mesh(path: str | Path, lines: list[np.ndarray], thickness: float,
                       file_format: str = "obj") -> None:
    """The surface's pieces extruded along z over ``thickness`` [m] into one ribbon mesh,
    written atomically (OBJ or PLY)."""
    from elastoflow.io._meshes import MESH_WRITERS, extrude_polyline

    vertices, faces = [], []
    count = 0
    for line in lines:
        v, f = extrude_polyline(line, thickness)
        vertices.append(v)
        faces.append(f + count)
        count += len(v)
    MESH_WRITERS[file_format](
        path, np.concatenate(vertices) if vertices else np.zeros((0, 3)),
        np.concatenate(faces) if faces else np.zeros((0, 3), dtype=np.int64))
