"""The free surface as lines: the zero contour of a level set, packed for the field files and
extruded for Blender."""

from __future__ import annotations

import numpy as np
import pytest

from elastoflow.grid import Grid2D
from elastoflow.io._surface import pack_polylines, surface_polylines, write_surface_mesh

GRID = Grid2D(64, 48, 1.0 / 32, origin=(-1.0, 0.0))


def _cell_centres():
    x = GRID.origin[0] + (np.arange(GRID.nx) + 0.5) * GRID.h
    y = GRID.origin[1] + (np.arange(GRID.ny) + 0.5) * GRID.h
    return np.meshgrid(x, y, indexing="ij")


def test_a_drop_is_one_closed_loop_on_its_circle() -> None:
    x, y = _cell_centres()
    phi = np.hypot(x - 0.1, y - 0.7) - 0.3
    lines = surface_polylines(GRID, phi)
    assert len(lines) == 1
    loop = lines[0]
    np.testing.assert_allclose(loop[0], loop[-1])
    radius = np.hypot(loop[:, 0] - 0.1, loop[:, 1] - 0.7)
    # Bilinear interpolation of a distance function: within h^2 / R of the circle.
    assert np.abs(radius - 0.3).max() < GRID.h**2 / 0.3


def test_a_flat_surface_is_one_line_at_its_height_and_dry_or_full_grids_have_none() -> None:
    x, y = _cell_centres()
    lines = surface_polylines(GRID, y - 0.61)
    assert len(lines) == 1 and np.allclose(lines[0][:, 1], 0.61)
    assert lines[0][:, 0].min() == pytest.approx(GRID.origin[0] + 0.5 * GRID.h)
    assert surface_polylines(GRID, np.ones(GRID.shape_cells)) == []
    assert surface_polylines(GRID, -np.ones(GRID.shape_cells)) == []
    with pytest.raises(ValueError, match="level_set shape"):
        surface_polylines(GRID, np.ones((3, 3)))


def test_pieces_pack_and_extrude(tmp_path) -> None:
    x, y = _cell_centres()
    phi = np.minimum(np.hypot(x + 0.5, y - 0.5) - 0.2, np.hypot(x - 0.5, y - 0.5) - 0.2)
    lines = surface_polylines(GRID, phi)
    assert len(lines) == 2
    points, offsets = pack_polylines(lines)
    assert offsets[0] == 0 and offsets[-1] == len(points) and len(offsets) == 3
    np.testing.assert_array_equal(points[offsets[1]:offsets[2]], lines[1])
    path = tmp_path / "surface.obj"
    write_surface_mesh(path, lines, 0.05)
    text = path.read_text()
    assert text.count("\nv ") == 2 * len(points)
    assert text.count("\nf ") == 2 * (len(points) - 2)
    empty_points, empty_offsets = pack_polylines([])
    assert empty_points.shape == (0, 2) and list(empty_offsets) == [0]
