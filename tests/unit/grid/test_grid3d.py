"""Grid3D: validation, shapes and the positions of each kind of point."""

from __future__ import annotations

import numpy as np
import pytest

from elastoflow.grid import Grid3D


def test_shapes_follow_the_mac_layout() -> None:
    grid = Grid3D(nx=4, ny=3, nz=2, h=0.5)
    assert grid.shape_cells == (4, 3, 2)
    assert grid.shape_faces_x == (5, 3, 2)
    assert grid.shape_faces_y == (4, 4, 2)
    assert grid.shape_faces_z == (4, 3, 3)
    assert [grid.shape_faces(a) for a in range(3)] == [
        grid.shape_faces_x, grid.shape_faces_y, grid.shape_faces_z]
    assert grid.cell_count == 24
    assert (grid.lx, grid.ly, grid.lz) == (2.0, 1.5, 1.0)


def test_points_sit_at_cell_centres_and_face_centres() -> None:
    grid = Grid3D(nx=3, ny=2, nz=2, h=0.25, origin=(1.0, -1.0, 2.0))
    x, y, z = grid.cell_centers()
    assert x.shape == grid.shape_cells
    assert (x[0, 0, 0], y[0, 0, 0], z[0, 0, 0]) == (1.125, -0.875, 2.125)
    xu, yu, zu = grid.faces_x()
    assert xu.shape == grid.shape_faces_x
    assert (xu[3, 1, 1], yu[3, 1, 1], zu[3, 1, 1]) == (1.75, -0.625, 2.375)
    xv, yv, zv = grid.faces_y()
    assert (xv[0, 2, 0], yv[0, 2, 0], zv[0, 2, 0]) == (1.125, -0.5, 2.125)
    xw, yw, zw = grid.faces_z()
    assert (xw[0, 0, 2], yw[0, 0, 2], zw[0, 0, 2]) == (1.125, -0.875, 2.5)
    # Each face lies halfway between the two cell centres it separates.
    np.testing.assert_allclose(xu[1:-1], 0.5 * (x[1:] + x[:-1]))
    np.testing.assert_allclose(zw[:, :, 1:-1], 0.5 * (z[:, :, 1:] + z[:, :, :-1]))


def test_from_extent_needs_whole_cells() -> None:
    grid = Grid3D.from_extent(2.0, 1.0, 0.5, nx=8)
    assert (grid.nx, grid.ny, grid.nz, grid.h) == (8, 4, 2, 0.25)
    with pytest.raises(ValueError, match="lz"):
        Grid3D.from_extent(2.0, 1.0, 0.6, nx=8)


@pytest.mark.parametrize("kwargs, message", [
    ({"nx": 1, "ny": 4, "nz": 4, "h": 1.0}, "nx"),
    ({"nx": 4, "ny": 2.5, "nz": 4, "h": 1.0}, "ny"),
    ({"nx": 4, "ny": 4, "nz": 0, "h": 1.0}, "nz"),
    ({"nx": 4, "ny": 4, "nz": 4, "h": 0.0}, "h"),
    ({"nx": 4, "ny": 4, "nz": 4, "h": float("nan")}, "h"),
    ({"nx": 4, "ny": 4, "nz": 4, "h": 1.0, "origin": (0.0, 0.0)}, "origin"),
])
def test_invalid_grids_are_refused(kwargs: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        Grid3D(**kwargs)


def test_shape_faces_refuses_a_fourth_axis() -> None:
    with pytest.raises(ValueError, match="axis"):
        Grid3D(nx=2, ny=2, nz=2, h=1.0).shape_faces(3)
